"""Hidden-effect cases: truth models (the virtual Omni plus effects) and their "measured" data.

Used by ``omni discrepancy --demo``, the tests, ``scripts/discrepancy_bank.py`` and
``scripts/discrepancy_coverage.py``.

Independence
------------
A truth model is written here, with MuJoCo's own features, by the writers in :data:`TRUTH`
(and :data:`OUTSIDE` for effects the library does not hold).  This module does NOT use the
workflow's effect library (``effects.py``: no ``apply``, ``compile_with`` or ``Effect.write``,
not even an import, direct or through another module; ``tests/test_discrepancy_bank.py``
checks it by reading this file's syntax tree and following its imports through the project),
so a fit that recovers a truth checks the library's writers too: a writer that put a value
into the wrong field, the wrong unit or the wrong side of the gear would be caught.
Where MuJoCo offers a second feature with the same physics the truth uses it (a tilted base
instead of a tilted gravity vector, the motor's rotor inertia ``actuator armature`` reflected
by the gear instead of the joint's armature).  What the truth shares with the library is only
the *meaning* of each parameter (its definition, unit and the model element it belongs to), so
that a fitted value is comparable with the truth; the test reads the compiled ``MjModel`` (or
its mass matrix) and checks that it holds exactly the values each case states.

Data
----
:func:`generate` runs the truth model through :func:`omni_sim.experiments.simulate` (the
device's closed-loop engine, the reference path) with the encoder's quantisation (15000
counts/rev) and white noise of :data:`BANK_NOISE_RAD` that the controller sees, as on the
device; the case ``none_exact`` has neither.  The workflow sees only these runs and the
nominal model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from identification.dataset import Run

from .. import experiments as ex
from .. import model as om

#: Poses [deg] (set points) of the compact experiment set: a folded and a stretched arm
#: (yaw inertia and the arm's mass moment differ by ~2x between them).
BANK_POSES = ((65.0, 90.0), (25.0, 115.0))
#: Sine frequencies [Hz] (below, near and above the ~3.4 Hz resonance) and amplitudes [rad].
BANK_FREQUENCIES_HZ = (1.5, 3.0, 5.0)
BANK_AMPLITUDES_RAD = (0.04, 0.15)
#: Square waves: amplitudes [rad], 0.5 Hz so a 2 s record holds two edges plus the start.
BANK_STEP_AMPLITUDES_RAD = (0.05, 0.2)
#: Run length [s] (sines: 0.5 s settling plus whole cycles for >= 1.5 s).
BANK_DURATION_S = 2.0
#: Encoder noise [rad] (std, on top of the 15000 counts/rev quantisation): ~1/4 count, the
#: order of the jitter of a quadrature count sampled asynchronously (estimate).
BANK_NOISE_RAD = 1e-4

# The contract's names in the virtual Omni (models/omni.xml, models/scene_lugre.xml).
JOINT = "yaw"
MOTOR = "yaw_motor"
FRICTION = "yaw_friction"


def bank_experiments(poses=BANK_POSES, frequencies_hz=BANK_FREQUENCIES_HZ,
                     amplitudes_rad=BANK_AMPLITUDES_RAD, step_amplitudes_rad=BANK_STEP_AMPLITUDES_RAD,
                     duration_s: float = BANK_DURATION_S) -> list[ex.Experiment]:
    """The compact, informative experiment set: sines at 2 amplitudes x 3 frequencies plus
    square waves of 2 sizes, at each pose (16 runs of 2 s by default)."""
    out = []
    for g1, g2 in poses:
        for f in frequencies_hz:
            for a in amplitudes_rad:
                e = ex.sine_experiment(g1, g2, f, a, settle_s=0.5, record_s=duration_s - 0.5)
                n = int(round(duration_s / ex.CONTROL_PERIOD_S))
                out.append(ex.Experiment(f"{e.name}_a{a * 1000:03.0f}", "sine", g1, g2, e.r[:n], f, a))
        for a in step_amplitudes_rad:
            e = ex.square_experiment(g1, g2, 0.5, a, duration_s)
            out.append(ex.Experiment(f"{e.name}_a{a * 1000:03.0f}", "step", g1, g2, e.r, 0.5, a,
                                     theta0_rad=e.theta0_rad))
    return out


# --- truth writers: MuJoCo features, written here -------------------------------------------
def _gear(spec: mujoco.MjSpec) -> float:
    return float(spec.actuator(MOTOR).gear[0])


def _truth_frictionloss(spec, v):
    # joint frictionloss [N*m]: MuJoCo's dry-friction constraint on the yaw dof (hard stick
    # with the scene's noslip_iterations=1), on top of the scene's LuGre drive friction
    spec.joint(JOINT).frictionloss = float(v[0])


def _truth_damping(spec, v):
    spec.joint(JOINT).damping[0] = float(v[0])  # joint damping [N*m*s/rad] (absolute)


def _truth_stiffness(spec, v):
    j = spec.joint(JOINT)
    j.stiffness[0] = float(v[0])  # joint stiffness [N*m/rad], rest at springref 0
    j.springref = 0.0


def _truth_tilt(spec, v):
    """The base tilted so that gravity, seen in the base's frame, has the components
    ``g (sin tx, sin ty, -sqrt(1 - sin^2 tx - sin^2 ty))`` (the library's definition of the two
    tilt angles).  MuJoCo feature: the ``base`` body's orientation (``quat``); gravity stays
    vertical.  The rotation is the smallest one that takes the world's up axis to that
    direction in the base frame."""
    sx, sy = math.sin(float(v[0])), math.sin(float(v[1]))
    up_in_base = np.array([-sx, -sy, math.sqrt(max(1.0 - sx * sx - sy * sy, 0.0))])  # world +z
    # base-to-world rotation R with R^T e_z = up_in_base: R^T is the rotation e_z -> up_in_base
    axis = np.cross([0.0, 0.0, 1.0], up_in_base)
    s = float(np.linalg.norm(axis))
    if s == 0.0:
        return
    angle = math.atan2(s, up_in_base[2])
    q_rt = np.r_[math.cos(angle / 2), math.sin(angle / 2) * axis / s]  # quaternion of R^T
    q = q_rt * np.array([1.0, -1.0, -1.0, -1.0])  # R = (R^T)^T: the conjugate
    spec.body("base").quat = q.tolist()


def _truth_armature(spec, v):
    """Total reflected rotor inertia [kg*m^2] at the yaw joint.  MuJoCo feature: the motor's
    own rotor inertia (actuator ``armature``, which MuJoCo reflects to the joint as
    ``gear^2 * armature``); the joint keeps its nominal armature and the motor carries the
    difference."""
    joint_arm = float(spec.joint(JOINT).armature)
    spec.actuator(MOTOR).armature = (float(v[0]) - joint_arm) / _gear(spec) ** 2


def _truth_lag(spec, v):
    # first-order lag of the drive: activation dynamics "filterexact" with time constant
    # dynprm[0] [s] (exact discretisation of act' = (ctrl - act)/tau)
    a = spec.actuator(MOTOR)
    a.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
    a.dynprm = [float(v[0])] + [0.0] * 9


def _truth_delay(spec, v):
    """Loop delay [s]: MuJoCo's actuator delay (a ring buffer of the control history).  The
    buffer holds two samples more than the delay needs; the history is interpolated linearly
    (interp 1), the library's definition of a delay between samples (at a 1 ms step the
    physics cannot place the command change inside a step anyway)."""
    a = spec.actuator(MOTOR)
    dt = float(spec.option.timestep)
    a.nsample = int(math.ceil(float(v[0]) / dt)) + 2
    a.interp = 1
    a.delay = float(v[0])


def _truth_torque_limit(spec, v):
    # torque limit [N*m] at the joint: the actuator force (before the gear, in V) clamped to
    # +-limit/gear by forcerange
    a = spec.actuator(MOTOR)
    a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    lim = float(v[0]) / _gear(spec)
    a.forcerange = [-lim, lim]


def _truth_gear(spec, v):
    spec.actuator(MOTOR).gear = [float(v[0]), 0, 0, 0, 0, 0]  # torque constant [N*m/V]


def _truth_bias(spec, v):
    # a drive offset voltage [V]: force = ctrl + bias (affine bias with no length or velocity
    # term); the torque is gear * (v + bias)
    a = spec.actuator(MOTOR)
    a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    a.biasprm = [float(v[0])] + [0.0] * 9


#: Cogging periods per turn of the yaw joint: the library's definition of ``cogging``
#: (effects.py's estimate: 6 cogs per turn of a 2-pole 3-slot motor x a capstan ratio of ~7.5
#: inferred from the encoder counts); the truth must share it for amplitude and phase to be
#: comparable.
COGGING_PERIODS_PER_TURN = 45.0
#: ``stribeck_friction``'s bristle stiffness [N*m/rad] and damping [N*m*s/rad]: the library's
#: definition of a Stribeck element "without visible pre-sliding" (Fs/sigma0 below one encoder
#: count, sigma1/sigma0 = one timestep; effects.py), shared so the levels are comparable.
STRIBECK_SIGMA = (1000.0, 1.0)
#: The backlash stop's impedance, part of the library's definition of a hard dead zone
#: (effects.py: solreflimit time constant 2 timesteps, solimplimit 0.99/0.999: 4e-5 rad at
#: 0.1 N*m), shared so the half-width is comparable.
BACKLASH_SOLREF_STEPS = 2.0
BACKLASH_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)
#: The Omni's arm links whose masses ``arm_mass`` states (models/omni.xml).
ARM_LINKS = ("upper_arm", "forearm")


def _passive_dcmotor(spec, name: str, lugre=(0.0,) * 5, cogging=(0.0, 0.0, 0.0)):
    """A passive ``dcmotor`` on the yaw (``input="none"``: no control, no electrical part),
    built with MuJoCo's own shortcut (``set_to_dcmotor``), added after every actuator (control
    indices stay those of the controlled actuators)."""
    a = spec.add_actuator()
    a.name = name
    a.target = JOINT
    a.trntype = mujoco.mjtTrn.mjTRN_JOINT
    a.set_to_dcmotor(motorconst=[0.0, 0.0], resistance=1.0, lugre=[float(v) for v in lugre],
                     cogging=[float(v) for v in cogging],
                     ctrlspec=int(mujoco.mjtCtrlInput.mjINPUT_NONE))
    return a


def _truth_cogging(spec, v):
    """Cogging ``amplitude * sin(periods * theta + phase)``, ``v = (amplitude [N*m], phase
    [rad])``: a passive dcmotor with ``cogging = (amplitude, periods, phase)``."""
    _passive_dcmotor(spec, "truth_cogging", cogging=(v[0], COGGING_PERIODS_PER_TURN, v[1]))


def _truth_presliding(spec, v):
    """The drive's LuGre friction changed: ``v = (sigma0 [N*m/rad], Fc, Fs [N*m], vs [rad/s])``
    with the model's bristle damping sigma1 kept.  MuJoCo feature: the scene's passive dcmotor
    ``yaw_friction`` rebuilt with ``set_to_dcmotor(lugre=...)``."""
    a = spec.actuator(FRICTION)
    sigma1 = float(a.dynprm[6])  # LuGre sigma1 compiles to dynprm[6] (layout checked in tests/test_effects_library.py)
    a.set_to_dcmotor(motorconst=[0.0, 0.0], resistance=1.0,
                     lugre=[float(v[0]), sigma1, float(v[1]), float(v[2]), float(v[3])],
                     cogging=[0.0, 0.0, 0.0], ctrlspec=int(mujoco.mjtCtrlInput.mjINPUT_NONE))


def _truth_stribeck(spec, v):
    """A second friction source with a Stribeck peak and no visible pre-sliding, ``v = (Fc, Fs
    [N*m], vs [rad/s])``: a passive LuGre dcmotor with the stiff bristle of
    :data:`STRIBECK_SIGMA`, on top of the drive's own friction."""
    _passive_dcmotor(spec, "truth_stribeck", lugre=(*STRIBECK_SIGMA, v[0], v[1], v[2]))


def _two_mass(spec) -> tuple:
    """The yaw split into a rotor (motor + encoder side) and the turret (output), coupled by a
    fixed tendon ``q_rotor - q_output`` (the rotor angle at the output side).

    The turret's hinge is renamed ``yaw_output``; a new body ``truth_rotor`` under the base,
    at the turret's frame, carries a hinge named ``yaw`` about the same axis, so the motor, the
    encoder sensors and the LuGre friction element (they name ``yaw``) act on the rotor.  The
    drive's joint properties (damping -- mostly back-EMF on the Omni --, frictionloss,
    stiffness) move to the rotor; the rotor's inertia is the rotor BODY's inertia about the
    axis (a disk: Izz = I, Ixx = Iyy = I/2; the joint's armature is set to 0), which is the
    same physics as the library's joint armature (MuJoCo feature: body inertia instead of
    ``armature``).  Keyframes get the rotor's angle (the output's: cable unstretched).
    Returns ``(rotor body, rotor joint, tendon)``; built once."""
    if spec.tendon("truth_cable") is not None:
        return spec.body("truth_rotor"), spec.joint(JOINT), spec.tendon("truth_cable")
    out = spec.joint(JOINT)
    turret = out.parent
    nq = spec.compile().nq
    inertia = float(out.armature)
    out.name = f"{JOINT}_output"
    rotor = spec.body("base").add_body(name="truth_rotor")
    rotor.pos = list(turret.pos)
    rotor.quat = list(turret.quat)
    rotor.explicitinertial = True
    rotor.mass = 1e-3  # [kg] any positive value: the rotor turns about a fixed axis of the base
    rotor.ipos = [0.0, 0.0, 0.0]
    j = rotor.add_joint(name=JOINT, type=mujoco.mjtJoint.mjJNT_HINGE)
    j.axis = list(out.axis)
    j.pos = list(out.pos)
    j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
    j.damping = list(out.damping)
    j.frictionloss = out.frictionloss
    j.stiffness = list(out.stiffness)
    j.springref = out.springref
    j.armature = 0.0
    out.damping = [0.0] * len(out.damping)
    out.frictionloss = 0.0
    out.stiffness = [0.0] * len(out.stiffness)
    out.armature = 0.0
    _rotor_inertia(rotor, inertia)
    t = spec.add_tendon(name="truth_cable")
    t.wrap_joint(JOINT, 1.0)
    t.wrap_joint(f"{JOINT}_output", -1.0)
    t.springlength = [0.0, 0.0]
    for key in spec.keys:
        # the rotor body is the base's last child: its coordinate comes after the turret's
        # subtree, which is the end of qpos in the Omni (base -> turret -> arm)
        if len(key.qpos) == nq:
            key.qpos = list(key.qpos) + [float(key.qpos[0])]
    return rotor, j, t


def _rotor_inertia(rotor, inertia: float) -> None:
    rotor.inertia = [inertia / 2, inertia / 2, inertia]  # a disk about its axis (z = the hinge axis)


def _truth_compliance(spec, v):
    """The capstan cable's compliance: ``v = (stiffness [N*m/rad], damping [N*m*s/rad], rotor
    inertia [kg*m^2])`` of the two-mass drive (:func:`_two_mass`): the tendon's spring and
    damper, the rotor body's inertia."""
    rotor, _, t = _two_mass(spec)
    t.stiffness[0] = float(v[0])
    t.damping[0] = float(v[1])
    _rotor_inertia(rotor, float(v[2]))


def _truth_backlash(spec, v):
    """A dead zone of half-width ``v[0]`` [rad] between rotor and turret: the two-mass drive's
    tendon limited to ``[-b, b]`` (a stop of :data:`BACKLASH_SOLIMP` impedance); a spring in
    the cable, if any, acts only outside the band."""
    _, _, t = _two_mass(spec)
    b = float(v[0])
    t.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    t.range = [-b, b]
    t.springlength = [-b, b]
    t.solref_limit = [BACKLASH_SOLREF_STEPS * float(spec.option.timestep), 1.0]
    t.solimp_limit = list(BACKLASH_SOLIMP)


def _truth_arm_mass(spec, v):
    """Masses [kg] of the upper arm and the forearm; each link keeps its shape (inertia scaled
    with the mass) and its centre of mass."""
    for name, mass in zip(ARM_LINKS, v):
        b = spec.body(name)
        ratio = float(mass) / float(b.mass)
        b.mass = float(mass)
        b.inertia = [float(i) * ratio for i in b.inertia]


#: Truth writers of the library's effects (same parameter meaning and units as the library,
#: written independently): name -> writer(spec, values).
TRUTH = {
    "coulomb_friction": _truth_frictionloss,
    "viscous_damping": _truth_damping,
    "joint_stiffness": _truth_stiffness,
    "gravity_tilt": _truth_tilt,
    "armature": _truth_armature,
    "actuator_lag": _truth_lag,
    "time_delay": _truth_delay,
    "torque_saturation": _truth_torque_limit,
    "torque_gain": _truth_gear,
    "position_offset": _truth_bias,
    "presliding_friction": _truth_presliding,
    "stribeck_friction": _truth_stribeck,
    "drive_compliance": _truth_compliance,
    "backlash": _truth_backlash,
    "arm_mass": _truth_arm_mass,
    "cogging": _truth_cogging,
}


# --- effects outside the library ---------------------------------------------------------
def _outside_gain_slope(spec, v):
    """A torque constant that varies with the yaw angle: ``k(theta) = gear (1 + s theta)``,
    ``s = v[0]`` [1/rad].  MuJoCo feature: the actuator's affine gain ``gain = gainprm[0] +
    gainprm[1] * length`` with the transmission's length ``gear * theta``, so
    ``gainprm[1] = s / gear``."""
    a = spec.actuator(MOTOR)
    a.gaintype = mujoco.mjtGain.mjGAIN_AFFINE
    a.gainprm = [1.0, float(v[0]) / _gear(spec)] + [0.0] * 8


def _outside_end_stop(spec, v):
    """A soft end stop inside the motion range at ``v[0]`` [rad] (positive side), e.g. the
    stylus cable pulled taut against the base: the yaw joint's upper limit moved in, with a
    soft constraint (``solreflimit`` time constant ``v[1]`` [s], critical damping)."""
    j = spec.joint(JOINT)
    lo = float(j.range[0])
    j.range = [lo, float(v[0])]
    j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    j.solref_limit = [float(v[1]), 1.0]


#: Effects outside the library: name -> writer(spec, values).
OUTSIDE = {
    "gain_slope": _outside_gain_slope,
    "end_stop": _outside_end_stop,
}


@dataclass(frozen=True)
class HiddenCase:
    """One case of the bank.

    Attributes
    ----------
    name : str
    effects : tuple of (str, tuple of float)
        Library effects hidden in the truth model and their values (absolute, library units).
    outside : tuple of (str, tuple of float)
        Effects outside the library (:data:`OUTSIDE`) and their values.
    expect : tuple of str
        Names the workflow should report (``("none",)`` for the null cases); for an outside
        effect, the names acceptable for it: ``"none"`` and the library's nearest stand-ins,
        these only with low confidence (:func:`assess`).
    exact : bool
        Data without noise and without quantisation (``none_exact``).
    note : str
        Why this magnitude is realistic (provenance).
    gap_lives : str
        For outside effects: where their gap should show (runs, amplitudes, position band).
    """

    name: str
    effects: tuple = ()
    outside: tuple = ()
    expect: tuple = ()
    exact: bool = False
    note: str = field(default="", compare=False)
    gap_lives: str = field(default="", compare=False)

    @property
    def extra(self) -> str:
        """Name of the (first) outside effect, "" if none (kept for callers of the old API)."""
        return self.outside[0][0] if self.outside else ""


def _single(name: str, values: tuple, note: str) -> HiddenCase:
    return HiddenCase(name, ((name, tuple(values)),), expect=(name,), note=note)


#: The bank.  Magnitudes: see the ``note`` of each case (models/README.md and
#: the effect library's docstring give the device estimates quoted there).
CASES: tuple[HiddenCase, ...] = (
    _single("coulomb_friction", (0.015,),
            "hard-stick frictionloss 15 mN*m on top of the LuGre drive friction (Fc 12.9 mN*m): "
            "the 5-20 mN*m estimate of the waist's dry friction; total 28 mN*m stays below the "
            "35 mN*m back-drive bound (models/README.md)"),
    _single("viscous_damping", (0.012,),
            "1.2e-2 N*m*s/rad instead of the calibrated 6.9e-3 (models/scene_lugre.xml): a "
            "+70 % change, e.g. cold grease or a lower-impedance amplifier (more back-EMF damping)"),
    _single("joint_stiffness", (0.06,),
            "cable spring 0.06 N*m/rad: the stylus cable pulls ~6 mN*m at 0.1 rad (estimate, a "
            "third of the dry friction)"),
    _single("gravity_tilt", (0.035, -0.02),
            "base tilted 2.0 deg about one axis, 1.1 deg about the other: a desk or cart off "
            "level (estimate)"),
    _single("armature", (2.5e-4,),
            "reflected rotor + capstan inertia 2.5e-4 kg*m^2 instead of 1e-4: the upper end of "
            "the 5e-5..2e-4 estimate (models/README.md) plus the capstan drum"),
    _single("actuator_lag", (0.002,),
            "2 ms drive lag: electrical time constant L/R of a small brushed motor (0.1-1 ms) "
            "plus the amplifier's input filter (estimate, upper end)"),
    _single("time_delay", (0.004,),
            "4 ms loop delay: USB frames of 1 ms plus the driver's scheduling on 700-900 Hz "
            "units (models/README.md: servo loop 700-900 Hz measured on some USB units)"),
    _single("torque_saturation", (0.1,),
            "drive limited to 100 mN*m: half the vendor demo's 200 mN*m waist limit (thermal "
            "foldback of the amplifier); only the 0.2 rad steps ask for more"),
    _single("torque_gain", (0.45,),
            "torque constant 0.45 instead of 0.5 N*m/V (-10 %): a motor's datasheet tolerance "
            "of its torque constant"),
    _single("position_offset", (0.02,),
            "20 mV drive offset (DAC zero error plus amplifier input offset, 10-50 mV typical "
            "of a 12-bit DAC drive): the loop settles 10 mrad off at kp = 2"),
    _single("presliding_friction", (6.0, 0.010, 0.025, 0.4),
            "another unit's LuGre drive friction: bristle stiffness 6 instead of 3.2 N*m/rad, "
            "Coulomb 10 instead of 12.9 mN*m, static 25 instead of 31.6 mN*m, Stribeck speed 0.4 "
            "instead of 0.62 rad/s (unit-to-unit spread of friction, estimate: all within the "
            "calibration's bounds, models/calibration.json)"),
    _single("stribeck_friction", (0.005, 0.010, 0.1),
            "a second dry-friction source with stiction (e.g. the capstan cable's wrap): Coulomb "
            "5, static 10 mN*m, Stribeck speed 0.1 rad/s; total static friction 42 mN*m, 1.2x the "
            "35 mN*m back-drive bound (a worn unit, estimate)"),
    _single("drive_compliance", (15.0, 0.002, 1e-4),
            "capstan cable 15 N*m/rad at the turret with 2e-3 N*m*s/rad damping, rotor 1e-4 "
            "kg*m^2 (the nominal armature): a rotor-cable mode at sqrt(k/J)/2pi ~ 60 Hz, the "
            "50-100 Hz order of capstan haptic devices' cable modes (estimate)"),
    _single("backlash", (0.001,),
            "a loose capstan cable: +-1 mrad of slack (2.4 encoder counts) between motor and "
            "turret (estimate; a tensioned capstan has none)"),
    _single("arm_mass", (0.080, 0.050),
            "link masses 80 and 50 g instead of the calibrated 68.8 and 59.5 g (models/omni.xml "
            "[calib]): +16 % and -16 %, the spread of a mass fitted through the yaw inertia"),
    _single("cogging", (0.003, 0.5),
            "motor cogging 3 mN*m at the turret, 45 periods per turn (a small iron-core motor's "
            "cogging of a few tenths of a mN*m times the ~7.5 capstan ratio, estimate)"),
    HiddenCase("none", (), expect=("none",), note="nominal model, encoder quantisation and noise"),
    HiddenCase("none_exact", (), expect=("none",), exact=True,
               note="nominal model, exact encoder (no noise, no quantisation): the gap is 0"),
    HiddenCase("delay+friction", (("time_delay", (0.004,)), ("coulomb_friction", (0.015,))),
               expect=("time_delay", "coulomb_friction"),
               note="two effects that mask each other (a delay takes damping away, friction adds "
                    "it); magnitudes as the single cases"),
    HiddenCase("delay+friction+armature",
               (("time_delay", (0.004,)), ("coulomb_friction", (0.015,)), ("armature", (2.5e-4,))),
               expect=("time_delay", "coulomb_friction", "armature"),
               note="three effects; magnitudes as the single cases"),
    HiddenCase("presliding+armature", (("presliding_friction", (6.0, 0.010, 0.025, 0.4)),
                                        ("armature", (2.5e-4,))),
               expect=("presliding_friction", "armature"),
               note="two effects; magnitudes as the single cases"),
    HiddenCase("backlash+coulomb", (("backlash", (0.001,)), ("coulomb_friction", (0.015,))),
               expect=("backlash", "coulomb_friction"),
               note="two effects; magnitudes as the single cases"),
    HiddenCase("gain_slope", outside=(("gain_slope", (0.5,)),), expect=("none", "torque_gain"),
               note="outside the library: torque constant 1 + 0.5/rad * theta (+-7.5 % over the "
                    "0.15 rad sines, +-10 % at the 0.2 rad steps; the order of a brushed motor's "
                    "5-10 % torque-constant variation, here as a trend over the yaw range)",
               gap_lives="the large-amplitude runs (0.15 rad sines, 0.2 rad steps), with opposite "
                         "sign on the two sides of theta = 0: a position band |theta| > ~0.1 rad"),
    HiddenCase("end_stop", outside=(("end_stop", (0.17, 0.01)),),
               expect=("none", "torque_saturation", "joint_stiffness"),
               note="outside the library: a soft stop at +0.17 rad (10 ms constraint time "
                    "constant), e.g. the stylus cable pulled taut against the base",
               gap_lives="only the 0.2 rad square waves, while theta > 0.17 rad (a position band at "
                         "the positive end; the sines reach 0.15 rad and never touch it)"),
)


#: Realistic ranges of each library effect's parameters for random hidden magnitudes
#: (``scripts/discrepancy_coverage.py``): per parameter ``(low, high, signed)``; the magnitude is
#: drawn uniformly in ``[low, high]`` and, when ``signed``, given a random sign.  Ranges from the
#: device estimates quoted in the cases' notes; each lower end keeps the effect visible above
#: the encoder noise (a magnitude the data cannot show is not a test of an interval).
RANGES = {
    # dry friction on top of the LuGre drive: the 5-20 mN*m estimate of the waist
    "coulomb_friction": ((0.005, 0.020, False),),
    # 0.6x..2x the calibrated 6.9e-3 N*m*s/rad (grease temperature, amplifier impedance)
    "viscous_damping": ((0.004, 0.014, False),),
    # cable springs: 1..10 mN*m at 0.1 rad
    "joint_stiffness": ((0.01, 0.10, False),),
    # a desk or cart off level by 0.9..2.3 deg about each axis, either way
    "gravity_tilt": ((0.015, 0.04, True), (0.015, 0.04, True)),
    # total reflected rotor inertia: 1.5x..4x the nominal 1e-4 (estimate 5e-5..2e-4 + capstan)
    "armature": ((1.5e-4, 4e-4, False),),
    # drive lag 0.5..4 ms (motor L/R 0.1-1 ms plus amplifier filtering)
    "actuator_lag": ((0.0005, 0.004, False),),
    # loop delay 1..6 ms (USB frames, 700-900 Hz servo loops)
    "time_delay": ((0.001, 0.006, False),),
    # torque limit 50..300 mN*m (the 0.2 rad steps ask for up to 400 mN*m)
    "torque_saturation": ((0.05, 0.30, False),),
    # torque constant 0.5 N*m/V off by 6..20 % either way (datasheet tolerance +-10 %, drift)
    "torque_gain": ((0.06, 0.20, True),),
    # drive offset 5..40 mV either way
    "position_offset": ((0.005, 0.04, True),),
    # LuGre drive friction of another unit: bristle stiffness 1.5..10 N*m/rad, Coulomb 6..18,
    # static 20..35 mN*m (up to the back-drive bound), Stribeck speed 0.2..1 rad/s
    "presliding_friction": ((1.5, 10.0, False), (0.006, 0.018, False), (0.020, 0.035, False),
                            (0.2, 1.0, False)),
    # a second stiction source: Coulomb 3..8, static 8..15 mN*m, Stribeck speed 0.05..0.3 rad/s
    "stribeck_friction": ((0.003, 0.008, False), (0.008, 0.015, False), (0.05, 0.3, False)),
    # cable 8..40 N*m/rad (modes ~45-100 Hz), damping 0.5..4e-3 N*m*s/rad, rotor 0.7..2e-4
    "drive_compliance": ((8.0, 40.0, False), (0.0005, 0.004, False), (7e-5, 2e-4, False)),
    # slack 0.5..3 mrad (1-7 encoder counts)
    "backlash": ((0.0005, 0.003, False),),
    # link masses +-(5..25) % around the calibrated 68.8 and 59.5 g
    "arm_mass": ((0.05, 0.25, True), (0.05, 0.25, True)),
    # cogging 1.5..6 mN*m at the turret, any phase (in [-pi, pi))
    "cogging": ((0.0015, 0.006, False), (-math.pi, math.pi, False)),
}
#: Nominal values the signed ranges of :data:`RANGES` are offsets from, as fractions
#: (``torque_gain``: the scene's gear; ``arm_mass``: the calibrated link masses; models/omni.xml);
#: other effects are drawn as absolute values.
RANGE_CENTRE = {"torque_gain": (0.5,), "arm_mass": (0.0687884, 0.0594899)}


def draw(effect: str, rng: np.random.Generator) -> tuple[float, ...]:
    """A random realistic magnitude of ``effect`` (:data:`RANGES`)."""
    centre = RANGE_CENTRE.get(effect)
    out = []
    for i, (lo, hi, signed) in enumerate(RANGES[effect]):
        v = rng.uniform(lo, hi)
        if signed and rng.random() < 0.5:
            v = -v
        out.append(float(centre[i] * (1 + v)) if centre else float(v))
    return tuple(out)


def case(name: str) -> HiddenCase:
    for c in CASES:
        if c.name == name:
            return c
    raise KeyError(name)


def truth_spec(hidden: HiddenCase, base: mujoco.MjSpec | None = None) -> mujoco.MjSpec:
    """The nominal model with the case's hidden effects written into it (a copy of ``base``)."""
    spec = (base or mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))).copy()
    # the gear first: the armature's reflection and the torque limit are expressed through it
    order = sorted(hidden.effects, key=lambda e: e[0] != "torque_gain")
    for name, values in order:
        TRUTH[name](spec, np.asarray(values, float))
    for name, values in hidden.outside:
        OUTSIDE[name](spec, np.asarray(values, float))
    return spec


def settings(hidden: HiddenCase, seed: int = 1, noise_rad: float | None = None) -> ex.Settings:
    """The measurement settings of the case: quantised encoder plus noise, or exact."""
    if hidden.exact:
        return ex.Settings(quantize=False, noise_rad=0.0, seed=seed)
    return ex.Settings(quantize=True, noise_rad=BANK_NOISE_RAD if noise_rad is None else noise_rad,
                       seed=seed)


def generate(hidden: HiddenCase, exps: list[ex.Experiment] | None = None, seed: int = 1,
             noise_rad: float | None = None, jobs: int | None = None,
             exact: bool | None = None) -> list[Run]:
    """"Measured" runs of the case's truth model (device engine; quantised, noisy encoder unless
    the case, or ``exact=True``, asks for exact data)."""
    m = truth_spec(hidden).compile()
    exps = exps if exps is not None else bank_experiments()
    st = settings(hidden, seed, noise_rad)
    if exact:
        st = ex.Settings(quantize=False, noise_rad=0.0, seed=seed)
    return ex.simulate(exps, model=m, settings=st, jobs=jobs, force_reference=True)


def error(param: str, fitted: float, truth: float) -> float:
    """``fitted - truth``; for a phase [rad] (``*phase_rad``) wrapped into [-pi, pi)."""
    d = float(fitted) - float(truth)
    if param.endswith("phase_rad"):
        d = (d + math.pi) % (2 * math.pi) - math.pi
    return d


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def assess(hidden: HiddenCase, report: dict) -> tuple[bool, str]:
    """Did the workflow pass this case?  (the bank's criteria; README, "The hidden-effect bank")

    * library effects: exactly the hidden effects named (``hidden.expect``, nothing else), each
      with ``confidence == "high"``; each named effect reports as many parameters as the truth
      holds (a list of another length fails, it is not truncated), every fitted value finite
      and within its reported 95 % half-width of the truth, and every half-width finite (an
      infinite or NaN half-width -- ``fit.jacobian_se``'s and ``uncertainty.numerical_floor``'s
      fallback when the normal matrix cannot be inverted -- would cover any value: it fails the
      case); the held-out gap shrunk at least 3x;
    * null cases (``expect == ("none",)``): ``none`` only;
    * effects outside the library: ``expect`` lists the names acceptable for the case:
      ``"none"`` (the library does not explain the gap) and the library's nearest stand-ins
      (the effects that can imitate part of it, stated with the case before it was run), the
      stand-ins only with low confidence.  Pass: ``none`` alone, or every named effect in
      ``expect`` with ``confidence == "low"``.  A name outside ``expect`` fails even with low
      confidence, and any name with high confidence fails (whatever the ``unexplained`` flag
      says): a confident wrong name is the error the bank guards against.
    """
    effects = report["effects"]
    named = [e["name"] for e in effects]
    if hidden.outside:
        if named == ["none"]:
            return True, "unexplained (none)"
        stray = [n for n in named if n not in hidden.expect]
        if stray:
            return False, f"named {stray}, not among the acceptable {list(hidden.expect)}"
        sure = [e["name"] for e in effects if e.get("confidence") != "low"]
        if sure:
            return False, f"confidently misnamed: {sure} not with low confidence"
        return True, "nearest candidate, low confidence"
    if sorted(named) != sorted(hidden.expect):
        return False, f"named {named}, hidden {list(hidden.expect)}"
    if named == ["none"]:
        return True, "none"
    weak = [f"{e['name']} ({e.get('confidence')})" for e in effects if e.get("confidence") != "high"]
    if weak:
        return False, f"named without high confidence: {', '.join(weak)}"
    truth = dict(hidden.effects)
    for e in effects:
        params, values = list(e["parameters"].items()), truth[e["name"]]
        if len(params) != len(values):
            return False, (f"{e['name']}: {len(params)} parameters reported "
                           f"({', '.join(p for p, _ in params)}), the truth holds {len(values)}")
        for (p, v), t in zip(params, values, strict=True):
            u = e["uncertainty"].get(p)
            if not _finite(u):
                return False, f"{p}: half-width {u} (not finite: it covers nothing)"
            if not _finite(v):
                return False, f"{p}: fitted {v}"
            if abs(error(p, v, t)) > u:
                return False, f"{p}: {v:.4g} vs truth {t:.4g} (± {u:.2g})"
    shrink = report["shrink_factor"]
    if not shrink >= 3:  # NaN fails too; inf (gap left exactly 0) passes
        return False, f"gap shrank only x{shrink:.1f}"
    return True, "ok"
