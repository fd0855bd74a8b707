"""Friction as ONE law with nested variants, and the drive's current limit that moves with the
back-EMF: effects the engine applies (:data:`omni_sim.device.FRICTION_FAMILY`,
:data:`omni_sim.device.CURRENT_LIMIT`): the family's variants staged for the search, the current
limit among its candidates (:data:`discrepancy.effects.LIBRARY`).

The law
-------
The dry friction model of Hamon, Gautier and Garrec (2010, "Dynamic identification of robots
with a dry friction model depending on load and velocity", IEEE/RSJ IROS; the paper's text was
not available when this module was written, so the equation below is the model as it is
commonly summarised, not checked against the paper)
with the exponential Stribeck curve of the friction literature (e.g. Armstrong-Helouvry,
Dupont and Canudas de Wit 1994, Automatica 30(7), the same caveat) and viscous friction::

    F(tau, w) = Fc0 + k |tau| + (Fs - Fc0) exp(-(|w| / ws)^delta) + Fv w
    k = k_drive while the motor drives the load (tau w > 0), k_back while the load
        back-drives it (blended over |w| ~ 0.05 rad/s as load_friction's coefficients,
        omni_sim.device.LOAD_FRICTION_BLEND_RAD_S)

``tau`` the torque the motor transmits, ``w`` the joint velocity.  Where it lives in the model:
``Fc0`` is the joint's ``frictionloss``, ``Fv`` the joint's ``damping`` (both native MJCF,
integrated by MuJoCo); ``k_drive, k_back, rise_nm = Fs - Fc0, omega_s, delta`` are the
``<custom><numeric name="friction_family">`` the engine reads (the dry level is written into
``dof_frictionloss`` at every control period, the torque read from an ``actuatorfrc`` sensor
this module adds, as ``load_friction``'s).

The variants (nested: each one's parameters contain its parent's; a variant is the full law
with the parameters it does not free held at the nominal model's values, the numeric's at 0 when
the model has none)

=========================  ===========================  ===============================  ==
name                       parent                       adds                             k
=========================  ===========================  ===============================  ==
friction_family_coulomb    (root)                       ``fc0_nm``                       1
friction_family_load       friction_family_coulomb      ``k_drive``, ``k_back``          3
friction_family_stribeck   friction_family_load         ``rise_nm``, ``omega_s_rad_s``,  6
                                                        ``delta``
friction_family_viscous    friction_family_stribeck     ``fv_nms_per_rad``               7
=========================  ===========================  ===============================  ==

(:data:`PARENT`, :data:`COMPLEXITY`; which variant a search keeps is decided by
:func:`discrepancy.nesting.choose_variant`, a rule fixed before any result.)  Bounds: ``fc0`` and
``rise`` 0-0.3 N*m as ``coulomb_friction``/``stribeck_friction``; ``k_drive`` 0-0.9 and
``k_back`` 0-9 as ``load_friction``'s (forward and back-driven efficiency down to 0.1, see
:mod:`.drive`); ``omega_s`` 0.01-3 rad/s as ``stribeck_friction``'s; ``delta`` 0.5-2.5 (1: the
exponential of Tustin's model, 2: the Gaussian of Armstrong's; the survey's range, estimate);
``fv`` 0-0.1 N*m*s/rad as ``viscous_damping`` (a servo whose damping holds its back-EMF, 0.37
on the servo pendulum, gets its bound widened by :func:`~discrepancy.effects.for_model`).  The
family applies to geared drives only (as ``load_friction``: not the Omni's capstan).

The current limit
-----------------
``current_limit``: a servo firmware's current limit on a motor driven by its voltage (the
``motor`` of the servo pendulum: ``gear`` = kt/R, ``ctrlrange`` +-V_s, the back-EMF kt*ke/R in
the joint's damping): the net motor torque stays within ``+-tau_i`` (``tau_i = kt i_max``), so
the torque the motor can give in the direction of motion is ``kt min(i_max, (V_s - ke |w|)/R)``.
Parameters ``torque_limit_nm`` (tau_i; 0.005-20 N*m: the Omni's 20 mN*m up to a large servo's
stall) and ``back_emf_nms_per_rad`` (b = kt*ke/R, the electrical part of the damping; 0-5).
With ``b = 0`` it is ``torque_saturation`` (nested: that effect is this one at b = 0; a model
without the numeric reads torque_saturation's limit and b = 0).  Written as the numeric
``current_limit`` (the engine moves the actuator's ``forcerange`` with the velocity at every
control period) and the bound at rest as the actuator's ``forcerange`` (what plain MuJoCo sees
without the runtime).  Not for a ``dcmotor`` actuator: its force holds the back-EMF already,
and MuJoCo 4 writes the limit natively (``saturation="0 i_max V_s"``: ``forcerange`` = K i_max,
checked in tests/test_friction_family_law.py).
"""

from __future__ import annotations

import mujoco
import numpy as np

from omni_sim.device import CURRENT_LIMIT, FRICTION_FAMILY
from .actuator import _read_limit
from .base import OMNI, Effect, Param, Target, actuator_of, joint_of
from .drive import _ensure_torque_sensor, _geared, _set_numeric

#: Every parameter of the law, in the order of the full variant.
FC0 = Param("fc0_nm", "N*m", 0.0, 0.3, 0.003)
K_DRIVE = Param("k_drive", "-", 0.0, 0.9, 0.02)
K_BACK = Param("k_back", "-", 0.0, 9.0, 0.02)
RISE = Param("rise_nm", "N*m", 0.0, 0.3, 0.003)
OMEGA_S = Param("omega_s_rad_s", "rad/s", 0.01, 3.0, 0.05)
DELTA = Param("delta", "-", 0.5, 2.5, 0.1)
FV = Param("fv_nms_per_rad", "N*m*s/rad", 0.0, 0.1, 0.002)
LAW_PARAMS = (FC0, K_DRIVE, K_BACK, RISE, OMEGA_S, DELTA, FV)


def _read_law(spec: mujoco.MjSpec, target: Target) -> np.ndarray:
    """The full law's 7 values the spec holds: frictionloss, the numeric's 5 (0 if absent),
    damping."""
    j = joint_of(spec, target)
    n = spec.numeric(FRICTION_FAMILY)
    mid = np.zeros(5) if n is None else np.array(list(n.data)[:5], float)
    return np.concatenate([[float(j.frictionloss)], mid, [float(j.damping[0])]])


def _write_law(spec: mujoco.MjSpec, full: np.ndarray, target: Target) -> None:
    j = joint_of(spec, target)
    j.frictionloss = float(full[0])
    j.damping[0] = float(full[6])
    if np.any(full[1:6] != 0) or spec.numeric(FRICTION_FAMILY) is not None:
        _set_numeric(spec, FRICTION_FAMILY, full[1:6])
        _ensure_torque_sensor(spec, target)


def _variant(name: str, parent: str | None, description: str, free: tuple[int, ...], grid) -> Effect:
    """An effect over the law's parameters ``free`` (indices into :data:`LAW_PARAMS`), the others
    kept as the spec holds them."""
    def read(spec, target=OMNI):
        return _read_law(spec, target)[list(free)]

    def write(spec, x, target=OMNI):
        full = _read_law(spec, target)
        full[list(free)] = x
        _write_law(spec, full, target)

    eff = Effect(name, description, tuple(LAW_PARAMS[i] for i in free), read, write, grid,
                 applies=lambda spec, target=OMNI: _geared(spec, target))
    PARENT[name] = parent
    return eff


#: Each variant's parent (None: the root).
PARENT: dict[str, str | None] = {}


def _coulomb_grid(x0):
    base = x0[0] if x0[0] > 0 else 0.03
    return np.array([[base * f] for f in (0.3, 0.6, 1.0, 1.5, 2.5)])


#: load_friction's starting pairs (forward, back-driven coefficients over their estimated ranges).
_LOAD_PAIRS = ((0.0, 0.0), (0.1, 0.2), (0.1, 0.5), (0.2, 0.4), (0.2, 0.8), (0.3, 0.3), (0.05, 1.0))


def _load_grid(x0):
    return np.array([[x0[0], d, b] for d, b in _LOAD_PAIRS])


def _stribeck_grid(x0):
    rise = max(x0[0], 0.01)  # a static level up to twice the Coulomb level
    return np.array([[*x0[:3], r, ws, dl] for r in (0.5 * rise, rise) for ws in (0.05, 0.3)
                     for dl in (1.0, 2.0)])


def _viscous_grid(x0):
    fv = x0[6]
    return np.array([[*row, v] for row in _stribeck_grid(x0[:6])[::2] for v in (fv, 1.3 * fv + 0.002)])


COULOMB = _variant("friction_family_coulomb", None,
                   "friction family, Coulomb level only (Fc0)", (0,), _coulomb_grid)
LOAD = _variant("friction_family_load", COULOMB.name,
                "friction family: Coulomb level rising with the transmitted torque, driving/back-driven",
                (0, 1, 2), _load_grid)
STRIBECK = _variant("friction_family_stribeck", LOAD.name,
                    "friction family: load-dependent Coulomb level and a Stribeck rise of its own shape",
                    (0, 1, 2, 3, 4, 5), _stribeck_grid)
VISCOUS = _variant("friction_family_viscous", STRIBECK.name,
                   "friction family: the full law (load, Stribeck, viscous)",
                   (0, 1, 2, 3, 4, 5, 6), _viscous_grid)

#: The variants, root first.
VARIANTS: tuple[Effect, ...] = (COULOMB, LOAD, STRIBECK, VISCOUS)
#: Each variant's number of free parameters (the complexity the selection rule penalises).
COMPLEXITY: dict[str, int] = {v.name: v.nparam for v in VARIANTS}


def _read_current(spec, target=OMNI):
    n = spec.numeric(CURRENT_LIMIT)
    if n is not None:
        return np.array(list(n.data)[:2], float)
    return np.array([_read_limit(spec, target)[0], 0.0])  # torque_saturation's limit, b = 0


def _write_current(spec, x, target=OMNI):
    _set_numeric(spec, CURRENT_LIMIT, x[:2])
    a = actuator_of(spec, target)
    lim = float(x[0]) / float(a.gear[0])  # the bound at rest (forcerange is before the gear)
    a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    a.forcerange = [-lim, lim]


def _current_grid(x0):
    return np.array([[t, b] for t in (0.02, 0.07, 0.2, 0.65, 2.0) for b in (0.0, 0.1, 0.4)])


def _servo_drive(spec, target=OMNI) -> bool:
    """A geared drive (:func:`~.drive._geared`: a user's own device, not the virtual Omni) whose
    actuator is driven by its voltage (not a ``dcmotor``, whose force holds the back-EMF and whose
    limit MuJoCo writes natively).  The Omni's amplifier limit stays ``torque_saturation``."""
    return ((target != OMNI or spec.numeric(CURRENT_LIMIT) is not None)
            and actuator_of(spec, target).gaintype != mujoco.mjtGain.mjGAIN_DCMOTOR)


CURRENT_LIMIT_EFFECT = Effect(
    "current_limit",
    "firmware current limit: the torque bound moves with the back-EMF (stall current, supply voltage)",
    (Param("torque_limit_nm", "N*m", 0.005, 20.0, 0.01),
     Param("back_emf_nms_per_rad", "N*m*s/rad", 0.0, 5.0, 0.02)),
    _read_current, _write_current, _current_grid, applies=_servo_drive)

#: The effects of this module not yet in the search's :data:`~discrepancy.effects.LIBRARY`
#: (staged; the current limit is in the library).
STAGED: tuple[Effect, ...] = VARIANTS


__all__ = ["VARIANTS", "PARENT", "COMPLEXITY", "STAGED", "CURRENT_LIMIT_EFFECT", "LAW_PARAMS"]
