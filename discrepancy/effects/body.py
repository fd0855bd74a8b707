"""Effects on bodies and the world: ``gravity_tilt`` (the gravity vector tilted) and
``arm_mass`` (the Omni's link masses).

* ``gravity_tilt``: tilting the gravity vector is the same physics as tilting the robot's base.
  Gravity acting on the arm's mass moment ``m*R`` about the yaw axis gives a torque
  ``m R g (sin(ty) cos(theta) - sin(tx) sin(theta))``: ``tx`` acts like a pose-dependent spring,
  ``ty`` like a pose-dependent constant torque.
* ``arm_mass``: the calibrated link masses (68.8 g, 59.5 g, models/omni/omni.xml) are inferred
  from the paper's data; +-30 % is a realistic doubt.  +20 % on both links is ~390x the noise
  floor (the package docstring; the arm's gravity sag changes too).  Applies only where both
  bodies have an explicit inertial.
"""

from __future__ import annotations

import math

import numpy as np

from .base import OMNI, Effect, Param


def _read_tilt(spec, target=OMNI):
    g = np.asarray(spec.option.gravity, dtype=float)
    n = float(np.linalg.norm(g))
    if n == 0:
        return np.zeros(2)
    return np.array([math.asin(np.clip(g[0] / n, -1, 1)), math.asin(np.clip(g[1] / n, -1, 1))])


def _write_tilt(spec, x, target=OMNI):
    g = np.asarray(spec.option.gravity, dtype=float)
    n = float(np.linalg.norm(g)) or 9.81
    sx, sy = math.sin(x[0]), math.sin(x[1])
    sz = math.sqrt(max(1.0 - sx * sx - sy * sy, 0.0))
    spec.option.gravity = [n * sx, n * sy, -n * sz]


def _tilt_grid(x0):
    d = 0.03
    pts = [(0, 0), (d, 0), (-d, 0), (0, d), (0, -d), (2 * d, 0), (-2 * d, 0), (0, 2 * d), (0, -2 * d)]
    return np.array([[x0[0] + a, x0[1] + b] for a, b in pts])


ARM_BODIES = ("upper_arm", "forearm")


def _applies_arm(spec, target=OMNI) -> bool:
    for name in ARM_BODIES:
        b = spec.body(name)
        if b is None or not b.explicitinertial or not b.mass > 0 or not np.all(np.isfinite(b.ipos)):
            return False
    return True


def _read_arm(spec, target=OMNI):
    return np.array([float(spec.body(n).mass) for n in ARM_BODIES])


def _write_arm(spec, x, target=OMNI):
    for name, mass in zip(ARM_BODIES, x):
        b = spec.body(name)
        f = float(mass) / float(b.mass)  # same shape: inertia scales with the mass, CoM kept
        b.mass = float(mass)
        b.inertia = [float(v) * f for v in b.inertia]
        if np.all(np.isfinite(b.fullinertia)):
            b.fullinertia = [float(v) * f for v in b.fullinertia]


def _arm_grid(x0):
    f = ((1, 1), (0.7, 1), (1.4, 1), (1, 0.7), (1, 1.4), (0.7, 0.7), (1.4, 1.4))
    return np.array([[x0[0] * a, x0[1] * b] for a, b in f])


GRAVITY_TILT = Effect(
    "gravity_tilt", "gravity torque from a tilted yaw axis (base not level)",
    (Param("tilt_x_rad", "rad", -0.3, 0.3, 0.01), Param("tilt_y_rad", "rad", -0.3, 0.3, 0.01)),
    _read_tilt, _write_tilt, _tilt_grid)

ARM_MASS = Effect(
    "arm_mass", "masses of the Omni's upper arm and forearm links (pose-dependent yaw inertia)",
    (Param("upper_arm_mass_kg", "kg", 0.02, 0.2, 0.005),
     Param("forearm_mass_kg", "kg", 0.02, 0.2, 0.005)),
    _read_arm, _write_arm, _arm_grid, _applies_arm)
