"""Your own robot (docs/method/discrepancy.md): the device, the replay and ``omni discrepancy`` on a user's
single-joint model without the Omni's arm (``--joint``/``--actuator``), the P law's saturation
from the metadata, the two-mass start state, and the pendulum example (examples/pendulum)."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from identification.dataset import Run, read_dataset, write_run
from identification.errors import UserError
from omni_app.cli import main
from omni_sim import model as om
from omni_sim.device import Device, Engine, run_p_loop
from discrepancy.replay import Replayer, prepare_runs
from discrepancy.workflow import run_discrepancy

ROOT = Path(__file__).resolve().parents[1]
PENDULUM = ROOT / "examples" / "pendulum"
MODEL = PENDULUM / "model.xml"
TARGET = om.Target("pivot", "servo")


def _make_data():
    spec = importlib.util.spec_from_file_location("pendulum_make_data", PENDULUM / "make_data.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# --- names: the target's hinge and actuator ----------------------------------------------------
def _xml(tmp_path, body: str, actuators: str) -> Path:
    p = tmp_path / "m.xml"
    p.write_text(f'<mujoco><option timestep="0.001"/><worldbody>{body}</worldbody>'
                 f'<actuator>{actuators}</actuator></mujoco>')
    return p


HINGE = ('<body><joint name="pivot" axis="0 1 0"/><geom size="0.02" pos="0 0 -0.2"/></body>'
         '<body><joint name="other" axis="0 1 0"/><geom size="0.02" pos="0 0 -0.2"/></body>')


@pytest.mark.parametrize("body, acts, target, words", [
    (HINGE, '<motor name="servo" joint="pivot"/>', om.Target("nope", "servo"), ["no joint", "'nope'"]),
    ('<body><joint name="pivot" type="slide"/><geom size="0.02"/></body>', '<motor name="servo" joint="pivot"/>',
     TARGET, ["'pivot'", "hinge"]),
    (HINGE, '<motor name="servo" joint="pivot"/>', om.Target("pivot", "nope"), ["no actuator", "'nope'"]),
    (HINGE, '<motor name="servo" joint="other"/>', TARGET, ["'servo'", "must act on joint 'pivot'"]),
    (HINGE, '<motor name="m" joint="pivot"/><dcmotor name="servo" joint="pivot" input="none" resistance="1" lugre="1 0 0.01 0.01 0.1"/>',
     TARGET, ["'servo'", "no control"]),
])
def test_target_errors(tmp_path, body, acts, target, words):
    path = _xml(tmp_path, body, acts)
    with pytest.raises(UserError) as exc:
        om.load_model(path, target=target)
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_omni_index_unchanged_and_pendulum_has_no_arm():
    scene = om.load_model()
    assert om.index(scene, target=om.OMNI) == om.index(scene)  # the Omni's contract either way
    assert om.index(scene).has_arm
    pend = om.load_model(MODEL, target=TARGET)
    ix = om.index(pend, target=TARGET)
    assert not ix.has_arm and ix.shoulder_qpos is None and ix.elbow_qpos is None
    assert ix.yaw_qpos == pend.jnt_qposadr[mujoco.mj_name2id(pend, mujoco.mjtObj.mjOBJ_JOINT, "pivot")]
    with pytest.raises(UserError, match="contract's joint"):  # without a target: the Omni's contract
        om.index(pend)
    assert Device(pend, target=TARGET).voltage_limit == 5.0 and Device(pend, target=TARGET).torque_constant == 0.07


# --- the two-mass start state -------------------------------------------------------------------
TWO_MASS = """
<mujoco>
  <option timestep="0.001" integrator="implicitfast"/>
  <worldbody>
    <body name="rotor"><joint name="motor" axis="0 0 1" armature="1e-4"/>
      <geom type="cylinder" size="0.02 0.01" mass="0.05"/></body>
    <body name="turret" pos="0 0 0.1"><joint name="motor_output" axis="0 0 1" damping="0.001"/>
      <geom type="box" size="0.05 0.02 0.02" mass="0.3"/></body>
  </worldbody>
  <tendon>
    <fixed name="cable" stiffness="20" damping="0.01">
      <joint joint="motor" coef="{c_rotor}"/><joint joint="motor_output" coef="{c_out}"/>
    </fixed>
  </tendon>
  <actuator><motor name="drive" joint="motor" gear="0.5" ctrlrange="-1 1"/></actuator>
</mujoco>"""


@pytest.mark.parametrize("c_rotor, c_out", [(1.0, -1.0), (0.25, -1.0)])
def test_two_mass_drive_starts_unstrained_and_rests(c_rotor, c_out):
    """The output hinge starts where the cable (fixed tendon) has zero length; with zero command
    nothing moves (vertical axes: no gravity torque).  The tendon's spring rests at length 0
    (springlength computed at qpos0 = 0), so a strained start would move."""
    model = mujoco.MjModel.from_xml_string(TWO_MASS.format(c_rotor=c_rotor, c_out=c_out))
    target = om.Target("motor", "drive")
    dev = Device(model, target=target)
    out_adr = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "motor_output")]
    assert dev.coupled == [(int(out_adr), -c_rotor / c_out)]
    theta0 = 0.3
    d = dev.start_data(theta0, None)
    assert d.ten_length[0] == pytest.approx(0.0, abs=1e-15)
    assert d.qpos[out_adr] == pytest.approx(-c_rotor * theta0 / c_out, rel=1e-15)
    # the same start without the coupling rule is strained (so the check above can fail)
    naive = mujoco.MjData(model)
    naive.qpos[dev.ix.yaw_qpos] = theta0
    mujoco.mj_forward(model, naive)
    assert abs(naive.ten_length[0]) > 0.07 and abs(naive.qfrc_passive).max() > 1.0
    # zero command: one row (mj_step) and a batch (rollout) both stay at rest
    for B in (1, 2):
        with Engine([dev] * B, [theta0] * B, [None] * B, nthread=1) as eng:
            for _ in range(300):
                eng.apply(np.zeros(B))
            assert np.all(eng.yaw() == theta0) and np.all(eng.yaw_velocity() == 0.0)
            if B == 1:
                assert eng.data.qpos[out_adr] == d.qpos[out_adr]
            else:
                assert np.all(eng.x[:, 1 + out_adr] == d.qpos[out_adr])


# --- the engine without the arm; the P law's saturation ---------------------------------------
def test_engine_without_arm_qpos_is_nan_for_the_arm():
    dev = Device(om.load_model(MODEL, target=TARGET), target=TARGET)
    for B in (1, 3):
        with dev.engine([0.1] * B, [None] * B, nthread=1) as eng:
            q = eng.qpos()
            assert q.shape == (B, 3) and np.all(q[:, 0] == 0.1) and np.all(np.isnan(q[:, 1:]))
            out = run_p_loop(eng, np.full((B, 50), 0.2), 10.0, record_arm=True)
            assert np.all(np.isnan(out["q1"])) and np.all(np.isnan(out["q2"]))
            assert np.all(np.isfinite(out["theta"]))


def _hand_loop(model, theta0, r, kp, limit):
    """An independent closed loop: plain mj_step, the P law clipped at ``limit`` and the
    actuator's ctrlrange clamping inside MuJoCo."""
    d = mujoco.MjData(model)
    d.qpos[0] = theta0
    mujoco.mj_forward(model, d)
    th, v = np.empty(len(r)), np.empty(len(r))
    for k, rk in enumerate(r):
        th[k] = d.qpos[0]
        v[k] = min(max(kp * (rk - th[k]), -limit), limit)
        d.ctrl[0] = v[k]
        mujoco.mj_step(model, d)
    return th, v


@pytest.mark.parametrize("limit, applied", [(2.0, 2.0), (8.0, 5.0)])
def test_command_limit_saturates_the_p_law(limit, applied):
    """A metadata ``command_limit`` below the actuator's ctrlrange (5 A) saturates the P law
    there; above it the drive's clip wins.  Replay == an independent mj_step loop, bit for bit:
    both make the same calls (mj_step, the P law's elementwise multiply and clip)."""
    model = om.load_model(MODEL, target=TARGET)
    dev = Device(model, target=TARGET)
    r = np.full(400, 1.0)  # kp * 1 rad = 10 A: far beyond both limits at the start
    with dev.engine([0.0], [None], nthread=1) as eng:
        out = run_p_loop(eng, r[None, :], 10.0, command_limit=limit)
    assert np.max(np.abs(out["v"])) == applied
    th, _ = _hand_loop(model, 0.0, r, 10.0, min(limit, 5.0))
    np.testing.assert_array_equal(out["theta"][0], th)
    run = Run("step", np.arange(400) * 1e-3, r, th, np.clip(10 * (r - th), -applied, applied),
              {"kind": "step", "kp": 10.0, "command_limit": limit, "frequency_hz": 0.0,
               "amplitude_rad": 1.0})
    rr = prepare_runs([run, run], Device(model, target=TARGET))
    assert rr[0].gamma_set_deg == () and rr[0].command_limit == limit
    with Replayer(1, TARGET) as rep:
        sim = rep.simulate([model], rr[:1])[0]
    np.testing.assert_array_equal(sim, th)


def test_prepare_runs_pose_and_command_limit_checks():
    pend = om.load_model(MODEL, target=TARGET)
    n = 300
    meta = {"kind": "sine", "kp": 10.0, "frequency_hz": 1.0, "amplitude_rad": 0.1}
    run = Run("a", np.arange(n) * 1e-3, np.zeros(n), np.zeros(n), np.zeros(n), dict(meta))
    assert prepare_runs([run], Device(pend, target=TARGET))[0].command_limit == math.inf
    for bad in (-1.0, 0.0, "4", True, float("nan")):
        r2 = Run("a", run.t, run.r, run.theta, run.v, {**meta, "command_limit": bad})
        with pytest.raises(UserError, match="command_limit"):
            prepare_runs([r2], Device(pend, target=TARGET))
    # the Omni still needs its pose
    with pytest.raises(UserError, match="gamma1"):
        prepare_runs([run], Device.load())


def test_read_dataset_without_pose(tmp_path):
    n = 10
    write_run(tmp_path, Run("a", np.arange(n) * 1e-3, np.zeros(n), np.zeros(n), np.zeros(n),
                            {"kind": "sine", "kp": 10.0, "frequency_hz": 1.0, "amplitude_rad": 0.1}))
    with pytest.raises(UserError, match="gamma1_deg"):
        read_dataset(tmp_path)
    assert read_dataset(tmp_path, require_pose=False)[0].meta["kp"] == 10.0


# --- the command line ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def quick_data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pendulum_quick")
    md = _make_data()
    runs = md.generate(quick=True)
    for r in runs:
        write_run(folder, r)
    return folder, runs, md


@pytest.mark.parametrize("extra, words", [
    (["--joint", "nope", "--actuator", "servo"], ["no joint", "'nope'"]),
    (["--joint", "pivot"], ["'yaw_motor'"]),  # the default actuator does not exist here
    (["--joint", "pivot", "--actuator", "servo", "--friction", "lugre"], ["--friction"]),
])
def test_cli_errors(quick_data, tmp_path, capsys, extra, words):
    folder, _, _ = quick_data
    args = ["discrepancy", "--measured", str(folder), "--out", str(tmp_path / "o")]
    if "--friction" not in extra:
        args += ["--model", str(MODEL)]
    assert main(args + extra) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and err.count("\n") == 1 and all(w in err for w in words), err
    assert not (tmp_path / "o").exists()


def test_cli_demo_refuses_a_target(capsys, tmp_path):
    assert main(["discrepancy", "--demo", "--joint", "pivot", "--out", str(tmp_path / "o")]) == 2
    assert "--demo" in capsys.readouterr().err


def test_cli_help_names_the_flags(capsys):
    with pytest.raises(SystemExit):
        main(["discrepancy", "--help"])
    out = capsys.readouterr().out
    assert "--joint NAME" in out and "--actuator NAME" in out and "command_limit" in out


# --- the worked example -------------------------------------------------------------------------
def _check(report, truth_fc):
    names = [e["name"] for e in report["effects"]]
    assert names == ["coulomb_friction"], report["rounds"]
    e = report["effects"][0]
    fit, half = e["parameters"]["frictionloss_nm"], e["uncertainty"]["frictionloss_nm"]
    assert abs(fit - truth_fc) <= half, (fit, half)
    assert report["shrink_factor"] >= 3.0


@pytest.mark.slow
def test_pendulum_quick_names_the_hidden_friction(quick_data):
    """Four short runs from truth.xml (hidden bearing friction 0.015 N*m); the workflow sees
    model.xml only.  Candidates restricted to three that all act like extra damping."""
    _, runs, md = quick_data
    out = run_discrepancy(runs, MODEL, target=TARGET, jobs=2, max_effects=1,
                          candidates=("coulomb_friction", "viscous_damping", "torque_gain"))
    _check(out.report, 0.015)


@pytest.mark.slow
def test_pendulum_example_through_the_cli(tmp_path, capsys):
    """docs/method/discrepancy.md's worked example: the full data set, the whole library, the command line."""
    md = _make_data()
    assert md.main(["--out", str(tmp_path / "measured")]) == 0
    assert main(["discrepancy", "--measured", str(tmp_path / "measured"), "--model", str(MODEL),
                 "--joint", "pivot", "--actuator", "servo", "--out", str(tmp_path / "out")]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    _check(report, 0.015)
    # the example's runs give no control_period_s: said once on stderr, recorded per run
    notes = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("note:")]
    assert len(notes) == 1 and "10 run(s) give no control_period_s" in notes[0], notes
    assert [s["control_period_given"] for s in report["sampling"]] == [False] * 10
