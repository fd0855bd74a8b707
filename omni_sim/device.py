"""The virtual Omni as a device: built once from a model, stepped by one closed-loop engine.

In the spirit of dm_control's ``Physics``: a :class:`Device` is built once per compiled model and
owns everything that makes the model a *device* rather than a physics model, and is the one
place each fact about it is computed, for its :class:`~omni_sim.model.Target` (the Omni's yaw
or a user's hinge):

* the name index of the contract's joints and actuators (:class:`omni_sim.model.OmniIndex`;
  :func:`omni_sim.model.index` is called here and by the loader, nowhere else);
* the drive's torque constant (gear), voltage limit and the physics substeps of one control
  period;
* the drive's friction (:meth:`Device.friction`, :meth:`Device.friction_family`,
  :meth:`Device.scale_friction`) and the encoder joint's inertia at a pose
  (:meth:`Device.inertia`, from MuJoCo's mass matrix);
* the arm: its control (:meth:`Device.set_arm_control`), its joint ranges
  (:meth:`Device.check_pose`) and the equilibrium (sagged) pose of each pair of servo set
  points (:meth:`Device.equilibrium`, cached);
* the start state of a run: arm at that pose, yaw at rest at ``theta0``;
* the encoder (:class:`Encoder`: quantisation, white noise, seeded per-run streams);
* the clipped P law ``v = clip(kp (r - y), -V, V)`` of the paper's experiments;
* the drive's friction laws that no MJCF attribute can hold (a registry, :data:`DRIVE_LAWS`:
  friction set by the torque the gearbox transmits, direction-dependent Coulomb friction, the
  next one a user writes), declared in the model's ``<custom>`` numerics and applied by the
  engine at every control period (:class:`DriveFriction`).

:class:`Engine` is the one closed loop every user of the device steps through: the generator's
reference path (:func:`run_p_loop`, used by :func:`omni_sim.experiments.simulate`), the gymnasium
environment (:mod:`omni_sim.env`, an agent instead of the P law) and the discrepancy replay
(:mod:`discrepancy.replay`, many models in one batch).  The ``mujoco.rollout`` fast path
of :mod:`omni_sim.experiments` (the P law folded into the model) is a shortcut, tested bit for
bit against it.

Time convention (the whole project): sample ``k`` is at ``t_k = k dt`` with ``dt`` the control
period; ``y_k`` is the yaw *measured* at ``t_k`` (before the controller acts), the command
``v_k`` is held (zero-order hold) over ``[t_k, t_k + dt)``, i.e. for ``substeps`` physics steps.
"""

from __future__ import annotations

import copy
import hashlib
import math
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from identification.errors import UserError

from . import model as om

#: The Omni's servo period [s] (1 kHz, models/omni/README.md).
CONTROL_PERIOD_S = 1e-3
#: Encoder resolution [rad]: 15000 counts per revolution (models/omni/README.md).
ENCODER_STEP_RAD = 2 * math.pi / 15000
#: The physics state the engine carries between control periods.
STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS
#: ``<custom><numeric name="load_friction" data="mu_drive mu_back"/>``: Coulomb friction that
#: rises with the torque the gearbox transmits (:data:`DRIVE_LAWS`).
LOAD_FRICTION = "load_friction"
#: The speed [rad/s] over which :data:`LOAD_FRICTION`'s coefficient passes from ``mu_back``
#: to ``mu_drive`` (a smooth sign, ``tanh(sign(tau) w / w_b)``): 0.05 rad/s.  An ESTIMATE, a
#: modelling choice like any regularised Coulomb law's transition speed: the speed the bank's
#: gear-efficiency truth uses for its smooth sign (discrepancy/servo_truth.py,
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
    # mu_drive while the motor drives the load (sign(tau) w >> w_b), mu_back while the load
    # back-drives the motor (sign(tau) w << -w_b), their mean at rest, smoothly in between
    if LOAD_FRICTION_BLEND_RAD_S == 0:  # the switch on sign(tau w), mu_back at rest (valley_scan.py)
        return np.where(tau * w > 0, v[:, 0], v[:, 1]) * np.abs(tau)
    s = 0.5 * (1.0 + np.tanh(np.sign(tau) * w / LOAD_FRICTION_BLEND_RAD_S))
    return (v[:, 1] + (v[:, 0] - v[:, 1]) * s) * np.abs(tau)


def _load_check(v: np.ndarray) -> str | None:
    ok = len(v) == 2 and np.all(np.isfinite(v)) and not np.any(v < 0)
    return None if ok else "must hold two coefficients >= 0 (mu_drive mu_back)"


def _family_term(v: np.ndarray, w: np.ndarray, tau: np.ndarray) -> np.ndarray:
    # the load-dependent part is load_friction's law (the same blend), the Stribeck rise
    # rise * exp(-(|w| / omega_s)^delta) is 1 x rise at rest and vanishes for |w| >> omega_s
    load = _load_term(v[:, :2], w, tau)
    rise, ws, delta = v[:, 2], v[:, 3], v[:, 4]
    on = (rise > 0) & (ws > 0)
    x = np.abs(w) / np.where(on, ws, 1.0)
    return load + np.where(on, rise * np.exp(-np.power(x, np.where(on, delta, 1.0))), 0.0)


def _family_check(v: np.ndarray) -> str | None:
    ok = (len(v) == 5 and np.all(np.isfinite(v)) and not np.any(v < 0)
          and (v[2] == 0 or (v[3] > 0 and v[4] > 0)))
    return None if ok else ("must hold five values >= 0 (k_drive k_back rise_nm omega_s delta), "
                            "omega_s and delta > 0 when rise_nm > 0")


def _limit_check(v: np.ndarray) -> str | None:
    ok = len(v) == 2 and np.all(np.isfinite(v)) and v[0] > 0 and v[1] >= 0
    return None if ok else "must hold a torque limit > 0 [N*m] and a back-EMF damping >= 0 [N*m*s/rad]"


#: The parameters of :data:`CURRENT_LIMIT`'s numeric, in order.
CURRENT_LIMIT_PARAMS = ("torque_limit_nm", "back_emf_nms_per_rad")


#: The drive laws the engine knows, by name, in the order their terms are added (the Coulomb
#: level is ``max(0, frictionloss + term_1 + term_2 + ...)``).  A new law is a
#: :class:`DriveLaw` added here (:func:`register_drive_law`).
DRIVE_LAWS: dict[str, DriveLaw] = {
    FRICTION_ASYMMETRY: DriveLaw(FRICTION_ASYMMETRY, ("a",), _asymmetry_term, _asymmetry_check),
    LOAD_FRICTION: DriveLaw(LOAD_FRICTION, ("mu_drive", "mu_back"), _load_term, _load_check,
                            needs_torque=True),
    FRICTION_FAMILY: DriveLaw(FRICTION_FAMILY, ("k_drive", "k_back", "rise_nm", "omega_s", "delta"),
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

        F = max(0, Fc + a sign(w) + mu |tau|),
        mu = mu_back + (mu_drive - mu_back) (1 + tanh(sign(tau) w / w_b)) / 2,

    for the two laws the library holds (in general ``Fc`` plus every declared law's term), with
    ``Fc`` the model's own ``frictionloss``, ``w`` the joint velocity, ``tau`` the torque the
    motor transmits (``gear * actuator_force`` of the last physics step, from an
    ``actuatorfrc`` sensor on the actuator; 0 before the first step), ``a``
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
    """

    dof: int
    base_nm: float
    values: dict
    sensor_adr: int
    gear: float
    limit: tuple | None = None
    act: int = -1

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
            values[name] = tuple(float(x) for x in v)
        limit = _numeric(model, CURRENT_LIMIT)
        if limit is not None:
            why = _limit_check(limit)
            if why:
                raise UserError(f"{source}: custom numeric {CURRENT_LIMIT!r} {why}, got {limit.tolist()}")
            limit = tuple(float(x) for x in limit)
        if not values and limit is None:
            return None
        adr = -1
        if any(DRIVE_LAWS[n].needs_torque for n in values):
            for i in range(model.nsensor):
                if (model.sensor_type[i] == mujoco.mjtSensor.mjSENS_ACTUATORFRC
                        and model.sensor_objid[i] == act):
                    adr = int(model.sensor_adr[i])
                    break
            else:
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, act)
                needs = ", ".join(repr(n) for n in values if DRIVE_LAWS[n].needs_torque)
                raise UserError(f"{source}: {needs} needs the transmitted torque: add "
                                f'<sensor><actuatorfrc actuator="{name}"/></sensor>')
        return cls(dof, float(model.dof_frictionloss[dof]), values, adr, float(model.actuator_gear[act, 0]),
                   limit, act)

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
        tau_i, b = self.limit[:, 0], self.limit[:, 1]
        return (b * w - tau_i) / self.gear, (b * w + tau_i) / self.gear

    def write(self, models, w: np.ndarray, force: np.ndarray) -> None:
        """Write the rows' Coulomb levels (joint ``frictionloss``) and, for the rows with a
        current limit, their actuator ``forcerange`` (forcelimited on) into ``models`` (one per
        row): what the engine and the runtime (:mod:`omni_sim.runtime`) do at every control
        period."""
        levels = self.levels(w, force)
        for m, f in zip(models, levels):
            m.dof_frictionloss[self.dof] = f
        if self.limited.any():
            lo, hi = self.force_ranges(w)
            for m, on, a, b in zip(models, self.limited, lo, hi):
                if on:
                    m.actuator_forcelimited[self.act] = 1
                    m.actuator_forcerange[self.act] = (a, b)


@dataclass(frozen=True)
class Encoder:
    """How the device measures the yaw angle.

    Attributes
    ----------
    quantize : bool
        Round the reading to the encoder's counts (``step_rad``).
    noise_rad : float [rad]
        Standard deviation of white measurement noise, added before quantisation.
    seed : int
        Seed of the per-run noise streams (:meth:`noise`).
    step_rad : float [rad]
        One count: 2 pi / 15000 (the Omni's encoders).
    """

    quantize: bool = False
    noise_rad: float = 0.0
    seed: int = 0
    step_rad: float = ENCODER_STEP_RAD

    def __post_init__(self):
        if not (self.noise_rad >= 0 and math.isfinite(self.noise_rad)):
            raise UserError(f"noise must be a finite standard deviation >= 0, got {self.noise_rad}")

    @property
    def exact(self) -> bool:
        """True when the reading is the true angle."""
        return not self.quantize and self.noise_rad == 0

    @property
    def quantum_rad(self) -> float:
        """The rounding step [rad] (0 when not quantising)."""
        return self.step_rad if self.quantize else 0.0

    def noise(self, name: str, n: int) -> np.ndarray:
        """The noise samples [rad] of run ``name``: one stream per (seed, run name), so a run's
        noise does not depend on which other runs are simulated or in which order."""
        if self.noise_rad <= 0:
            return np.zeros(n)
        digest = hashlib.sha256(f"{self.seed}:{name}".encode()).digest()
        rng = np.random.default_rng(int.from_bytes(digest[:8], "little"))
        return rng.normal(0.0, self.noise_rad, n)


def encoder_reader(quantum_rad):
    """The encoder for a fixed rounding step ``quantum_rad`` [rad] (scalar, or one per row; 0:
    no rounding): a function ``read(theta, noise)`` giving ``theta + noise`` rounded to the
    step.  A count of zero reads +0.0, never -0.0 (as an integer count would).  The arrays
    that depend only on the step are made once, for loops that read every control period."""
    q = np.asarray(quantum_rad, dtype=float)
    if not np.any(q > 0):
        return lambda theta, noise: np.asarray(theta, dtype=float) + noise
    rounds = q > 0
    qdiv = np.where(rounds, q, 1.0)

    def read(theta, noise):
        y = np.asarray(theta, dtype=float) + noise
        return np.where(rounds, np.round(y / qdiv) * qdiv + 0.0, y)

    return read


def read_encoder(theta, noise, quantum_rad):
    """The encoder's reading of the true yaw ``theta`` [rad] (elementwise; scalars or arrays):
    :func:`encoder_reader` for one call."""
    return encoder_reader(quantum_rad)(theta, noise)


def p_law(kp, r, y, vmax):
    """The paper's P controller, clipped to the drive: ``clip(kp (r - y), -vmax, vmax)`` [V]."""
    return np.clip(kp * (r - y), -vmax, vmax)


def substeps_of(model: mujoco.MjModel, control_period_s: float) -> int:
    """Physics steps per control period (UserError unless it divides exactly)."""
    n = control_period_s / model.opt.timestep
    if not (n >= 1 - 1e-9 and abs(n - round(n)) < 1e-9):
        raise UserError(f"control period {control_period_s} s is not a whole multiple of the "
                        f"physics timestep {model.opt.timestep} s")
    return int(round(n))


def coupled_hinges(model: mujoco.MjModel, joint_id: int) -> list[tuple[int, float]]:
    """Hinges tied to joint ``joint_id`` by a fixed tendon of exactly two joints (a two-mass
    drive: rotor and output coupled by a cable), as ``(qpos address, factor)``: the tendon's
    length ``c_j q_j + c_h q_h`` is zero at ``q_h = factor * q_j`` (``factor = -c_j / c_h``).
    Tendons with a zero coefficient on the other hinge are skipped."""
    out = []
    for t in range(model.ntendon):
        adr, num = int(model.tendon_adr[t]), int(model.tendon_num[t])
        if num != 2:
            continue
        wraps = range(adr, adr + num)
        if any(model.wrap_type[w] != mujoco.mjtWrap.mjWRAP_JOINT for w in wraps):
            continue  # a spatial tendon
        ids = [int(model.wrap_objid[w]) for w in wraps]
        coef = [float(model.wrap_prm[w]) for w in wraps]
        if joint_id not in ids or ids[0] == ids[1]:
            continue
        i = ids.index(joint_id)
        other, c_other = ids[1 - i], coef[1 - i]
        if model.jnt_type[other] != mujoco.mjtJoint.mjJNT_HINGE or c_other == 0:
            continue
        out.append((int(model.jnt_qposadr[other]), -coef[i] / c_other))
    return out


class Device:
    """The virtual Omni (or a user's single-joint device) built once from a compiled model.

    Parameters
    ----------
    model : MjModel
        A model keeping the contract's names (:func:`omni_sim.model.load_model`).  The device
        reads it live: a change of a parameter in place (friction scaling, a candidate effect's
        value) is seen by the next step, but not by the cached equilibrium poses.
    control_period_s : float [s]
        Servo period; a whole multiple of the model's timestep.
    target : omni_sim.model.Target, optional
        The controlled hinge (the encoder's joint) and its actuator of a user's device (default
        None: the Omni's contract, ``yaw``/``yaw_motor`` and the arm).  Without the Omni's arm
        (``ix.has_arm`` False) a run has no pose: its start leaves every other joint at
        ``qpos0`` (see :meth:`start_data`).
    source : str
        What the model is, for error messages (a file name, ``"<variant>"``).

    Attributes
    ----------
    model : MjModel
    ix : OmniIndex
        Addresses of the contract's joints and actuators.
    control_period_s, dt : float [s]
    substeps : int
        Physics steps per control period.
    voltage_limit : float [V]
        ``ctrlrange`` of ``yaw_motor`` / the target's actuator (inf if unlimited): the drive's
        clip of every command.
    torque_constant : float [N*m/V]
        Torque per unit of control of ``yaw_motor`` / the target's actuator (the paper's
        beta_bar): gear x gain of a ``motor``, gear x K/R of a ``dcmotor`` at rest.
    drive_friction : DriveFriction or None
        Friction laws the engine applies at every control period (the model's ``<custom>``
        numerics :data:`LOAD_FRICTION`, :data:`FRICTION_ASYMMETRY`, :data:`FRICTION_FAMILY`)
        and the current limit it moves with the back-EMF (:data:`CURRENT_LIMIT`).
    joint_id : int
        The encoder joint (``yaw`` or the target's hinge).
    target : Target or None
    coupled : list of (int, float)
        Hinges tied to the encoder joint by a two-joint fixed tendon (:func:`coupled_hinges`),
        started where that tendon's length is zero.
    """

    def __init__(self, model: mujoco.MjModel, control_period_s: float = CONTROL_PERIOD_S,
                 target: om.Target | None = None, source: str = "<model>",
                 file: str | None = None, digest: str | None = None):
        self.model = model
        self.target = target
        #: Where the model came from (:meth:`load` sets both): the MJCF file as the caller named
        #: it (None: the built-in ``scene.xml``) and its digest (:func:`omni_sim.model.model_digest`);
        #: ``digest`` None: a model compiled in memory.
        self.file, self.digest = file, digest
        #: The friction family of a built-in scene the device was loaded from (:meth:`load`;
        #: None: another file, or a model compiled in memory).
        self.scene_family: str | None = None
        self.ix = om.index(model, source, target)
        self.control_period_s = float(control_period_s)
        self.substeps = substeps_of(model, control_period_s)
        act = self.ix.yaw_act
        self.voltage_limit = (float(min(-model.actuator_ctrlrange[act, 0], model.actuator_ctrlrange[act, 1]))
                              if model.actuator_ctrllimited[act] else math.inf)
        gear = float(model.actuator_gear[act, 0])
        if model.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_DCMOTOR:
            # a dcmotor's torque per volt is gear * K / R (gainprm[1] = K, gainprm[0] = R;
            # docs/method/servo-actuators.md)
            gear *= float(model.actuator_gainprm[act, 1] / model.actuator_gainprm[act, 0])
        else:
            gear *= float(model.actuator_gainprm[act, 0])  # a motor's gain is 1
        self.torque_constant = gear
        self.joint_id = int(model.dof_jntid[self.ix.yaw_dof])
        arm = {self.ix.shoulder_qpos, self.ix.elbow_qpos}
        self.coupled = [(a, f) for a, f in coupled_hinges(model, self.joint_id) if a not in arm]
        self.nstate = mujoco.mj_stateSize(model, STATE_SPEC)
        #: the drive's friction laws the engine applies (None: the model declares none)
        self.drive_friction = DriveFriction.of(model, act, self.ix.yaw_dof, source)
        self._eq: dict[tuple[float, float], tuple[float, float]] = {}
        self._scratch: mujoco.MjData | None = None  # start_state's MjData (made on first use)
        self._off_model: mujoco.MjModel | None = None  # off_model()'s (made on first use)

    @classmethod
    def load(cls, path=None, control_period_s: float = CONTROL_PERIOD_S, friction: str | None = None,
             target: om.Target | None = None) -> "Device":
        """Compile an MJCF file (default: the built-in scene of the friction family
        ``friction``, or ``scene.xml``) into a device that knows its file and digest."""
        where = om.model_path(path, friction)
        model = om.load_model(where, target=target)
        # the file as the caller named it; None for the built-in scene.xml (runs say so)
        file = None if path is None and friction is None else str(where)
        device = cls(model, control_period_s, target, file=file, digest=om.model_digest(where))
        device.scene_family = om.builtin_family(where)
        return device

    def at_period(self, control_period_s: float) -> "Device":
        """This device at another servo period (itself if it is the same): the same model
        object, source and equilibrium poses (they do not depend on the period)."""
        if float(control_period_s) == self.control_period_s:
            return self
        other = copy.copy(self)
        other.control_period_s = float(control_period_s)
        other.substeps = substeps_of(self.model, control_period_s)
        other._scratch = None  # start_state's MjData: one per device (not shared by threads)
        return other

    # -- where the model came from ---------------------------------------------------------------
    @property
    def in_memory(self) -> bool:
        """True for a model compiled in memory (no file, no digest)."""
        return self.digest is None

    @property
    def run_model_name(self) -> str:
        """What a run's metadata calls the model: the file's name, ``scene.xml (built-in)``
        for the default scene, ``in-memory model`` for a model compiled in memory."""
        if self.in_memory:
            return "in-memory model"
        return "scene.xml (built-in)" if self.file is None else os.path.basename(self.file)

    @property
    def label(self) -> str:
        """The model for a reader: ``built-in scene_coulomb.xml`` for a built-in scene (where
        it is installed says nothing), the file as named, or ``in-memory model``."""
        if self.in_memory:
            return "in-memory model"
        if self.file is None:
            return "built-in scene.xml"
        p = Path(self.file)
        return f"built-in {p.name}" if p.resolve().parent == om.OMNI_DIR.resolve() else self.file

    # -- named parameters: read and set in the model the device reads live ---------------------
    @property
    def yaw_damping(self) -> float:
        """The encoder joint's viscous damping [N*m*s/rad] (its MJCF ``damping``, as the model
        holds it now; settable)."""
        return float(self.model.dof_damping[self.ix.yaw_dof])

    @yaw_damping.setter
    def yaw_damping(self, value: float) -> None:
        self.model.dof_damping[self.ix.yaw_dof] = value

    @property
    def yaw_frictionloss(self) -> float:
        """The encoder joint's ``frictionloss`` [N*m] (the hard stick; settable)."""
        return float(self.model.dof_frictionloss[self.ix.yaw_dof])

    @yaw_frictionloss.setter
    def yaw_frictionloss(self, value: float) -> None:
        self.model.dof_frictionloss[self.ix.yaw_dof] = value

    def _named(self, kind: "mujoco.mjtObj", name: str, what: str) -> int:
        i = mujoco.mj_name2id(self.model, kind, name)
        if i < 0:
            raise UserError(f"the model has no {what} {name!r}")
        return int(i)

    def body(self, name: str) -> tuple[float, np.ndarray]:
        """A body's mass [kg] and principal inertia [kg*m^2] (a copy)."""
        b = self._named(mujoco.mjtObj.mjOBJ_BODY, name, "body")
        return float(self.model.body_mass[b]), self.model.body_inertia[b].copy()

    def set_body(self, name: str, mass: float | None = None, inertia=None) -> None:
        """Set a body's mass [kg] and/or principal inertia [kg*m^2] (call ``mj_setConst``
        after changing masses, as MuJoCo's derived constants depend on them)."""
        b = self._named(mujoco.mjtObj.mjOBJ_BODY, name, "body")
        if mass is not None:
            self.model.body_mass[b] = mass
        if inertia is not None:
            self.model.body_inertia[b] = inertia

    def servo_gain(self, joint: str) -> float:
        """The P gain [N*m/rad] of an arm servo (``shoulder`` or ``elbow``)."""
        return float(self.model.actuator_gainprm[self._servo(joint), 0])

    def set_servo_gain(self, joint: str, kp: float) -> None:
        """Set an arm servo's P gain (a ``position`` actuator: gain kp, bias -kp)."""
        a = self._servo(joint)
        self.model.actuator_gainprm[a, 0] = kp
        self.model.actuator_biasprm[a, 1] = -kp

    def _servo(self, joint: str) -> int:
        act = {"shoulder": self.ix.shoulder_act, "elbow": self.ix.elbow_act}.get(joint)
        if act is None:
            raise UserError(f"the model has no arm servo on {joint!r}")
        return act

    def friction_actuator(self) -> int | None:
        """The drive's LuGre friction actuator (the first of :meth:`lugre_actuators`), or None."""
        acts = self.lugre_actuators()
        return acts[0] if acts else None

    def lugre(self) -> dict:
        """The LuGre actuator's parameters (:meth:`friction_actuator`): bristle stiffness
        ``sigma0`` [N*m/rad] and damping ``sigma1`` [N*m*s/rad], Coulomb and static levels
        ``Fc``, ``Fs`` [N*m], Stribeck speed ``vs`` [rad/s] (UserError without one)."""
        m, f = self.model, self._lugre_actuator()
        return {"sigma0": float(m.actuator_dynprm[f, 5]), "sigma1": float(m.actuator_dynprm[f, 6]),
                "Fc": float(m.actuator_biasprm[f, 3]),
                "Fs": float(m.actuator_biasprm[f, 4]), "vs": float(m.actuator_biasprm[f, 5])}

    def set_lugre(self, sigma0: float, Fc: float, Fs: float, vs: float) -> None:
        """Set the LuGre actuator's parameters (names: :meth:`lugre`)."""
        m, f = self.model, self._lugre_actuator()
        m.actuator_dynprm[f, 5] = sigma0
        m.actuator_biasprm[f, 3:6] = Fc, Fs, vs

    def _lugre_actuator(self) -> int:
        f = self.friction_actuator()
        if f is None:
            raise UserError("the model has no LuGre friction actuator on its drive")
        return f

    # -- the drive's friction ------------------------------------------------------------------
    def lugre_actuators(self) -> list[int]:
        """Ids of the passive LuGre friction actuators (``dcmotor`` bias) on the encoder joint."""
        m = self.model
        return [a for a in range(m.nactuator)
                if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_DCMOTOR
                and m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                and m.actuator_trnid[a, 0] == self.joint_id]

    def friction(self) -> dict:
        """The drive's dry friction: ``frictionloss`` [N*m] (hard stick) and the LuGre
        actuators' ``lugre_sigma0`` [N*m/rad], ``lugre_Fc``, ``lugre_Fs`` [N*m] (summed levels;
        stiffness of the first)."""
        m, acts = self.model, self.lugre_actuators()
        return {
            "frictionloss": self.yaw_frictionloss,
            "lugre_sigma0": float(m.actuator_dynprm[acts[0], 5]) if acts else 0.0,
            "lugre_Fc": float(sum(m.actuator_biasprm[a, 3] for a in acts)),
            "lugre_Fs": float(sum(m.actuator_biasprm[a, 4] for a in acts)),
        }

    def friction_family(self, path: str | os.PathLike | None = None) -> str:
        """The friction family a run's metadata names.

        The model's file (``path``; default: the one the device was loaded from) a built-in scene:
        its family (``scene.xml`` is the default family).  Otherwise (a user's file, or a model
        compiled in memory) what the drive carries: ``"lugre"`` (a LuGre actuator with a
        non-zero level), ``"coulomb"`` (``frictionloss``), ``"lugre+coulomb"`` or ``"none"``."""
        family = om.builtin_family(path) if path is not None else self.scene_family
        if family is not None:
            return family
        f = self.friction()
        kinds = [k for k, on in (("lugre", f["lugre_Fc"] > 0 or f["lugre_Fs"] > 0),
                                 ("coulomb", f["frictionloss"] > 0)) if on]
        return "+".join(kinds) or "none"

    def scale_friction(self, factor: float, base: "Device | None" = None) -> None:
        """Set the drive's dry-friction levels (``frictionloss`` and LuGre Fc, Fs) to ``factor``
        times those of ``base`` (default: this device itself), in place."""
        base = self if base is None else base
        m, b = self.model, base.model
        self.yaw_frictionloss = factor * base.yaw_frictionloss
        for a in self.lugre_actuators():
            m.actuator_biasprm[a, 3:5] = factor * b.actuator_biasprm[a, 3:5]

    def off_model(self) -> mujoco.MjModel:
        """The model with the drive switched off (torque disabled: the actuator exerts no force;
        a ``dcmotor``'s winding open, so no back-EMF braking either; back-EMF written as joint
        damping stays, it is the joint's).  Made once, from the model as it is then."""
        if self._off_model is None:
            m = copy.deepcopy(self.model)
            a = self.ix.yaw_act
            if m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_DCMOTOR:
                m.actuator_gainprm[a, 1] = 0.0  # motor constant K = 0: no torque, no back-EMF
            else:
                m.actuator_gainprm[a, :] = 0.0
                m.actuator_biasprm[a, :] = 0.0
            self._off_model = m
        return self._off_model

    def without_friction(self) -> "Device":
        """A device on a copy of the model with no dry friction on the drive (viscous damping
        kept)."""
        dev = Device(copy.deepcopy(self.model), self.control_period_s, self.target)
        dev.scale_friction(0.0)
        return dev

    # -- the arm and the inertia -----------------------------------------------------------------
    def _arm_joint(self, name: str) -> int:
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, name)

    def check_pose(self, gamma1_deg: float, gamma2_deg: float) -> None:
        """Raise UserError if a pose is not finite or outside the shoulder/elbow joint ranges."""
        for name, val in (("shoulder", gamma1_deg), ("elbow", gamma2_deg)):
            if not math.isfinite(val):
                raise UserError(f"{name} angle must be finite, got {val}")
            if not self.ix.has_arm:
                continue
            j = self._arm_joint(name)
            if self.model.jnt_limited[j]:
                lo, hi = np.degrees(self.model.jnt_range[j])
                if not lo - 1e-9 <= val <= hi + 1e-9:
                    raise UserError(f"{name} angle {val:g} deg is outside the joint range "
                                    f"[{lo:.1f}, {hi:.1f}] deg")

    def set_arm_control(self, data: mujoco.MjData, gamma1_set_deg: float, gamma2_set_deg: float) -> None:
        """Write the shoulder/elbow servo set points [deg] into ``data.ctrl`` (servos present)."""
        if self.ix.shoulder_act is not None:
            data.ctrl[self.ix.shoulder_act] = math.radians(gamma1_set_deg)
        if self.ix.elbow_act is not None:
            data.ctrl[self.ix.elbow_act] = math.radians(gamma2_set_deg)

    def inertia(self, gamma1_deg: float | None = None, gamma2_deg: float | None = None) -> float:
        """MuJoCo's inertia [kg*m^2] about the encoder joint with the arm at these ACTUAL angles
        [deg] (the others at ``qpos0``; without the Omni's arm no angles are needed): the
        joint's diagonal element of the joint-space mass matrix (``mj_fullM``), armature
        included."""
        m, ix = self.model, self.ix
        data = mujoco.MjData(m)
        data.qpos[:] = m.qpos0
        if ix.has_arm:
            data.qpos[ix.shoulder_qpos] = math.radians(gamma1_deg)
            data.qpos[ix.elbow_qpos] = math.radians(gamma2_deg)
        mujoco.mj_forward(m, data)
        mass = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, data, mass)
        return float(mass[ix.yaw_dof, ix.yaw_dof])

    @property
    def dt(self) -> float:
        """Control period [s]: ``timestep * substeps``."""
        return float(self.model.opt.timestep) * self.substeps

    def equilibrium(self, gamma1_set_deg: float, gamma2_set_deg: float) -> tuple[float, float]:
        """Actual (sagged) arm angles [deg] for these servo set points (cached per device)."""
        key = (float(gamma1_set_deg), float(gamma2_set_deg))
        if key not in self._eq:
            self._eq[key] = self._solve_equilibrium(*key)
        return self._eq[key]

    def _solve_equilibrium(self, gamma1_set_deg: float, gamma2_set_deg: float,
                           tol_rad: float = 1e-10) -> tuple[float, float]:
        """Solve ``qfrc_bias + qfrc_passive = qfrc_actuator`` for the shoulder and elbow, the
        encoder joint at 0, by Newton's method on MuJoCo's own forces (finite-difference
        Jacobian)."""
        m, ix = self.model, self.ix
        self.check_pose(gamma1_set_deg, gamma2_set_deg)
        data = mujoco.MjData(m)
        self.set_arm_control(data, gamma1_set_deg, gamma2_set_deg)
        dofs = [int(m.jnt_dofadr[self._arm_joint(j)]) for j in ("shoulder", "elbow")]
        qadr = [ix.shoulder_qpos, ix.elbow_qpos]
        q = np.radians([gamma1_set_deg, gamma2_set_deg])

        def residual(qa: np.ndarray) -> np.ndarray:
            data.qpos[:] = m.qpos0
            data.qpos[qadr] = qa
            data.qvel[:] = 0
            mujoco.mj_forward(m, data)
            f = data.qfrc_actuator + data.qfrc_passive - data.qfrc_bias
            return f[dofs].copy()

        for _ in range(50):
            f = residual(q)
            h = 1e-7
            jac = np.column_stack([(residual(q + h * e) - f) / h for e in np.eye(2)])
            step = np.linalg.solve(jac, -f)
            q = q + step
            if np.max(np.abs(step)) < tol_rad:
                break
        return float(np.degrees(q[0])), float(np.degrees(q[1]))

    def start_data(self, theta0_rad: float, gamma_set_deg: tuple[float, float] | None,
                   data: mujoco.MjData | None = None) -> mujoco.MjData:
        """The start of a run: arm at the equilibrium of its set points, servos holding them,
        yaw at rest at ``theta0_rad``; ``mj_forward`` done.  Writes into ``data`` if given.

        Without the Omni's arm (``ix.has_arm`` False) ``gamma_set_deg`` is ignored (None or an
        empty tuple are fine) and the other joints start at ``qpos0``.  Every hinge tied to the
        encoder joint by a two-joint fixed tendon (:attr:`coupled`, a two-mass drive) starts
        where that tendon's length is zero: the cable unstretched, all at rest."""
        m, ix = self.model, self.ix
        d = mujoco.MjData(m) if data is None else data
        mujoco.mj_resetData(m, d)
        d.qpos[ix.yaw_qpos] = theta0_rad
        if ix.has_arm:
            if gamma_set_deg is None or len(gamma_set_deg) != 2:
                raise UserError("this model has the Omni's arm (shoulder, elbow): a run needs its "
                                "two set points gamma1, gamma2 [deg]")
            g1, g2 = self.equilibrium(*gamma_set_deg)
            d.qpos[ix.shoulder_qpos] = math.radians(g1)
            d.qpos[ix.elbow_qpos] = math.radians(g2)
            self.set_arm_control(d, *gamma_set_deg)  # the arm servos hold their set points
        for adr, factor in self.coupled:
            d.qpos[adr] = factor * theta0_rad
        mujoco.mj_forward(m, d)
        return d

    def start_state(self, theta0_rad: float, gamma_set_deg: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray]:
        """The start of a run as ``(full physics state, ctrl vector)`` (see :meth:`start_data`).

        Computed in one scratch ``MjData`` of the device (``mj_resetData`` first, as a new one
        is), so a batch of many runs does not allocate an ``MjData`` per run; so one device's
        ``start_state`` is not for concurrent calls from several threads."""
        if self._scratch is None:
            self._scratch = mujoco.MjData(self.model)
        d = self.start_data(theta0_rad, gamma_set_deg, self._scratch)
        x0 = np.empty(self.nstate)
        mujoco.mj_getState(self.model, d, x0, STATE_SPEC)
        return x0, d.ctrl.copy()

    def engine(self, theta0_rad, gamma_set_deg, nthread: int | None = None) -> "Engine":
        """An :class:`Engine` of B runs of this device (``theta0_rad``: B floats,
        ``gamma_set_deg``: B pairs, or B Nones without the Omni's arm)."""
        return Engine([self] * len(theta0_rad), theta0_rad, gamma_set_deg, nthread=nthread)


def _pose(gamma_set_deg):
    """A run's set points as a tuple (None stays None: a device without the Omni's arm)."""
    return None if gamma_set_deg is None else tuple(gamma_set_deg)


#: MuJoCo's warnings of an unstable state (it resets the data when it issues one).
_INSTABILITY = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL,
                mujoco.mjtWarning.mjWARN_BADQPOS)


def _instability_warnings(datas) -> int:
    """How many instability warnings these ``MjData`` have issued so far."""
    return sum(int(d.warning[w].number) for d in datas for w in _INSTABILITY)


def _warns(model: mujoco.MjModel, state: np.ndarray, ctrl: np.ndarray) -> bool:
    """Whether one control period from ``state`` under ``ctrl`` (substeps x nu) makes MuJoCo
    reset the data (a fresh ``MjData``; the same steps as the rollout's)."""
    d = mujoco.MjData(model)
    mujoco.mj_setState(model, d, state, STATE_SPEC)
    for u in ctrl:
        d.ctrl[:] = u
        mujoco.mj_step(model, d)
    return _instability_warnings([d]) > 0


class Engine:
    """The closed loop of B virtual devices, advanced one control period at a time.

    Row ``b`` is a run on ``devices[b]`` (devices may wrap different models of one size
    signature, e.g. the candidates of a parameter fit) started by :meth:`Device.start_state`.
    Each :meth:`apply` clips the commands to each drive's limit, holds them for one control
    period (``substeps`` physics steps) and advances every row.  One row is stepped with
    ``mj_step`` on its own ``MjData``; a batch with :func:`mujoco.rollout` on ``pool``'s
    threads.  Both give the same trajectory bit for bit (``tests/test_device.py``).

    Parameters
    ----------
    devices : list of Device
    theta0_rad : sequence of float [rad]
    gamma_set_deg : sequence of (float, float) [deg]
        One pair per row (None, or an empty tuple, per row for a device without the arm).
    nthread : int, optional
        Threads for a batch (default: all cores).
    pool : mujoco.rollout.Rollout, optional
        A thread pool of ``nthread`` threads to share between engines (default: the engine
        makes its own, stopped by :meth:`close`).
    data : MjData, optional
        For one row: the ``MjData`` to start and step (e.g. one a viewer shows).
    """

    def __init__(self, devices: list[Device], theta0_rad, gamma_set_deg,
                 nthread: int | None = None, pool=None, data: mujoco.MjData | None = None):
        if not devices:
            raise ValueError("an engine needs at least one run")
        d0 = devices[0]
        if any(d.substeps != d0.substeps or d.nstate != d0.nstate for d in devices):
            raise ValueError("the devices of one engine need the same substeps and state size")
        if any(d.ix != d0.ix for d in devices):
            raise ValueError("the devices of one engine need the same joint and actuator addresses")
        self.devices = devices
        self.B = len(devices)
        self.substeps = d0.substeps
        self.vmax = np.array([d.voltage_limit for d in devices])
        self._yaw_act = d0.ix.yaw_act
        #: the rows' models have the Omni's arm (else :meth:`qpos` gives NaN arm angles)
        self.has_arm = d0.ix.has_arm
        self._q = ((d0.ix.yaw_qpos, d0.ix.shoulder_qpos, d0.ix.elbow_qpos) if self.has_arm
                   else (d0.ix.yaw_qpos,))
        self._qadr = 1 + np.array(self._q)  # FULLPHYSICS state = [time, qpos, qvel, act, ...]
        # the drive's friction laws (DriveFriction): each row steps its own copy of its model,
        # whose frictionloss the engine sets at every control period
        laws = [d.drive_friction for d in devices]
        self._laws = None
        if any(f is not None for f in laws):
            # a row without laws (a candidate model without them, batched with ones that have
            # them) keeps its own frictionloss: the null law
            self._laws = _DriveLaws([f if f is not None else
                                     DriveFriction.none(d.ix.yaw_dof, d.model.dof_frictionloss[d.ix.yaw_dof],
                                                        d.ix.yaw_act)
                                     for f, d in zip(laws, devices)])
            self._force = np.zeros(self.B)  # each row's actuator force of its last step
            self._law_models = [copy.deepcopy(d.model) for d in devices]
        # torque-off periods (run_p_loop's ``enabled``) step each row's off model
        self._on_models = self._law_models if self._laws else [d.model for d in devices]
        self._off_models = None  # made at the first torque-off period
        if self.B == 1:
            m1 = self._law_models[0] if self._laws else d0.model
            self._data = d0.start_data(float(theta0_rad[0]), _pose(gamma_set_deg[0]), data)
            self._m1 = m1
            self._vmax1 = float(self.vmax[0])
            self.unstable = np.zeros(1, bool)  # see the batch's below
            self._own_pool = False
            self.pool = None
            return
        self._data = None
        self.x = np.empty((self.B, d0.nstate))
        self._ctrl = np.empty((self.B, self.substeps, d0.model.nu))
        for b, (dev, th0, gs) in enumerate(zip(devices, theta0_rad, gamma_set_deg)):
            self.x[b], self._ctrl[b, :] = dev.start_state(float(th0), _pose(gs))
        self._models = list(self._on_models)
        nthread = max(1, nthread or os.cpu_count() or 1)
        self._own_pool = pool is None
        # one thread: the calling thread steps the batch (no hand-off to a pool thread at
        # every control period); same trajectories either way
        self.pool = rollout.Rollout(nthread=nthread if nthread > 1 else 0) if pool is None else pool
        self._datas = [mujoco.MjData(d0.model) for _ in range(nthread)]
        # a row's simulated time advances by one control period per apply; MuJoCo resets an
        # unstable row's data (time back to 0) and warns without saying which row: a row whose
        # time fell behind is flagged in ``unstable`` for good (its trajectory is not physics)
        self._period = np.array([d.model.opt.timestep * self.substeps for d in devices])
        self.unstable = np.zeros(self.B, bool)
        self._state = np.empty((self.B, self.substeps, d0.nstate))
        self._sens = np.empty((self.B, self.substeps, d0.model.nsensordata))
        self._chunk = max(1, -(-self.B // len(self._datas)))  # one task per thread

    def close(self) -> None:
        """Stop the engine's own thread pool (if it made one)."""
        if self._own_pool and self.pool is not None:
            self.pool.close()
            self.pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def data(self) -> mujoco.MjData | None:
        """The ``MjData`` of a one-row engine (None for a batch)."""
        return self._data

    def qpos(self) -> np.ndarray:
        """True ``(yaw, shoulder, elbow)`` angles [rad] of every row, shape ``(B, 3)``; yaw is
        the controlled joint.  Without the Omni's arm (:attr:`has_arm` False) the shoulder and
        elbow columns are NaN (the shape stays ``(B, 3)``)."""
        if not self.has_arm:
            out = np.full((self.B, 3), np.nan)
            out[:, 0] = self.yaw()
            return out
        if self._data is not None:
            return self._data.qpos[list(self._q)][None, :].copy()
        return self.x[:, self._qadr].copy()

    def yaw(self) -> np.ndarray:
        """True yaw angle [rad] of every row, shape ``(B,)``."""
        if self._data is not None:
            return np.array([self._data.qpos[self._q[0]]])
        return self.x[:, self._qadr[0]].copy()

    def yaw_velocity(self) -> np.ndarray:
        """True yaw velocity [rad/s] of every row, shape ``(B,)``."""
        dof = self.devices[0].ix.yaw_dof
        if self._data is not None:
            return np.array([self._data.qvel[dof]])
        return self.x[:, 1 + self.devices[0].model.nq + dof].copy()

    def time(self) -> np.ndarray:
        """Simulated time [s] of every row since its start, shape ``(B,)``."""
        if self._data is not None:
            return np.array([self._data.time])
        return self.x[:, 0].copy()

    def reset_rows(self, rows, theta0_rad, gamma_set_deg) -> None:
        """Start rows ``rows`` again from :meth:`Device.start_state` (the others go on)."""
        for b, th0, gs in zip(rows, theta0_rad, gamma_set_deg):
            dev = self.devices[b]
            self.unstable[b] = False
            if self._laws:
                self._force[b] = 0.0
            if self._data is not None:
                dev.start_data(float(th0), _pose(gs), self._data)
            else:
                self.x[b], self._ctrl[b, :] = dev.start_state(float(th0), _pose(gs))

    def _off(self) -> list:
        if self._off_models is None:
            self._off_models = [copy.deepcopy(d.off_model()) if self._laws else d.off_model()
                                for d in self.devices]
        return self._off_models

    def apply(self, v, on=None) -> np.ndarray:
        """Hold the commands ``v`` [V] (one per row, clipped to each drive) for one control
        period and advance the physics; returns the applied (clipped) commands.  ``on`` (B
        bools, default all True): rows switched off step with the drive off
        (:meth:`Device.off_model`; their command is 0)."""
        if self._data is not None:  # one row: plain floats and mj_step (the env's hot path)
            vk = float(v[0]) if np.ndim(v) else float(v)
            vk = min(max(vk, -self._vmax1), self._vmax1)
            m, d = self._m1, self._data
            if on is not None and not bool(np.ravel(on)[0]):
                m, vk = self._off()[0], 0.0
            if self._laws:
                self._set_friction()
            d.ctrl[self._yaw_act] = vk
            warned = _instability_warnings([d])
            for _ in range(self.substeps):
                mujoco.mj_step(m, d)
            if _instability_warnings([d]) > warned:
                self.unstable[0] = True
            if self._laws and self._laws.sensor[0] >= 0:
                self._force[0] = d.sensordata[self._laws.sensor[0]]
            return np.array([vk])
        v = np.clip(np.asarray(v, dtype=float).reshape(self.B), -self.vmax, self.vmax)
        if on is not None:
            v = np.where(on, v, 0.0)
        self._advance(v, on)
        return v

    def apply_per_step(self, v) -> np.ndarray:
        """As :meth:`apply` for a batch, with a command for every physics step of the control
        period: ``v`` (B, substeps) [V], clipped to each drive.  Returns the yaw velocity
        [rad/s] after each physics step, shape (B, substeps) (e.g. to integrate the power of
        a force held over each step)."""
        if self._data is not None:
            raise ValueError("apply_per_step steps a batch engine (two rows or more)")
        v = np.asarray(v, dtype=float).reshape(self.B, self.substeps)
        self._advance(np.clip(v, -self.vmax[:, None], self.vmax[:, None]))
        d0 = self.devices[0]
        return self._state[:, :, 1 + d0.model.nq + d0.ix.yaw_dof].copy()

    def _advance(self, v: np.ndarray, on=None) -> None:
        """A batch's :meth:`apply` after the clip: ``v`` (B,) or (B, substeps) already within
        each drive's limit (one command for the period, or one per physics step); ``on``: see
        :meth:`apply`."""
        self._ctrl[:, :, self._yaw_act] = v[:, None] if v.ndim == 1 else v
        if on is not None or self._off_models is not None:
            off = self._off()
            self._models = [mo if (on is None or on[b]) else off[b] for b, mo in enumerate(self._on_models)]
        if self._laws:
            self._set_friction()
        x_before = self.x
        first = x_before[:, 0] < 0.5 * self._period
        warnings = []
        if first.any():  # count MuJoCo's warnings of this period (the handler chains to the caller's)
            prev = mujoco.get_mju_user_warning()
            mujoco.set_mju_user_warning(lambda msg: (warnings.append(msg), prev and prev(msg)))
        try:
            self.pool.rollout(self._models, self._datas, self.x, self._ctrl, nstep=self.substeps,
                              skip_checks=True, state=self._state, sensordata=self._sens,
                              chunk_size=self._chunk)
        finally:
            if first.any():
                mujoco.set_mju_user_warning(prev)
        self.x = self._state[:, -1, :].copy()
        self.unstable |= self.x[:, 0] < x_before[:, 0] + 0.5 * self._period
        if warnings:
            # a reset at a row's very first physics step leaves its time as expected: the rows
            # in their first period are stepped again one by one, each on its own MjData, to see
            # which of them warned
            self.unstable[first] |= [_warns(self._models[b], x_before[b], self._ctrl[b])
                                     for b in np.flatnonzero(first)]
        if self._laws and np.any(self._laws.sensor >= 0):
            adr = self._laws.sensor
            self._force = np.where(adr >= 0, self._sens[np.arange(self.B), -1, np.maximum(adr, 0)], 0.0)

    def _set_friction(self) -> None:
        """Every row's :class:`DriveFriction` level for the coming control period, written into
        the row's own model."""
        w = self.yaw_velocity()
        self._laws.write(self._law_models, w, self._force)  # the one row's model is _law_models[0]
        if self._off_models is not None:  # the drive off: no force, only the friction level
            levels = self._laws.levels(w, self._force)
            dof = self._laws.dof
            for m, f in zip(self._off_models, levels):
                m.dof_frictionloss[dof] = f


def run_p_loop(engine: Engine, r: np.ndarray, kp, noise: np.ndarray | None = None,
               quantum_rad=0.0, record_arm: bool = False, command_limit=None,
               enabled: np.ndarray | None = None) -> dict:
    """The paper's experiment: the clipped P law closed around the encoder, for every row.

    Parameters
    ----------
    engine : Engine
        B rows at their start states.
    r : ndarray, shape (B, n) [rad]
        References, one sample per control period.
    kp : float or ndarray (B,) [V/rad]
    noise : ndarray, shape (B, n), optional [rad]
        Measurement noise of each sample (:meth:`Encoder.noise`).
    quantum_rad : float or ndarray (B,) [rad]
        Encoder rounding step (0: none).
    record_arm : bool
        Also return the true shoulder/elbow angles (NaN without the Omni's arm).
    command_limit : float or ndarray (B,), optional [V]
        The P law's own saturation (a run's metadata ``command_limit``); default: each drive's
        limit (``ctrlrange``).  The drive still clips what it receives to its ``ctrlrange``, so
        the applied command is clipped at the smaller of the two.
    enabled : ndarray of bool, shape (B, n), optional
        Whether the actuator is on at each period: while False the command is 0 and the drive
        exerts no force (torque off, :meth:`Device.off_model`: the joint swings free).
        Default: always on.

    Returns
    -------
    dict
        ``theta`` (measured, what the controller saw) and ``v`` (applied) of shape ``(B, n)``;
        ``unstable`` (B,) bool: rows MuJoCo found unstable and reset (:attr:`Engine.unstable`;
        their trajectories are not physics); with ``record_arm`` also ``q1``, ``q2`` [rad].
    """
    B, n = r.shape
    kp = np.broadcast_to(np.asarray(kp, dtype=float), (B,))
    exact = noise is None and not np.any(np.asarray(quantum_rad) > 0)
    theta = np.empty((B, n))
    v = np.empty((B, n))
    if record_arm:
        q1 = np.empty((B, n))
        q2 = np.empty((B, n))
    vmax = engine.vmax
    if command_limit is not None:
        vmax = np.minimum(vmax, np.broadcast_to(np.asarray(command_limit, dtype=float), (B,)))
    on = None if enabled is None else np.broadcast_to(np.asarray(enabled, dtype=bool), (B, n))
    if engine.data is None:  # a batch: the same steps as below, without the per-call overheads
        _batch_p_loop(engine, r, kp, noise, quantum_rad, theta, v,
                      (q1, q2) if record_arm else None, vmax, on)
    else:
        _one_row_p_loop(engine, r, kp, noise, quantum_rad, exact, theta, v,
                        (q1, q2) if record_arm else None, vmax, on)
    if not np.all(np.isfinite(theta[~engine.unstable])):
        raise RuntimeError("simulation diverged (non-finite yaw angle)")
    out = {"theta": theta, "v": v, "unstable": engine.unstable.copy()}
    if record_arm:
        out.update(q1=q1, q2=q2)
    return out


def _one_row_p_loop(engine, r, kp, noise, quantum_rad, exact, theta, v, arm, vmax, on) -> None:
    n = r.shape[1]
    read = encoder_reader(quantum_rad)
    for k in range(n):
        if arm is not None:
            q = engine.qpos()
            th, arm[0][:, k], arm[1][:, k] = q[:, 0], q[:, 1], q[:, 2]
        else:
            th = engine.yaw()
        y = th if exact else read(th, 0.0 if noise is None else noise[:, k])
        theta[:, k] = y
        v[:, k] = engine.apply(p_law(kp, r[:, k], y, vmax), None if on is None else on[:, k])


def _batch_p_loop(engine, r, kp, noise, quantum_rad, theta, v, arm, vmax, on) -> None:
    """:func:`run_p_loop` on a batch engine: the same encoder and P law, reading the state and
    advancing the batch directly (no per-period copies; :meth:`Engine.apply`'s second clip
    would leave the clipped command as it is)."""
    n = r.shape[1]
    qa = engine._qadr
    if arm is not None and not engine.has_arm:
        arm[0][:] = np.nan
        arm[1][:] = np.nan
        arm = None
    exact = noise is None and not np.any(np.asarray(quantum_rad) > 0)
    read = encoder_reader(quantum_rad)
    for k in range(n):
        x = engine.x
        th = x[:, qa[0]]
        if arm is not None:
            arm[0][:, k] = x[:, qa[1]]
            arm[1][:, k] = x[:, qa[2]]
        y = th if exact else read(th, 0.0 if noise is None else noise[:, k])
        theta[:, k] = y
        u = p_law(kp, r[:, k], y, vmax)
        if on is not None:
            u = np.where(on[:, k], u, 0.0)
        v[:, k] = u
        engine._advance(u, None if on is None else on[:, k])
