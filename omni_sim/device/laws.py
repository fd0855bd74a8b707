"""The drive's friction laws that no MJCF attribute can hold: a registry (:data:`DRIVE_LAWS`).

Friction set by the torque the gearbox transmits (:data:`LOAD_FRICTION`), direction-dependent
Coulomb friction (:data:`FRICTION_ASYMMETRY`), the load- and velocity-dependent family
(:data:`FRICTION_FAMILY`), the next one a user writes (:func:`register_drive_law`), and a servo
firmware's current limit (:data:`CURRENT_LIMIT`): declared in the model's ``<custom>`` numerics,
read into a :class:`DriveFriction` by the :class:`~omni_sim.device.Device` and applied by the
:class:`~omni_sim.device.Engine` at every control period (:class:`_DriveLaws`, the rows of a
batch as arrays; also :mod:`omni_sim.runtime`'s).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from identification.errors import UserError

#: ``<custom><numeric name="load_friction" data="mu_drive mu_back [b_emf]"/>``: Coulomb friction
#: that rises with the torque the gearbox transmits (:data:`DRIVE_LAWS`), the actuator's torque
#: less ``b_emf`` [N*m*s/rad] times the joint velocity (the motor's back-EMF; 0 when absent).
LOAD_FRICTION = "load_friction"
#: The speed [rad/s] over which :data:`LOAD_FRICTION`'s coefficient passes from ``mu_back``
#: to ``mu_drive`` (a smooth sign, ``tanh(sign(tau) w / w_b)``): 0.05 rad/s.  An ESTIMATE, a
#: modelling choice like any regularised Coulomb law's transition speed: the speed the bank's
#: gear-efficiency truth uses for its smooth sign (bank/servo_truth.py,
#: 0.5 % of the geared servo's no-load speed), 0.12 of one encoder count per 1 ms period on
#: the Omni (0.42 rad/s), so no log resolves it within one period.  Why not a switch on
#: ``sign(tau w)`` (mu_back at rest): the training error is jagged in the coefficients and a
#: fit stalls wherever it starts (on the bank's load_friction_nominal_off runs, fits from the
#: truth, from a point 20 % off and from the nominal stopped at training gaps of 6.2e-4,
#: 8.7e-4 and 1.3e-3 rad), while with the blend all three land on one point, 6.0e-4 rad
#: (docs/studies/discrepancy/valley_scan.json).  0 makes the law that switch (mu_back at rest), kept
#: for that record.
LOAD_FRICTION_BLEND_RAD_S = 0.05
#: ``<custom><numeric name="friction_asymmetry" data="a"/>`` [N*m]: the joint's Coulomb level is
#: ``frictionloss + a`` moving positive, ``frictionloss - a`` moving negative.
FRICTION_ASYMMETRY = "friction_asymmetry"
#: ``<custom><numeric name="friction_family" data="k_drive k_back rise_nm omega_s delta"/>``:
#: the load- and velocity-dependent dry friction of a geared drive, after Hamon, Gautier and
#: Garrec (2010, "Dynamic identification of robots with a dry friction model depending on load
#: and velocity", IEEE/RSJ IROS): the Coulomb level ``Fc0 + k |tau|`` (``k_drive`` while the
#: motor drives the load, ``k_back`` while the load back-drives it, blended as
#: :data:`LOAD_FRICTION`'s coefficients) plus a Stribeck rise
#: ``rise_nm exp(-(|w| / omega_s)^delta)`` (``rise_nm`` = Fs - Fc0, the static level's excess).
#: ``Fc0`` is the joint's own ``frictionloss`` and the law's viscous term ``Fv w`` the joint's
#: own ``damping`` (both native MJCF, integrated by MuJoCo); the numeric holds the rest.  The
#: nested variants the discrepancy library fits are in :mod:`discrepancy.effects.family`.
FRICTION_FAMILY = "friction_family"
#: ``<custom><numeric name="load_friction_smooth" data="mu_drive mu_back b_emf w_s"/>``:
#: :data:`LOAD_FRICTION`'s load-dependent friction behind a smooth sign instead of a stick, the
#: regularised Coulomb law of Makkar, Dixon, Sawyer and Hu (2005, "A new continuously
#: differentiable friction model for control systems design", IEEE/ASME AIM) with a level that
#: grows with the transmitted torque: the joint force ``-L tanh(w / w_s)``, ``L = mu |tau|``,
#: ``tau = gear * actuator_force - b_emf w``, ``mu = mu_drive`` while ``tau w > 0`` (the motor
#: drives) else ``mu_back`` (continuous: ``L tanh`` vanishes where either side switches).  It
#: holds nothing at rest: a load on a held joint creeps until its speed engages the level.  MuJoCo
#: has no such element; the engine applies it linearly implicitly at every control period: the
#: slope ``s = L (1 - tanh^2) / w_s`` is added to the joint's ``damping`` (which MuJoCo's
#: implicit integrators treat implicitly) and ``-L tanh(w / w_s) + s w`` goes to
#: ``qfrc_applied``, so a period sees ``-L tanh(w0 / w_s) - s (w - w0)``, stable for any
#: ``w_s`` (``bank/servo_truth.py``'s efficiency truth applies its loss so).  Why: a load law
#: that sticks cannot follow a gear whose loss vanishes at rest (docs/method/discrepancy.md,
#: "A load law that sticks, beside one behind a smooth sign").
LOAD_FRICTION_SMOOTH = "load_friction_smooth"
#: The parameters of :data:`LOAD_FRICTION_SMOOTH`'s numeric, in order.
LOAD_FRICTION_SMOOTH_PARAMS = ("mu_drive", "mu_back", "b_emf", "w_s")
#: ``<custom><numeric name="current_limit" data="torque_limit_nm back_emf_nms_per_rad"/>``: a
#: servo firmware's current limit ``|i| <= i_max`` on a motor driven by its voltage, whose
#: back-EMF the model writes as joint damping.  With ``tau_i = kt i_max`` and ``b = kt ke / R``
#: (the electrical part of the damping) the motor's net torque ``gear * force - b w`` stays in
#: ``[-tau_i, tau_i]``: the engine sets the actuator's ``forcerange`` to
#: ``[(b w - tau_i) / gear, (b w + tau_i) / gear]`` at every control period.  With the voltage
#: clip (``ctrlrange`` +-V_s, ``gear`` = kt / R) the torque the motor can give in the direction
#: of motion is ``kt min(i_max, (V_s - ke |w|) / R)``, a servo datasheet's stall current and
#: supply voltage.  ``b = 0``: a fixed torque saturation (``torque_saturation``).  For a
#: ``dcmotor`` actuator (back-EMF inside its force) MuJoCo 4 has this natively:
#: ``saturation="0 i_max V_s"`` (``forcerange`` = K i_max, the voltage clamp in ``dynprm[1]``).
CURRENT_LIMIT = "current_limit"


def current_limit_range(tau_i, b, gear, w):
    """:data:`CURRENT_LIMIT`'s actuator force range ``(lower, upper)`` at joint velocity ``w``:
    the net motor torque ``gear * force - b w`` within ``+-tau_i``, i.e. ``force`` in
    ``[(b w - tau_i) / gear, (b w + tau_i) / gear]`` (numbers or arrays of rows)."""
    return (b * w - tau_i) / gear, (b * w + tau_i) / gear


def _numeric(model: mujoco.MjModel, name: str) -> np.ndarray | None:
    """The data of the model's ``<custom><numeric name=...>``, or None."""
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, name)
    if i < 0:
        return None
    a = int(model.numeric_adr[i])
    return np.array(model.numeric_data[a: a + int(model.numeric_size[i])], float)


@dataclass(frozen=True)
class DriveLaw:
    """One named term of the drive's Coulomb level, which no MJCF attribute can hold: the
    engine adds it to the joint's own ``frictionloss`` at every control period
    (:class:`DriveFriction`).  A model declares it with ``<custom><numeric name="NAME"
    data="..."/>`` (its :attr:`params`, in order).

    Attributes
    ----------
    name : str
        The ``<custom>`` numeric's name.
    params : tuple of str
        Its entries, in order.
    term : callable
        ``term(values, w, tau) -> ndarray (B,)`` [N*m]: the term of B rows, with ``values`` of
        shape (B, len(params)), the joint velocities ``w`` [rad/s] and the transmitted torques
        ``tau`` [N*m] (B,).  All-zero values must give a zero term (a row without the law).
    check : callable
        ``check(values) -> str | None``: why a model's values are not a law (one line), or None.
    needs_torque : bool
        The term reads ``tau``: the model needs an ``actuatorfrc`` sensor on the actuator.
    """

    name: str
    params: tuple
    term: object
    check: object
    needs_torque: bool = False


def _asymmetry_term(v: np.ndarray, w: np.ndarray, tau: np.ndarray) -> np.ndarray:
    return v[:, 0] * np.sign(w)


def _asymmetry_check(v: np.ndarray) -> str | None:
    return None if len(v) == 1 and np.isfinite(v[0]) else "must hold one finite level [N*m]"


def _load_term(v: np.ndarray, w: np.ndarray, tau: np.ndarray) -> np.ndarray:
    # the torque the gearbox transmits is the motor's net torque: the actuator's minus the
    # back-EMF's share of the joint damping, b_emf w (v[:, 2]; 0 for a two-entry numeric)
    if v.shape[1] > 2:
        tau = tau - v[:, 2] * w
    # mu_drive while the motor drives the load (sign(tau) w >> w_b), mu_back while the load
    # back-drives the motor (sign(tau) w << -w_b), their mean at rest, smoothly in between
    if LOAD_FRICTION_BLEND_RAD_S == 0:  # the switch on sign(tau w), mu_back at rest (valley_scan.py)
        return np.where(tau * w > 0, v[:, 0], v[:, 1]) * np.abs(tau)
    s = 0.5 * (1.0 + np.tanh(np.sign(tau) * w / LOAD_FRICTION_BLEND_RAD_S))
    return (v[:, 1] + (v[:, 0] - v[:, 1]) * s) * np.abs(tau)


def _load_check(v: np.ndarray) -> str | None:
    ok = len(v) in (2, 3) and np.all(np.isfinite(v)) and not np.any(v < 0)
    return None if ok else ("must hold two coefficients >= 0 (mu_drive mu_back) and optionally the "
                            "back-EMF damping >= 0 [N*m*s/rad]")


def _family_term(v: np.ndarray, w: np.ndarray, tau: np.ndarray) -> np.ndarray:
    # the load-dependent part is load_friction's law (the same blend), the Stribeck rise
    # rise * exp(-(|w| / omega_s)^delta) is 1 x rise at rest and vanishes for |w| >> omega_s
    load = _load_term(v[:, [0, 1, 5]] if v.shape[1] > 5 else v[:, :2], w, tau)
    rise, ws, delta = v[:, 2], v[:, 3], v[:, 4]
    on = (rise > 0) & (ws > 0)
    x = np.abs(w) / np.where(on, ws, 1.0)
    return load + np.where(on, rise * np.exp(-np.power(x, np.where(on, delta, 1.0))), 0.0)


def _family_check(v: np.ndarray) -> str | None:
    ok = (len(v) in (5, 6) and np.all(np.isfinite(v)) and not np.any(v < 0)
          and (v[2] == 0 or (v[3] > 0 and v[4] > 0)))
    return None if ok else ("must hold five values >= 0 (k_drive k_back rise_nm omega_s delta) and "
                            "optionally the back-EMF damping b_emf, omega_s and delta > 0 when rise_nm > 0")


def _limit_check(v: np.ndarray) -> str | None:
    ok = len(v) == 2 and np.all(np.isfinite(v)) and v[0] > 0 and v[1] >= 0
    return None if ok else "must hold a torque limit > 0 [N*m] and a back-EMF damping >= 0 [N*m*s/rad]"


def _smooth_check(v: np.ndarray) -> str | None:
    ok = len(v) == 4 and np.all(np.isfinite(v)) and not np.any(v < 0) and v[3] > 0
    return None if ok else "must hold mu_drive mu_back b_emf >= 0 and a sign speed w_s > 0 [rad/s]"


def smooth_load_level(v: np.ndarray, w: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """:data:`LOAD_FRICTION_SMOOTH`'s level ``L = mu |tau - b_emf w|`` [N*m], ``mu = mu_drive``
    where the motor drives (``(tau - b_emf w) w > 0``) else ``mu_back``; ``v`` (B, 4) the rows'
    values, ``w`` their joint velocities, ``tau`` their actuators' torques (``gear *
    actuator_force``)."""
    tau = tau - v[:, 2] * w
    return np.where(tau * w > 0, v[:, 0], v[:, 1]) * np.abs(tau)


def smooth_load_force(v: np.ndarray, w: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:data:`LOAD_FRICTION_SMOOTH`'s joint force ``-L tanh(w / w_s)`` [N*m] of B rows and its
    slope ``-dF/dw = L (1 - tanh^2) / w_s`` [N*m*s/rad], with ``v`` (B, 4) the rows' values
    (``w_s`` > 0), ``w`` their joint velocities and ``tau`` their actuators' torques
    (``gear * actuator_force``); ``L`` :func:`smooth_load_level`."""
    level = smooth_load_level(v, w, tau)
    th = np.tanh(w / v[:, 3])
    return -level * th, level * (1.0 - th * th) / v[:, 3]


#: The parameters of :data:`CURRENT_LIMIT`'s numeric, in order.
CURRENT_LIMIT_PARAMS = ("torque_limit_nm", "back_emf_nms_per_rad")


#: The drive laws the engine knows, by name, in the order their terms are added (the Coulomb
#: level is ``max(0, frictionloss + term_1 + term_2 + ...)``).  A new law is a
#: :class:`DriveLaw` added here (:func:`register_drive_law`).
DRIVE_LAWS: dict[str, DriveLaw] = {
    FRICTION_ASYMMETRY: DriveLaw(FRICTION_ASYMMETRY, ("a",), _asymmetry_term, _asymmetry_check),
    LOAD_FRICTION: DriveLaw(LOAD_FRICTION, ("mu_drive", "mu_back", "b_emf"), _load_term, _load_check,
                            needs_torque=True),
    FRICTION_FAMILY: DriveLaw(FRICTION_FAMILY, ("k_drive", "k_back", "rise_nm", "omega_s", "delta", "b_emf"),
                              _family_term, _family_check, needs_torque=True),
}


def register_drive_law(law: DriveLaw) -> None:
    """Add ``law`` to :data:`DRIVE_LAWS` (after the others; a name already there is an error)."""
    if law.name in DRIVE_LAWS:
        raise ValueError(f"a drive law named {law.name!r} exists already")
    DRIVE_LAWS[law.name] = law


@dataclass(frozen=True)
class DriveFriction:
    """The drive laws (:data:`DRIVE_LAWS`) a model declares, applied by the engine.

    At the start of every control period the joint's Coulomb level (MuJoCo's
    ``dof_frictionloss``, a true stick) is set to

        F = max(0, Fc + a sign(w) + mu |tau|),   tau = gear * actuator_force - b_emf w,
        mu = mu_back + (mu_drive - mu_back) (1 + tanh(sign(tau) w / w_b)) / 2,

    for the two laws the library holds (in general ``Fc`` plus every declared law's term), with
    ``Fc`` the model's own ``frictionloss``, ``w`` the joint velocity, ``tau`` the torque the
    motor transmits (``gear * actuator_force`` of the last physics step, from an
    ``actuatorfrc`` sensor on the actuator; 0 before the first step) less the back-EMF's share
    ``b_emf w`` (:data:`LOAD_FRICTION`'s optional third entry, 0 when absent: a voltage-driven
    motor's gearbox transmits its net torque ``kt i = kt/R u - kt^2/R w``, whose second term the
    model writes as joint damping), ``a``
    (:data:`FRICTION_ASYMMETRY`) the direction-dependent part and ``mu_drive``, ``mu_back``
    (:data:`LOAD_FRICTION`) the load-dependent coefficients: ``mu_drive`` while the motor drives
    the load (``tau w > 0``), ``mu_back`` while the load back-drives the motor, where a geared
    drive's friction is larger (a self-locking gearbox when ``mu_back >= 1``); the coefficient
    passes from one to the other over ``|w| ~ w_b`` (:data:`LOAD_FRICTION_BLEND_RAD_S`, a
    smooth sign), so at rest it is their mean: a load back-driving a held servo creeps until
    its speed engages ``mu_back`` (1 mrad on tests/test_servo_truth.py's hold, mu_back 1.5).

    The one-row and batch engines agree to the last bits, not bit for bit: the blend carries
    last-bit differences of ``mj_step``'s and ``mujoco.rollout``'s velocities into the level
    (3.3e-16 rad on tests/test_drive_friction.py's runs), and a stick-slip event can grow them.

    Attributes
    ----------
    dof : int
    base_nm : float
        The model's own ``frictionloss`` of the joint.
    values : dict
        ``{law name: its values}`` of the declared laws.
    sensor_adr : int
        ``sensordata`` address of the transmitted-torque sensor, -1 if none.
    gear : float
    limit : tuple of float or None
        :data:`CURRENT_LIMIT`'s ``(torque_limit_nm, back_emf_nms_per_rad)`` when the model
        declares it: the engine then also sets the actuator's ``forcerange`` at every control
        period (:meth:`_DriveLaws.force_ranges`).
    act : int
        The actuator (-1 for a row without laws).
    smooth : tuple of float or None
        :data:`LOAD_FRICTION_SMOOTH`'s ``(mu_drive, mu_back, b_emf, w_s)`` when the model
        declares it: the engine then also writes the joint's ``damping`` (``damping`` plus the
        law's slope) and applies the law's force at every control period
        (:meth:`_DriveLaws.write`, :attr:`_DriveLaws.applied`).
    damping : float
        The model's own ``damping`` of the joint (used by :data:`LOAD_FRICTION_SMOOTH` only).
    """

    dof: int
    base_nm: float
    values: dict
    sensor_adr: int
    gear: float
    limit: tuple | None = None
    act: int = -1
    smooth: tuple | None = None
    damping: float = 0.0

    @classmethod
    def of(cls, model: mujoco.MjModel, act: int, dof: int, source: str) -> "DriveFriction | None":
        values = {}
        for name, law in DRIVE_LAWS.items():
            v = _numeric(model, name)
            if v is None:
                continue
            why = law.check(v)
            if why:
                raise UserError(f"{source}: custom numeric {name!r} {why}, got {v.tolist()}")
            # a law's optional trailing entries (load_friction's b_emf) read as 0
            values[name] = tuple(float(x) for x in v) + (0.0,) * (len(law.params) - len(v))
        limit = _numeric(model, CURRENT_LIMIT)
        if limit is not None:
            why = _limit_check(limit)
            if why:
                raise UserError(f"{source}: custom numeric {CURRENT_LIMIT!r} {why}, got {limit.tolist()}")
            limit = tuple(float(x) for x in limit)
        smooth = _numeric(model, LOAD_FRICTION_SMOOTH)
        if smooth is not None:
            why = _smooth_check(smooth)
            if why:
                raise UserError(f"{source}: custom numeric {LOAD_FRICTION_SMOOTH!r} {why}, got {smooth.tolist()}")
            smooth = tuple(float(x) for x in smooth)
        if not values and limit is None and smooth is None:
            return None
        adr = -1
        if smooth is not None or any(DRIVE_LAWS[n].needs_torque for n in values):
            for i in range(model.nsensor):
                if (model.sensor_type[i] == mujoco.mjtSensor.mjSENS_ACTUATORFRC
                        and model.sensor_objid[i] == act):
                    adr = int(model.sensor_adr[i])
                    break
            else:
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, act)
                needs = ", ".join([repr(n) for n in values if DRIVE_LAWS[n].needs_torque]
                                  + ([repr(LOAD_FRICTION_SMOOTH)] if smooth is not None else []))
                raise UserError(f"{source}: {needs} needs the transmitted torque: add "
                                f'<sensor><actuatorfrc actuator="{name}"/></sensor>')
        return cls(dof, float(model.dof_frictionloss[dof]), values, adr, float(model.actuator_gear[act, 0]),
                   limit, act, smooth, float(model.dof_damping[dof]))

    def force_range(self, w: float) -> tuple[float, float]:
        """The actuator force range :data:`CURRENT_LIMIT` allows at joint velocity ``w``
        (:func:`current_limit_range`; the model must declare the limit)."""
        return current_limit_range(*self.limit, self.gear, w)

    @classmethod
    def none(cls, dof: int, base_nm: float, act: int = -1) -> "DriveFriction":
        """A row without laws (batched with rows that have some): its own level, always."""
        return cls(dof, float(base_nm), {}, -1, 1.0, None, act)


class _DriveLaws:
    """The :class:`DriveFriction` of B rows as arrays (made once per engine: the levels are
    computed at every control period).  Every law any row declares is applied to all rows, a
    row without it at all-zero values (a zero term)."""

    def __init__(self, laws: list[DriveFriction]):
        self.dof = laws[0].dof
        self.sensor = np.array([f.sensor_adr for f in laws])
        self.base = np.array([f.base_nm for f in laws])
        self.gear = np.array([f.gear for f in laws])
        self.terms = [(law, np.array([f.values.get(name, (0.0,) * len(law.params)) for f in laws], float))
                      for name, law in DRIVE_LAWS.items() if any(name in f.values for f in laws)]
        #: rows with a current limit, its values (zeros elsewhere) and the actuator it bounds
        self.limited = np.array([f.limit is not None for f in laws])
        self.limit = np.array([f.limit if f.limit is not None else (0.0, 0.0) for f in laws], float)
        self.act = max(f.act for f in laws)
        #: rows with LOAD_FRICTION_SMOOTH, their values (w_s 1 elsewhere: a zero force) and own
        #: damping; ``applied``: each row's force of the period (0 without the law), set by write
        self.smoothed = np.array([f.smooth is not None for f in laws])
        self.any_smooth = bool(self.smoothed.any())
        self.smooth = np.array([f.smooth if f.smooth is not None else (0.0, 0.0, 0.0, 1.0) for f in laws], float)
        self.damping = np.array([f.damping for f in laws])
        self.applied = np.zeros(len(laws))

    def levels(self, w: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The Coulomb levels [N*m] of the rows: velocities ``w`` and actuator forces ``force``."""
        tau = force * self.gear
        level = self.base
        for law, values in self.terms:
            level = level + law.term(values, w, tau)
        return np.maximum(0.0, level)

    def force_ranges(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:data:`CURRENT_LIMIT`'s actuator force range ``(lower, upper)`` of the rows at joint
        velocities ``w``: the net motor torque ``gear * force - b w`` within ``+-tau_i``, i.e.
        ``force`` in ``[(b w - tau_i) / gear, (b w + tau_i) / gear]`` (meaningful for the
        :attr:`limited` rows only)."""
        return current_limit_range(self.limit[:, 0], self.limit[:, 1], self.gear, w)

    def write(self, models, w: np.ndarray, force: np.ndarray, frictionloss: list | None = None,
              damping: list | None = None) -> np.ndarray:
        """Write the rows' Coulomb levels (joint ``frictionloss``) and, for the rows with a
        current limit, their actuator ``forcerange`` (forcelimited on) into ``models`` (one per
        row): what the engine and the runtime (:mod:`omni_sim.runtime`) do at every control
        period.  ``frictionloss``: the models' ``dof_frictionloss`` arrays, taken once by a
        caller that writes every period (each attribute read makes a new array); ``damping``
        the same of ``dof_damping``.  For the rows with :data:`LOAD_FRICTION_SMOOTH` it writes
        the joint's damping plus the law's slope and leaves the force to apply in
        :attr:`applied` (the caller's ``qfrc_applied`` of the joint for the period).  Returns
        the levels."""
        if self.any_smooth:
            f, slope = smooth_load_force(self.smooth, w, force * self.gear)
            self.applied = np.where(self.smoothed, f + slope * w, 0.0)
            for dm, on, b in zip(damping if damping is not None else [m.dof_damping for m in models],
                                 self.smoothed, (self.damping + slope).tolist()):
                if on:
                    dm[self.dof] = b
        levels = self.levels(w, force)
        for fl, f in zip(frictionloss if frictionloss is not None else [m.dof_frictionloss for m in models],
                         levels.tolist()):  # Python floats: the same doubles, written faster
            fl[self.dof] = f
        if self.limited.any():
            lo, hi = self.force_ranges(w)
            for m, on, a, b in zip(models, self.limited, lo, hi):
                if on:
                    m.actuator_forcelimited[self.act] = 1
                    m.actuator_forcerange[self.act] = (a, b)
        return levels
