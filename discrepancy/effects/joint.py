"""Effects that change the target joint's own attributes: ``coulomb_friction``
(``frictionloss``), ``viscous_damping``, ``joint_stiffness`` (rest at 0) and ``armature``."""

from __future__ import annotations

import numpy as np

from .base import OMNI, Effect, Param, absolute_grid, joint_of, scaled_grid


def _set_joint(attr: str, index: int | None = None):
    def write(spec, x, target=OMNI):
        j = joint_of(spec, target)
        if index is None:
            setattr(j, attr, float(x[0]))
        else:
            getattr(j, attr)[index] = float(x[0])
    return write


def _get_joint(attr: str, index: int | None = None):
    def read(spec, target=OMNI):
        j = joint_of(spec, target)
        val = getattr(j, attr)
        return np.array([float(val if index is None else val[index])])
    return read


COULOMB_FRICTION = Effect(
    "coulomb_friction", "Coulomb (dry) friction at the yaw joint",
    (Param("frictionloss_nm", "N*m", 0.0, 0.3, 0.01),),
    _get_joint("frictionloss"), _set_joint("frictionloss"),
    absolute_grid((0.0, 0.01, 0.02, 0.035, 0.05, 0.08, 0.12)))

VISCOUS_DAMPING = Effect(
    "viscous_damping", "viscous damping at the yaw joint",
    (Param("damping_nms_per_rad", "N*m*s/rad", 0.0, 0.1, 0.002),),
    _get_joint("damping", 0), _set_joint("damping", 0),
    scaled_grid((0.25, 0.5, 1.0, 1.5, 2.0, 3.0)))

JOINT_STIFFNESS = Effect(
    "joint_stiffness", "a torsional spring at the yaw joint (cables, springs), rest at 0",
    (Param("stiffness_nm_per_rad", "N*m/rad", -0.3, 1.0, 0.02),),
    _get_joint("stiffness", 0), _set_joint("stiffness", 0),
    absolute_grid((-0.05, 0.0, 0.03, 0.1, 0.3)))

ARMATURE = Effect(
    "armature", "reflected rotor inertia (armature) at the yaw joint",
    (Param("armature_kgm2", "kg*m^2", 0.0, 0.01, 1e-4),),
    _get_joint("armature"), _set_joint("armature"),
    absolute_grid((0.0, 1e-4, 3e-4, 1e-3, 3e-3)))
