"""The device layer: one start state, one encoder, one P law, one closed-loop engine.

The generator's reference path, the gymnasium environment and the discrepancy replay all step
through :class:`omni_sim.device.Engine`; these tests hold them to identical trajectories (not
close ones), and the engine's two ways of advancing the physics (``mj_step`` on one row,
``mujoco.rollout`` on a batch) to each other, bit for bit.

Why bitwise equality holds on any CPU here: every path runs the same arithmetic by
construction. The physics is MuJoCo's compiled ``mj_step`` in each case (``mujoco.rollout``
calls it row by row on the same state), and what numpy adds around it (the encoder's
quantisation and noise, the P law, the clip) is elementwise +, -, *, /, floor and clip, which
IEEE 754 rounds exactly whatever SIMD code numpy picks; no transcendental function or
reduction lies between the two sides.  (Comparisons across paths whose arithmetic differs, such
as the compiled α loop and the numpy loop, use a stated tolerance: tests/test_simulate_fast.py.)
"""

from __future__ import annotations

import math
import os

import mujoco
import numpy as np
import pytest

from identification.errors import UserError
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import (ENCODER_STEP_RAD, Device, Encoder, Engine, p_law, read_encoder,
                             run_p_loop)
from omni_sim.device.engine import SERIAL_BELOW
from discrepancy.replay import Replayer, prepare_runs
from omni_sim.env import OmniYawEnv


@pytest.fixture(scope="module")
def device():
    return Device.load()


def _short(exp, n):
    return ex.Experiment(exp.name, exp.kind, exp.gamma1_set_deg, exp.gamma2_set_deg, exp.r[:n],
                         exp.frequency_hz, exp.amplitude_rad, exp.theta0_rad)


def test_start_state_is_the_sagged_pose_at_rest(device):
    d = device.start_data(-0.07, (45.0, 90.0))
    g1, g2 = device.equilibrium(45.0, 90.0)
    ix = device.ix
    assert d.qpos[ix.yaw_qpos] == -0.07
    assert math.degrees(d.qpos[ix.shoulder_qpos]) == pytest.approx(g1, abs=1e-12)
    assert math.degrees(d.qpos[ix.elbow_qpos]) == pytest.approx(g2, abs=1e-12)
    assert not np.any(d.qvel)
    assert d.ctrl[ix.shoulder_act] == pytest.approx(math.radians(45.0))
    # the arm sags below its set points under gravity (Table 3), and the servos balance it
    assert g1 < 45.0
    f = d.qfrc_actuator + d.qfrc_passive - d.qfrc_bias
    dofs = [model_dof for model_dof in range(device.model.nv) if model_dof != ix.yaw_dof]
    assert np.max(np.abs(f[dofs])) < 1e-6
    assert device.equilibrium(45, 90) is device.equilibrium(45.0, 90.0)  # cached


def test_encoder_reading():
    q = ENCODER_STEP_RAD
    y = read_encoder(np.array([0.3 * q, -0.3 * q, 2.6 * q, -2.6 * q]), 0.0, q)
    np.testing.assert_array_equal(y, [0.0, 0.0, 3 * q, -3 * q])
    assert math.copysign(1.0, float(y[1])) == 1.0  # a zero count reads +0.0
    np.testing.assert_array_equal(read_encoder(np.array([0.123]), 0.001, 0.0), [0.124])
    # per-row quantum: 0 means exact
    np.testing.assert_array_equal(read_encoder(np.array([0.3 * q, 0.3 * q]), 0.0, np.array([q, 0.0])),
                                  [0.0, 0.3 * q])
    enc = Encoder(noise_rad=1e-4, seed=5)
    a = enc.noise("run_a", 100)
    assert np.array_equal(a, enc.noise("run_a", 100))  # same seed and name, same noise
    assert not np.array_equal(a, enc.noise("run_b", 100))
    assert not np.array_equal(a, Encoder(noise_rad=1e-4, seed=6).noise("run_a", 100))
    assert np.std(a) == pytest.approx(1e-4, rel=0.3)
    assert not np.any(Encoder().noise("x", 10))
    with pytest.raises(Exception, match="noise"):
        Encoder(noise_rad=-1.0)


def test_p_law_clips_to_the_drive():
    np.testing.assert_array_equal(p_law(2.0, np.array([0.1, 1.0, -1.0]), 0.0, 1.3), [0.2, 1.3, -1.3])


@pytest.mark.parametrize("frictionloss", [0.0, 0.02])
@pytest.mark.parametrize("rows", [2, SERIAL_BELOW])
def test_one_row_equals_batch_bit_for_bit(device, frictionloss, rows):
    """mj_step on one row and mujoco.rollout on a batch are the same physics, bit for bit, with
    the LuGre model and with a hard-stick Coulomb frictionloss (constraints, noslip); a small
    batch is stepped on the calling thread, a larger one on the pool's threads (SERIAL_BELOW)."""
    m = om.load_model()
    m.dof_frictionloss[om.index(m).yaw_dof] = frictionloss
    dev = Device(m)
    exps = [_short(ex.square_experiment(45, 90), 1500), _short(ex.sine_experiment(25, 115, 3.0), 1500)]
    exps = (exps * rows)[:rows]
    r = np.array([e.r for e in exps])
    noise = np.array([Encoder(noise_rad=2e-4, seed=1).noise(e.name, 1500) for e in exps])
    starts = ([e.theta0_rad for e in exps], [(e.gamma1_set_deg, e.gamma2_set_deg) for e in exps])
    with dev.engine(*starts, nthread=2) as eng:
        batch = run_p_loop(eng, r, 2.0, noise, ENCODER_STEP_RAD)
    for b in range(2):
        one = Engine([dev], [starts[0][b]], [starts[1][b]])
        assert one.data is not None  # the one-row path
        res = run_p_loop(one, r[b:b + 1], 2.0, noise[b:b + 1], ENCODER_STEP_RAD)
        np.testing.assert_array_equal(res["theta"][0], batch["theta"][b])
        np.testing.assert_array_equal(res["v"][0], batch["v"][b])
    assert np.ptp(batch["theta"][0]) > 0.1  # a non-trivial trajectory


@pytest.mark.parametrize("quantize", [False, True])
def test_generator_env_and_replay_share_one_engine(device, quantize):
    """One experiment, three users of the device: the generator's reference path, the
    environment under a P controller and the discrepancy replay give identical trajectories.

    The replay starts from the first *measured* angle (all a real record has); with an exact
    encoder that is the true start, so all three must agree.  With a quantised encoder the
    measured start is off by up to half a count, so there the replay is compared on its own
    measured start, through the same quantised encoder."""
    exp = _short(ex.square_experiment(35, 110), 2500)
    kp = ex.KP_DEFAULT
    gen = ex.simulate(device, [exp], settings=ex.Settings(kp=kp, quantize=quantize), force_reference=True)[0]

    env = OmniYawEnv(gamma1_set_deg=35, gamma2_set_deg=110, reference=exp.r,
                     theta0_rad=exp.theta0_rad, quantize=quantize)
    obs, _ = env.reset(seed=0)
    th_env, v_env = [], []
    for _ in range(len(exp.r)):
        th_env.append(obs[0])
        obs, _, terminated, truncated, info = env.step(np.array([kp * (obs[2] - obs[0])]))
        v_env.append(info["voltage"])
        assert not terminated
    assert truncated
    np.testing.assert_array_equal(np.array(th_env), gen.theta)
    np.testing.assert_array_equal(np.array(v_env), gen.v)
    assert np.ptp(gen.theta) > 0.1

    rr = prepare_runs([gen], device)
    q = ENCODER_STEP_RAD if quantize else 0.0
    with Replayer(2) as rep:
        th_rep = rep.simulate([device.model], rr, measurement=([np.zeros(len(exp.r))], [q]))[0]
    if not quantize:
        np.testing.assert_array_equal(th_rep, gen.theta)
    else:  # the same engine and encoder from the measured start
        start = _short(exp, len(exp.r))
        start = ex.Experiment(start.name, start.kind, 35, 110, exp.r, 0.0, 0.0, float(gen.theta[0]))
        again = ex.simulate(device, [start], settings=ex.Settings(kp=kp, quantize=True), force_reference=True)[0]
        np.testing.assert_array_equal(th_rep, again.theta)


def test_engine_rejects_mixed_devices():
    a = Device.load()
    m = om.load_model()
    m.opt.timestep = 0.0005
    with pytest.raises(ValueError, match="substeps"):
        Engine([a, Device(m)], [0.0, 0.0], [(45, 90), (45, 90)])


@pytest.fixture
def quiet_mujoco():
    """Swallow MuJoCo's warnings (else it appends them to MUJOCO_LOG.TXT in the working folder)."""
    seen = []
    old = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(seen.append)
    yield seen
    mujoco.set_mju_user_warning(old)


def test_env_divergence_terminates_with_reason(quiet_mujoco):
    """A diverging simulation ends the episode (gymnasium's MuJoCo convention), it does not
    raise; info says why, and the observation stays inside its box."""
    env = OmniYawEnv(duration_s=1.0)
    env.reset(seed=0)
    env.data.qvel[env.device.ix.yaw_dof] = 1e6  # a blown-up state [rad/s] (finite: MuJoCo resets on inf)
    obs, reward, terminated, truncated, info = env.step(np.array([0.0]))
    assert terminated and not truncated
    assert info["diverged"] and "diverged" in info["reason"]
    assert env.observation_space.contains(obs)
    assert reward == 0.0
    assert any("unstable" in w for w in quiet_mujoco)  # MuJoCo saw it too
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.array([0.0]))
    env.reset(seed=0)  # a reset starts a fresh episode
    assert env.step(np.array([0.0]))[2] is False


def test_env_scalar_action_is_a_value_error():
    env = OmniYawEnv(duration_s=0.1)
    env.reset(seed=0)
    for bad in (0.1, np.float32(0.1), np.zeros(2), np.zeros((1, 1))):
        with pytest.raises(ValueError, match="shape"):
            env.step(bad)


def test_apply_per_step_is_apply_with_the_command_held(device):
    """A batch's command per physics step, the same in every step, is :meth:`Engine.apply`
    (the same rollout, bit for bit); the velocities it returns end at the row's state."""
    m = om.load_model()
    m.opt.timestep = 2.5e-4  # 4 physics steps per control period
    dev = Device(m)
    starts = ([0.01, -0.02], [(45, 90), (25, 115)])
    v = np.array([0.3, -2.0])  # the second beyond the drive's limit: clipped either way
    with dev.engine(*starts, nthread=1) as a, dev.engine(*starts, nthread=1) as b:
        for _ in range(20):
            a.apply(v)
            vs = b.apply_per_step(np.repeat(v[:, None], dev.substeps, axis=1))
            np.testing.assert_array_equal(a.x, b.x)
            np.testing.assert_array_equal(vs[:, -1], b.yaw_velocity())
    assert vs.shape == (2, 4) and np.ptp(a.yaw()) > 0
    with pytest.raises(ValueError, match="batch"):
        Engine([dev], [0.0], [(45, 90)]).apply_per_step(np.zeros((1, 4)))


def test_named_parameters_are_the_model_fields():
    """The device's named parameters read and write MuJoCo's own fields (found here by name,
    independently of the device's index), and a missing name is a user error."""
    dev = Device.load(friction="lugre")
    m = dev.model
    bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "forearm")
    yaw = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "yaw")]
    servo = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "elbow_servo")
    lugre = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "yaw_friction")
    mass, inertia = dev.body("forearm")
    assert mass == m.body_mass[bid] and np.array_equal(inertia, m.body_inertia[bid])
    assert dev.lugre() == {"sigma0": m.actuator_dynprm[lugre, 5], "sigma1": m.actuator_dynprm[lugre, 6],
                           "Fc": m.actuator_biasprm[lugre, 3], "Fs": m.actuator_biasprm[lugre, 4],
                           "vs": m.actuator_biasprm[lugre, 5]}
    dev.set_body("forearm", 0.05, (1e-6, 2e-5, 2e-5))
    dev.yaw_damping, dev.yaw_frictionloss = 0.004, 0.002
    dev.set_servo_gain("elbow", 3.5)
    dev.set_lugre(sigma0=80.0, Fc=0.01, Fs=0.02, vs=0.3)
    assert m.body_mass[bid] == 0.05 and list(m.body_inertia[bid]) == [1e-6, 2e-5, 2e-5]
    assert (m.dof_damping[yaw], m.dof_frictionloss[yaw]) == (0.004, 0.002)
    assert (m.actuator_gainprm[servo, 0], m.actuator_biasprm[servo, 1]) == (3.5, -3.5)
    assert (m.actuator_dynprm[lugre, 5], *m.actuator_biasprm[lugre, 3:6]) == (80.0, 0.01, 0.02, 0.3)
    with pytest.raises(UserError, match="no body 'wrist'"):
        dev.body("wrist")
    with pytest.raises(UserError, match="no LuGre"):
        Device.load(friction="coulomb").lugre()


def test_threads_from_the_environment(monkeypatch, capsys):
    """OMNI_THREADS sets the threads of every batch a caller gives no count; anything but a
    positive whole number is refused: one error line and status 2 from the command, before
    any work."""
    from omni_app.cli import main
    from omni_sim.device import THREADS_ENV, default_threads

    monkeypatch.setenv(THREADS_ENV, "3")
    assert default_threads() == 3
    assert Replayer().nthread == 3
    monkeypatch.delenv(THREADS_ENV)
    assert default_threads() == max(1, os.cpu_count() or 1)
    for bad in ("0", "-2", "two", "1.5"):
        monkeypatch.setenv(THREADS_ENV, bad)
        assert main(["generate", "--campaign", "step", "--out", "unused"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("error: OMNI_THREADS must be a positive whole number")
