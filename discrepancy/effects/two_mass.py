"""The two-mass drive, rotor + cable: ``drive_compliance`` and ``backlash``.

* ``drive_compliance``: the capstan cable as a spring between the rotor (motor and encoder:
  the encoder joint keeps the name, so the motor, the sensors and the drive friction act on it,
  with the joint's damping, frictionloss, stiffness and armature) and the turret.  A real
  steel capstan cable is ~1e3 N*m/rad at the turret (estimate: 0.45 mm stranded steel,
  EA ~ 1.6e4 N, ~2 cm free length, two strands, ~3 cm drum radius): its mode (~500 Hz with a
  1e-4 kg*m^2 rotor) sits at the 1 kHz loop's Nyquist frequency and the explicit spring of the
  1 ms step is unstable above k ~ 4 J/dt^2 (~400 N*m/rad for 1e-4 kg*m^2; a probe script
  diverged at 400).  The candidate therefore covers soft drives, 0.5-100 N*m/rad (a loose or
  stretched cable, an elastic coupling; the default scene's sigma0 ~ 3 N*m/rad lumps such a
  low-energy stiffness, models/omni/README.md), with the rotor inertia bounded below by the
  5e-5 kg*m^2 end of the rotor estimate (sqrt(100/5e-5) * 1 ms = 1.4 < 2: stable).  Nominal of
  a rigid drive: read gives inf, :func:`~discrepancy.effects.nominal_values` the
  upper bound 100 N*m/rad, no cable damping, the joint's armature as the rotor -- NOT the rigid
  model: near the ~3.4 Hz loop resonance even 100 N*m/rad differs from the rigid drive (30x
  the noise floor of the bank set; k = 20: 160x, k = 5: 600x).  A drive stiffer than
  ~100 N*m/rad is beyond this candidate.
* ``backlash``: the same two-mass drive with the cable's length limited to [-b, b] (a stop,
  solref 2 timesteps, solimp 0.99/0.999: 4e-5 rad penetration at 0.1 N*m) and no spring force
  inside the band.  A pre-tensioned capstan has no backlash; a slack cable or a loose coupling
  gives a few counts: b = 1 count is 8x the floor, 3 counts 19x.  A rigid model reads 0 (the
  lower bound is 1e-6 rad: MuJoCo needs range[0] < range[1]).

(The Omni's numbers are estimates: models/omni/README.md, models/omni/omni.xml; "the floor": see the
package docstring.)
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from omni_sim.device import ENCODER_STEP_RAD  # the Omni's encoder count [rad]
from .base import OMNI, Effect, Param, Target, element_exists, suffixed

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
    return tuple(suffixed(f"{target.joint}_{n}", k) for n in ("output", "rotor", "cable"))


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
    properties go with it: damping (mostly back-EMF on the Omni, models/omni/README.md),
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
        if not (element_exists(spec, mujoco.mjtObj.mjOBJ_JOINT, out_name)
                or element_exists(spec, mujoco.mjtObj.mjOBJ_BODY, rotor_name)
                or element_exists(spec, mujoco.mjtObj.mjOBJ_TENDON, cable_name)):
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


DRIVE_COMPLIANCE = Effect(
    "drive_compliance",
    "compliant capstan cable between the motor (encoder) and the turret: a two-mass drive",
    (Param("stiffness_nm_per_rad", "N*m/rad", 0.5, 100.0, 2.0),
     Param("damping_nms_per_rad", "N*m*s/rad", 0.0, 0.05, 0.001),
     Param("rotor_inertia_kgm2", "kg*m^2", 5e-5, 1e-3, 2e-5)),
    _read_compliance, _write_compliance, _compliance_grid, _applies_two_mass)

BACKLASH = Effect(
    "backlash", "dead zone (slack) between the motor (encoder) and the turret",
    (Param("half_width_rad", "rad", 1e-6, 0.02, 2e-4),),
    _read_backlash, _write_backlash, _backlash_grid, _applies_two_mass)
