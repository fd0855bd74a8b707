"""The geared-servo truth (omni_sim/discrepancy/servo_truth.py): its load-dependent and
direction-dependent friction law step by step, the nominal model when the asymmetry and both
coefficients are 0 (bit for bit, and the device's own loop on regular times), self-locking,
energy in free swing, where a free fall stops with an asymmetry, and the host's log (irregular
times, goal held, torque-off spans, encoder counts)."""

import math

import mujoco
import numpy as np
import pytest

from identification.dataset import write_run
from omni_sim import model as om
from omni_sim.device import Device, run_p_loop
from omni_sim.discrepancy import hidden
from omni_sim.discrepancy import servo_truth as st

DT = st.CONTROL_PERIOD_S


@pytest.fixture(scope="module")
def nominal():
    return mujoco.MjModel.from_xml_path(str(st.model_path()))


def _regular(duration_s=2.0, period_s=st.LOG_PERIOD_S):
    return np.arange(int(round(duration_s / period_s)) + 1) * period_s


def test_nominal_model_numbers(nominal):
    """The model holds the stated servo: gear kt/R = 0.30 N*m/V, damping kt^2/R + bearing =
    0.37, armature 2.5e-3, Fc 0.03, +-12 V; the pendulum's m*g*l ~1.18 N*m."""
    j, a = nominal.joint("pivot").id, nominal.actuator("servo").id
    dof = nominal.jnt_dofadr[j]
    assert nominal.actuator_gear[a, 0] == pytest.approx(1.2 / 4.0)
    assert nominal.dof_damping[dof] == pytest.approx(1.2**2 / 4.0 + 0.01)
    assert nominal.dof_armature[dof] == 2.5e-3 and nominal.dof_frictionloss[dof] == 0.03
    assert tuple(nominal.actuator_ctrlrange[a]) == (-12.0, 12.0) == (-st.COMMAND_LIMIT, st.COMMAND_LIMIT)
    assert nominal.opt.timestep == DT
    d = mujoco.MjData(nominal)
    mujoco.mj_forward(nominal, d)
    b = nominal.body("pendulum").id
    mgl = nominal.body_subtreemass[b] * 9.81 * (d.xpos[b][2] - d.subtree_com[b][2])
    assert mgl == pytest.approx(1.18, abs=0.01)
    om.load_model(st.model_path(), target=st.target())  # the contract's names


def test_mu_zero_is_the_nominal_model_bit_for_bit():
    """mu_drive = mu_back = 0 (and the asymmetry 0, its default) writes Fc every step: the same
    trajectory as the plain loop that never writes the friction (noise and counts on)."""
    e = st.EXPERIMENTS[7]  # square waves about 0.6 rad
    t = st.log_times(3.0, np.random.default_rng(3))
    noise = np.random.default_rng(4).normal(0, st.NOISE_RAD, int(t[-1] / DT) + 1)
    a = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.0, mu_back=0.0, noise=noise)
    b = st.simulate(t, e.goal(t), e.enabled(t), noise=noise, friction_law=False)
    c = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.0, mu_back=0.0, asymmetry_nm=0.0,
                    noise=noise)
    for f in ("theta", "omega", "y", "u", "tau"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
        np.testing.assert_array_equal(getattr(a, f), getattr(c, f), err_msg=f)
    assert np.all(a.frictionloss == 0.03)


def test_zero_asymmetry_leaves_the_load_friction_law_bit_for_bit():
    """The asymmetry's default 0 leaves the load-dependent law as it was (the load_friction
    case's runs unchanged): the same trajectory with asymmetry_nm = 0 given or not."""
    e = st.EXPERIMENTS[3]
    t = st.log_times(2.0, np.random.default_rng(7))
    a = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.15, mu_back=0.45)
    b = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.15, mu_back=0.45, asymmetry_nm=0.0)
    for f in ("theta", "omega", "u", "tau", "frictionloss"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)


def test_nominal_loop_is_the_devices_on_regular_times(nominal):
    """With a goal written every tick and an exact encoder, the truth's loop at mu = 0 is the
    project's closed loop (omni_sim.device.run_p_loop) on the nominal model: the same
    conventions (read, clip, hold, step)."""
    t = np.arange(2001) * DT
    r = 0.4 * np.sin(2 * np.pi * 1.5 * t) + 0.3
    tr = st.simulate(t, r, np.ones_like(t), mu_drive=0.0, mu_back=0.0, step_rad=0.0)
    dev = Device(nominal, DT, target=st.target())
    with dev.engine([0.0], [None], nthread=1) as engine:
        out = run_p_loop(engine, r[None, :], st.KP, command_limit=st.COMMAND_LIMIT)
    np.testing.assert_allclose(out["theta"][0], tr.theta[: len(t)], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["v"][0], tr.u[: len(t)], rtol=0, atol=1e-9)


def test_the_friction_law_step_by_step():
    """Each step's frictionloss is max(0, Fc + mu |tau_prev|) with mu by the sign of
    tau_prev * w (w the velocity before the step, tau_prev the previous step's transmitted torque,
    0 before the first); a run visits both branches."""
    e = st.EXPERIMENTS[3]  # a sine about +0.6 rad: up driven, down back-driven
    t = st.log_times(e.duration_s, np.random.default_rng(5))
    tr = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.15, mu_back=0.45,
                     noise=np.random.default_rng(6).normal(0, st.NOISE_RAD, 5001))
    tau_prev = np.concatenate(([0.0], tr.tau[:-1]))
    w = tr.omega[:-1]
    drive = tau_prev * w > 0
    expect = np.maximum(0.0, 0.03 + np.where(drive, 0.15, 0.45) * np.abs(tau_prev))
    np.testing.assert_array_equal(tr.frictionloss, expect)
    assert tr.frictionloss[0] == 0.03
    assert drive.mean() > 0.2 and (~drive & (np.abs(w) > 0.05)).mean() > 0.2
    # the transmitted torque is the command through the gear (no saturation beyond ctrlrange)
    np.testing.assert_allclose(tr.tau, 0.30 * tr.u, rtol=1e-12, atol=1e-15)


def test_the_asymmetry_step_by_step():
    """With an asymmetry ``a`` (and no load-dependent part) each step's frictionloss is
    max(0, Fc + a sign(w)), w the velocity before the step: Fc + a moving positive, Fc - a moving
    negative, Fc at rest exactly (the first step); with the load-dependent part too, the two
    add (max(0, Fc + a sign(w) + mu |tau_prev|)); a = -0.05 > Fc clips at 0 moving negative."""
    e = st.EXPERIMENTS[1]  # a 1.5 Hz sine about the hanging pose: both directions
    t = st.log_times(e.duration_s, np.random.default_rng(8))
    noise = np.random.default_rng(9).normal(0, st.NOISE_RAD, 5001)
    for a, mu in ((0.0075, (0.0, 0.0)), (-0.01, (0.15, 0.45)), (-0.05, (0.0, 0.0))):
        tr = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=mu[0], mu_back=mu[1], asymmetry_nm=a,
                         noise=noise)
        w = tr.omega[:-1]
        tau_prev = np.concatenate(([0.0], tr.tau[:-1]))
        m = np.where(tau_prev * w > 0, mu[0], mu[1])
        expect = np.maximum(0.0, 0.03 + a * np.sign(w) + m * np.abs(tau_prev))
        np.testing.assert_array_equal(tr.frictionloss, expect)
        assert tr.frictionloss[0] == 0.03 and w[0] == 0.0
        assert (w > 0.05).mean() > 0.2 and (w < -0.05).mean() > 0.2
        if mu == (0.0, 0.0):
            levels = set(np.unique(tr.frictionloss))
            assert levels <= {0.03, max(0.0, 0.03 + a), max(0.0, 0.03 - a)}, levels


def test_the_asymmetry_is_the_devices_law(nominal):
    """On regular times with an exact encoder, the truth's loop with an asymmetry agrees with
    the device's engine (omni_sim.device.DriveFriction) on the nominal model declaring the same
    ``friction_asymmetry``: the two were written apart and implement one law."""
    spec = mujoco.MjSpec.from_file(str(st.model_path()))
    spec.add_numeric(name="friction_asymmetry", data=[st.ASYMMETRY_NM])
    m = spec.compile()
    t = np.arange(2001) * DT
    r = 0.4 * np.sin(2 * np.pi * 1.5 * t) + 0.3
    tr = st.simulate(t, r, np.ones_like(t), mu_drive=0.0, mu_back=0.0,
                     asymmetry_nm=st.ASYMMETRY_NM, step_rad=0.0)
    plain = st.simulate(t, r, np.ones_like(t), mu_drive=0.0, mu_back=0.0, step_rad=0.0)
    dev = Device(m, DT, target=st.target())
    with dev.engine([0.0], [None], nthread=1) as engine:
        out = run_p_loop(engine, r[None, :], st.KP, command_limit=st.COMMAND_LIMIT)
    np.testing.assert_allclose(out["theta"][0], tr.theta[: len(t)], rtol=0, atol=1e-9)
    assert np.max(np.abs(tr.theta - plain.theta)) > 1e-4  # the asymmetry shows


def test_free_fall_stops_where_gravity_meets_the_lower_level():
    """Torque off after a lift to 1.0 rad: the pendulum falls (moving negative, overdamped by
    the back-EMF, slow time constant ~0.24 s) and comes to rest where the gravity torque
    m g l sin(theta) meets the friction level it was moving against, Fc - a with an asymmetry a,
    Fc without (closed form); the torque-off span is 4 s here (the bank's runs: 1.5 s)."""
    e = st.Experiment("lift_drop_long", "other", 0.0, 1.00, shape="lift_drop", off_s=(2.0, 6.0),
                      duration_s=6.5)
    t = _regular(e.duration_s)
    k = int(5.9 / DT)
    for a in (0.0, st.ASYMMETRY_NM):
        tr = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.0, mu_back=0.0, asymmetry_nm=a,
                         step_rad=0.0)
        assert abs(tr.omega[k]) < 1e-3
        rest = math.asin((0.03 - a) / 1.1847)
        assert tr.theta[k] == pytest.approx(rest, abs=2e-4), a


def _hold_then_relax(mu_back, mu_drive=0.15):
    """Lift to 0.6 rad and hold 2 s; then write a goal that asks the motor for half the gravity
    torque at the held angle.  Returns (angle at 2 s, angle at the end, final motor torque,
    gravity torque at 2 s)."""
    t = _regular(4.0)
    on = np.ones_like(t)
    lift = 0.6 * st._ramp(t)
    first = st.simulate(t, lift, on, mu_drive=mu_drive, mu_back=mu_back, step_rad=0.0)
    k2 = int(round(2.0 / DT))
    th = first.theta[k2]
    gravity = 1.1847 * math.sin(th)
    goal = np.where(t >= 2.0, th + 0.5 * gravity / (st.KP * 0.30), lift)
    tr = st.simulate(t, goal, on, mu_drive=mu_drive, mu_back=mu_back, step_rad=0.0)
    assert tr.theta[k2] == th
    return th, tr.theta[-1], tr.tau[-1], gravity


def test_self_locking():
    """A back-driven gearbox holds the load: with mu_back = 1.5 (friction (Fc + 1.5 tau) >= G -
    tau down to tau = 0.4 G) the pendulum stays where it was when the motor's torque drops to
    half the gravity torque; with mu_back = 0 it sinks until the P law's torque meets gravity
    (tens of mrad); the case's 0.45 holds down to (G - Fc) / 1.45 = 0.67 G only: it sinks, but
    less."""
    th, end_lock, tau_lock, g = _hold_then_relax(1.5)
    assert abs(end_lock - th) < 2e-4 and tau_lock == pytest.approx(0.5 * g, rel=0.01)
    th0, end_free, _, _ = _hold_then_relax(0.0)
    th45, end_45, _, _ = _hold_then_relax(0.45)
    assert th0 - end_free > 0.02
    assert 0 < th45 - end_45 < th0 - end_free


def test_free_swing_loses_energy():
    """Torque off (0 V): the motor transmits nothing, the friction is the nominal Fc whatever
    the coefficients, and the pendulum's mechanical energy only decreases (back-EMF braking,
    bearing loss, Fc) until it comes to rest near the bottom."""
    e = st.EXPERIMENTS[11]  # lift to 1.0 rad, torque off 2.0-3.5 s
    t = _regular(e.duration_s)
    tr = st.simulate(t, e.goal(t), e.enabled(t), step_rad=0.0)
    off = slice(int(2.0 / DT) + 1, int(3.5 / DT))
    assert np.all(tr.u[off] == 0) and np.all(tr.tau[off] == 0)
    assert np.all(tr.frictionloss[off] == 0.03)
    inertia = 1.8153e-2 + 2.5e-3
    energy = 0.5 * inertia * tr.omega**2 + 1.1847 * (1 - np.cos(tr.theta))
    seg = energy[off]
    assert np.all(np.diff(seg) <= 1e-12)
    assert seg[0] > 0.4 and seg[-1] < 0.01 * seg[0]


def test_log_times_irregular():
    rng = np.random.default_rng(0)
    t = st.log_times(5.0, rng)
    d = np.diff(t)
    assert t[0] == 0.0 and np.all(d > 0)
    assert d.max() <= 2 * st.LOG_PERIOD_S + 1e-12 and d.min() >= st.LOG_PERIOD_S - 2 * st.JITTER_CLIP_S
    dev = t - np.round(t / st.LOG_PERIOD_S) * st.LOG_PERIOD_S
    assert 0.3e-3 < np.std(dev[1:]) < 0.5e-3
    assert 1 <= np.sum(d > 1.5 * st.LOG_PERIOD_S) <= 30  # a few missed frames
    assert np.std(d) > 0.1 * st.LOG_PERIOD_S  # not a uniform grid


@pytest.fixture(scope="module")
def runs():
    return st.generate()


def test_runs_as_the_host_logs_them(runs, tmp_path):
    """12 runs of ~5 s at ~200 Hz; the goal held between writes; torque-off spans command 0;
    theta on the encoder's counts; the metadata the replay needs (control_period_s = 1 ms)."""
    assert len(runs) == 12 and len({r.name for r in runs}) == 12
    assert {r.kind for r in runs} == {"sine", "step", "other"}
    for r in runs:
        assert abs(r.t[-1] - 5.0) <= st.JITTER_CLIP_S and 950 <= len(r.t) <= 1001
        assert np.all(np.diff(r.t) > 0)
        counts = r.theta / st.ENCODER_STEP_RAD
        np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)
        assert r.meta["control_period_s"] == 0.001 and r.meta["kp"] == st.KP
        assert r.meta["command_limit"] == 12.0
        assert set(r.extra) == {"enabled"} and set(np.unique(r.extra["enabled"])) <= {0.0, 1.0}
        assert np.all(np.abs(r.v) <= 12.0)
        off = r.extra["enabled"] == 0
        # v is the command in force at the read: 0 once a write of enable = 0 has taken effect
        # (from the row after it; the row of the write still shows the last tick's command)
        assert np.all(r.v[1:][off[1:] & off[:-1]] == 0)
    drops = [r for r in runs if np.any(r.extra["enabled"] == 0)]
    assert [r.name for r in drops] == ["lift_drop_a060", "lift_drop_a100"]
    write_run(tmp_path, runs[0])
    assert (tmp_path / f"{runs[0].name}.csv").read_text().splitlines()[0] == "t,r,theta,v,enabled"


def test_log_is_the_truth_at_the_log_times():
    """Exact data: theta is the 1 kHz trajectory interpolated at the log times, v the command of
    the last tick at or before each, and each tick's command the P law on the goal (and enable)
    of the last write at or before it."""
    e = st.EXPERIMENTS[10]
    run = st.measure(e, exact=True)
    t_log = run.t
    tr = st.simulate(t_log, e.goal(t_log), e.enabled(t_log), step_rad=0.0)
    np.testing.assert_array_equal(run.theta, np.interp(t_log, tr.t, tr.theta))
    k = np.floor(t_log / DT + 1e-9).astype(int)
    np.testing.assert_array_equal(run.v, tr.u[np.minimum(k, len(tr.u) - 1)])
    ticks = np.arange(len(tr.u)) * DT
    j = np.searchsorted(t_log, ticks, side="right") - 1
    law = np.clip(st.KP * (run.r[j] - tr.y), -12, 12) * (run.extra["enabled"][j] != 0)
    np.testing.assert_array_equal(tr.u, law)
    assert np.any(np.diff(j) == 0)  # goals held over several ticks


def test_generate_is_reproducible_and_seeded():
    a = st.measure(st.EXPERIMENTS[0])
    b = st.measure(st.EXPERIMENTS[0])
    c = st.measure(st.EXPERIMENTS[0], seed=2)
    np.testing.assert_array_equal(a.theta, b.theta)
    np.testing.assert_array_equal(a.t, b.t)
    assert not np.array_equal(a.t, c.t)


def test_hidden_friction_shows_above_the_noise(runs):
    """The truth differs from the nominal model by far more than a count on every run."""
    nominal = st.generate(effects=())
    for a, b in zip(runs, nominal, strict=True):
        np.testing.assert_array_equal(a.t, b.t)
        assert np.sqrt(np.mean((a.theta - b.theta) ** 2)) > 2 * st.ENCODER_STEP_RAD, a.name


def test_only_load_friction_and_asymmetry_are_simulated():
    with pytest.raises(ValueError, match="only load_friction and asymmetric_friction"):
        st.generate(effects=(("coulomb_friction", (0.01,)),))


def test_the_bank_case():
    """The bank's geared-servo case: its truth is this module's, its nominal model and target
    the servo pendulum's, its runs what :func:`servo_truth.generate` makes."""
    c = hidden.case("load_friction")
    assert c.truth == "servo" and c.effects == (("load_friction", (st.MU_DRIVE, st.MU_BACK)),)
    assert c.expect == ("load_friction",)
    path, target = hidden.nominal(c)
    assert path == st.model_path() and target == st.target()
    assert hidden.nominal(hidden.case("coulomb_friction")) == (None, None)
    runs = hidden.generate(c, st.EXPERIMENTS[:1])
    np.testing.assert_array_equal(runs[0].theta, st.measure(st.EXPERIMENTS[0]).theta)
    with pytest.raises(ValueError):
        hidden.truth_spec(c)


def test_the_asymmetric_friction_case():
    """The bank's asymmetric_friction case: the servo truth with the asymmetry alone (no
    load-dependent part) on the load_friction case's experiments, log times and noise; its
    friction differs from the nominal model's by more than a count on the torque-off runs."""
    c = hidden.case("asymmetric_friction")
    assert c.truth == "servo" and c.effects == (("asymmetric_friction", (st.ASYMMETRY_NM,)),)
    assert c.expect == ("asymmetric_friction",)
    assert 0.1 <= st.ASYMMETRY_NM / 0.03 <= 0.5  # a few tens of % of the nominal Fc
    assert hidden.nominal(c) == (st.model_path(), st.target())
    exps = [st.EXPERIMENTS[0], st.EXPERIMENTS[11]]
    runs = hidden.generate(c, exps)
    nominal = st.generate(effects=(), experiments=exps)
    for e, r, n in zip(exps, runs, nominal, strict=True):
        np.testing.assert_array_equal(r.theta, st.measure(e, mu_drive=0.0, mu_back=0.0,
                                                          asymmetry_nm=st.ASYMMETRY_NM).theta)
        np.testing.assert_array_equal(r.t, n.t)
    assert np.max(np.abs(runs[1].theta - nominal[1].theta)) > 2 * st.ENCODER_STEP_RAD
