"""omni_sim.runtime: the drive laws in a user's plain ``mujoco.mj_step`` loop, against our engine.

The reference is the engine (:class:`omni_sim.device.Engine`, one row and the batch the
discrepancy replay steps); the loop under test is written here from the dataset contract alone:
``v_k = clip(kp (r_k - y_k), +-limit)`` with ``y_k`` the joint angle at ``t_k = k P``, held for
the ``P / timestep`` physics steps of the period, ``cb(model, data)`` before each ``mj_step``.
"""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from omni_app import discrepancy_report as rp
from omni_sim import model as om
from omni_sim import runtime
from omni_sim.device import DRIVE_LAWS, Device, Engine, run_p_loop
from discrepancy import effects as fx

HINGE = om.Target("hinge", "drive")
SERVO = om.Target("pivot", "servo")


def _hinge(load=None, asym=None, family=None, limit=None):
    """A damped hinge under gravity-free motor drive (as tests/test_drive_friction.py's)."""
    custom = ""
    if load is not None:
        custom += f'<numeric name="load_friction" data="{load[0]} {load[1]}"/>'
    if asym is not None:
        custom += f'<numeric name="friction_asymmetry" data="{asym}"/>'
    if family is not None:
        custom += f'<numeric name="friction_family" data="{" ".join(map(str, family))}"/>'
    if limit is not None:
        custom += f'<numeric name="current_limit" data="{limit[0]} {limit[1]}"/>'
    return mujoco.MjModel.from_xml_string(f"""<mujoco><option timestep="0.001" gravity="0 0 0"/>
    <worldbody><body><joint name="hinge" axis="0 0 1" damping="0.02" frictionloss="0.05"/>
    <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody>
    <actuator><motor name="drive" joint="hinge" gear="2" ctrllimited="true" ctrlrange="-1 1"/></actuator>
    <sensor><actuatorfrc actuator="drive"/></sensor><custom>{custom}</custom></mujoco>""")


def _servo_spec(load=None) -> mujoco.MjSpec:
    """The geared-servo pendulum (models/servo_pendulum/), its load_friction set to ``load``."""
    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    if load is not None:
        fx.get("load_friction").write(spec, np.array(load, float), SERVO)
    return spec


def _runs(n: int, dt: float) -> list[tuple[float, np.ndarray, float]]:
    """A few runs ``(theta0, reference, kp)``: steps both ways, a sine, a hold."""
    t = np.arange(n) * dt
    return [(0.0, np.where(t % 0.6 < 0.3, 0.3, -0.3), 3.0),
            (0.1, 0.2 * np.sin(2 * np.pi * 1.5 * t), 5.0),
            (-0.05, np.full(n, 0.25), 2.0)]


def _plain_p_loop(model, target, theta0, r, kp, period, cb=None) -> np.ndarray:
    """The dataset contract's P loop in plain MuJoCo (no omni_sim but the callback ``cb``)."""
    q = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, target.joint)]
    a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, target.actuator)
    limit = model.actuator_ctrlrange[a, 1]
    substeps = round(period / model.opt.timestep)
    d = mujoco.MjData(model)
    d.qpos[q] = theta0
    mujoco.mj_forward(model, d)
    theta = np.empty(len(r))
    for k in range(len(r)):
        theta[k] = d.qpos[q]
        d.ctrl[a] = np.clip(kp * (r[k] - theta[k]), -limit, limit)
        for _ in range(substeps):
            if cb is not None:
                cb(model, d)
            mujoco.mj_step(model, d)
    return theta


def _engine(model, target, runs, period, batch=True) -> np.ndarray:
    """The engine's replay of ``runs`` (a batch as the discrepancy replay, or one row each)."""
    dev = Device(model, period, target)
    if not batch:
        return np.vstack([run_p_loop(Engine([dev], [th0], [None]), r[None], kp)["theta"]
                          for th0, r, kp in runs])
    return run_p_loop(Engine([dev] * len(runs), [th0 for th0, _, _ in runs], [None] * len(runs), nthread=2),
                      np.vstack([r for _, r, _ in runs]), np.array([kp for *_, kp in runs]))["theta"]


def _plain(model, target, runs, period, with_runtime=True, **kw) -> np.ndarray:
    """Each run in its own copy of ``model`` (the callback writes the model's frictionloss)."""
    out = []
    for th0, r, kp in runs:
        m = mujoco.MjModel.from_xml_string(model) if isinstance(model, str) else _copy(model)
        cb = runtime.drive_laws(m, **kw) if with_runtime else None
        out.append(_plain_p_loop(m, target, th0, r, kp, period, cb))
    return np.vstack(out)


def _copy(model: mujoco.MjModel) -> mujoco.MjModel:
    import copy
    return copy.deepcopy(model)


@pytest.mark.parametrize("laws", [dict(load=(0.25, 0.6), asym=0.01), dict(asym=0.02), dict(load=(0.1, 1.5)),
                                  dict(family=(0.2, 0.8, 0.04, 0.3, 1.5)), dict(limit=(0.6, 0.02)),
                                  dict(family=(0.1, 0.5, 0.03, 0.1, 2.0), limit=(0.8, 0.01))])
def test_the_runtime_replays_like_the_engine(laws):
    """Two physics steps per period (the level is set at the period's start only): the plain
    loop with the runtime equals the one-row engine bit for bit (the same mj_step arithmetic
    and the same law terms) and the batch engine to 1e-6 rad (measured up to 6.1e-16: rollout's
    last bits, see DriveFriction); without the runtime it is another model."""
    model, period = _hinge(**laws), 0.002
    runs = _runs(1000, period)
    plain = _plain(model, HINGE, runs, period, control_period_s=period, joint="hinge", actuator="drive")
    assert np.array_equal(plain, _engine(model, HINGE, runs, period, batch=False))
    assert np.max(np.abs(plain - _engine(model, HINGE, runs, period))) < 1e-6
    bare = _plain(model, HINGE, runs, period, with_runtime=False)
    assert np.max(np.abs(bare - plain)) > 1e-3


def test_the_geared_servo_with_load_friction():
    """The servo pendulum with a load law (mu_drive 0.2, mu_back 1.2: a self-locking train),
    its own kp 40 V/rad and 12 V limit, 1 ms period, under gravity."""
    model = _servo_spec((0.2, 1.2)).compile()
    t = np.arange(1500) * 1e-3
    runs = [(0.0, np.where(t % 0.5 < 0.25, 0.4, -0.2), 40.0), (0.3, 0.3 * np.sin(2 * np.pi * 2 * t), 40.0)]
    plain = _plain(model, SERVO, runs, 1e-3, control_period_s=1e-3, joint="pivot", actuator="servo")
    assert np.max(np.abs(plain - _engine(model, SERVO, runs, 1e-3))) < 1e-6
    assert np.max(np.abs(_plain(model, SERVO, runs, 1e-3, with_runtime=False) - plain)) > 1e-3


def _outcome(spec, effects, period):
    """What model_xml reads of a discrepancy outcome: the patched spec, the named effects, the
    target and the runs' control period."""
    # each effect entry as the workflow's report writes it: its values, their units and nominals
    effects = [{**e, "units": {k: "-" for k in e["parameters"]},
                "nominal": {k: 0.0 for k in e["parameters"]}} for e in effects]
    report = {"effects": effects, "settings": {"joint": SERVO.joint, "actuator": SERVO.actuator}}
    return SimpleNamespace(report=report, spec=spec, runs=[SimpleNamespace(period=period)])


def test_model_xml_reloaded_with_the_runtime_is_the_patched_model():
    """model.xml of a named load_friction, read back from its text, declares its control
    period (2 ms here, two physics steps) and target: ``drive_laws(model)`` with no argument
    replays like the engine on the patched spec (1e-6 rad); its header says the runtime is
    needed and how to call it; without the runtime it is not the named model."""
    spec, period = _servo_spec((0.15, 0.9)), 2e-3
    out = _outcome(spec, [{"name": "load_friction", "parameters": {"mu_drive": 0.15, "mu_back": 0.9}}], period)
    xml = rp.model_xml(out)
    head = xml[: xml.index("<mujoco")]
    assert f"runtime: {runtime.RUNTIME}" in head and "NOT the named model" in head
    assert "cb = drive_laws(model) once" in head and "cb(model, data) before each mujoco.mj_step" in head
    assert "load_friction (mu_drive=0.15, mu_back=0.9)" in head and "0.002 s" in head
    assert "not carried" not in head
    runs = _runs(800, period)
    runs = [(th0, r, 40.0) for th0, r, _ in runs]
    want = _engine(spec.compile(), SERVO, runs, period)
    got = _plain(xml, SERVO, runs, period)
    assert np.max(np.abs(got - want)) < 1e-6
    m = mujoco.MjSpec.from_string(xml).compile()
    cb = runtime.drive_laws(m)
    assert (cb.substeps, cb.laws) == (2, {"load_friction": (0.15, 0.9, 0.0)})  # b_emf read as 0
    assert np.max(np.abs(_plain(xml, SERVO, runs, period, with_runtime=False) - want)) > 1e-3
    assert "needs the runtime `omni_sim.runtime:drive_laws` for load_friction" in rp._md_runtime(out)


def test_a_model_without_a_law_says_plain_mujoco():
    """The servo pendulum's nominal declares load_friction at zero (no effect) and the Omni's
    scene none: both run in plain MuJoCo; model.xml says so and gets no runtime declarations."""
    for spec, name in ((_servo_spec(), "none"), (mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE)), "time_delay")):
        out = _outcome(spec, [{"name": name, "parameters": {}}], 1e-3)
        xml = rp.model_xml(out)
        head = xml[: xml.index("<mujoco")]
        assert "runs in plain MuJoCo, no runtime" in head
        assert "runtime:" not in head and "NOT" not in head and runtime.TARGET_TEXT not in xml
        assert runtime.runtime_note(spec) == (False, ["runs in plain MuJoCo, no runtime"])
        assert rp._md_runtime(out) == "It runs in plain MuJoCo, no runtime. "
        assert runtime.drive_laws(spec.compile(), joint=SERVO.joint if name == "none" else None,
                                  actuator=SERVO.actuator if name == "none" else None).laws == {}


def test_a_named_effect_model_xml_cannot_hold_is_said_so():
    out = _outcome(_servo_spec(), [{"name": "thermal_drift", "parameters": {"k": 1.0}}], 1e-3)
    head = rp.model_xml(out).split("<mujoco")[0]
    assert "thermal_drift: not carried by model.xml" in head
    assert "thermal_drift is not carried by model.xml" in rp._md_runtime(out)


def test_a_law_only_this_process_knows_is_said_so(monkeypatch):
    """A law registered by user code (register_drive_law) travels as values only."""
    from omni_sim import device as dv
    registry = dict(dv.DRIVE_LAWS)  # the registry's room (device.laws), its names elsewhere
    for module in (dv.laws, dv, runtime):
        monkeypatch.setattr(module, "DRIVE_LAWS", registry)
    dv.register_drive_law(dv.DriveLaw("speed_friction", ("c",), lambda v, w, tau: v[:, 0] * np.abs(w),
                                      lambda v: None))
    spec = _servo_spec()
    spec.add_numeric(name="speed_friction", data=[0.03])
    needs, lines = runtime.runtime_note(spec)
    assert needs and any(line.startswith("speed_friction: a law registered outside omni_sim") and
                         "not carried by model.xml" in line for line in lines)


def test_the_runtime_needs_a_period_and_its_target():
    m = _hinge(asym=0.01)
    with pytest.raises(ValueError, match="control_period_s="):
        runtime.drive_laws(m, joint="hinge", actuator="drive")
    with pytest.raises(ValueError, match="joint= and actuator="):
        runtime.drive_laws(m, 1e-3)


def test_every_library_effect_is_native_mjcf_or_a_runtime_law():
    """Each library effect at a value off the nominal, written into the servo pendulum and
    read back from model.xml's text: plain MuJoCo (with the runtime when the header says it
    is needed) replays like the engine on the spec (1e-6 rad); the only custom numerics any
    effect writes are drive laws (and the current limit) the runtime applies.  (arm_mass needs the Omni's arm: it
    writes body masses, read back from the Omni scene's XML below.)"""
    spec = _servo_spec()
    t = np.arange(600) * 1e-3
    runs = [(0.0, np.where(t % 0.3 < 0.15, 0.3, -0.1), 40.0)]
    checked = []
    for eff in fx.LIBRARY:
        if not eff.applies(spec, SERVO):
            continue
        e = fx.for_model(eff, spec, SERVO)
        x = e.clip(fx.nominal_values(e, spec, SERVO) + 3 * e.scales())
        patched = fx.apply(spec, [(e, x)], SERVO)
        out = _outcome(patched, [{"name": eff.name, "parameters": {}}], 1e-3)
        xml = rp.model_xml(out)
        numerics = {n.name for n in mujoco.MjSpec.from_string(xml).numerics}
        assert numerics <= set(DRIVE_LAWS) | {runtime.PERIOD_NUMERIC, "current_limit", "load_friction_smooth"}, eff.name
        needs = "runtime:" in xml.split("<mujoco")[0]
        assert needs == (eff.name in ("load_friction", "current_limit")), eff.name
        got = _plain(xml, SERVO, runs, 1e-3, with_runtime=needs)
        want = _engine(patched.compile(), SERVO, runs, 1e-3, batch=False)
        assert np.max(np.abs(got - want)) < 1e-6, eff.name
        checked.append(eff.name)
    assert set(checked) == set(fx.NAMES) - {"arm_mass"}
    omni = mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))
    e = fx.get("arm_mass")
    x = e.clip(fx.nominal_values(e, omni) * 1.3)
    back = mujoco.MjSpec.from_string(fx.apply(omni, [(e, x)]).to_xml())
    # MjSpec.to_xml writes 6 significant digits (0.08942492 -> "0.0894249"): half a unit of
    # the 6th digit is at most 5e-6 relative
    np.testing.assert_allclose(fx.nominal_values(e, back), x, rtol=5e-6)


def test_a_control_callback_would_not_be_the_engine():
    """Why the runtime is not offered as ``mujoco.set_mjcb_control``: MuJoCo calls it inside
    mj_step after the step's friction rows are built, so the level acts a step late; the same
    callback installed there leaves the engine's trajectory (measured 2.1e-2 rad here)."""
    model, period = _hinge(load=(0.25, 0.6), asym=0.01), 0.002
    runs = _runs(1000, period)[:1]
    want = _engine(model, HINGE, runs, period, batch=False)
    m = _copy(model)
    cb = runtime.drive_laws(m, period, "hinge", "drive")
    mujoco.set_mjcb_control(lambda mm, dd: cb(mm, dd))
    try:
        late = _plain_p_loop(m, HINGE, *runs[0], period)
    finally:
        mujoco.set_mjcb_control(None)
    assert np.max(np.abs(late - want[0])) > 1e-4


@pytest.mark.parametrize("name", [e.name for e in fx.STAGED] + ["current_limit"])
def test_every_staged_effect_is_native_mjcf_or_a_runtime_law(name):
    """As the library's (above), for the staged effects (the friction family's variants, the
    current limit) at values where they act: written into the servo pendulum, read back from
    the MJCF text with the runtime's declarations, plain MuJoCo (with the runtime when the
    header says so) replays like the engine on the spec (1e-6 rad); both need the runtime."""
    values = {"friction_family_stribeck": [0.2, 0.6, 0.36, 0.03, 0.2, 1.5], "current_limit": [0.8, 0.36],
              "load_friction_smooth": [0.2, 0.2, 0.36, 0.02]}
    spec = _servo_spec()
    e = fx.for_model(fx.get(name), spec, SERVO)
    patched = fx.apply(spec, [(e, np.array(values[name]))], SERVO)
    needs = runtime.runtime_note(patched)[0]
    assert needs
    xml = runtime.declare(patched, SERVO.joint, SERVO.actuator, 1e-3).to_xml()
    numerics = {n.name for n in mujoco.MjSpec.from_string(xml).numerics}
    assert numerics <= set(DRIVE_LAWS) | {runtime.PERIOD_NUMERIC, "current_limit", "load_friction_smooth"}
    t = np.arange(600) * 1e-3
    runs = [(0.0, np.where(t % 0.3 < 0.15, 0.3, -0.1), 40.0)]
    want = _engine(patched.compile(), SERVO, runs, 1e-3, batch=False)
    assert np.max(np.abs(_plain(xml, SERVO, runs, 1e-3, with_runtime=needs) - want)) < 1e-6
    if needs:  # the law matters on these runs: plain MuJoCo alone is another model
        assert np.max(np.abs(_plain(xml, SERVO, runs, 1e-3, with_runtime=False) - want)) > 1e-4
