"""Hidden-effect cases: truth models (the virtual Omni plus effects, :mod:`.omni_truths`) and
their "measured" data, and whether a report found what was hidden.

Used by the bank's studies (:mod:`bank.studies`: the bank's run, ``scripts/discrepancy_bank.py``;
the coverage study), the tests, and the commands that run a case: ``omni bench``'s discrepancy
figures and ``omni sweep``'s discrepancy pipeline, which import it through
:mod:`omni_studies.bank_link` only when asked to run one.  ``omni discrepancy --demo`` hides the
``time_delay`` case's delay with a truth of its own (:mod:`discrepancy.demo`, the same model and
runs).  Like the truth models it imports nothing of the effect library
(``tests/test_discrepancy_bank.py``).

Data
----
:func:`generate` runs the truth model through :func:`omni_sim.experiments.simulate` (the
device's closed-loop engine, the reference path) on the compact experiment set
(:mod:`discrepancy.experiment_set`) with the encoder's quantisation (15000 counts/rev) and white noise of
:data:`~discrepancy.experiment_set.NOISE_RAD` that the controller sees, as on the
device; the case ``none_exact`` has neither.  The workflow sees only these runs and the nominal
model.

Four cases are not the Omni: ``load_friction``, ``friction_family_stribeck``, ``asymmetric_friction``
and ``current_limit`` (``truth="servo"``) are a pendulum on a geared servo (nominal model
``models/servo_pendulum/servo_pendulum.xml``, joint ``pivot``, actuator ``servo``: see :func:`nominal`)
whose gearbox friction grows with the torque it transmits (with a Stribeck rise at low speed, the
second), or whose Coulomb level depends on the direction of motion, or whose firmware
limits the motor's current; their truth is a
per-step simulation of its own and their runs are logged as a host logs a servo (irregular
times at ~200 Hz, the goal held between writes, torque-off spans), :mod:`.servo_truth`.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from identification.dataset import Run

from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device
from discrepancy import experiment_set

from . import servo_truth
from .omni_truths import OUTSIDE, TRUTH


@dataclass(frozen=True)
class HiddenCase:
    """One case of the bank.

    Attributes
    ----------
    name : str
    effects : tuple of (str, tuple of float)
        Library effects hidden in the truth model and their values (absolute, library units).
    outside : tuple of (str, tuple of float)
        Effects outside the library (:data:`~.omni_truths.OUTSIDE`) and their values.
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
    truth : str
        ``"omni"``: the virtual Omni with the effects written by :mod:`.omni_truths`, run
        through the device's loop on the compact experiment set; ``"servo"``: the geared-servo
        pendulum of :mod:`.servo_truth` (its own nominal model and target, :func:`nominal`).
    nominal_joint : tuple of (str, float)
        A nominal that is off: MJCF attributes of the controlled joint (``armature``,
        ``frictionloss``, ``damping``) that the model the workflow is given holds instead of
        the truth's values (:func:`nominal`); the report's corrections must come back to the
        truth's (:func:`assess`).
    """

    name: str
    effects: tuple = ()
    outside: tuple = ()
    expect: tuple = ()
    exact: bool = False
    note: str = field(default="", compare=False)
    gap_lives: str = field(default="", compare=False)
    truth: str = "omni"
    nominal_joint: tuple = ()


#: The geared-servo nominal that is off (the ``*nominal_off`` cases): the pendulum's inertia
#: about the pivot taken 15 % too large (+3.1e-3 kg*m^2 on the armature's 2.5e-3: 0.15 x 2.07e-2)
#: and the gear train's Coulomb level 40 % low (0.018 instead of 0.03 N*m).  Sizes of a
#: datasheet-and-CAD nominal's errors, as the issue that asked for them states them.
SERVO_NOMINAL_OFF = (("armature", 5.6e-3), ("frictionloss", 0.018))


def _single(name: str, values: tuple, note: str) -> HiddenCase:
    return HiddenCase(name, ((name, tuple(values)),), expect=(name,), note=note)


#: The cases (the bank).  Magnitudes: see the ``note`` of each case (models/omni/README.md and
#: the effect library's docstring give the device estimates quoted there).
CASES: tuple[HiddenCase, ...] = (
    _single("coulomb_friction", (0.015,),
            "hard-stick frictionloss 15 mN*m on top of the LuGre drive friction (Fc 12.9 mN*m): "
            "the 5-20 mN*m estimate of the waist's dry friction; total 28 mN*m stays below the "
            "35 mN*m back-drive bound (models/omni/README.md)"),
    _single("viscous_damping", (0.012,),
            "1.2e-2 N*m*s/rad instead of the calibrated 6.9e-3 (models/omni/scene_lugre.xml): a "
            "+70 % change, e.g. cold grease or a lower-impedance amplifier (more back-EMF damping)"),
    _single("joint_stiffness", (0.06, 0.0),
            "cable spring 0.06 N*m/rad at rest 0: the stylus cable pulls ~6 mN*m at 0.1 rad (estimate, a "
            "third of the dry friction)"),
    _single("gravity_tilt", (0.035, -0.02),
            "base tilted 2.0 deg about one axis, 1.1 deg about the other: a desk or cart off "
            "level (estimate)"),
    _single("armature", (2.5e-4,),
            "reflected rotor + capstan inertia 2.5e-4 kg*m^2 instead of 1e-4: the upper end of "
            "the 5e-5..2e-4 estimate (models/omni/README.md) plus the capstan drum"),
    _single("actuator_lag", (0.002,),
            "2 ms drive lag: electrical time constant L/R of a small brushed motor (0.1-1 ms) "
            "plus the amplifier's input filter (estimate, upper end)"),
    _single("time_delay", (0.004,),
            "4 ms loop delay: USB frames of 1 ms plus the driver's scheduling on 700-900 Hz "
            "units (models/omni/README.md: servo loop 700-900 Hz measured on some USB units)"),
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
            "calibration's bounds, models/omni/calibration.json)"),
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
            "link masses 80 and 50 g instead of the calibrated 68.8 and 59.5 g (models/omni/omni.xml "
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
    HiddenCase("load_friction", (("load_friction", (servo_truth.MU_DRIVE, servo_truth.MU_BACK, servo_truth.B_EMF)),),
               expect=("load_friction",), truth="servo",
               note="a pendulum (0.82 kg, m*g*l 1.18 N*m) on a 12 V geared servo (models/servo_pendulum/servo_pendulum.xml: "
                    "0.30 N*m/V, back-EMF 0.36 N*m*s/rad, Fc 30 mN*m) whose gearbox friction grows with "
                    "the torque it transmits: mu_drive 0.15 (forward efficiency 0.85 of a ~350:1 spur "
                    "gearbox, 0.96-0.97 per mesh) and mu_back 0.45 (back-driving efficiency 0.69, an "
                    "estimate: back-driving such servos loses markedly more, up to self-locking); 12 runs "
                    "of 5 s logged at ~200 Hz with jitter, 4096-count encoder (servo_truth.py)"),
    HiddenCase("friction_family_stribeck",
               (("friction_family_stribeck", (servo_truth.MU_DRIVE, servo_truth.MU_BACK, servo_truth.B_EMF,
                                              servo_truth.STRIBECK_RISE_NM,
                                              servo_truth.STRIBECK_SPEED_RAD_S, servo_truth.STRIBECK_SHAPE)),),
               expect=("friction_family_stribeck",), truth="servo",
               note="the load_friction case's geared servo and gearbox (mu_drive 0.15, mu_back 0.45) whose "
                    "Coulomb level also rises at low speed: + 0.03 N*m exp(-|w| / 0.1 rad/s) (a static level "
                    "twice the model's Coulomb level at rest; the friction family's Stribeck variant, "
                    "discrepancy/effects/family.py); the load_friction case's 12 runs and log (servo_truth.py)"),
    HiddenCase("asymmetric_friction", (("asymmetric_friction", (servo_truth.ASYMMETRY_NM,)),),
               expect=("asymmetric_friction",), truth="servo",
               note="the same geared servo and pendulum (models/servo_pendulum/servo_pendulum.xml, Fc 30 mN*m) whose "
                    "Coulomb friction depends on the direction of motion: +7.5 mN*m moving positive, "
                    "-7.5 mN*m moving negative (25 % of Fc; an estimate set before the case was run: "
                    "about half of a small servo's no-load friction is the brushed motor's, whose brush "
                    "friction differs with the direction of rotation by up to about half); no "
                    "load-dependent friction (mu_drive = mu_back = 0); the load_friction case's 12 runs "
                    "and log (servo_truth.py)"),
    HiddenCase("current_limit", (("current_limit", (servo_truth.CURRENT_LIMIT_NM,
                                                    servo_truth.BACK_EMF_NMS_PER_RAD)),),
               expect=("current_limit",), truth="servo",
               note="the same geared servo and pendulum (models/servo_pendulum/servo_pendulum.xml: kt 1.2 "
                    "N*m/A after the gear, R 4 ohm, stall 3.6 N*m at 12 V) whose firmware limits the "
                    "winding's current to 1.5 A, half the stall current (an estimate of a protective "
                    "setting; such servos ship a settable current limit): the motor's torque kt i = "
                    "gear u - (kt^2/R) w stays within 1.8 N*m, so the bound in the direction of motion "
                    "moves with the back-EMF 0.36 N*m*s/rad; it binds on the square waves and the "
                    "lifts; no gearbox friction law (servo_truth.py, written from the motor's "
                    "equations, not from the engine's law)"),
    HiddenCase("users_pendulum", (("load_friction_smooth", servo_truth.USERS_PENDULUM),),
               expect=("load_friction_smooth",), truth="servo", nominal_joint=SERVO_NOMINAL_OFF,
               note="the user's pendulum of the first test half (i_users_pendulum, spent there: a "
                    "development case here), rebuilt on this servo: a gear friction 0.2 |tau_m| "
                    "tanh(w / 0.02) the same both ways, tau_m the motor's net torque (its back-EMF "
                    "0.36 N*m*s/rad), the user's own law (Makkar et al. 2005's smooth sign), and the "
                    "load_friction_nominal_off case's wrong nominal (armature +15 % of the inertia, "
                    "Coulomb level 40 % low); the load_friction case's 12 runs and log"),
)

#: The geared-servo cases whose nominal is off (:attr:`HiddenCase.nominal_joint`): the workflow
#: must correct the nominal's constants back and name only what is hidden.  Apart from
#: :data:`CASES` (whose records are docs/studies/discrepancy/bank.json): their bank test runs them and
#: judges them with :func:`assess` like the others; ``omni bench --only discrepancy_servo``
#: times the first.
NOMINAL_OFF_CASES = (
    HiddenCase("load_friction_nominal_off", (("load_friction", (servo_truth.MU_DRIVE, servo_truth.MU_BACK, servo_truth.B_EMF)),),
               expect=("load_friction",), truth="servo", nominal_joint=SERVO_NOMINAL_OFF,
               note="the load_friction case's truth and runs, with a nominal that is off where a "
                    "user's is: its armature 5.6e-3 instead of 2.5e-3 kg*m^2 (the pendulum's whole "
                    "inertia about the pivot, 2.07e-2 kg*m^2, taken 15 % too large) and its Coulomb "
                    "level 18 instead of 30 mN*m (40 % low); the corrections must bring both back"),
    HiddenCase("nominal_off", (), expect=("none",), truth="servo", nominal_joint=SERVO_NOMINAL_OFF,
               note="the geared servo with nothing hidden (the truth is models/servo_pendulum/servo_pendulum.xml "
                    "itself) and the load_friction_nominal_off case's wrong nominal: corrections "
                    "only, no effect named"),
)


def case(name: str) -> HiddenCase:
    """The case called ``name`` (KeyError if unknown)."""
    for c in CASES + NOMINAL_OFF_CASES:
        if c.name == name:
            return c
    raise KeyError(name)


def nominal(hidden: HiddenCase) -> tuple:
    """The nominal model the workflow is given for this case and its target: ``(None, None)``
    for the Omni's cases (the built-in scene, ``yaw``/``yaw_motor``), the servo pendulum's file
    and ``pivot``/``servo`` for a ``truth="servo"`` case."""
    if hidden.truth == "servo":
        path = servo_truth.model_path()
        if hidden.nominal_joint:
            path = _nominal_off(path, servo_truth.JOINT, hidden.nominal_joint)
        return path, servo_truth.target()
    if hidden.nominal_joint:
        return _nominal_off(om.DEFAULT_SCENE, om.OMNI.joint, hidden.nominal_joint), None
    return None, None


#: The controlled joint's MJCF attributes a case's nominal may hold off the truth, and the
#: library effect (and its parameter) the workflow's corrections re-estimate them with -- named
#: here as data so that this module needs none of the library's code.
CORRECTED_BY = {"armature": ("armature", "armature_kgm2"),
                "frictionloss": ("coulomb_friction", "frictionloss_nm"),
                "damping": ("viscous_damping", "damping_nms_per_rad")}


def _nominal_off(path, joint: str, values: tuple) -> Path:
    """A copy of the model ``path`` whose ``joint`` holds the attribute ``values`` (a file in
    the temporary folder, named by its content)."""
    spec = mujoco.MjSpec.from_file(str(path))
    j = spec.joint(joint)
    for attr, v in values:
        if attr not in CORRECTED_BY:
            raise ValueError(f"nominal_joint: {attr!r} is not one of {sorted(CORRECTED_BY)}")
        if attr == "damping":
            j.damping[0] = float(v)
        else:
            setattr(j, attr, float(v))
    xml = spec.to_xml()
    folder = Path(tempfile.gettempdir()) / "omni_bank_nominals"
    folder.mkdir(exist_ok=True)
    out = folder / f"{Path(path).stem}-{hashlib.sha1(xml.encode()).hexdigest()[:12]}.xml"
    if not out.exists():
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(xml)
        tmp.replace(out)
    return out


def truth_joint(hidden: HiddenCase) -> dict:
    """The truth's values of the attributes ``hidden.nominal_joint`` holds off (from the
    truth's own model file)."""
    path = servo_truth.model_path() if hidden.truth == "servo" else om.DEFAULT_SCENE
    m = mujoco.MjModel.from_xml_path(str(path))
    joint = servo_truth.JOINT if hidden.truth == "servo" else om.OMNI.joint
    dof = int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, joint)])
    field_of = {"armature": m.dof_armature, "frictionloss": m.dof_frictionloss, "damping": m.dof_damping}
    return {attr: float(field_of[attr][dof]) for attr, _ in hidden.nominal_joint}


def truth_spec(hidden: HiddenCase, base: mujoco.MjSpec | None = None) -> mujoco.MjSpec:
    """The nominal model with the case's hidden effects written into it (a copy of ``base``).
    Only for the Omni's cases (a ``truth="servo"`` case's effect is a law applied at every
    step, not a model: ValueError)."""
    if hidden.truth != "omni":
        raise ValueError(f"case {hidden.name!r}: its truth is a simulation of its own "
                         f"({hidden.truth}), not a model written on the Omni")
    spec = (base or mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))).copy()
    # the gear first: the armature's reflection and the torque limit are expressed through it
    order = sorted(hidden.effects, key=lambda e: e[0] != "torque_gain")
    for name, values in order:
        TRUTH[name](spec, np.asarray(values, float))
    for name, values in hidden.outside:
        OUTSIDE[name](spec, np.asarray(values, float))
    return spec


def generate(hidden: HiddenCase, exps: list[ex.Experiment] | None = None, seed: int = 1,
             noise_rad: float | None = None, jobs: int | None = None,
             exact: bool | None = None) -> list[Run]:
    """"Measured" runs of the case's truth model (device engine; quantised, noisy encoder unless
    the case, or ``exact=True``, asks for exact data).  A ``truth="servo"`` case: the runs of
    :func:`.servo_truth.generate` (``exps``: its experiments, default all; its own encoder,
    so ``noise_rad`` must be None; ``jobs`` unused)."""
    if hidden.truth == "servo":
        if noise_rad is not None:
            raise ValueError("the servo truth has its own encoder noise (servo_truth.NOISE_RAD)")
        return servo_truth.generate(hidden.effects, seed=seed, exact=hidden.exact or bool(exact),
                                    experiments=servo_truth.EXPERIMENTS if exps is None else exps)
    m = truth_spec(hidden).compile()
    exps = exps if exps is not None else experiment_set.experiments()
    st = experiment_set.measurement(hidden.exact or bool(exact), seed, noise_rad)
    return ex.simulate(Device(m), exps, st, jobs=jobs, force_reference=True)


def _assess_corrections(hidden: HiddenCase, corrections: list[dict]) -> tuple[bool, str]:
    """Each attribute the case's nominal holds off must be corrected back: the report's
    correction of it within its 95 % half-width (finite) of the truth's value."""
    truth = truth_joint(hidden)
    for attr, _ in hidden.nominal_joint:
        effect, param = CORRECTED_BY[attr]
        items = [c for c in corrections if c.get("effect") == effect and c.get("parameter") == param]
        if not items:
            return False, f"the nominal's {attr} was not corrected (no {effect}.{param} in corrections)"
        c = items[0]
        u, v = c.get("half_width_95"), c.get("fitted")
        if not (_finite(u) and _finite(v)):
            return False, f"correction {param}: fitted {v}, half-width {u}"
        if abs(v - truth[attr]) > u:
            return False, f"correction {param}: {v:.4g} vs truth {truth[attr]:.4g} (± {u:.2g})"
    return True, "corrections cover the truth"


def error(param: str, fitted: float, truth: float) -> float:
    """``fitted - truth``; for a phase [rad] (``*phase_rad``) wrapped into [-pi, pi)."""
    d = float(fitted) - float(truth)
    if param.endswith("phase_rad"):
        d = (d + math.pi) % (2 * math.pi) - math.pi
    return d


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def assess(hidden: HiddenCase, report: dict) -> tuple[bool, str]:
    """Did the workflow pass this case?  (the bank's criteria; docs/method/discrepancy.md, the hidden-effect bank)

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
    if hidden.nominal_joint:
        ok, why = _assess_corrections(hidden, report.get("corrections", []))
        if not ok:
            return False, why
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
