"""The geared-servo truth (bank/servo_truth.py): its load-dependent and
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
from bank import hidden
from bank import servo_truth as st

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
    """Each step's frictionloss is max(0, Fc + mu |tau_prev|) with mu passing from mu_back to
    mu_drive by a logistic in sign(tau_prev) * w over the blend speed 0.05 rad/s (w the velocity
    before the step, tau_prev the previous step's transmitted torque, 0 before the first); a
    run visits both branches."""
    e = st.EXPERIMENTS[3]  # a sine about +0.6 rad: up driven, down back-driven
    t = st.log_times(e.duration_s, np.random.default_rng(5))
    tr = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.15, mu_back=0.45,
                     noise=np.random.default_rng(6).normal(0, st.NOISE_RAD, 5001))
    tau_prev = np.concatenate(([0.0], tr.tau[:-1]))
    w = tr.omega[:-1]
    drive = tau_prev * w > 0
    # (1 + tanh(x)) / 2 = 1 / (1 + exp(-2x)): the same law written another way
    share = 1.0 / (1.0 + np.exp(-2.0 * np.where(tau_prev > 0, w, -w) / 0.05))
    expect = np.maximum(0.0, 0.03 + (0.45 + (0.15 - 0.45) * share) * np.abs(tau_prev))
    # two formulas of one law: they differ in the last bits (1e-15 N*m on levels of ~0.1)
    np.testing.assert_allclose(tr.frictionloss, expect, rtol=0, atol=1e-14)
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
        share = 1.0 / (1.0 + np.exp(-2.0 * np.where(tau_prev > 0, w, -w) / 0.05))  # the blend
        m = mu[1] + (mu[0] - mu[1]) * share
        expect = np.maximum(0.0, 0.03 + a * np.sign(w) + m * np.abs(tau_prev))
        # the blend written another way: last bits differ (1e-15 N*m on levels of ~0.1)
        np.testing.assert_allclose(tr.frictionloss, expect, rtol=0, atol=1e-14)
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
    tau down to tau = 0.4 G) the pendulum stays within one encoder count (1.53 mrad) of where
    it was when the motor's torque drops to half the gravity torque -- at rest the coefficient
    is the mean of mu_drive and mu_back (the blend), so the load creeps until its speed engages
    mu_back, then holds with the motor near half the gravity torque; with mu_back = 0 it sinks
    until the P law's torque meets gravity (tens of mrad); the case's 0.45 holds down to
    (G - Fc) / 1.45 = 0.67 G only: it sinks, but less."""
    th, end_lock, tau_lock, g = _hold_then_relax(1.5)
    assert 0 <= th - end_lock < st.ENCODER_STEP_RAD and 0.5 * g <= tau_lock < 0.55 * g
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


def test_only_its_own_laws_are_simulated():
    with pytest.raises(ValueError, match="only load_friction, asymmetric_friction, current_limit"):
        st.generate(effects=(("coulomb_friction", (0.01,)),))
    with pytest.raises(ValueError, match="one law"):
        st.generate(effects=(("load_friction", (0.1, 0.2, 0.0)), ("friction_family_stribeck", (0.1, 0.2, 0.0, 0.03, 0.1, 1.0))))
    with pytest.raises(ValueError, match="one law"):
        st.generate(effects=(("load_friction", (0.1, 0.2, 0.0)), ("load_friction_smooth", st.USERS_PENDULUM)))


def test_the_stribeck_rise_is_the_devices_family_law(nominal):
    """On regular times with an exact encoder, the truth's loop with the load law and a Stribeck
    rise agrees with the device's engine on the nominal model declaring the same
    ``friction_family`` (omni_sim.device: written apart, one law); the rise shows."""
    law = (st.MU_DRIVE, st.MU_BACK, st.STRIBECK_RISE_NM, st.STRIBECK_SPEED_RAD_S, st.STRIBECK_SHAPE)
    spec = mujoco.MjSpec.from_file(str(st.model_path()))
    spec.add_numeric(name="friction_family", data=list(law))
    m = spec.compile()
    t = np.arange(2001) * DT
    r = 0.4 * np.sin(2 * np.pi * 1.5 * t) + 0.3
    tr = st.simulate(t, r, np.ones_like(t), mu_drive=law[0], mu_back=law[1], stribeck=law[2:], step_rad=0.0)
    no_rise = st.simulate(t, r, np.ones_like(t), mu_drive=law[0], mu_back=law[1], step_rad=0.0)
    dev = Device(m, DT, target=st.target())
    with dev.engine([0.0], [None], nthread=1) as engine:
        out = run_p_loop(engine, r[None, :], st.KP, command_limit=st.COMMAND_LIMIT)
    np.testing.assert_allclose(out["theta"][0], tr.theta[: len(t)], rtol=0, atol=1e-9)
    assert np.max(np.abs(tr.theta - no_rise.theta)) > 1e-4


def test_the_smooth_load_law_is_the_devices():
    """The truth's smooth load law (the user's pendulum: 0.2 |tau_m| tanh(w / 0.02), tau_m net of
    the back-EMF) agrees with the device's engine on the nominal model declaring
    ``load_friction_smooth`` (written apart, one law) on regular times with an exact encoder, and
    differs from the nominal by far more."""
    law = st.USERS_PENDULUM
    spec = mujoco.MjSpec.from_file(str(st.model_path()))
    spec.add_numeric(name="load_friction_smooth", data=list(law))
    spec.add_sensor(name="transmitted", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                    objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=st.ACTUATOR)
    m = spec.compile()
    t = np.arange(2001) * DT
    r = 0.4 * np.sin(2 * np.pi * 1.5 * t) + 0.3
    tr = st.simulate(t, r, np.ones_like(t), mu_drive=0.0, mu_back=0.0, smooth_load=law, step_rad=0.0)
    plain = st.simulate(t, r, np.ones_like(t), mu_drive=0.0, mu_back=0.0, step_rad=0.0)
    dev = Device(m, DT, target=st.target())
    with dev.engine([0.0], [None], nthread=1) as engine:
        out = run_p_loop(engine, r[None, :], st.KP, command_limit=st.COMMAND_LIMIT)
    np.testing.assert_allclose(out["theta"][0], tr.theta[: len(t)], rtol=0, atol=1e-9)
    assert np.max(np.abs(tr.theta - plain.theta)) > 1e-3


def test_the_bank_case():
    """The bank's geared-servo case: its truth is this module's, its nominal model and target
    the servo pendulum's, its runs what :func:`servo_truth.generate` makes."""
    c = hidden.case("load_friction")
    assert c.truth == "servo" and c.effects == (("load_friction", (st.MU_DRIVE, st.MU_BACK, st.B_EMF)),)
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


# --- the efficiency truth: a gear efficiency law with a smooth sign ---------------------------
def _variant(tmp_path, load_nm: float = 0.0) -> str:
    """The nominal model without gravity and, if ``load_nm``, with a constant load torque on the
    pivot (a ``general`` actuator of gain 0 and affine bias ``load_nm``): a file for ``path=``."""
    spec = mujoco.MjSpec.from_file(str(st.model_path()))
    spec.option.gravity = [0.0, 0.0, 0.0]
    if load_nm:
        a = spec.add_actuator()
        a.name, a.target, a.trntype = "load", st.JOINT, mujoco.mjtTrn.mjTRN_JOINT
        a.gaintype, a.gainprm = mujoco.mjtGain.mjGAIN_FIXED, [0.0] * 10
        a.biastype, a.biasprm = mujoco.mjtBias.mjBIAS_AFFINE, [load_nm] + [0.0] * 9
    p = tmp_path / f"variant_{load_nm:g}.xml"
    p.write_text(spec.to_xml())
    return str(p)


#: The nominal model's numbers the closed forms below use (test_nominal_model_numbers checks the
#: model holds them): torque per volt, back-EMF kt^2/R = 1.2^2/4, bearing damping, Coulomb level.
G, CE, B, FC = 0.30, 0.36, 0.01, 0.03
#: Steady speeds agree with the closed form to 1e-10 relative: at a steady speed the linearly
#: implicit step applies exactly -L(w) (its correction s (w+ - w) is 0) and the rotor term
#: J_r a_prev is 0, so the fixed point of the loop is the root of the steady equation; the
#: transient decays with a time constant <= J / (c_e + b) = 0.056 s, e^-50 of it left after 3 s;
#: the rest is round-off (observed <= 6e-15 relative).
STEADY_REL = 1e-10


def _steady(residual) -> float:
    from scipy.optimize import brentq
    return brentq(residual, 1e-9, 50.0, xtol=1e-15, rtol=1e-15)


@pytest.mark.parametrize("volts", [12.0, 1.0, 0.2])
def test_efficiency_driving_steady_speed(tmp_path, volts):
    """No gravity, the command held at +volts (P law saturated on a far goal): the motor drives
    the load; the speed settles where g u - (c_e + b) w - Fc - (1 - eta_drive) (g u - c_e w)
    tanh(w / w_s) = 0 (root found by brentq; 0.2 V settles at ~1.4 w_s, in the smooth sign's
    transition).  The other branch's efficiency gives another speed (the check can fail)."""
    t = _regular(3.0)
    tr = st.simulate_efficiency(t, np.full_like(t, 1e3), np.ones_like(t), command_limit=volts,
                                step_rad=0.0, path=_variant(tmp_path))

    def residual(w, k=1.0 - st.ETA_DRIVE):
        return G * volts - (CE + B) * w - FC - k * (G * volts - CE * w) * math.tanh(w / st.SMOOTH_SPEED_RAD_S)

    w = _steady(residual)
    assert tr.omega[-1] == pytest.approx(w, rel=STEADY_REL)
    assert tr.tau_m[-1] * tr.omega[-2] > 0  # the driving branch
    wrong = _steady(lambda x: residual(x, 1.0 / st.ETA_BACK - 1.0))
    assert abs(wrong - w) > 1e-3 * w


@pytest.mark.parametrize("load_nm, volts", [(1.0, 2.0), (0.5, 1.0), (0.2, 0.55)])
def test_efficiency_back_driven_steady_speed(tmp_path, load_nm, volts):
    """No gravity, a constant load torque T pushing positive, the command held at -volts: the
    load back-drives the motor (tau_m = -g u - c_e w < 0 < w); the speed settles where
    T - g u - (c_e + b) w - Fc - (1/eta_back - 1) |g u + c_e w| tanh(w / w_s) = 0.  The last pair
    creeps at ~0.05 w_s: the smooth sign does not stick, where the library's law (a hard stick up
    to Fc + mu_back g u = 0.104 N*m) would hold a net 0.035 N*m."""
    t = _regular(3.0)
    tr = st.simulate_efficiency(t, np.full_like(t, -1e3), np.ones_like(t), command_limit=volts,
                                step_rad=0.0, path=_variant(tmp_path, load_nm))

    def residual(w):
        return (load_nm - G * volts - (CE + B) * w - FC
                - (1.0 / st.ETA_BACK - 1.0) * abs(G * volts + CE * w) * math.tanh(w / st.SMOOTH_SPEED_RAD_S))

    w = _steady(residual)
    assert tr.omega[-1] == pytest.approx(w, rel=STEADY_REL)
    assert tr.tau_m[-1] < 0 < tr.omega[-1]  # the back-driven branch
    if load_nm == 0.2:
        assert w < 0.1 * st.SMOOTH_SPEED_RAD_S
        assert load_nm - G * volts < FC + st.MU_BACK * G * volts  # the engine's law would stick


def test_efficiency_law_step_by_step():
    """Each step's mesh torque, loss and slope are the law's, recomputed here from the recorded
    speeds and commands in another form (numpy over the whole run): tau_m = g u - c_e w -
    J_r (w - w_prev)/dt, L = k |tau_m| tanh(w/w_s), dL/dw = k |tau_m| / (w_s cosh^2(w/w_s)); a
    lift-and-drop run visits driving, back-driving and the torque-off fall (0 V: the back-EMF's
    torque passes the mesh, back-driven)."""
    e = st.EXPERIMENTS[10]
    t = st.log_times(e.duration_s, np.random.default_rng(11))
    tr = st.simulate_efficiency(t, e.goal(t), e.enabled(t),
                                noise=np.random.default_rng(12).normal(0, st.NOISE_RAD, 5001))
    w = tr.omega[:-1]
    acc = np.concatenate(([0.0], np.diff(tr.omega)[:-1] / DT))
    tau_m = G * tr.u - CE * w - 2.5e-3 * acc
    k = np.where(tau_m * w > 0, 1.0 - st.ETA_DRIVE, 1.0 / st.ETA_BACK - 1.0)
    np.testing.assert_allclose(tr.tau_m, tau_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.loss, k * np.abs(tau_m) * np.tanh(w / st.SMOOTH_SPEED_RAD_S), rtol=0, atol=1e-12)
    slope = k * np.abs(tau_m) / (st.SMOOTH_SPEED_RAD_S * np.cosh(w / st.SMOOTH_SPEED_RAD_S) ** 2)
    np.testing.assert_allclose(tr.slope, slope, rtol=1e-12, atol=1e-12)
    assert np.all(tr.frictionloss == FC)
    drive = tau_m * w > 0
    off = np.flatnonzero(tr.u == 0)
    fall = off[np.abs(w[off]) > 0.1]
    assert drive.mean() > 0.05 and (~drive & (np.abs(w) > 0.1)).mean() > 0.05 and len(fall) > 100
    assert np.all(tau_m[fall] * w[fall] < 0)  # the fall back-drives the shorted motor


def test_efficiency_one_is_the_nominal_model_bit_for_bit():
    """eta_drive = eta_back = 1: the loss and its slope are 0 every step (damping written back as
    the nominal 0.37 + 0.0): the same trajectory as the plain nominal loop."""
    e = st.EXPERIMENTS[11]
    t = st.log_times(e.duration_s, np.random.default_rng(13))
    noise = np.random.default_rng(14).normal(0, st.NOISE_RAD, 5001)
    a = st.simulate_efficiency(t, e.goal(t), e.enabled(t), eta_drive=1.0, eta_back=1.0, noise=noise)
    b = st.simulate(t, e.goal(t), e.enabled(t), noise=noise, friction_law=False)
    for f in ("theta", "omega", "y", "u"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    assert not np.any(a.loss) and not np.any(a.slope)


def test_efficiency_truth_differs_from_the_engine_law():
    """The efficiency truth is not the engine's law in disguise: on the same run it differs from
    the load_friction truth (mu = 1 - eta_drive, 1/eta_back - 1) by far more than a count, most
    where the engine's law cannot follow it (the torque-off fall, where the mesh carries the
    back-EMF's torque), and both differ from the nominal model."""
    e = st.EXPERIMENTS[11]
    t = st.log_times(e.duration_s, np.random.default_rng(15))
    eff = st.simulate_efficiency(t, e.goal(t), e.enabled(t), step_rad=0.0)
    law = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=1 - st.ETA_DRIVE,
                      mu_back=1 / st.ETA_BACK - 1, step_rad=0.0)
    nom = st.simulate(t, e.goal(t), e.enabled(t), mu_drive=0.0, mu_back=0.0, step_rad=0.0)
    assert st.MU_BACK == pytest.approx(1 / st.ETA_BACK - 1, rel=1e-15)
    for other in (law, nom):
        assert np.max(np.abs(eff.theta - other.theta)) > 10 * st.ENCODER_STEP_RAD


def test_efficiency_runs_share_the_cases_log():
    """The efficiency case's runs are logged as the other geared-servo cases' (same log times,
    goals, enable; seeded, reproducible); with eta = 1 they are the nominal model's runs."""
    exps = [st.EXPERIMENTS[0], st.EXPERIMENTS[10]]
    a = st.generate_efficiency(experiments=exps)
    b = st.generate(effects=(), experiments=exps)
    one = st.generate_efficiency(1.0, 1.0, experiments=exps)
    for x, y, z in zip(a, b, one, strict=True):
        np.testing.assert_array_equal(x.t, y.t)
        np.testing.assert_array_equal(x.r, y.r)
        np.testing.assert_array_equal(x.extra["enabled"], y.extra["enabled"])
        np.testing.assert_array_equal(z.theta, y.theta)
        assert np.sqrt(np.mean((x.theta - y.theta) ** 2)) > 2 * st.ENCODER_STEP_RAD
    np.testing.assert_array_equal(a[0].theta, st.generate_efficiency(experiments=exps[:1])[0].theta)


def test_assess_efficiency():
    """The case's criterion on hand-made reports: load_friction first with mu_back > mu_drive and
    a shrink >= 3 passes (a second name after it too); otherwise it fails, saying why."""
    def rep(names, mu=(0.1, 0.4), shrink=5.0):
        effects = [{"name": n, "parameters": {"mu_drive": mu[0], "mu_back": mu[1]} if n == "load_friction"
                    else {"x": 1.0}} for n in names]
        return {"effects": effects, "shrink_factor": shrink}

    assert st.assess_efficiency(rep(["load_friction"])) == (True, "ok")
    assert st.assess_efficiency(rep(["load_friction", "viscous_damping"]))[0]
    assert st.assess_efficiency(rep(["viscous_damping", "load_friction"])) == \
        (False, "named ['viscous_damping', 'load_friction'], not load_friction first")
    assert st.assess_efficiency(rep(["none"]))[1].startswith("named ['none']")
    assert st.assess_efficiency(rep(["load_friction"], mu=(0.3, 0.2)))[1] == "mu_back 0.2 <= mu_drive 0.3"
    assert st.assess_efficiency(rep(["load_friction"], shrink=2.9)) == (False, "gap shrank only x2.9")
    assert not st.assess_efficiency(rep(["load_friction"], shrink=math.nan))[0]
