"""The library of named candidate effects, each a change of the MJCF model.

Every effect is a small set of physical parameters and a function that writes them into a
:class:`mujoco.MjSpec` of the virtual Omni (joint ``yaw``, actuator ``yaw_motor``).  Values are
*absolute* (the fitted frictionloss, not an increment), starting from what the nominal model
holds, so a fitted effect is read directly as "the model should say X".

=================  ==========================================  ===================================
name               MJCF change                                 parameters [unit]
=================  ==========================================  ===================================
coulomb_friction   ``yaw`` joint ``frictionloss``               ``frictionloss_nm`` [N*m]
viscous_damping    ``yaw`` joint ``damping``                    ``damping_nms_per_rad`` [N*m*s/rad]
joint_stiffness    ``yaw`` joint ``stiffness``, ``springref``   ``stiffness_nm_per_rad`` [N*m/rad],
                                                                ``rest_rad`` [rad]
gravity_tilt       ``option/gravity`` tilted (the base tilted)  ``tilt_x_rad``, ``tilt_y_rad`` [rad]
armature           ``yaw`` joint ``armature``                   ``armature_kgm2`` [kg*m^2]
actuator_lag       ``yaw_motor`` dyntype filterexact, dynprm[0] ``time_constant_s`` [s]
time_delay         ``yaw_motor`` ``delay`` (``nsample`` buffer) ``delay_s`` [s]
torque_saturation  ``yaw_motor`` ``forcerange``                 ``torque_limit_nm`` [N*m]
torque_gain        ``yaw_motor`` ``gear``                       ``gear_nm_per_v`` [N*m/V]
position_offset    ``yaw_motor`` affine bias ``biasprm[0]``     ``bias_v`` [V]
presliding_        LuGre ``dcmotor`` on ``yaw`` (the scene's    ``sigma0_nm_per_rad`` [N*m/rad],
friction           ``yaw_friction``, else a new passive one)    ``fc_nm``, ``fs_nm`` [N*m],
                                                                ``vs_rad_per_s`` [rad/s]
stribeck_friction  new passive LuGre ``dcmotor``                ``fc_nm``, ``fs_nm`` [N*m],
                   ``yaw_stribeck``, sigma0 fixed stiff         ``vs_rad_per_s`` [rad/s]
drive_compliance   rotor body + hinge ``yaw``; the turret's     ``stiffness_nm_per_rad`` [N*m/rad],
                   hinge renamed ``yaw_output``; fixed tendon   ``damping_nms_per_rad`` [N*m*s/rad],
                   ``yaw_cable`` = q_yaw - q_yaw_output         ``rotor_inertia_kgm2`` [kg*m^2]
                   (stiffness, damping; rotor armature)
backlash           the same two-mass drive, ``yaw_cable``       ``half_width_rad`` [rad]
                   limited to [-b, b] (springlength [-b, b])
arm_mass           ``upper_arm``, ``forearm`` body masses       ``upper_arm_mass_kg``,
                   (inertia scaled, CoM kept)                   ``forearm_mass_kg`` [kg]
cogging            new passive ``dcmotor`` ``yaw_cogging``,     ``amplitude_nm`` [N*m],
                   torque a*sin(n*q_yaw + phase), n fixed       ``phase_rad`` [rad]
load_friction      ``<custom>`` numeric ``load_friction`` (the  ``mu_drive``, ``mu_back`` [-],
                   engine's law) + ``actuatorfrc`` sensor       ``b_emf_nms_per_rad`` [N*m*s/rad]
current_limit      ``<custom>`` numeric ``current_limit`` (the  ``torque_limit_nm`` [N*m],
                   engine moves ``forcerange`` with the         ``back_emf_nms_per_rad``
                   back-EMF), the bound at rest as              [N*m*s/rad]
                   ``forcerange``; geared drives only
=================  ==========================================  ===================================

Staged (:data:`STAGED`, :mod:`.family`: written, read and tested like the library's, found by
:func:`get`, not candidates of their own in :data:`LIBRARY`/:data:`NAMES`): the friction
family's Stribeck variant ``friction_family_stribeck`` (``load_friction``'s coefficients and a
Stribeck rise of its own shape, ``<custom>`` numeric ``friction_family``, the engine's law, and
an ``actuatorfrc`` sensor), which the search confirms beside ``load_friction`` and keeps when
:func:`discrepancy.nesting.choose_variant` picks it (:data:`.family.NESTED`).

(``yaw``/``yaw_motor`` stand for the :class:`Target`'s joint and actuator; added elements are
named after the joint, with a suffix ``_2``... if the model already uses the name.  Passive
actuators are appended after every actuator, so controlled ones keep control index = id.)

The families, one module each (their docstrings give each effect's magnitudes, bounds and
sources): :mod:`.joint` (the joint's own attributes), :mod:`.actuator` (the drive),
:mod:`.friction` (passive dcmotor elements: LuGre friction, cogging), :mod:`.two_mass` (rotor
and cable), :mod:`.body` (gravity tilt, link masses), :mod:`.drive` (the engine's friction laws
of geared drives); :mod:`.base` holds :class:`Param`,
:class:`Effect` and the helpers they share, :mod:`.separation` the experiments that tell two
candidates apart.  This module is the registry: :data:`LIBRARY` in its fixed order and the
functions that read and write effects.

"Noise floor" in the families' notes: the gap of the nominal replay to data from the nominal
model with the encoder's quantisation and 1e-4 rad noise (1.6e-4 rad over
``experiment_set.experiments()``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import mujoco
import numpy as np

from . import actuator, body, drive, family, friction, joint, two_mass
from .base import OMNI, Effect, Param, Target
from .body import ARM_BODIES
from .friction import COGGING_PERIODS
from .separation import DEFAULT_SEPARATION, SEPARATING_EXPERIMENTS, separating_experiment

__all__ = ["LIBRARY", "NAMES", "STAGED", "Effect", "Param", "Target", "OMNI", "ARM_BODIES", "COGGING_PERIODS",
           "SEPARATING_EXPERIMENTS", "DEFAULT_SEPARATION", "separating_experiment", "applicable", "get",
           "nominal_values", "apply", "compile_with", "ModelBuilder"]

#: The library, in a fixed order (ties are broken by this order).
LIBRARY: tuple[Effect, ...] = (
    joint.COULOMB_FRICTION,
    joint.VISCOUS_DAMPING,
    joint.JOINT_STIFFNESS,
    body.GRAVITY_TILT,
    joint.ARMATURE,
    actuator.ACTUATOR_LAG,
    actuator.TIME_DELAY,
    actuator.TORQUE_SATURATION,
    actuator.TORQUE_GAIN,
    actuator.POSITION_OFFSET,
    friction.PRESLIDING_FRICTION,
    friction.STRIBECK_FRICTION,
    two_mass.DRIVE_COMPLIANCE,
    two_mass.BACKLASH,
    body.ARM_MASS,
    friction.COGGING,
    drive.LOAD_FRICTION_EFFECT,
    family.CURRENT_LIMIT_EFFECT,
)

NAMES = tuple(e.name for e in LIBRARY)

#: Effects written and tested like the library's, not candidates of their own: the friction
#: family's nested variants (:mod:`.family`), confirmed with their parent and chosen by
#: :func:`discrepancy.nesting.choose_variant`; the bank has a case for each
#: (tests/test_discrepancy_bank.py::test_bank_covers_the_library).
STAGED: tuple[Effect, ...] = family.STAGED


def applicable(spec: mujoco.MjSpec, target: Target = OMNI) -> tuple[str, ...]:
    """Names of the library effects that can be written into ``spec`` for ``target``."""
    return tuple(e.name for e in LIBRARY if e.applies(spec, target))


def get(name: str) -> Effect:
    """The library (or staged, :data:`STAGED`) effect called ``name`` (KeyError if unknown)."""
    for e in LIBRARY + STAGED:
        if e.name == name:
            return e
    raise KeyError(name)


def nominal_values(effect: Effect, spec: mujoco.MjSpec, target: Target = OMNI) -> np.ndarray:
    """The parameter values ``spec`` holds for ``effect``, clipped into its bounds."""
    x = effect.read(spec, target)
    x = np.where(np.isfinite(x), x, [p.upper for p in effect.params])
    return effect.clip(x)


#: A bound is widened to this multiple of the nominal value when the nominal model holds more
#: than half of it (:func:`for_model`).
WIDEN = 3.0


def for_model(effect: Effect, spec: mujoco.MjSpec, target: Target = OMNI) -> Effect:
    """``effect`` with bounds that fit the nominal model: the library's bounds are sized for the
    virtual Omni (mN*m of friction, 1e-4 kg*m^2 of rotor inertia); a user's device whose nominal
    value passes half a bound (a geared servo's reflected rotor of 1e-2 kg*m^2) gets that bound
    moved to :data:`WIDEN` times its nominal value, so the fit can start at the nominal model
    and move both ways.  The Omni's nominal values are all below half their bounds: unchanged."""
    x = effect.read(spec, target)
    params, changed = [], False
    for p, v in zip(effect.params, x):
        lo, hi = p.lower, p.upper
        if np.isfinite(v) and v > 0.5 * hi > 0:
            hi, changed = WIDEN * float(v), True
        if np.isfinite(v) and v < 0.5 * lo < 0:
            lo, changed = WIDEN * float(v), True
        params.append(dataclasses.replace(p, lower=lo, upper=hi))
    return dataclasses.replace(effect, params=tuple(params)) if changed else effect


def apply(spec: mujoco.MjSpec, changes: list[tuple[Effect, np.ndarray]],
          target: Target = OMNI) -> mujoco.MjSpec:
    """A copy of ``spec`` with every ``(effect, values)`` written into ``target``."""
    out = spec.copy()
    for eff, x in changes:
        eff.write(out, np.asarray(x, dtype=float), target)
    return out


def compile_with(spec: mujoco.MjSpec, changes: list[tuple[Effect, np.ndarray]],
                 target: Target = OMNI) -> mujoco.MjModel:
    """Compile ``spec`` with the changes applied (the spec itself is left untouched)."""
    return apply(spec, changes, target).compile()


@dataclass(frozen=True)
class ModelBuilder:
    """The library's effects on one nominal model: what the statistics (:mod:`..fit`,
    :mod:`..select`, :mod:`..uncertainty`) use to look effects up and to compile the models
    they simulate, so that they need no MuJoCo of their own.

    Attributes
    ----------
    spec : MjSpec
        The nominal model (never modified).
    target : Target
        The controlled joint and actuator the effects are written into.
    """

    spec: mujoco.MjSpec
    target: Target = OMNI

    @property
    def names(self) -> tuple[str, ...]:
        """Every library name (:data:`NAMES`)."""
        return NAMES

    def effect(self, name: str) -> Effect:
        """The library effect called ``name`` (:func:`get`), its bounds fitted to the nominal
        model (:func:`for_model`)."""
        return for_model(get(name), self.spec, self.target)

    def nested(self, name: str) -> tuple[str, ...]:
        """The richer nested variants of candidate ``name`` the search confirms with it
        (:data:`.family.NESTED`; none for most)."""
        return family.NESTED.get(name, ())

    def parent(self, name: str) -> str | None:
        """The variant effect ``name`` is nested in (:data:`.family.PARENT`), None if none."""
        return family.PARENT.get(name)

    def nominal_values(self, effect: Effect) -> np.ndarray:
        """The values the nominal model holds for ``effect`` (:func:`nominal_values`)."""
        return nominal_values(for_model(effect, self.spec, self.target), self.spec, self.target)

    def compile(self, changes: list[tuple[Effect, np.ndarray]]) -> mujoco.MjModel:
        """The nominal model with ``changes`` written in, compiled (:func:`compile_with`)."""
        return compile_with(self.spec, changes, self.target)
