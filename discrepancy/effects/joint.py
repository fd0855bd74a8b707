"""Effects that change the target joint's own attributes: ``coulomb_friction``
(``frictionloss``), ``viscous_damping``, ``joint_stiffness`` (its rest angle too) and ``armature``."""

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


def _read_spring(spec, target=OMNI):
    j = joint_of(spec, target)
    return np.array([float(j.stiffness[0]), float(j.springref)])


def _write_spring(spec, x, target=OMNI):
    j = joint_of(spec, target)
    j.stiffness[0] = float(x[0])
    j.springref = float(x[1])


#: Starting points (stiffness, rest): the one-parameter grid at rest 0 (a spring of 0-0.3 N*m/rad,
#: or a small negative one standing in for a destabilising gravity term), and the stiffest
#: spring preloaded either way by 0.3 rad (the width of the Omni's and the servo pendulum's
#: swings, about +-0.3-0.5 rad); the fit moves the rest from there.
_SPRING_GRID = np.array([[-0.05, 0.0], [0.0, 0.0], [0.03, 0.0], [0.1, 0.0], [0.3, 0.0],
                         [0.3, 0.3], [0.3, -0.3]])

JOINT_STIFFNESS = Effect(
    "joint_stiffness", "a torsional spring at the yaw joint (cables, springs, a gravity-balancing "
    "spring's preload): torque -k (q - rest), MuJoCo's stiffness and springref",
    (Param("stiffness_nm_per_rad", "N*m/rad", -0.3, 1.0, 0.02),
     Param("rest_rad", "rad", -3.0, 3.0, 0.05)),
    _read_spring, _write_spring, lambda x0: _SPRING_GRID.copy())

ARMATURE = Effect(
    "armature", "reflected rotor inertia (armature) at the yaw joint",
    (Param("armature_kgm2", "kg*m^2", 0.0, 0.01, 1e-4),),
    _get_joint("armature"), _set_joint("armature"),
    absolute_grid((0.0, 1e-4, 3e-4, 1e-3, 3e-3)))
