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
=================  ==========================================  ===================================

(``yaw``/``yaw_motor`` stand for the :class:`Target`'s joint and actuator; added elements are
named after the joint, with a suffix ``_2``... if the model already uses the name.  Passive
actuators are appended after every actuator, so controlled ones keep control index = id.)

The drive effects, their magnitudes and where they come from (the Omni's numbers are
estimates: models/README.md, models/omni.xml):

* ``presliding_friction``: changes the LuGre element the model has (default scene:
  ``yaw_friction``, calibrated sigma0 = 3.2 N*m/rad, Fc = 12.9, Fs = 31.6 mN*m, vs = 0.62 rad/s;
  its sigma1 is kept) or adds one with sigma1 = 0 (the scene's choice).  A model without one
  reads levels 0 (no pre-sliding friction; sigma0 and vs then read 0 and clip to their lower
  bounds).  Bounds: sigma0 0.3-100 N*m/rad (pre-sliding range Fs/sigma0 from ~0.1 rad down to
  ~0.3 mrad, under one count at the top); levels 0-0.3 N*m (as ``coulomb_friction``).
  Visible: sigma0 3.2 -> 10 in the default scene is 54x the noise floor of the bank set.
* ``stribeck_friction``: a separate stiff LuGre element on top of whatever friction the model
  has (levels read 0 when absent): sigma0 = :data:`STRIBECK_SIGMA0` so the pre-sliding range
  stays under one encoder count, sigma1 = :data:`STRIBECK_SIGMA1` to damp the stiff bristle at
  the 1 ms step.  Realistic: Fc 5-20 mN*m, Fs up to the 35 mN*m back-drive bound; Fc = 5,
  Fs = 15 mN*m, vs = 0.1 rad/s added to the default scene is ~800x the floor.
* ``drive_compliance``: the capstan cable as a spring between the rotor (motor and encoder:
  the encoder joint keeps the name, so the motor, the sensors and the drive friction act on it,
  with the joint's damping, frictionloss, stiffness and armature) and the turret.  A real
  steel capstan cable is ~1e3 N*m/rad at the turret (estimate: 0.45 mm stranded steel,
  EA ~ 1.6e4 N, ~2 cm free length, two strands, ~3 cm drum radius): its mode (~500 Hz with a
  1e-4 kg*m^2 rotor) sits at the 1 kHz loop's Nyquist frequency and the explicit spring of the
  1 ms step is unstable above k ~ 4 J/dt^2 (~400 N*m/rad for 1e-4 kg*m^2; a probe script
  diverged at 400).  The candidate therefore covers soft drives, 0.5-100 N*m/rad (a loose or
  stretched cable, an elastic coupling; the default scene's sigma0 ~ 3 N*m/rad lumps such a
  low-energy stiffness, models/README.md), with the rotor inertia bounded below by the
  5e-5 kg*m^2 end of the rotor estimate (sqrt(100/5e-5) * 1 ms = 1.4 < 2: stable).  Nominal of
  a rigid drive: read gives inf, :func:`nominal_values` the upper bound 100 N*m/rad, no cable
  damping, the joint's armature as the rotor -- NOT the rigid model: near the ~3.4 Hz loop
  resonance even 100 N*m/rad differs from the rigid drive (30x the noise floor of the bank set;
  k = 20: 160x, k = 5: 600x).  A drive stiffer than ~100 N*m/rad is beyond this candidate.
* ``backlash``: the same two-mass drive with the cable's length limited to [-b, b] (a stop,
  solref 2 timesteps, solimp 0.99/0.999: 4e-5 rad penetration at 0.1 N*m) and no spring force
  inside the band.  A pre-tensioned capstan has no backlash; a slack cable or a loose coupling
  gives a few counts: b = 1 count is 8x the floor, 3 counts 19x.  A rigid model reads 0 (the
  lower bound is 1e-6 rad: MuJoCo needs range[0] < range[1]).
* ``arm_mass``: the calibrated link masses (68.8 g, 59.5 g, models/omni.xml) are inferred
  from the paper's data; +-30 % is a realistic doubt.  +20 % on both links is ~390x the floor
  (the arm's gravity sag changes too).  Applies only where both bodies have an explicit
  inertial.
* ``cogging``: :data:`COGGING_PERIODS` periods per joint turn (estimate with its reasoning);
  amplitude 1-3 mN*m (a few % of a small iron-core motor's rated torque times the capstan
  ratio, ~1/10-1/4 of the drive's Coulomb level; estimate): 1 mN*m is 4.8x the floor, 3 mN*m 14x.
  The phase is bounded to +-2 pi so a fit started in [-pi, pi) does not sit on a bound.

"Noise floor" above: the gap of the nominal replay to data from the nominal model with the
encoder's quantisation and 1e-4 rad noise (1.6e-4 rad over ``bank.bank_experiments()``).

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
from ..device import ENCODER_STEP_RAD  # the Omni's encoder count [rad]

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
    applies : callable(spec, target) -> bool
        Whether the effect can be written into this model (e.g. ``arm_mass`` needs the Omni's
        arm bodies); default: always.
    """

    name: str
    description: str
    params: tuple[Param, ...]
    read: Callable[..., np.ndarray] = field(repr=False)
    write: Callable[..., None] = field(repr=False)
    grid: Callable[[np.ndarray], np.ndarray] = field(repr=False)
    applies: Callable[..., bool] = field(default=lambda spec, target=None: True, repr=False)

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


# --- drive friction: LuGre elements (pre-sliding, Stribeck) and cogging ---------------------
#: ``stribeck_friction``'s bristle stiffness sigma0 [N*m/rad], fixed: the pre-sliding range is
#: below Fs/sigma0 <= 0.3/1000 = 3e-4 rad for every Fs within the bounds, under one encoder
#: count (4.19e-4 rad), so the element is a Stribeck curve with a true stick and no visible
#: elastic range (tests/test_effects_library.py measures it).
STRIBECK_SIGMA0 = 1000.0
#: ``stribeck_friction``'s bristle damping sigma1 [N*m*s/rad]: sigma1/sigma0 = 1 ms, one
#: timestep.  A stiff bristle with sigma1 = 0 rings at sqrt(sigma0/J) and ratchets at the 1 ms
#: step (a probe script: sigma0 = 300-1000, sigma1 = 0, J = 2e-3 kg*m^2 under 0.8 Fs drifted
#: 0.04 rad instead of resting 0.2 mrad away); with sigma1 = sigma0 * 1 ms it rests within
#: 1.5 % of -(Fs/sigma0) ln(1 - tau/Fs) for J = 1e-5..2e-3 kg*m^2 (MuJoCo's implicitfast
#: integrates the sigma1 term implicitly).
STRIBECK_SIGMA1 = 1.0
#: ``cogging``'s periods per joint revolution (estimate, not a measurement: the Omni's motors
#: and capstan ratio are not public).  A 2-pole, 3-slot iron-core DC motor cogs lcm(2, 3) = 6
#: times per motor turn; a capstan ratio of ~7.5 is inferred from the 15000 counts per joint
#: turn over a 500-line (2000-count) motor encoder; 6 * 7.5 = 45 periods per joint turn, one
#: period every 0.14 rad (8 deg).  Change it for a device whose motor is known.
COGGING_PERIODS = 45.0
#: MJCF ``input="none"``: a passive actuator without a control (``MjsActuator.ctrlspec``).
_INPUT_NONE = 16


def _stribeck_name(target: Target) -> str:
    return f"{target.joint}_stribeck"


def _cogging_name(target: Target) -> str:
    return f"{target.joint}_cogging"


def _presliding_name(target: Target) -> str:
    return f"{target.joint}_presliding"


def _unique(spec: mujoco.MjSpec, objtype, name: str) -> str:
    """``name``, or ``name_2``, ``name_3``... if an element of ``objtype`` already has it."""
    out, k = name, 1
    while _exists(spec, objtype, out):
        k += 1
        out = f"{name}_{k}"
    return out


def _exists(spec: mujoco.MjSpec, objtype, name: str) -> bool:
    get = {mujoco.mjtObj.mjOBJ_JOINT: spec.joint, mujoco.mjtObj.mjOBJ_BODY: spec.body,
           mujoco.mjtObj.mjOBJ_TENDON: spec.tendon, mujoco.mjtObj.mjOBJ_ACTUATOR: spec.actuator}[objtype]
    return get(name) is not None


def _is_passive_dcmotor(a, joint: str) -> bool:
    return (a.trntype == mujoco.mjtTrn.mjTRN_JOINT and a.target == joint
            and a.biastype == mujoco.mjtBias.mjBIAS_DCMOTOR)


def _suffixed(name: str, k: int) -> str:
    return name if k == 1 else f"{name}_{k}"


def _own_dcmotor(spec: mujoco.MjSpec, name: str, joint: str):
    """The passive dcmotor an effect added: ``name`` (or ``name_2``... if the model already had
    an element called ``name``, see :func:`_unique`) on ``joint``; None if there is none."""
    for k in range(1, 100):
        a = spec.actuator(_suffixed(name, k))
        if a is None:
            return None
        if _is_passive_dcmotor(a, joint):
            return a
    return None


def _add_dcmotor(spec: mujoco.MjSpec, name: str, joint: str, lugre: bool):
    """Append a passive ``dcmotor`` (``input="none"``, no electrical part) on ``joint``: the
    MJCF ``<dcmotor joint=.. input="none" resistance="1" lugre=../cogging=../>`` (same compiled
    arrays, checked in tests/test_effects_library.py).  Appended after every actuator, so the
    controlled actuators keep control index = actuator index (as :func:`omni_sim.model.index` requires)."""
    a = spec.add_actuator(name=_unique(spec, mujoco.mjtObj.mjOBJ_ACTUATOR, name), target=joint,
                          trntype=mujoco.mjtTrn.mjTRN_JOINT)
    a.gaintype = mujoco.mjtGain.mjGAIN_DCMOTOR
    a.biastype = mujoco.mjtBias.mjBIAS_DCMOTOR
    a.dyntype = mujoco.mjtDyn.mjDYN_DCMOTOR
    a.gainprm = [1.0] + [0.0] * (len(a.gainprm) - 1)
    a.biasprm = [0.0] * len(a.biasprm)
    a.dynprm = [0.0] * len(a.dynprm)  # a new actuator's dynprm[0] = 1 would be an inductance
    a.ctrlspec = _INPUT_NONE
    a.actearly = True
    a.actdim = 1 if lugre else 0  # the LuGre bristle state z
    a.actlimited = mujoco.mjtLimited.mjLIMITED_FALSE
    _extend_key_act(spec, a.actdim)
    return a


def _extend_key_act(spec: mujoco.MjSpec, n: int) -> None:
    """Keyframes that give ``act`` get ``n`` zeros for an actuator appended at the end."""
    if n:
        for key in spec.keys:
            if len(key.act):
                key.act = list(key.act) + [0.0] * n


def _lugre_of(a) -> np.ndarray:
    """sigma0, sigma1, Fc, Fs, vs of a LuGre dcmotor (dynprm[5:7], biasprm[3:6])."""
    return np.array([a.dynprm[5], a.dynprm[6], a.biasprm[3], a.biasprm[4], a.biasprm[5]], float)


def _set_lugre(a, sigma0, sigma1, fc, fs, vs) -> None:
    a.dynprm[5], a.dynprm[6] = float(sigma0), float(sigma1)
    a.biasprm[3], a.biasprm[4], a.biasprm[5] = float(fc), float(fs), float(vs)


def _presliding_element(spec: mujoco.MjSpec, target: Target):
    """The LuGre element ``presliding_friction`` changes: the first passive LuGre dcmotor on the
    joint that is not another effect's element (e.g. the default scene's ``yaw_friction``)."""
    skip = {_stribeck_name(target), _cogging_name(target)}
    for a in spec.actuators:
        if (_is_passive_dcmotor(a, target.joint) and a.name not in skip
                and not any(a.name.startswith(s + "_") for s in skip) and a.dynprm[5] > 0):
            return a
    return None


def _read_presliding(spec, target=OMNI):
    a = _presliding_element(spec, target)
    if a is None:  # no LuGre element: no pre-sliding friction (levels 0)
        return np.zeros(4)
    s0, _, fc, fs, vs = _lugre_of(a)
    return np.array([s0, fc, fs, vs])


def _write_presliding(spec, x, target=OMNI):
    a = _presliding_element(spec, target)
    if a is None:
        a = _add_dcmotor(spec, _presliding_name(target), target.joint, lugre=True)
        sigma1 = 0.0  # as the default scene's yaw_friction (models/scene_lugre.xml)
    else:
        sigma1 = float(a.dynprm[6])  # kept as in the model
    _set_lugre(a, x[0], sigma1, x[1], x[2], x[3])


def _presliding_grid(x0):
    if x0[2] > 0:  # the model has a LuGre drive: around it
        f = [(1, 1, 1, 1), (0.3, 1, 1, 1), (3, 1, 1, 1), (1, 1, 1.5, 1), (1, 1, 0.7, 1),
             (1, 1.5, 1.5, 1), (1, 1, 1, 0.3)]
        return np.array([[x0[0] * a, x0[1] * b, x0[2] * c, x0[3] * d] for a, b, c, d in f])
    # none yet: the default scene's calibrated LuGre (sigma0 ~ 3 N*m/rad, Fc ~ 13, Fs ~ 32 mN*m,
    # vs ~ 0.6 rad/s; models/README.md) and stiffer/weaker variants
    return np.array([[s0, fc, fs, 0.5] for s0, fc, fs in
                     ((3.0, 0.01, 0.02), (10.0, 0.01, 0.02), (30.0, 0.01, 0.02), (3.0, 0.005, 0.01),
                      (10.0, 0.02, 0.04))])


def _read_stribeck(spec, target=OMNI):
    a = _own_dcmotor(spec, _stribeck_name(target), target.joint)
    if a is None:
        return np.zeros(3)
    return _lugre_of(a)[2:5]


def _write_stribeck(spec, x, target=OMNI):
    a = _own_dcmotor(spec, _stribeck_name(target), target.joint)
    if a is None:
        a = _add_dcmotor(spec, _stribeck_name(target), target.joint, lugre=True)
    _set_lugre(a, STRIBECK_SIGMA0, STRIBECK_SIGMA1, x[0], x[1], x[2])


def _stribeck_grid(x0):
    # levels around the Omni's estimate (Fc 5-20 mN*m, Fs up to the 35 mN*m back-drive bound;
    # models/README.md) and Stribeck speeds a decade apart
    return np.array([[fc, fs, vs] for fc, fs, vs in
                     ((0.005, 0.015, 0.1), (0.005, 0.015, 0.5), (0.01, 0.03, 0.1), (0.01, 0.03, 0.5),
                      (0.02, 0.035, 0.3))])


def _read_cogging(spec, target=OMNI):
    a = _own_dcmotor(spec, _cogging_name(target), target.joint)
    if a is None:
        return np.zeros(2)
    return np.array([a.biasprm[0], a.biasprm[2]], float)


def _write_cogging(spec, x, target=OMNI):
    a = _own_dcmotor(spec, _cogging_name(target), target.joint)
    if a is None:
        a = _add_dcmotor(spec, _cogging_name(target), target.joint, lugre=False)
    # MuJoCo 4 dcmotor cogging = "amplitude periods phase" -> biasprm[0:3]; the torque on the
    # joint is amplitude * sin(periods * q + phase) (checked in tests/test_effects_library.py)
    a.biasprm[0], a.biasprm[1], a.biasprm[2] = float(x[0]), COGGING_PERIODS, float(x[1])


def _cogging_grid(x0):
    return np.array([[a, ph] for a in (0.001, 0.003) for ph in (-math.pi / 2, 0.0, math.pi / 2, math.pi)])


# --- two-mass drive: rotor + cable (drive_compliance, backlash) ----------------------------
#: Mass [kg] and principal inertia [kg*m^2] of the rotor body the two-mass drive adds: numerical
#: placeholders (MuJoCo rejects a moving body without mass); the rotor's inertia is its joint's
#: armature (``rotor_inertia_kgm2``); the placeholder adds 1e-12 kg*m^2 to it (its centre of
#: mass is on the axis, so gravity puts no torque on it).
ROTOR_BODY_MASS = 1e-6
ROTOR_BODY_INERTIA = 1e-12
#: The backlash stop's impedance: solimplimit (dmin, dmax, width, midpoint, power) and the
#: solreflimit time constant in timesteps.  The default (0.9, 0.95, 0.001) with 0.02 s let a
#: 0.1 N*m load push 21 mrad into the stop (a probe script); 2 timesteps (the smallest
#: MuJoCo recommends) and 0.99/0.999 leave 4e-5 rad at 0.1 N*m (0.1 encoder count).
BACKLASH_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)
BACKLASH_SOLREF_STEPS = 2.0


def _two_mass_names(target: Target, k: int = 1) -> tuple[str, str, str]:
    """Names of the output joint, the rotor body and the cable tendon (suffix ``_k`` for
    ``k`` > 1: used when the model already had one of the plain names)."""
    return tuple(_suffixed(f"{target.joint}_{n}", k) for n in ("output", "rotor", "cable"))


def _two_mass(spec: mujoco.MjSpec, target: Target):
    """``(rotor joint, output joint, cable tendon)`` if the two-mass drive exists, else None.

    It exists when the target joint sits in a body ``<joint>_rotor[_k]`` and the joint
    ``<joint>_output[_k]`` and the tendon ``<joint>_cable[_k]`` of the same suffix exist."""
    jr = spec.joint(target.joint)
    if jr is None:
        return None
    for k in range(1, 100):
        out_name, rotor_name, cable = _two_mass_names(target, k)
        if jr.parent.name == rotor_name:
            t, jo = spec.tendon(cable), spec.joint(out_name)
            return (jr, jo, t) if t is not None and jo is not None else None
    return None


def _subtree_end(model: mujoco.MjModel, body: int) -> int:
    """Id of the last body of ``body``'s subtree (bodies are numbered depth first)."""
    last = body
    for b in range(body + 1, model.nbody):
        p = b
        while p > body:
            p = int(model.body_parentid[p])
        if p == body:
            last = b
        else:
            break
    return last


def _ensure_two_mass(spec: mujoco.MjSpec, target: Target):
    """Split the target joint into rotor + output coupled by a cable (once; idempotent).

    The hinge ``target.joint`` becomes ``<joint>_output`` (the turret keeps its body, range and
    everything that hangs on it); a new body ``<joint>_rotor``, a sibling at the same place,
    carries a hinge about the same axis named ``target.joint``, so every element that named
    the joint -- the motor, the encoder sensors, a LuGre friction element -- now acts on the
    rotor, where the encoder and the motor sit on a capstan drive.  The drive's joint
    properties go with it: damping (mostly back-EMF on the Omni, models/README.md),
    frictionloss, stiffness/springref and the armature (the rotor's reflected inertia).  A
    fixed tendon ``<joint>_cable`` = q_rotor - q_output (rotor angle at the output side) joins
    them, rest length 0.  Keyframes get the rotor at the output's angle (cable unstretched).
    """
    found = _two_mass(spec, target)
    if found is not None:
        return found
    jo = spec.joint(target.joint)
    body = jo.parent
    parent = body.parent
    m = spec.compile()  # the resolved geometry (classes, frames, alternative orientations)
    jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, target.joint)
    bid = int(m.jnt_bodyid[jid])
    pid = int(m.body_parentid[bid])
    # qpos/dof addresses of the new rotor: it is the parent's last child, so its coordinates
    # follow the parent's subtree (depth-first numbering)
    end = _subtree_end(m, pid)
    later = [j for j in range(m.njnt) if m.jnt_bodyid[j] > end]
    qadr = int(m.jnt_qposadr[later[0]]) if later else m.nq
    vadr = int(m.jnt_dofadr[later[0]]) if later else m.nv
    for k in range(1, 100):  # one suffix for all three names, none taken
        out_name, rotor_name, cable_name = _two_mass_names(target, k)
        if not (_exists(spec, mujoco.mjtObj.mjOBJ_JOINT, out_name)
                or _exists(spec, mujoco.mjtObj.mjOBJ_BODY, rotor_name)
                or _exists(spec, mujoco.mjtObj.mjOBJ_TENDON, cable_name)):
            break
    jo.name = out_name
    rb = parent.add_body(name=rotor_name)
    rb.pos = m.body_pos[bid].copy()
    rb.quat = m.body_quat[bid].copy()
    rb.explicitinertial = True
    rb.ipos = [0.0, 0.0, 0.0]
    rb.iquat = [1.0, 0.0, 0.0, 0.0]
    rb.mass = ROTOR_BODY_MASS
    rb.inertia = [ROTOR_BODY_INERTIA] * 3
    jr = rb.add_joint(name=target.joint, type=jo.type)
    jr.pos = m.jnt_pos[jid].copy()
    jr.axis = m.jnt_axis[jid].copy()
    jr.limited = mujoco.mjtLimited.mjLIMITED_FALSE
    jr.ref = jo.ref
    # the drive's properties move to the rotor
    jr.armature = jo.armature
    jr.frictionloss = jo.frictionloss
    jr.damping = list(jo.damping)
    jr.stiffness = list(jo.stiffness)
    jr.springref = jo.springref
    jr.solref_friction = list(jo.solref_friction)
    jr.solimp_friction = list(jo.solimp_friction)
    jo.armature = 0.0
    jo.frictionloss = 0.0
    jo.damping = [0.0] * len(jo.damping)
    jo.stiffness = [0.0] * len(jo.stiffness)
    t = spec.add_tendon(name=cable_name)
    t.wrap_joint(target.joint, 1.0)
    t.wrap_joint(out_name, -1.0)
    t.springlength = [0.0, 0.0]
    t.limited = mujoco.mjtLimited.mjLIMITED_FALSE
    oq = int(m.jnt_qposadr[jid])
    for key in spec.keys:
        if len(key.qpos) == m.nq:
            q = list(key.qpos)
            key.qpos = q[:qadr] + [q[oq]] + q[qadr:]
        if len(key.qvel) == m.nv:
            v = list(key.qvel)
            key.qvel = v[:vadr] + [0.0] + v[vadr:]
    return jr, jo, t


def _applies_two_mass(spec, target=OMNI) -> bool:
    j = spec.joint(target.joint)
    return j is not None and j.type == mujoco.mjtJoint.mjJNT_HINGE


def _read_compliance(spec, target=OMNI):
    tm = _two_mass(spec, target)
    if tm is None:  # rigid drive: infinitely stiff, no cable damping, the joint's armature
        return np.array([math.inf, 0.0, float(spec.joint(target.joint).armature)])
    jr, _, t = tm
    return np.array([float(t.stiffness[0]), float(t.damping[0]), float(jr.armature)])


def _write_compliance(spec, x, target=OMNI):
    jr, _, t = _ensure_two_mass(spec, target)
    t.stiffness[0] = float(x[0])
    t.damping[0] = float(x[1])
    jr.armature = float(x[2])


def _compliance_grid(x0):
    return np.array([[k, 0.0, x0[2]] for k in (2.0, 5.0, 15.0, 40.0, x0[0])])


def _read_backlash(spec, target=OMNI):
    tm = _two_mass(spec, target)
    if tm is None or tm[2].limited != mujoco.mjtLimited.mjLIMITED_TRUE:
        return np.zeros(1)
    return np.array([float(tm[2].range[1])])


def _write_backlash(spec, x, target=OMNI):
    _, _, t = _ensure_two_mass(spec, target)
    b = float(x[0])
    t.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    t.range = [-b, b]
    t.springlength = [-b, b]  # a cable spring (drive_compliance) has no force inside the band
    t.solref_limit = [BACKLASH_SOLREF_STEPS * float(spec.option.timestep), 1.0]
    t.solimp_limit = list(BACKLASH_SOLIMP)


def _backlash_grid(x0):
    return np.array([[c * ENCODER_STEP_RAD] for c in (0.5, 1.0, 2.0, 4.0, 8.0)])


# --- arm link masses (the Omni) ------------------------------------------------------------
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
    Effect("presliding_friction",
           "LuGre drive friction with an elastic pre-sliding range (bristle stiffness sigma0)",
           (Param("sigma0_nm_per_rad", "N*m/rad", 0.3, 100.0, 1.0),
            Param("fc_nm", "N*m", 0.0, 0.3, 0.003),
            Param("fs_nm", "N*m", 0.0, 0.3, 0.003),
            Param("vs_rad_per_s", "rad/s", 0.02, 3.0, 0.1)),
           _read_presliding, _write_presliding, _presliding_grid),
    Effect("stribeck_friction",
           "static friction above the Coulomb level (Stribeck curve), stick without pre-sliding",
           (Param("fc_nm", "N*m", 0.0, 0.3, 0.003),
            Param("fs_nm", "N*m", 0.0, 0.3, 0.003),
            Param("vs_rad_per_s", "rad/s", 0.01, 3.0, 0.05)),
           _read_stribeck, _write_stribeck, _stribeck_grid),
    Effect("drive_compliance",
           "compliant capstan cable between the motor (encoder) and the turret: a two-mass drive",
           (Param("stiffness_nm_per_rad", "N*m/rad", 0.5, 100.0, 2.0),
            Param("damping_nms_per_rad", "N*m*s/rad", 0.0, 0.05, 0.001),
            Param("rotor_inertia_kgm2", "kg*m^2", 5e-5, 1e-3, 2e-5)),
           _read_compliance, _write_compliance, _compliance_grid, _applies_two_mass),
    Effect("backlash", "dead zone (slack) between the motor (encoder) and the turret",
           (Param("half_width_rad", "rad", 1e-6, 0.02, 2e-4),),
           _read_backlash, _write_backlash, _backlash_grid, _applies_two_mass),
    Effect("arm_mass", "masses of the Omni's upper arm and forearm links (pose-dependent yaw inertia)",
           (Param("upper_arm_mass_kg", "kg", 0.02, 0.2, 0.005),
            Param("forearm_mass_kg", "kg", 0.02, 0.2, 0.005)),
           _read_arm, _write_arm, _arm_grid, _applies_arm),
    Effect("cogging", "motor cogging: a torque periodic in the motor angle",
           (Param("amplitude_nm", "N*m", 0.0, 0.05, 0.001),
            Param("phase_rad", "rad", -2 * math.pi, 2 * math.pi, 0.3)),
           _read_cogging, _write_cogging, _cogging_grid),
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
    frozenset({"presliding_friction", "coulomb_friction"}):
        "small steps and slow sines of 1-5 mrad (kp*gear*|e| below the static level): pre-sliding "
        "follows them elastically (the loop gets stiffer, the small-amplitude resonance moves up) "
        "and creeps on to the set point; a hard Coulomb stick does not move at all until "
        "kp*gear*|e| exceeds Fc and then stops a constant Fc/(kp*gear) short",
    frozenset({"stribeck_friction", "coulomb_friction"}):
        "slow triangle references (constant speeds 0.02-1 rad/s) and slow ramps from rest: the torque "
        "kp*gear*e needed to keep moving falls with speed from Fs to Fc with Stribeck friction, "
        "it is flat with Coulomb; from rest Stribeck breaks away at Fs and jumps (stick-slip)",
    frozenset({"presliding_friction", "stribeck_friction"}):
        "steps of a few mrad: pre-sliding moves elastically by tau/sigma0 below the break-away, "
        "a Stribeck stick does not move by even one encoder count",
    frozenset({"drive_compliance", "armature"}):
        "small sines or a chirp from 10 to 100 Hz: a compliant cable adds a resonance/antiresonance "
        "pair near sqrt(k (1/J_rotor + 1/J_out)) that moves with the arm pose (J_out), a rotor "
        "inertia only lowers the ~3.4 Hz loop resonance; or measure the turret (tip position) "
        "against the encoder: they differ by tau/k only with a compliant cable",
    frozenset({"drive_compliance", "actuator_lag"}):
        "sines above the resonance (10-60 Hz): a lag rolls the gain off monotonically, a compliant "
        "drive adds a resonance peak near sqrt(k (1/J_rotor + 1/J_out)) and changes with the pose",
    frozenset({"drive_compliance", "backlash"}):
        "sines of 2-3 amplitudes at one frequency: backlash is a fixed dead angle at every reversal "
        "(its effect shrinks as the amplitude grows), compliance deflects in proportion to the "
        "transmitted torque (the same fraction at every amplitude)",
    frozenset({"backlash", "coulomb_friction"}):
        "slow sines around reversals at 2-3 amplitudes, with the turret or tip measured (camera, "
        "tip tracker) against the encoder: with backlash the motor angle runs through +-b while "
        "the turret rests at each reversal, with Coulomb friction the motor itself stops",
    frozenset({"arm_mass", "armature"}):
        "repeat the runs at two arm poses of very different reach (gamma1=25/gamma2=115 deg vs "
        "gamma1=65/gamma2=90 deg): a link mass changes the yaw inertia by m*r^2 with the link's "
        "distance r from the yaw axis (and the arm's sag), an armature by the same amount at every pose",
    frozenset({"arm_mass", "torque_gain"}):
        "repeat the runs at two arm poses of very different reach: a link mass shifts the resonance "
        "differently at each pose, a torque constant by the same factor at every pose",
    frozenset({"cogging", "gravity_tilt"}):
        "hold the yaw at closely spaced angles (every 1-2 deg over the range) or follow a slow ramp: "
        "cogging's torque repeats every 2*pi/n (n periods per turn, 8 deg for the Omni estimate), "
        "a tilt's torque goes with sin(theta) over the whole range and scales with the arm's reach",
    frozenset({"cogging", "joint_stiffness"}):
        "hold the yaw at closely spaced angles (every 1-2 deg) or follow a slow ramp: cogging's "
        "torque repeats every 2*pi/n, a spring's grows linearly with theta",
    frozenset({"cogging", "position_offset"}):
        "steps around set points a fraction of a cogging period (2*pi/n) apart: the offset cogging "
        "leaves changes sign along theta, a bias does not",
}
DEFAULT_SEPARATION = ("repeat the worst-fitting runs at other amplitudes, frequencies and poses")



def applicable(spec: mujoco.MjSpec, target: Target = OMNI) -> tuple[str, ...]:
    """Names of the library effects that can be written into ``spec`` for ``target``."""
    return tuple(e.name for e in LIBRARY if e.applies(spec, target))


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
