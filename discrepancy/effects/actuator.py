"""Effects that change the target actuator: ``actuator_lag`` (dynamics ``filterexact``),
``time_delay`` (``delay`` with a control-history buffer), ``torque_saturation``
(``forcerange``), ``torque_gain`` (``gear``) and ``position_offset`` (affine bias).

``position_offset``: a pure encoder offset shared by the controller and the log is
unobservable on a yaw axis without position-dependent torque (the closed loop is invariant
to a shift of theta, and the replay starts from the measured angle).  What the data can show
is a constant *bias*: the loop settles a constant ``bias_v / kp`` [rad] away from the
reference.  It is modelled as a drive offset voltage, the actuator's affine bias
(force = v + bias_v), so it lives in the MJCF.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from scipy import signal

from .base import OMNI, Effect, Param, absolute_grid, actuator_of, scaled_grid

#: Ring-buffer length [samples] given to ``yaw_motor`` by ``time_delay``: the largest delay
#: the candidate can represent is ``DELAY_NSAMPLE * timestep`` (40 ms at 1 kHz, ~7 % of the
#: Omni's 3.4 Hz resonance period: far beyond a USB servo loop's few ms).
DELAY_NSAMPLE = 40
#: Smallest first-order time constant [s] (MuJoCo's filterexact needs tau > 0).
MIN_TIME_CONSTANT_S = 1e-4


def _read_lag(spec, target=OMNI):
    a = actuator_of(spec, target)
    if a.dyntype in (mujoco.mjtDyn.mjDYN_FILTER, mujoco.mjtDyn.mjDYN_FILTEREXACT):
        return np.array([float(a.dynprm[0])])
    return np.array([MIN_TIME_CONSTANT_S])


def _write_lag(spec, x, target=OMNI):
    a = actuator_of(spec, target)
    a.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
    a.dynprm[0] = max(float(x[0]), MIN_TIME_CONSTANT_S)


def _lagged(v: np.ndarray, dt: float, x) -> np.ndarray:
    """MuJoCo's ``filterexact`` on the command held over each step ``dt``: the force at step k
    reads the activation before that step's update, ``a_k = e a_(k-1) + (1 - e) v_(k-1)``,
    ``e = exp(-dt / tau)``; the activation starts at the first command (a run starts at rest)."""
    e = math.exp(-dt / max(float(x[0]), MIN_TIME_CONSTANT_S))
    v = np.asarray(v, float)
    out, _ = signal.lfilter([0.0, 1.0 - e], [1.0, -e], v, zi=[v[0]])
    return out


def _delayed(v: np.ndarray, dt: float, x) -> np.ndarray:
    """MuJoCo's actuator ``delay`` with linear interpolation in the command's history: the
    command ``delay_s`` earlier (the first command before the run's start)."""
    t = np.arange(len(v)) * dt
    return np.interp(t - max(float(x[0]), 0.0), t, np.asarray(v, float))


def _read_delay(spec, target=OMNI):
    return np.array([float(actuator_of(spec, target).delay)])


def _write_delay(spec, x, target=OMNI):
    a = actuator_of(spec, target)
    a.nsample = max(int(a.nsample), DELAY_NSAMPLE)
    a.interp = 1  # linear interpolation in the ctrl history: a delay between samples is smooth
    a.delay = max(float(x[0]), 0.0)


def _read_limit(spec, target=OMNI):
    a = actuator_of(spec, target)
    gear = float(a.gear[0])
    if a.forcelimited == mujoco.mjtLimited.mjLIMITED_TRUE or (
            a.forcelimited == mujoco.mjtLimited.mjLIMITED_AUTO and a.forcerange[1] > a.forcerange[0]):
        return np.array([gear * float(min(-a.forcerange[0], a.forcerange[1]))])
    return np.array([math.inf])


def _write_limit(spec, x, target=OMNI):
    a = actuator_of(spec, target)
    lim = float(x[0]) / float(a.gear[0])  # forcerange clamps the actuator force [V] before gear
    a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    a.forcerange = [-lim, lim]


def _limit_grid(x0):
    # limits [N*m] from 2 % to 100 % of the nominal drive's peak (ctrlrange 1.3 V * gear 0.5)
    return np.array([[v] for v in (0.02, 0.04, 0.07, 0.12, 0.2, 0.35, 0.65)])


def _read_gear(spec, target=OMNI):
    return np.array([float(actuator_of(spec, target).gear[0])])


def _write_gear(spec, x, target=OMNI):
    actuator_of(spec, target).gear[0] = float(x[0])


def _read_bias(spec, target=OMNI):
    a = actuator_of(spec, target)
    return np.array([float(a.biasprm[0]) if a.biastype == mujoco.mjtBias.mjBIAS_AFFINE else 0.0])


def _write_bias(spec, x, target=OMNI):
    a = actuator_of(spec, target)
    if a.biastype != mujoco.mjtBias.mjBIAS_AFFINE:
        a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        a.biasprm[1] = 0.0
        a.biasprm[2] = 0.0
    a.biasprm[0] = float(x[0])


ACTUATOR_LAG = Effect(
    "actuator_lag", "first-order lag of the drive (amplifier/current loop)",
    (Param("time_constant_s", "s", MIN_TIME_CONSTANT_S, 0.05, 0.002),),
    _read_lag, _write_lag, absolute_grid((MIN_TIME_CONSTANT_S, 0.002, 0.005, 0.01, 0.02)), command=_lagged)

TIME_DELAY = Effect(
    "time_delay", "pure time delay in the loop (USB, servo scheduling)",
    (Param("delay_s", "s", 0.0, (DELAY_NSAMPLE - 1) * 1e-3, 0.001),),
    _read_delay, _write_delay, absolute_grid((0.0, 0.002, 0.005, 0.01, 0.02)), command=_delayed)

TORQUE_SATURATION = Effect(
    "torque_saturation", "the drive's torque limit (current limit)",
    (Param("torque_limit_nm", "N*m", 0.005, 2.0, 0.01),),
    _read_limit, _write_limit, _limit_grid)

TORQUE_GAIN = Effect(
    "torque_gain", "torque constant (gear) of the yaw drive",
    (Param("gear_nm_per_v", "N*m/V", 0.05, 5.0, 0.02),),
    _read_gear, _write_gear, scaled_grid((0.6, 0.8, 1.0, 1.25, 1.6)))

POSITION_OFFSET = Effect(
    "position_offset", "constant bias: drive offset voltage, the loop settles bias/kp off",
    (Param("bias_v", "V", -0.5, 0.5, 0.005),),
    _read_bias, _write_bias, absolute_grid((-0.05, -0.01, 0.0, 0.01, 0.05)))
