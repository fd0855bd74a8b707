"""LuGre bristles along a logged motion: the torque of a model's passive LuGre ``dcmotor``
actuators (the Omni's ``yaw_friction``, a ``presliding_friction`` candidate) from the smoothed
velocity, so that the missing torque can be seen under a model that has them (:mod:`.torque`).

MuJoCo's LuGre ``dcmotor`` (``input="none"``, ``lugre="sigma0 sigma1 Fc Fs vs"``, compiled into
``actuator_dynprm[5:7]`` and ``actuator_biasprm[3:6]``) holds the bristle deflection ``z`` as its
activation, with::

    g(v) = Fc + (Fs - Fc) exp(-(v / vs)^2),     z' = v - sigma0 |v| z / g(v),
    force = -(sigma0 z + sigma1 z')

and steps ``z`` exactly for the step's start velocity ``v`` held over the step::

    z_(k+1) = v / a + (z_k - v / a) exp(-a dt),    a = sigma0 |v| / g(v)   (z + v dt when a = 0)

(both checked against MuJoCo's stepping, ``tests/test_bristles.py``).  The bristle state is a
function of the motion's history, not of the current angle, so it is integrated here along the
whole run, from ``z = 0`` at its start (the replay's start: MuJoCo's data at reset), on the
model's timestep grid, with the velocity of the angle smoothed by the narrow window the
friction's direction is read on (:data:`~.smoothing.STICK_SHARE`).  Its torque is then seen
through the smoothing window like every other term (consistent filtering).
"""

from __future__ import annotations

import mujoco
import numpy as np


def with_bristles(model: mujoco.MjModel, actuators: list[int]) -> list[int]:
    """Those of ``actuators`` (the device's LuGre actuators on its joint,
    :meth:`omni_sim.device.Device.lugre_actuators`) that hold a bristle state: one activation
    and a bristle stiffness (a cogging ``dcmotor`` has neither)."""
    return [a for a in actuators if model.actuator_actnum[a] == 1 and model.actuator_dynprm[a, 5] > 0]


def parameters(model: mujoco.MjModel, a: int) -> tuple[float, ...]:
    """``(sigma0, sigma1, Fc, Fs, vs, gear)`` of LuGre actuator ``a``."""
    s0, s1 = (float(x) for x in model.actuator_dynprm[a, 5:7])
    fc, fs, vs = (float(x) for x in model.actuator_biasprm[a, 3:6])
    return s0, s1, fc, fs, vs, float(model.actuator_gear[a, 0])


def torque(params: tuple[float, ...], v: np.ndarray, dt: float) -> np.ndarray:
    """The joint torque [N*m] of one LuGre actuator along the velocity ``v`` [rad/s] (one
    value per step of ``dt`` [s], the step's start velocity), its bristle starting at 0."""
    s0, s1, fc, fs, vs, gear = params
    v = np.asarray(v, float)
    g = fc + (fs - fc) * np.exp(-(v / vs) ** 2) if vs > 0 else np.full(len(v), fc)
    g = np.maximum(g, 1e-300)
    rate = s0 * np.abs(v) / g
    decay = np.exp(-rate * dt)
    z = np.empty(len(v))
    zk = 0.0
    for k in range(len(v)):  # a recursion of a few thousand steps per run
        z[k] = zk
        r = rate[k]
        zk = v[k] / r + (zk - v[k] / r) * decay[k] if r > 0 else zk + v[k] * dt
    zdot = v - rate * z
    return -gear * (s0 * z + s1 * zdot)

