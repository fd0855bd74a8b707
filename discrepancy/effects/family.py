"""Friction as ONE law with nested variants, and the drive's current limit that moves with the
back-EMF: effects the engine applies (:data:`omni_sim.device.FRICTION_FAMILY`,
:data:`omni_sim.device.CURRENT_LIMIT`): the family's Stribeck variant nested in ``load_friction``
(the search confirms it with its parent, :data:`NESTED`), the current
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

The variants the search chooses among (nested: each one's parameters contain its parent's; a
variant is the full law with the parameters it does not free held at the nominal model's values,
the numeric's at 0 when the model has none).  ``Fc0`` and ``Fv`` are the joint's own
``frictionloss`` and ``damping``, which the library frees as ``coulomb_friction`` and
``viscous_damping`` (a user's device: corrections of the nominal when it states them, candidates
when it does not); a variant that freed them too would free the same MJCF attribute twice in one
fit.  So the family's own variants are its load-dependent part and the Stribeck rise on top:

=========================  ===========================  ===============================  ==
name                       parent                       adds                             k
=========================  ===========================  ===============================  ==
load_friction              (root; :mod:`.drive`)        ``mu_drive``, ``mu_back``        2
friction_family_stribeck   load_friction                ``rise_nm``, ``omega_s_rad_s``,  5
                                                        ``delta``
load_friction_smooth       load_friction                ``w_s_rad_s``                    4
=========================  ===========================  ===============================  ==

(:data:`PARENT`, :data:`COMPLEXITY`; ``load_friction`` is the library's effect, the same law as
the family's with the rise at 0, written as its own numeric.)  The search confirms the Stribeck
variant whenever it confirms ``load_friction`` in a round of single candidates and keeps the one
:func:`discrepancy.nesting.choose_variant` picks (a rule fixed before any result;
:data:`NESTED`).  Bounds: ``rise`` 0-0.3 N*m as ``stribeck_friction``'s; ``k_drive`` 0-0.9 and
``k_back`` 0-9 as ``load_friction``'s (forward and back-driven efficiency down to 0.1, see
:mod:`.drive`); ``omega_s`` 0.01-3 rad/s as ``stribeck_friction``'s; ``delta`` 0.5-2.5 (1: the
exponential of Tustin's model, 2: the Gaussian of Armstrong's; the survey's range, estimate).
The family applies to geared drives only (as ``load_friction``: not the Omni's capstan).

``load_friction_smooth`` is the parent's law behind a smooth sign instead of a stick
(:data:`omni_sim.device.LOAD_FRICTION_SMOOTH`: the force ``-mu |tau| tanh(w / w_s)``, the
regularised Coulomb law of Makkar et al. 2005, the level ``mu |tau|`` with the parent's
coefficients by quadrant): nested in the limit, as ``w_s -> 0`` it is the parent's sliding force
(a Coulomb force of level ``mu |tau|`` against the motion); it differs at rest, where it holds
nothing (a gear whose loss vanishes with the speed, as an efficiency law does) while the parent
sticks.  Why a variant: the parent's fit slid on a truth of that form (the user's pendulum of
the first test half, gear +18 %, the coefficients apart: docs/method/discrepancy.md, "A load law
that sticks, beside one behind a smooth sign").  It is written in the parent's place (a nominal
``load_friction`` numeric is removed where it writes its own).  ``w_s`` 0.002-1 rad/s: from a tenth
of the smallest speed a servo's log resolves (a count of a 4096-count encoder, 1.5e-3 rad, over
a 50 ms window: 0.03 rad/s; estimate), below which the law is a sign to the logs, up to the
speeds the runs move at (~1 rad/s), above which it is viscous damping everywhere; its starting
speeds half a decade apart about the parent's blend speed 0.05 rad/s
(:data:`omni_sim.device.LOAD_FRICTION_BLEND_RAD_S`): 0.005, 0.016, 0.05, 0.16 (fixed before
any fit).

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

from omni_sim.device import (CURRENT_LIMIT, FRICTION_FAMILY, LOAD_FRICTION, LOAD_FRICTION_BLEND_RAD_S,
                             LOAD_FRICTION_SMOOTH)
from .actuator import _read_limit
from .base import OMNI, Effect, Param, actuator_of
from .drive import (LOAD_FRICTION_EFFECT, _ensure_torque_sensor, _geared, _load_grid, _numeric_values, _read_load,
                    _set_numeric)

RISE = Param("rise_nm", "N*m", 0.0, 0.3, 0.003)
OMEGA_S = Param("omega_s_rad_s", "rad/s", 0.01, 3.0, 0.05)
DELTA = Param("delta", "-", 0.5, 2.5, 0.1)
#: The variant's parameters: its parent's, ``load_friction``'s own (the search starts a variant
#: from its parent's values, so they come first and in its order), then the rise's.
LAW_PARAMS = (*LOAD_FRICTION_EFFECT.params, RISE, OMEGA_S, DELTA)
#: Where each of :data:`LAW_PARAMS` sits in the numeric ``friction_family``, whose order is the
#: engine's, ``k_drive k_back rise_nm omega_s delta b_emf`` (b_emf last: optional).
_IN_NUMERIC = np.array([0, 1, 5, 2, 3, 4])


def _read_stribeck(spec, target=OMNI):
    if spec.numeric(FRICTION_FAMILY) is None:  # no law: the parent's nominal values, no rise
        return np.concatenate([_read_load(spec, target), np.zeros(3)])
    return _numeric_values(spec, FRICTION_FAMILY, 6)[_IN_NUMERIC]


def _write_stribeck(spec, x, target=OMNI):
    data = np.empty(len(_IN_NUMERIC))
    data[_IN_NUMERIC] = np.asarray(x, float)[:len(_IN_NUMERIC)]
    _set_numeric(spec, FRICTION_FAMILY, data)
    _ensure_torque_sensor(spec, target)


#: The rise's starting levels [N*m]: from the library's smallest Stribeck rise (stribeck_friction's
#: grid, Fs - Fc = 0.01) to a small servo's gear-train Coulomb level (the servo pendulum's 0.03-0.05
#: N*m, models/servo_pendulum); Stribeck speeds a decade apart as stribeck_friction's grid; delta 1
#: (Tustin's exponential) and 2 (Armstrong's Gaussian).  Estimates, fixed before any fit.
_RISES, _SPEEDS, _SHAPES = (0.01, 0.05), (0.05, 0.5), (1.0, 2.0)


def _stribeck_grid(x0):
    """The load coefficients as given (load_friction's fit when the search starts the variant
    from it), the rise's shape over :data:`_RISES` x :data:`_SPEEDS` x :data:`_SHAPES`."""
    return np.array([[x0[0], x0[1], x0[2], r, ws, dl] for r in _RISES for ws in _SPEEDS for dl in _SHAPES])


STRIBECK = Effect("friction_family_stribeck",
                  "load-dependent gear friction with a Stribeck rise of its own shape (friction family)",
                  LAW_PARAMS, _read_stribeck, _write_stribeck, _stribeck_grid,
                  applies=lambda spec, target=OMNI: _geared(spec, target))

W_S = Param("w_s_rad_s", "rad/s", 0.002, 1.0, 0.01)
#: ``load_friction_smooth``'s starting sign speeds [rad/s] (module docstring).
_SIGN_SPEEDS = (0.005, 0.016, 0.05, 0.16)


def _read_smooth(spec, target=OMNI):
    if spec.numeric(LOAD_FRICTION_SMOOTH) is None:  # no law: the parent's values, its blend speed
        return np.concatenate([_read_load(spec, target), [LOAD_FRICTION_BLEND_RAD_S]])
    return _numeric_values(spec, LOAD_FRICTION_SMOOTH, 4)


def _write_smooth(spec, x, target=OMNI):
    stick = spec.numeric(LOAD_FRICTION)
    if stick is not None:  # the variant is written in its parent's place
        spec.delete(stick)
    _set_numeric(spec, LOAD_FRICTION_SMOOTH, np.asarray(x, float)[:4])
    _ensure_torque_sensor(spec, target)


def _smooth_grid(x0):
    """The coefficients as given at every starting sign speed (the search starts the variant from
    its parent's fit: its coefficients kept), then the parent's own grid at the blend speed (an
    equation-error fit from the nominal, whose coefficients are 0)."""
    given = [[x0[0], x0[1], x0[2], ws] for ws in _SIGN_SPEEDS]
    return np.array(given + [[*g, LOAD_FRICTION_BLEND_RAD_S] for g in _load_grid(x0)])


SMOOTH = Effect("load_friction_smooth",
                "load-dependent gear friction behind a smooth sign: no stick, the loss vanishes at rest",
                (*LOAD_FRICTION_EFFECT.params, W_S), _read_smooth, _write_smooth, _smooth_grid,
                applies=lambda spec, target=OMNI: _geared(spec, target))

#: Each variant's parent (None: the root), root first.
PARENT: dict[str, str | None] = {LOAD_FRICTION_EFFECT.name: None, STRIBECK.name: LOAD_FRICTION_EFFECT.name,
                                 SMOOTH.name: LOAD_FRICTION_EFFECT.name}
#: The variants, root first.
VARIANTS: tuple[Effect, ...] = (LOAD_FRICTION_EFFECT, STRIBECK, SMOOTH)
#: Each variant's number of free parameters (the complexity the selection rule penalises).
COMPLEXITY: dict[str, int] = {v.name: v.nparam for v in VARIANTS}
#: A library candidate -> its richer nested variants (:data:`PARENT` read the other way), which the
#: search confirms with it and chooses among (:func:`discrepancy.nesting.choose_variant`).
NESTED: dict[str, tuple[str, ...]] = {p: tuple(c for c, q in PARENT.items() if q == p)
                                      for p in PARENT if p in PARENT.values()}


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

#: The effects of this module the search names but does not score as candidates of their own
#: (nested variants, :data:`NESTED`; the current limit is in the library).
STAGED: tuple[Effect, ...] = (STRIBECK, SMOOTH)


__all__ = ["VARIANTS", "PARENT", "COMPLEXITY", "NESTED", "STAGED", "STRIBECK", "SMOOTH", "CURRENT_LIMIT_EFFECT",
           "LAW_PARAMS"]
