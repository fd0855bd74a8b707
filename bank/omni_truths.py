"""Truth models: the library's effects (and a few outside it) written into the virtual Omni
with MuJoCo's own features, independently of the effect library.

Independence
------------
A truth model is written here by the writers in :data:`TRUTH` (and :data:`OUTSIDE` for effects
the library does not hold).  This module does NOT use the workflow's effect library (the
package :mod:`discrepancy.effects`: no ``apply``, ``compile_with`` or
``Effect.write``, not even an import, direct or through another module;
``tests/test_discrepancy_bank.py`` checks it by reading the syntax tree of this module and of
the modules that use it, and following their imports through the project), so a fit that
recovers a truth checks the library's writers too: a writer that put a value into the wrong
field, the wrong unit or the wrong side of the gear would be caught.  Where MuJoCo offers a
second feature with the same physics the truth uses it (a tilted base instead of a tilted
gravity vector, the motor's rotor inertia ``actuator armature`` reflected by the gear instead
of the joint's armature).  What the truth shares with the library is only the *meaning* of
each parameter (its definition, unit and the model element it belongs to), so that a fitted
value is comparable with the truth; the tests read the compiled ``MjModel`` (or its mass
matrix) and check that it holds exactly the values each case states.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

# The contract's names in the virtual Omni (models/omni/omni.xml, models/omni/scene_lugre.xml).
JOINT = "yaw"
MOTOR = "yaw_motor"
FRICTION = "yaw_friction"


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
#: (the library's estimate: 6 cogs per turn of a 2-pole 3-slot motor x a capstan ratio of ~7.5
#: inferred from the encoder counts); the truth must share it for amplitude and phase to be
#: comparable.
COGGING_PERIODS_PER_TURN = 45.0
#: ``stribeck_friction``'s bristle stiffness [N*m/rad] and damping [N*m*s/rad]: the library's
#: definition of a Stribeck element "without visible pre-sliding" (Fs/sigma0 below one encoder
#: count, sigma1/sigma0 = one timestep; the library's friction module), shared so the levels are comparable.
STRIBECK_SIGMA = (1000.0, 1.0)
#: The backlash stop's impedance, part of the library's definition of a hard dead zone
#: (the library's two-mass module: solreflimit time constant 2 timesteps, solimplimit 0.99/0.999: 4e-5 rad at
#: 0.1 N*m), shared so the half-width is comparable.
BACKLASH_SOLREF_STEPS = 2.0
BACKLASH_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)
#: The Omni's arm links whose masses ``arm_mass`` states (models/omni/omni.xml).
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
