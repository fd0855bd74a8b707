"""Logs as real devices write them: any sample period, irregular timestamps, the device's own
control period (metadata ``control_period_s``) and torque-off spans (column ``enabled``).

Truths: the closed-form free decay of a damped torsion oscillator (a torque-off run), and a
plain ``mj_step`` loop written here (the slow reference) for a log at 200 Hz with jitter whose
servo closes its loop at 1 kHz and is switched off half-way."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from identification.dataset import Run, read_dataset, resample_uniform, timing, write_run
from identification.errors import UserError
from omni_sim import model as om
from omni_sim.device import Device
from discrepancy.replay import Replayer, control_period_of, prepare_runs
from discrepancy.runs import ON_GRID, ReplayRun

# a rotor on a torsion spring: J = 0.01 kg*m^2, k = 1 N*m/rad (w0 = 10 rad/s), b = 0.004
# N*m*s/rad (zeta = 0.02); no gravity; a 1:1 motor limited to +-5 (N*m = control units)
J, K, B = 0.01, 1.0, 0.004
TIMESTEP = 1e-4
# RK4: its error on this linear oscillator is ~1e-14 rad over 2 s (MuJoCo's first-order
# integrators are O(h) off at the step times: 4.7e-5 rad at h = 0.1 ms, measured)
XML = f"""<mujoco><option timestep="{TIMESTEP}" gravity="0 0 0" integrator="RK4"/>
<worldbody><body name="rotor"><joint name="hinge" axis="0 0 1" stiffness="{K}" damping="{B}"/>
<inertial pos="0 0 0" mass="1" diaginertia="{J} {J} {J}"/></body></worldbody>
<actuator><motor name="drive" joint="hinge" gear="1" ctrllimited="true" ctrlrange="-5 5"/></actuator>
</mujoco>"""
TARGET = om.Target("hinge", "drive")
KP = 2.0  # [N*m/rad]


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_string(XML)


def _log_times(rng, duration=2.0, period=0.005, jitter=0.0004):
    """A host polling at 200 Hz: period 5 ms with N(0, 0.4 ms) jitter, strictly increasing."""
    n = int(duration / period) + 1
    t = np.arange(n) * period + rng.normal(0.0, jitter, n)
    t[0] = 0.0
    return np.maximum.accumulate(t + np.arange(n) * 1e-9)


def _run(name, t, r, theta0, enabled=None, control_period_s=0.001):
    theta = np.full_like(t, theta0)
    extra = {} if enabled is None else {"enabled": np.asarray(enabled, float)}
    meta = {"kind": "other", "kp": KP, "frequency_hz": 0.0, "amplitude_rad": 0.1}
    if control_period_s is not None:
        meta["control_period_s"] = control_period_s
    return Run(name, t, r, theta, np.zeros_like(t), meta, extra)


def _replay(model, runs):
    period = control_period_of(runs)
    rr = prepare_runs(runs, Device(model, period, target=TARGET))
    with Replayer(1, TARGET, period) as rep:
        return rep.simulate([model], rr), rr


def test_torque_off_run_is_the_free_decay_closed_form(model):
    """enabled = 0 throughout: the P law never acts, the rotor released at rest at 0.1 rad
    rings down as theta0 e^(-zeta w0 t) (cos wd t + zeta w0 / wd sin wd t).  Tolerance: the
    linear interpolation between the 1 ms grid samples around each logged time, at most
    T^2 max|theta''| / 8 = (1e-3)^2 * 100 * 0.1 / 8 = 1.25e-6 rad (RK4 adds ~1e-14)."""
    rng = np.random.default_rng(3)
    t = _log_times(rng)
    theta0 = 0.1
    run = _run("off", t, np.full_like(t, 0.3), theta0, enabled=np.zeros_like(t))
    (got,), _ = _replay(model, [run])
    w0 = math.sqrt(K / J)
    zeta = B / (2 * math.sqrt(K * J))
    wd = w0 * math.sqrt(1 - zeta**2)
    want = theta0 * np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta * w0 / wd * np.sin(wd * t))
    assert np.max(np.abs(got - want)) < 1.25e-6
    # the reference (0.3 rad away, kp = 2: a 0.4 N*m command) would have pulled the rotor: the
    # same run switched on ends far from the free decay
    (on,), _ = _replay(model, [_run("on", t, np.full_like(t, 0.3), theta0, enabled=np.ones_like(t))])
    assert np.max(np.abs(on - want)) > 0.05


def test_torque_off_opens_a_dcmotor_winding():
    """A dcmotor's back-EMF (K^2/R = 0.25 N*m*s/rad here, 60x the joint's damping) brakes at zero
    volts, as a shorted winding; torque off opens the winding: the same free decay closed form
    as the plain motor (tolerance as above), and far from the braked decay."""
    xml = XML.replace('<motor name="drive" joint="hinge" gear="1" ctrllimited="true" ctrlrange="-5 5"/>',
                      '<dcmotor name="drive" joint="hinge" motorconst="0.5" resistance="1" '
                      'ctrllimited="true" ctrlrange="-5 5"/>')
    m = mujoco.MjModel.from_xml_string(xml)
    rng = np.random.default_rng(3)
    t = _log_times(rng)
    (got,), _ = _replay(m, [_run("off", t, np.full_like(t, 0.3), 0.1, enabled=np.zeros_like(t))])
    w0 = math.sqrt(K / J)
    zeta = B / (2 * math.sqrt(K * J))
    wd = w0 * math.sqrt(1 - zeta**2)
    want = 0.1 * np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta * w0 / wd * np.sin(wd * t))
    assert np.max(np.abs(got - want)) < 1.25e-6
    d = mujoco.MjData(m)  # zero volts, winding shorted: the braked decay
    d.qpos[0] = 0.1
    braked = []
    for k in range(int(t[-1] / TIMESTEP) + 1):
        braked.append(d.qpos[0])
        mujoco.mj_step(m, d)
    braked = np.interp(t, np.arange(len(braked)) * TIMESTEP, braked)
    assert np.max(np.abs(braked - want)) > 0.05


def _reference_loop(model, t, r, on, theta0, control_period):
    """The slow reference: the servo's loop written out with mj_step, by the documented rule
    (discrepancy.runs.ReplayRun).  Grid time tau_j = j T; the goal and switch of the
    last logged sample at or before tau_j; the command clip(kp (goal - q), -5, 5) (0 when off)
    held for T; the angle at each logged time interpolated linearly between the grid samples
    around it; a logged time within ON_GRID periods of a grid time is that grid time."""
    d = mujoco.MjData(model)
    d.qpos[0] = theta0
    mujoco.mj_forward(model, d)
    sub = int(round(control_period / model.opt.timestep))
    n = int(math.ceil(t[-1] / control_period)) + 2
    q = np.empty(n)
    for j in range(n):
        q[j] = d.qpos[0]
        i = max(0, int(np.searchsorted(t, (j + ON_GRID) * control_period, side="right")) - 1)
        d.ctrl[0] = min(max(KP * (r[i] - q[j]), -5.0), 5.0) if on[i] else 0.0
        for _ in range(sub):
            mujoco.mj_step(model, d)
    out = np.empty_like(t)
    for i, ti in enumerate(t):
        s = ti / control_period
        j = int(math.floor(s + ON_GRID))
        f = s - j
        out[i] = q[j] if abs(f) < ON_GRID else q[j] + f * (q[j + 1] - q[j])
    return out


def test_200hz_log_with_a_1khz_loop_and_a_torque_off_span(model):
    """A jittered 200 Hz log of a servo whose loop runs at 1 kHz, a square goal, switched off
    at t = 1.2 s: the replay equals the hand-written loop.  Tolerance 1e-12 rad: the same
    mj_step arithmetic on both sides; only the interpolation at the logged times is computed
    in another order (a few ulp)."""
    rng = np.random.default_rng(5)
    t = _log_times(rng)
    r = np.where((t > 0.3) & (t < 0.9), 0.2, -0.1)
    on = t < 1.2
    run = _run("square", t, r, 0.0, enabled=on)
    (got,), (rr,) = _replay(model, [run])
    want = _reference_loop(model, t, r, on, 0.0, 0.001)
    assert np.max(np.abs(got - want)) < 1e-12
    assert rr.steps == int(math.floor(t[-1] / 0.001)) + 2  # last logged time between grid samples
    # without control_period_s the loop runs at the log's own rate: an even 5 ms log is a 200 Hz
    # loop, a visibly different trajectory; a jittered log's median period (not a multiple of
    # the timestep) is refused with the metadata's name
    even = np.arange(len(t)) * 0.005
    slow = _run("square", even, np.interp(even, t, r), 0.0, enabled=even < 1.2, control_period_s=None)
    (got_slow,), (rr_slow,) = _replay(model, [slow])
    assert rr_slow.period == pytest.approx(0.005) and rr_slow.steps == len(even)
    fast = _run("square", even, slow.r, 0.0, enabled=even < 1.2)
    (got_fast,), _ = _replay(model, [fast])
    assert np.max(np.abs(got_slow - got_fast)) > 1e-3
    with pytest.raises(UserError, match="control_period_s"):
        prepare_runs([_run("square", t, r, 0.0, enabled=on, control_period_s=None)],
                     Device(model, 0.001, target=TARGET))


def test_a_log_at_the_control_period_is_replayed_sample_for_sample(model):
    """Logged at the loop's own 1 ms: every logged time is on the control grid (no
    interpolation) and the reference is used sample for sample."""
    t = np.arange(800) * 0.001
    r = 0.1 * np.sin(2 * math.pi * 2 * t)
    run = _run("sine", t, r, 0.0, control_period_s=None)
    (rr,) = prepare_runs([run], Device(model, 0.001, target=TARGET))
    assert rr.steps == len(t)
    grid_r, on = rr.grid_inputs()
    assert on is None and np.array_equal(grid_r, r)
    grid = np.arange(len(t)) * 3.0
    assert np.array_equal(rr.at_logged_times(grid), grid)


def test_data_files_round_trip_and_resampling(tmp_path):
    """Irregular timestamps and ``enabled`` survive the files; read for identification
    (uniform) the run is resampled onto its median period with ``enabled`` held."""
    rng = np.random.default_rng(7)
    t = _log_times(rng, duration=1.0)
    on = (t < 0.5).astype(float)
    run = _run("log", t, np.sin(t), 0.0, enabled=on)
    run.theta = np.cos(t)
    write_run(tmp_path, run)
    (back,) = read_dataset(tmp_path, require_pose=False, uniform=False)
    assert np.array_equal(back.t, t) and np.array_equal(back.enabled, on > 0.5)
    assert not back.uniform
    (uni,) = read_dataset(tmp_path, require_pose=False)
    assert uni.uniform and uni.dt == pytest.approx(np.median(np.diff(t)))
    assert np.max(np.abs(uni.theta - np.cos(uni.t))) < 1e-4  # linear interpolation of a cosine
    assert uni.meta["resampled_from"]["max_gap_s"] == pytest.approx(np.max(np.diff(t)))
    assert np.array_equal(uni.enabled, np.asarray(on)[np.searchsorted(t, uni.t, side="right") - 1] > 0.5)
    assert resample_uniform(uni) is uni


@pytest.mark.parametrize("damage, words", [
    (lambda c: c.replace("\n1,", "\n2,", 1), ["enabled", "0 or 1"]),
])
def test_bad_enabled_column(tmp_path, damage, words):
    t = np.arange(50) * 0.005
    run = _run("log", t, np.zeros_like(t), 0.0, enabled=np.ones_like(t))
    write_run(tmp_path, run)
    csv = tmp_path / "log.csv"
    lines = csv.read_text().splitlines()
    head = lines[0].split(",")
    k = head.index("enabled")
    parts = lines[5].split(",")
    parts[k] = "2"
    lines[5] = ",".join(parts)
    csv.write_text("\n".join(lines) + "\n")
    with pytest.raises(UserError) as exc:
        read_dataset(tmp_path, require_pose=False, uniform=False)
    assert all(w in str(exc.value) for w in words)


def test_control_period_errors(tmp_path, model):
    t = np.arange(100) * 0.005
    a = _run("a", t, np.zeros_like(t), 0.0, control_period_s=0.001)
    b = _run("b", t, np.zeros_like(t), 0.0, control_period_s=0.002)
    with pytest.raises(UserError, match="different control periods"):
        control_period_of([a, b])
    c = _run("c", t, np.zeros_like(t), 0.0, control_period_s=0.00015)  # not a multiple of 0.1 ms
    with pytest.raises(UserError, match="whole multiple"):
        prepare_runs([c], Device(model, 0.001, target=TARGET))
    meta_bad = _run("d", t, np.zeros_like(t), 0.0, control_period_s=None)
    meta_bad.meta["control_period_s"] = -1
    write_run(tmp_path, meta_bad)
    with pytest.raises(UserError, match="control_period_s"):
        read_dataset(tmp_path, require_pose=False)


def test_replay_run_grid_of_a_truncated_run():
    """The first samples of a run keep its control period and switch."""
    t = np.arange(40) * 0.005
    rr = ReplayRun("x", "other", t, np.zeros(40), np.zeros(40), np.zeros(40), 0.005, 1.0, (), 0.0,
                   0.0, {}, 0.001, np.arange(40) % 2 == 0)
    short = rr.truncated(10)
    assert short.period == 0.001 and len(short.enabled) == 10
    assert short.steps == 46  # 0 .. 45 ms on the 1 ms grid


def test_batches_of_the_replay_change_nothing_but_memory(model, monkeypatch):
    """Many models on a run are stepped in batches of BATCH_SAMPLES control periods; every
    row's trajectory is its own, so batches of 1 row give the same arrays bit for bit."""
    from discrepancy import replay
    rng = np.random.default_rng(11)
    t = _log_times(rng, duration=0.5)
    run = _run("square", t, np.where(t > 0.1, 0.2, 0.0), 0.0, enabled=t < 0.4)
    models = []
    for k in range(5):
        m = mujoco.MjModel.from_xml_string(XML)
        m.dof_damping[0] = B * (1 + k)
        models.append(m)
    (rr,) = prepare_runs([run], Device(model, 0.001, target=TARGET))
    with Replayer(2, TARGET, 0.001) as rep:
        whole = rep.simulate(models, [rr])
    monkeypatch.setattr(replay, "BATCH_SAMPLES", 1)
    with Replayer(2, TARGET, 0.001) as rep:
        one_by_one = rep.simulate(models, [rr])
    assert all(np.array_equal(a, b) for a, b in zip(whole, one_by_one))
    assert not np.array_equal(whole[0], whole[4])
