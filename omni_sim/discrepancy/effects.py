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
joint_stiffness    ``yaw`` joint ``stiffness`` (springref 0)    ``stiffness_nm_per_rad`` [N*m/rad]
gravity_tilt       ``option/gravity`` tilted (the base tilted)  ``tilt_x_rad``, ``tilt_y_rad`` [rad]
armature           ``yaw`` joint ``armature``                   ``armature_kgm2`` [kg*m^2]
actuator_lag       ``yaw_motor`` dyntype filterexact, dynprm[0] ``time_constant_s`` [s]
time_delay         ``yaw_motor`` ``delay`` (``nsample`` buffer) ``delay_s`` [s]
torque_saturation  ``yaw_motor`` ``forcerange``                 ``torque_limit_nm`` [N*m]
torque_gain        ``yaw_motor`` ``gear``                       ``gear_nm_per_v`` [N*m/V]
position_offset    ``yaw_motor`` affine bias ``biasprm[0]``     ``bias_v`` [V]
=================  ==========================================  ===================================

Notes on two of them:

* ``gravity_tilt``: tilting the gravity vector is the same physics as tilting the robot's base.
  Gravity acting on the arm's mass moment ``m*R`` about the yaw axis gives a torque
  ``m R g (sin(ty) cos(theta) - sin(tx) sin(theta))``: ``tx`` acts like a pose-dependent spring,
  ``ty`` like a pose-dependent constant torque.
* ``position_offset``: a pure encoder offset shared by the controller and the log is
  unobservable on a yaw axis without position-dependent torque (the closed loop is invariant
  to a shift of theta, and the replay starts from the measured angle).  What the data can show
  is a constant *bias*: the loop settles a constant ``bias_v / kp`` [rad] away from the
  reference.  It is modelled as a drive offset voltage, the actuator's affine bias
  (force = v + bias_v), so it lives in the MJCF.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import mujoco
import numpy as np

from .. import model as om

#: Ring-buffer length [samples] given to ``yaw_motor`` by ``time_delay``: the largest delay
#: the candidate can represent is ``DELAY_NSAMPLE * timestep`` (40 ms at 1 kHz, ~7 % of the
#: Omni's 3.4 Hz resonance period: far beyond a USB servo loop's few ms).
DELAY_NSAMPLE = 40
#: Smallest first-order time constant [s] (MuJoCo's filterexact needs tau > 0).
MIN_TIME_CONSTANT_S = 1e-4


@dataclass(frozen=True)
class Param:
    """One physical parameter of an effect.

    Attributes
    ----------
    name : str
        Name with its unit (``frictionloss_nm``).
    unit : str
        Unit, for reports.
    lower, upper : float
        Box bounds of the fit (in the parameter's unit).
    scale : float
        Typical size of a realistic change (sets the fit's step and the starting grid).
    """

    name: str
    unit: str
    lower: float
    upper: float
    scale: float


@dataclass(frozen=True)
class Effect:
    """A named candidate effect: parameters, how to read them from a spec and how to write them.

    Attributes
    ----------
    name : str
        snake_case name (the report's ``effects[].name``).
    description : str
        One line: what it is physically.
    params : tuple of Param
    read : callable(spec, target) -> ndarray
        The parameter values the spec holds now (the nominal values) for ``target``
        (:class:`Target`: the controlled joint and its actuator).
    write : callable(spec, values, target) -> None
        Put parameter values into the spec (in place).
    grid : callable(nominal) -> ndarray (G, p)
        Starting points tried before the local fit (the fit is local; a saturation limit far
        above anything the data reaches has no gradient, so a coarse grid comes first).
    """

    name: str
    description: str
    params: tuple[Param, ...]
    read: Callable[..., np.ndarray] = field(repr=False)
    write: Callable[..., None] = field(repr=False)
    grid: Callable[[np.ndarray], np.ndarray] = field(repr=False)

    @property
    def nparam(self) -> int:
        return len(self.params)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([p.lower for p in self.params]), np.array([p.upper for p in self.params]))

    def scales(self) -> np.ndarray:
        return np.array([p.scale for p in self.params])

    def clip(self, x: np.ndarray) -> np.ndarray:
        lo, hi = self.bounds()
        return np.clip(x, lo, hi)


#: The virtual Omni's yaw drive (the dataset contract's names).
Target = om.Target
OMNI = om.OMNI


def _yaw(spec: mujoco.MjSpec, target: Target):
    return spec.joint(target.joint)


def _motor(spec: mujoco.MjSpec, target: Target):
    return spec.actuator(target.actuator)


def _set_joint(attr: str, index: int | None = None):
    def write(spec, x, target=OMNI):
        j = _yaw(spec, target)
        if index is None:
            setattr(j, attr, float(x[0]))
        else:
            getattr(j, attr)[index] = float(x[0])
    return write


def _get_joint(attr: str, index: int | None = None):
    def read(spec, target=OMNI):
        j = _yaw(spec, target)
        val = getattr(j, attr)
        return np.array([float(val if index is None else val[index])])
    return read


def _scaled_grid(factors):
    def grid(x0):
        return np.array([[x0[0] * f] for f in factors])
    return grid


def _abs_grid(values):
    def grid(x0):
        return np.array([[v] for v in values])
    return grid


# --- gravity tilt --------------------------------------------------------------------------
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


# --- actuator effects ----------------------------------------------------------------------
def _read_lag(spec, target=OMNI):
    a = _motor(spec, target)
    if a.dyntype in (mujoco.mjtDyn.mjDYN_FILTER, mujoco.mjtDyn.mjDYN_FILTEREXACT):
        return np.array([float(a.dynprm[0])])
    return np.array([MIN_TIME_CONSTANT_S])


def _write_lag(spec, x, target=OMNI):
    a = _motor(spec, target)
    a.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
    a.dynprm[0] = max(float(x[0]), MIN_TIME_CONSTANT_S)


def _read_delay(spec, target=OMNI):
    return np.array([float(_motor(spec, target).delay)])


def _write_delay(spec, x, target=OMNI):
    a = _motor(spec, target)
    a.nsample = max(int(a.nsample), DELAY_NSAMPLE)
    a.interp = 1  # linear interpolation in the ctrl history: a delay between samples is smooth
    a.delay = max(float(x[0]), 0.0)


def _read_limit(spec, target=OMNI):
    a = _motor(spec, target)
    gear = float(a.gear[0])
    if a.forcelimited == mujoco.mjtLimited.mjLIMITED_TRUE or (
            a.forcelimited == mujoco.mjtLimited.mjLIMITED_AUTO and a.forcerange[1] > a.forcerange[0]):
        return np.array([gear * float(min(-a.forcerange[0], a.forcerange[1]))])
    return np.array([math.inf])


def _write_limit(spec, x, target=OMNI):
    a = _motor(spec, target)
    lim = float(x[0]) / float(a.gear[0])  # forcerange clamps the actuator force [V] before gear
    a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    a.forcerange = [-lim, lim]


def _limit_grid(x0):
    # limits [N*m] from 2 % to 100 % of the nominal drive's peak (ctrlrange 1.3 V * gear 0.5)
    return np.array([[v] for v in (0.02, 0.04, 0.07, 0.12, 0.2, 0.35, 0.65)])


def _read_gear(spec, target=OMNI):
    return np.array([float(_motor(spec, target).gear[0])])


def _write_gear(spec, x, target=OMNI):
    _motor(spec, target).gear[0] = float(x[0])


def _read_bias(spec, target=OMNI):
    a = _motor(spec, target)
    return np.array([float(a.biasprm[0]) if a.biastype == mujoco.mjtBias.mjBIAS_AFFINE else 0.0])


def _write_bias(spec, x, target=OMNI):
    a = _motor(spec, target)
    if a.biastype != mujoco.mjtBias.mjBIAS_AFFINE:
        a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        a.biasprm[1] = 0.0
        a.biasprm[2] = 0.0
    a.biasprm[0] = float(x[0])


#: The library, in a fixed order (ties are broken by this order).
LIBRARY: tuple[Effect, ...] = (
    Effect("coulomb_friction", "Coulomb (dry) friction at the yaw joint",
           (Param("frictionloss_nm", "N*m", 0.0, 0.3, 0.01),),
           _get_joint("frictionloss"), _set_joint("frictionloss"),
           _abs_grid((0.0, 0.01, 0.02, 0.035, 0.05, 0.08, 0.12))),
    Effect("viscous_damping", "viscous damping at the yaw joint",
           (Param("damping_nms_per_rad", "N*m*s/rad", 0.0, 0.1, 0.002),),
           _get_joint("damping", 0), _set_joint("damping", 0),
           _scaled_grid((0.25, 0.5, 1.0, 1.5, 2.0, 3.0))),
    Effect("joint_stiffness", "a torsional spring at the yaw joint (cables, springs), rest at 0",
           (Param("stiffness_nm_per_rad", "N*m/rad", -0.3, 1.0, 0.02),),
           _get_joint("stiffness", 0), _set_joint("stiffness", 0),
           _abs_grid((-0.05, 0.0, 0.03, 0.1, 0.3))),
    Effect("gravity_tilt", "gravity torque from a tilted yaw axis (base not level)",
           (Param("tilt_x_rad", "rad", -0.3, 0.3, 0.01), Param("tilt_y_rad", "rad", -0.3, 0.3, 0.01)),
           _read_tilt, _write_tilt, _tilt_grid),
    Effect("armature", "reflected rotor inertia (armature) at the yaw joint",
           (Param("armature_kgm2", "kg*m^2", 0.0, 0.01, 1e-4),),
           _get_joint("armature"), _set_joint("armature"),
           _abs_grid((0.0, 1e-4, 3e-4, 1e-3, 3e-3))),
    Effect("actuator_lag", "first-order lag of the drive (amplifier/current loop)",
           (Param("time_constant_s", "s", MIN_TIME_CONSTANT_S, 0.05, 0.002),),
           _read_lag, _write_lag, _abs_grid((MIN_TIME_CONSTANT_S, 0.002, 0.005, 0.01, 0.02))),
    Effect("time_delay", "pure time delay in the loop (USB, servo scheduling)",
           (Param("delay_s", "s", 0.0, (DELAY_NSAMPLE - 1) * 1e-3, 0.001),),
           _read_delay, _write_delay, _abs_grid((0.0, 0.002, 0.005, 0.01, 0.02))),
    Effect("torque_saturation", "the drive's torque limit (current limit)",
           (Param("torque_limit_nm", "N*m", 0.005, 2.0, 0.01),),
           _read_limit, _write_limit, _limit_grid),
    Effect("torque_gain", "torque constant (gear) of the yaw drive",
           (Param("gear_nm_per_v", "N*m/V", 0.05, 5.0, 0.02),),
           _read_gear, _write_gear, _scaled_grid((0.6, 0.8, 1.0, 1.25, 1.6))),
    Effect("position_offset", "constant bias: drive offset voltage, the loop settles bias/kp off",
           (Param("bias_v", "V", -0.5, 0.5, 0.005),),
           _read_bias, _write_bias, _abs_grid((-0.05, -0.01, 0.0, 0.01, 0.05))),
)

NAMES = tuple(e.name for e in LIBRARY)

#: What experiment separates two candidates that explain the data alike (unordered pairs).
SEPARATING_EXPERIMENTS = {
    frozenset({"joint_stiffness", "gravity_tilt"}):
        "hold the yaw at several angles up to +-0.9 rad at two arm poses of very different reach "
        "(e.g. gamma1=25/gamma2=115 deg vs gamma1=65/gamma2=70 deg): a spring's torque is linear in "
        "theta and the same at every pose, gravity's goes with sin(theta) and scales with the arm's "
        "mass moment",
    frozenset({"gravity_tilt", "position_offset"}):
        "steps around several yaw set points at two arm poses: a bias is the same everywhere, a "
        "tilt's torque changes with yaw angle and reach",
    frozenset({"joint_stiffness", "position_offset"}):
        "steps around several yaw set points: a spring's torque grows with the angle, a bias does not",
    frozenset({"time_delay", "actuator_lag"}):
        "sines above the resonance (8-20 Hz) or the command-to-angle response: a lag rolls the "
        "gain off, a delay only adds phase -w*tau",
    frozenset({"coulomb_friction", "viscous_damping"}):
        "sines at the same frequency and 2-3 amplitudes: Coulomb damping falls with amplitude, "
        "viscous does not",
    frozenset({"armature", "torque_gain"}):
        "repeat a step or sine sweep at a second kp: inertia and gain shift the resonance "
        "differently with kp",
    frozenset({"viscous_damping", "time_delay"}):
        "sines near and above the resonance: damping lowers the peak, delay raises it",
    frozenset({"viscous_damping", "actuator_lag"}):
        "sines near and above the resonance: damping lowers the peak, a lag raises it",
    frozenset({"torque_saturation", "coulomb_friction"}):
        "steps of 2-3 sizes: saturation only bites on large steps, friction on small ones",
}
DEFAULT_SEPARATION = ("repeat the worst-fitting runs at other amplitudes, frequencies and poses")



def get(name: str) -> Effect:
    """The library effect called ``name`` (KeyError if unknown)."""
    for e in LIBRARY:
        if e.name == name:
            return e
    raise KeyError(name)


def nominal_values(effect: Effect, spec: mujoco.MjSpec, target: Target = OMNI) -> np.ndarray:
    """The parameter values ``spec`` holds for ``effect``, clipped into its bounds."""
    x = effect.read(spec, target)
    x = np.where(np.isfinite(x), x, [p.upper for p in effect.params])
    return effect.clip(x)


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
