"""The task objects on their own: the tracking and wall tasks' observation, reward and
termination against values computed by hand from the engine's state."""

import math

import mujoco
import numpy as np
import pytest

from omni_sim.device import ENCODER_STEP_RAD, Device, Engine
from omni_sim.options import InvalidOptionError
from omni_sim.tracking_task import TrackingTask, tracking_reward
from omni_sim.wall_task import WallTask, add_hand, grasp_impedance


@pytest.fixture(scope="module")
def device():
    return Device.load()


@pytest.fixture
def quiet_mujoco():
    """Swallow MuJoCo's warnings (else it appends them to MUJOCO_LOG.TXT in the working folder)."""
    old = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: None)
    yield
    mujoco.set_mju_user_warning(old)


def _one_row(device, task, options, seed=0):
    theta0, gs = task.start_episode(options, np.random.default_rng(seed))
    engine = Engine([device], [theta0], [gs])
    return engine, task.first_observation(engine)


def test_tracking_reward_and_truncation_by_hand(device):
    task = TrackingTask(device)
    engine, (obs, info) = _one_row(device, task, {"reference": "sine", "amplitude_rad": 0.2,
                                                 "frequency_hz": 5.0, "duration_s": 0.003,
                                                 "effort_weight": 0.5})
    assert obs[2] == 0.0 and info["voltage"] == 0.0  # r_0 = A sin(0)
    for k in range(1, 4):
        v = float(engine.apply(task.before_step(np.array([0.8])))[0])
        obs, reward, terminated, truncated, info = task.after_step(engine, v)
        r_k = 0.2 * math.sin(2 * math.pi * 5.0 * min(k, 2) * 1e-3)  # held after the last sample
        theta = float(engine.yaw()[0])
        assert obs[2] == pytest.approx(r_k, abs=1e-15)
        assert reward == pytest.approx(-(r_k - theta) ** 2 - 0.5 * 0.8 ** 2, rel=1e-12)
        assert not terminated and truncated == (k == 3)
    with pytest.raises(RuntimeError, match="truncated"):
        task.before_step(np.array([0.0]))


def test_tracking_quantised_reading(device):
    task = TrackingTask(device)
    _, (obs, _) = _one_row(device, task, {"quantize": True, "theta0_rad": 0.1})
    assert obs[0] == round(0.1 / ENCODER_STEP_RAD) * ENCODER_STEP_RAD != 0.1


@pytest.mark.parametrize("qvel,why", [(2e4, "theta_dot = 19939.8 outside [-12566.4, 12566.4]"),
                                      (1e6, "MuJoCo found a non-finite or huge state")])
def test_tracking_divergence_terminates(device, qvel, why, quiet_mujoco):
    """Out of the box (the entries named, the observation clipped back into it) or reset by
    MuJoCo: terminated, reward 0, and no further step."""
    task = TrackingTask(device)
    engine, _ = _one_row(device, task, {"theta0_rad": 0.1})
    engine.data.qvel[device.ix.yaw_dof] = qvel  # a blown-up state [rad/s]
    v = float(engine.apply(task.before_step(np.array([0.0])))[0])
    obs, reward, terminated, truncated, info = task.after_step(engine, v)
    assert terminated and not truncated and reward == 0.0 and info["diverged"]
    assert why in info["reason"]
    assert task.observation_space.contains(obs)
    with pytest.raises(RuntimeError, match="diverged"):
        task.before_step(np.array([0.0]))


def test_tracking_rows_keep_their_own_episode(device):
    """Two rows of one task: each its own reference and effort weight; the batch reward is the
    formula row by row."""
    task = TrackingTask(device, rows=2)
    rng = np.random.default_rng(0)
    user = np.array([0.05, 0.06, 0.07])
    starts = [task.start_row(0, {"reference": user}, rng),
              task.start_row(1, {"reference": "steps", "effort_weight": 2.0}, rng)]
    assert starts[0] == (0.05, (65.0, 90.0)) and starts[1][0] == 0.0
    engine = Engine([device] * 2, [s[0] for s in starts], [s[1] for s in starts], nthread=1)
    task.k[:] = 1
    np.testing.assert_array_equal(task.reference()[0], 0.06)
    v = np.array([0.3, -0.4])
    info = task.info(engine, v)
    want = -(task.reference() - engine.yaw()) ** 2 - np.array([0.0, 2.0]) * v * v
    np.testing.assert_array_equal(task.reward(info), want)
    engine.close()


def test_tracking_reward_is_python_power_on_floats():
    assert tracking_reward(0.1, 2.0, 0.5) == -(0.1 ** 2) - 0.5 * 4.0
    np.testing.assert_array_equal(tracking_reward(np.array([0.1, -0.2]), np.array([1.0, 0.0]), 1.0),
                                  [-(0.1 * 0.1) - 1.0, -(0.2 * 0.2)])


def _wall(delay=0, quantize=False, K=5.0):
    dev0 = Device.load()
    hand = grasp_impedance("medium")
    add_hand(dev0.model, dev0, hand, 0.02)
    device = Device(dev0.model)
    task = WallTask(device, hand, K, 0.0, 0.0, 0.02, quantize, delay, 0.01, None, (65.0, 90.0))
    return device, task


def test_wall_hand_and_observer_by_hand():
    device, task = _wall()
    assert device.model.jnt_stiffness[device.joint_id] == pytest.approx(200.0 * 0.2 ** 2)
    assert device.model.qpos_spring[device.ix.yaw_qpos] == 0.02
    engine, (obs, info) = _one_row(device, task, None)
    y0 = obs[0]
    assert y0 == -0.005 and obs[1] == 0.0 and info["energy"] == 0.0
    v = float(engine.apply(task.before_step(np.array([0.7])))[0])
    obs, reward, terminated, truncated, info = task.after_step(engine, v)
    y1 = float(engine.yaw()[0])  # exact encoder
    assert obs[0] == y1 and obs[1] == (y1 - y0) / 1e-3 and obs[2] == y1
    assert info["energy"] == 0.7 * device.torque_constant * (y1 - y0) == -info["wall_energy"]
    assert reward == -(y1 ** 2) and not terminated and not truncated
    with pytest.raises(InvalidOptionError, match="when made"):
        task.start_episode({"stiffness": 1.0})


def test_wall_delay_line_and_clip():
    device, task = _wall(delay=2)
    _one_row(device, task, None)
    out = [task.before_step(np.array([a])) for a in (0.5, 9.0, -0.25, 0.0)]
    assert out == [0.0, 0.0, 0.5, task.vlim]  # two periods late, clipped to the drive


def test_wall_command_is_the_spring_and_damper_inside_only():
    device, task = _wall(K=5.0)
    task.B = 0.002
    task._y, task._y_prev = 0.01, 0.008
    tau = -(5.0 * 0.01 + 0.002 * 0.002 / 1e-3)
    assert task.wall_command()[0] == np.float32(tau / device.torque_constant)
    task._y, task._y_prev = -0.01, 0.0
    assert task.wall_command()[0] == 0.0


def test_wall_task_defaults_are_the_environments():
    """WallTask's settings default to OmniWallEnv's (one set of documented defaults)."""
    import inspect

    from omni_sim.wall_env import OmniWallEnv

    task = inspect.signature(WallTask).parameters
    env = inspect.signature(OmniWallEnv).parameters
    shared = [name for name in task if name in env]
    assert len(shared) == 8  # stiffness ... start_rad (a renamed setting would drop out)
    for name in shared:
        assert task[name].default == env[name].default, name
    assert task["gamma_set"].default == (env["gamma1_set_deg"].default,
                                         env["gamma2_set_deg"].default)
    device, _ = _wall()
    assert WallTask(device, grasp_impedance("medium")).n == 1000  # 1 s of 1 ms periods
