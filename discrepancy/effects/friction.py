"""Drive friction and cogging, each a passive ``dcmotor`` on the target joint (``input="none"``:
no control, no electrical part): ``presliding_friction`` and ``stribeck_friction`` (LuGre
elements) and ``cogging``.

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
* ``cogging``: :data:`COGGING_PERIODS` periods per joint turn (estimate with its reasoning);
  amplitude 1-3 mN*m (a few % of a small iron-core motor's rated torque times the capstan
  ratio, ~1/10-1/4 of the drive's Coulomb level; estimate): 1 mN*m is 4.8x the floor, 3 mN*m 14x.
  The phase is bounded to +-2 pi so a fit started in [-pi, pi) does not sit on a bound.

(The Omni's numbers are estimates: models/omni/README.md, models/omni/omni.xml; "the floor": see the
package docstring.)
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from .base import OMNI, Effect, Param, Target, suffixed, unique_name

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


def _is_passive_dcmotor(a, joint: str) -> bool:
    return (a.trntype == mujoco.mjtTrn.mjTRN_JOINT and a.target == joint
            and a.biastype == mujoco.mjtBias.mjBIAS_DCMOTOR)


def _own_dcmotor(spec: mujoco.MjSpec, name: str, joint: str):
    """The passive dcmotor an effect added: ``name`` (or ``name_2``... if the model already had
    an element called ``name``, see :func:`~.base.unique_name`) on ``joint``; None if there is none."""
    for k in range(1, 100):
        a = spec.actuator(suffixed(name, k))
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
    a = spec.add_actuator(name=unique_name(spec, mujoco.mjtObj.mjOBJ_ACTUATOR, name), target=joint,
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
        sigma1 = 0.0  # as the default scene's yaw_friction (models/omni/scene_lugre.xml)
    else:
        sigma1 = float(a.dynprm[6])  # kept as in the model
    _set_lugre(a, x[0], sigma1, x[1], x[2], x[3])


def _presliding_grid(x0):
    if x0[2] > 0:  # the model has a LuGre drive: around it
        f = [(1, 1, 1, 1), (0.3, 1, 1, 1), (3, 1, 1, 1), (1, 1, 1.5, 1), (1, 1, 0.7, 1),
             (1, 1.5, 1.5, 1), (1, 1, 1, 0.3)]
        return np.array([[x0[0] * a, x0[1] * b, x0[2] * c, x0[3] * d] for a, b, c, d in f])
    # none yet: the default scene's calibrated LuGre (sigma0 ~ 3 N*m/rad, Fc ~ 13, Fs ~ 32 mN*m,
    # vs ~ 0.6 rad/s; models/omni/README.md) and stiffer/weaker variants
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
    # models/omni/README.md) and Stribeck speeds a decade apart
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


PRESLIDING_FRICTION = Effect(
    "presliding_friction",
    "LuGre drive friction with an elastic pre-sliding range (bristle stiffness sigma0)",
    (Param("sigma0_nm_per_rad", "N*m/rad", 0.3, 100.0, 1.0),
     Param("fc_nm", "N*m", 0.0, 0.3, 0.003),
     Param("fs_nm", "N*m", 0.0, 0.3, 0.003),
     Param("vs_rad_per_s", "rad/s", 0.02, 3.0, 0.1)),
    _read_presliding, _write_presliding, _presliding_grid)

STRIBECK_FRICTION = Effect(
    "stribeck_friction",
    "static friction above the Coulomb level (Stribeck curve), stick without pre-sliding",
    (Param("fc_nm", "N*m", 0.0, 0.3, 0.003),
     Param("fs_nm", "N*m", 0.0, 0.3, 0.003),
     Param("vs_rad_per_s", "rad/s", 0.01, 3.0, 0.05)),
    _read_stribeck, _write_stribeck, _stribeck_grid)

COGGING = Effect(
    "cogging", "motor cogging: a torque periodic in the motor angle",
    (Param("amplitude_nm", "N*m", 0.0, 0.05, 0.001),
     Param("phase_rad", "rad", -2 * math.pi, 2 * math.pi, 0.3)),
    _read_cogging, _write_cogging, _cogging_grid)
