"""The gymnasium environment: gymnasium's checker, invariants in the style of gymnasium/dm_control
(determinism, finite and bounded observations, reset restores the state, dt = timestep x
substeps), one source of truth with the dataset generator, the velocity estimator and the
alpha-invariant wrapper against slow references, rendering, and the error paths."""

import json
import math
import os
import re
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy.signal import lfilter

import omni_sim  # noqa: F401  (registers the environment)
from identification.errors import UserError
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device
from omni_sim.env import (VELOCITY_FILTER_HZ, AlphaInvariantObservation, InvalidOptionError,
                          OmniYawEnv)

ENV_ID = "omni_sim/OmniYaw-v0"
KP = 2.0  # [V/rad], the paper's yaw gain
NOISY = dict(reference="steps", quantize=True, noise_rad=1e-3, velocity="estimated",
             effort_weight=0.1, duration_s=0.5)


def _p_rollout(env, kp=KP, return_arm=False):
    """Run a clipped P controller v = kp (r - theta) through the env to truncation."""
    vmax = env.unwrapped.voltage_limit
    obs, _ = env.reset(seed=0)
    theta, v, r, arm = [], [], [], []
    truncated = False
    while not truncated:
        vk = min(max(kp * (obs[2] - obs[0]), -vmax), vmax)
        theta.append(obs[0]), v.append(vk), r.append(obs[2]), arm.append(obs[3:5])
        obs, _, terminated, truncated, _ = env.step(np.array([vk]))
        assert not terminated
    if return_arm:
        return np.array(theta), np.array(v), np.array(r), np.array(arm)
    return np.array(theta), np.array(v), np.array(r)


def _random_rollout(env, seed, n, options=None, bang_bang=False):
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed, options=options)
    out = [obs]
    vmax = env.unwrapped.voltage_limit
    for k in range(n):
        a = (vmax * np.sign(math.sin(k / 150.0)) if bang_bang else rng.uniform(-vmax, vmax))
        obs, reward, _, truncated, info = env.step(np.array([a], dtype=np.float32))
        out.append(obs)
        if truncated:
            break
    return np.array(out)


# --- gymnasium's checker and the invariants ------------------------------------------------
@pytest.mark.parametrize("options", [{}, NOISY], ids=["default", "noisy"])
def test_check_env(options):
    env = gym.make(ENV_ID, **options)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # the render modes: headless in a subprocess (test_check_env_headless_tries_every_mode)
        check_env(env.unwrapped, skip_render_check=True)
    # the only accepted warning: gymnasium's advice to normalise the action space (ours is in V)
    other = [str(w.message) for w in caught if "normalized space" not in str(w.message)]
    assert not other, other
    env.close()


def _rescaled(**options):
    from gymnasium.wrappers import RescaleAction

    return RescaleAction(gym.make(ENV_ID, **options), np.float32(-1), np.float32(1))


def test_rescaled_action_is_the_documented_normalisation():
    """RescaleAction with float32 bounds: a float32 box of +-1 mapped linearly onto +-1.3 V,
    made without a warning (float64 bounds would warn that the box's precision is lowered)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = _rescaled(reference="sine")
    assert not [str(w.message) for w in caught]
    assert env.action_space.dtype == np.float32
    assert np.array_equal(env.action_space.low, [-1]) and np.array_equal(env.action_space.high, [1])
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([0.5], np.float32))
    assert info["voltage"] == pytest.approx(0.5 * env.unwrapped.voltage_limit, rel=1e-6)


def test_rescaled_env_passes_stable_baselines3_check_without_warning():
    """stable-baselines3's checker on the documented wrapped env: no warning (it warns about the
    raw +-1.3 V box).  Optional: the core install has no stable-baselines3."""
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(_rescaled())
    assert not [str(w.message) for w in caught]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(gym.make(ENV_ID))
    assert any("symmetric and normalized" in str(w.message) for w in caught)


def test_dt_is_timestep_times_substeps(tmp_path):
    env = OmniYawEnv()
    assert env.substeps == 1 and env.dt == env.model.opt.timestep * env.substeps == 1e-3
    assert env.metadata["render_fps"] == round(1 / env.dt)
    env2 = OmniYawEnv(control_period_s=2e-3)
    assert env2.substeps == 2 and env2.dt == pytest.approx(2e-3, abs=1e-15)
    assert env2.metadata["render_fps"] == 500
    # a model with a 0.5 ms physics step: two substeps per 1 ms control period
    xml = (om.OMNI_DIR / "omni.xml").read_text().replace('timestep="0.001"', 'timestep="0.0005"')
    (tmp_path / "omni_fast.xml").write_text(xml)
    env3 = gym.make(ENV_ID, model_path=tmp_path / "omni_fast.xml")
    assert env3.unwrapped.substeps == 2
    assert env3.unwrapped.dt == env3.unwrapped.model.opt.timestep * 2 == 1e-3
    assert env3.unwrapped.data.time == 0
    env3.reset(seed=0)
    env3.step(np.array([0.1]))
    assert env3.unwrapped.data.time == pytest.approx(1e-3, abs=1e-15)
    with pytest.raises(ValueError, match="whole multiple"):
        OmniYawEnv(control_period_s=1.5e-3)


def test_determinism_under_a_seed():
    a = _random_rollout(gym.make(ENV_ID, **NOISY), seed=7, n=300)
    b = _random_rollout(gym.make(ENV_ID, **NOISY), seed=7, n=300)
    c = _random_rollout(gym.make(ENV_ID, **NOISY), seed=8, n=300)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[:, 0], c[:, 0])  # noise and steps come from the seed
    assert not np.array_equal(a[:, 2], c[:, 2])


def test_reset_restores_full_state():
    env = OmniYawEnv(**NOISY)
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    size = mujoco.mj_stateSize(env.model, spec)

    def state():
        x = np.empty(size)
        mujoco.mj_getState(env.model, env.data, x, spec)
        return x

    obs0, _ = env.reset(seed=3)
    s0 = state()
    _random_rollout(env, seed=3, n=200)
    _random_rollout(env, seed=4, n=100, options={"friction_scale": 0.0, "gamma1_set_deg": 25.0})
    assert env.device.friction() == {**Device.load().friction(), "frictionloss": 0.0,
                                     "lugre_Fc": 0.0, "lugre_Fs": 0.0}
    obs1, _ = env.reset(seed=3)
    np.testing.assert_array_equal(state(), s0)
    np.testing.assert_array_equal(obs0, obs1)
    # per-episode options do not leak into the next episode
    assert env.device.friction() == Device.load().friction()


@pytest.mark.parametrize("bang_bang", [False, True], ids=["random", "bang-bang"])
@pytest.mark.parametrize("options", [{}, NOISY, {"friction_scale": 0.0, "velocity": "estimated"}],
                         ids=["default", "noisy", "frictionless"])
def test_observations_finite_and_within_bounds(options, bang_bang):
    env = OmniYawEnv(**{**options, "duration_s": 1.5})
    obs = _random_rollout(env, seed=1, n=1500, bang_bang=bang_bang)
    assert np.all(np.isfinite(obs))
    space = env.observation_space
    assert all(space.contains(o) for o in obs)
    if bang_bang:  # the yaw reached its stop and stayed within the bound
        assert np.max(np.abs(obs[:, 0])) > 0.9


def test_observation_not_shared_between_steps():
    env = OmniYawEnv()
    obs0, _ = env.reset(seed=0)
    keep = obs0.copy()
    env.step(np.array([1.0]))
    np.testing.assert_array_equal(obs0, keep)


# --- one source of truth: the env and the dataset generator -------------------------------
@pytest.mark.parametrize("kind,quantize,pose", [
    ("sine", False, (65, 90)),
    ("sine", True, (45, 70)),
    ("square", True, (35, 110)),
    ("square", False, (25, 60)),
])
def test_p_controller_reproduces_generator(kind, quantize, pose):
    """kp = 2 V/rad through the env == omni_sim.experiments.simulate (same pose, reference)."""
    if kind == "sine":
        exp = ex.sine_experiment(*pose, 3.0, settle_s=1.0, record_s=1.0)
    else:
        exp = ex.square_experiment(*pose, duration_s=2.0)
    run = ex.simulate(Device.load(), [exp], settings=ex.Settings(kp=KP, quantize=quantize), jobs=1)[0]
    env = gym.make(ENV_ID, gamma1_set_deg=pose[0], gamma2_set_deg=pose[1], reference=kind,
                   frequency_hz=exp.frequency_hz, amplitude_rad=exp.amplitude_rad,
                   duration_s=len(exp.r) * ex.CONTROL_PERIOD_S, quantize=quantize)
    theta, v, r, arm = _p_rollout(env, return_arm=True)
    assert len(theta) == len(run.theta)
    np.testing.assert_allclose(r, run.r, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(theta, run.theta)  # one engine: identical, not close
    np.testing.assert_array_equal(v, run.v)
    # the arm's actual pose in the observation gives the generator's metadata (mean of q1, q2,
    # rounded to 1e-6 deg)
    g1, g2 = np.degrees(arm.mean(axis=0))
    assert g1 == pytest.approx(run.meta["gamma1_deg"], abs=1e-6)
    assert g2 == pytest.approx(run.meta["gamma2_deg"], abs=1e-6)
    assert np.max(np.abs(theta - r)) > 1e-3  # a non-trivial trajectory


def test_user_array_reference_matches_generator_reference_loop():
    t = np.arange(1500) * ex.CONTROL_PERIOD_S
    r = 0.05 * np.sin(2 * np.pi * 1.7 * t) + 0.03 * np.sign(np.sin(2 * np.pi * 0.9 * t))
    exp = ex.Experiment("user", "other", 55.0, 110.0, r, 0.0, 0.08, theta0_rad=float(r[0]))
    run = ex.simulate(Device.load(), [exp], force_reference=True, jobs=1)[0]
    env = OmniYawEnv(gamma1_set_deg=55.0, gamma2_set_deg=110.0, reference=r)
    theta, v, r_obs = _p_rollout(env)
    np.testing.assert_array_equal(r_obs, r)
    np.testing.assert_array_equal(theta, run.theta)


# --- options ------------------------------------------------------------------------------
def test_truncation_and_reward():
    env = gym.make(ENV_ID, duration_s=0.05, effort_weight=0.5)
    obs, info = env.reset(seed=0)
    steps = 0
    truncated = False
    while not truncated:
        obs, reward, terminated, truncated, info = env.step(np.array([5.0]))  # clipped
        steps += 1
        assert info["voltage"] == env.unwrapped.voltage_limit
        assert reward == pytest.approx(-info["tracking_error"] ** 2 - 0.5 * info["voltage"] ** 2,
                                       rel=1e-12)
    assert steps == 50 and info["time"] == pytest.approx(0.05)
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.array([0.0]))


def test_reference_shapes():
    env = OmniYawEnv()
    dt = env.dt

    def refs(seed=0, **options):
        out = [env.reset(seed=seed, options=options)[0][2]]
        truncated = False
        while not truncated:
            obs, _, _, truncated, _ = env.step(np.array([0.0]))
            out.append(obs[2])
        return np.array(out[:-1])  # the last observation holds the final sample

    sine = refs(reference="sine", frequency_hz=1.5, amplitude_rad=0.2, duration_s=1.0)
    np.testing.assert_allclose(sine, 0.2 * np.sin(2 * np.pi * 1.5 * np.arange(1000) * dt), atol=1e-15)
    sq = refs(reference="square", frequency_hz=1.0, amplitude_rad=0.05, duration_s=2.0)
    np.testing.assert_array_equal(sq, ex.square_experiment(65, 90, 1.0, 0.05, 2.0).r)
    assert env.reset(options={"reference": "square"})[0][0] == -ex.STEP_AMPLITUDE_RAD  # theta0 = -A
    steps = refs(seed=5, reference="steps", amplitude_rad=0.3, step_period_s=0.25, duration_s=1.0)
    levels = steps.reshape(4, 250)
    assert np.all(levels == levels[:, :1]) and np.all(np.abs(levels) <= 0.3)
    assert len(np.unique(levels[:, 0])) == 4
    np.testing.assert_array_equal(steps, refs(seed=5, reference="steps", amplitude_rad=0.3,
                                              step_period_s=0.25, duration_s=1.0))
    user = np.linspace(0.1, -0.1, 300)
    assert env.reset(options={"reference": user})[0][0] == 0.1  # theta0 = r[0]
    np.testing.assert_array_equal(refs(reference=user), user)
    np.testing.assert_array_equal(refs(reference=user, duration_s=0.1), user[:100])


def test_friction_scale_and_pose_options():
    env = OmniYawEnv(friction_scale=2.0, gamma1_set_deg=25.0, gamma2_set_deg=115.0)
    base_dev = Device.load()
    base, ix = base_dev.model, base_dev.ix
    obs, _ = env.reset(seed=0)
    f, f0 = env.device.friction(), base_dev.friction()
    for k in ("frictionloss", "lugre_Fc", "lugre_Fs"):
        assert f[k] == 2.0 * f0[k], k
    assert f["lugre_sigma0"] == f0["lugre_sigma0"]
    assert env.model.dof_damping[ix.yaw_dof] == 2.0 * base.dof_damping[ix.yaw_dof]
    g1, g2 = base_dev.equilibrium(25.0, 115.0)
    assert obs[3] == pytest.approx(math.radians(g1), abs=1e-12)
    assert obs[4] == pytest.approx(math.radians(g2), abs=1e-12)
    assert g1 < 25.0  # sagged below the set point
    env.reset(options={"friction_scale": 0.5})
    assert env.model.dof_damping[ix.yaw_dof] == 0.5 * base.dof_damping[ix.yaw_dof]


def test_estimated_velocity_against_offline_filter():
    """'estimated' = 2nd-order backward difference of theta, then a 20 Hz first-order low-pass."""
    opts = dict(reference="sine", frequency_hz=3.0, duration_s=1.0, quantize=True)
    theta, _, _ = _p_rollout(OmniYawEnv(**opts))
    env = OmniYawEnv(velocity="estimated", **opts)
    obs, _ = env.reset(seed=0)
    est = [obs[1]]
    for k in range(len(theta) - 1):
        obs, *_ = env.step(np.array([np.clip(KP * (obs[2] - obs[0]), -1.3, 1.3)]))
        est.append(obs[1])
    dt = env.dt
    y = np.concatenate([[theta[0], theta[0]], theta])  # at rest before the episode
    diff = (3 * y[2:] - 4 * y[1:-1] + y[:-2]) / (2 * dt)
    a = 1 - math.exp(-2 * math.pi * VELOCITY_FILTER_HZ * dt)
    ref = lfilter([a], [1, -(1 - a)], diff)
    np.testing.assert_allclose(est, ref, rtol=0, atol=1e-9)
    # and it follows the true velocity with the filter's lag (~8 ms at 20 Hz): loose check
    exact, *_ = _p_rollout(OmniYawEnv(**opts))
    assert np.corrcoef(np.gradient(exact, dt)[300:], np.array(est)[300:])[0, 1] > 0.95


def test_alpha_wrapper_constant_for_sine_voltage():
    """For v = A sin(w t) the backward-difference alpha is exactly A^2 w^2 (sin d/d)^2 (1 - sin^2 d),
    d = w dt / 2 (independent truth; -> A^2 w^2 as dt -> 0), once the low-pass has settled."""
    env = AlphaInvariantObservation(gym.make(ENV_ID, duration_s=2.0), time_constant_s=0.1)
    assert env.observation_space.shape == (6,)
    obs, _ = env.reset(seed=0)
    assert obs[5] == 0.0
    A, w, dt = 0.2, 2 * np.pi * 2.0, env.unwrapped.dt
    alphas = []
    for k in range(2000):
        obs, _, _, truncated, info = env.step(np.array([A * math.sin(w * k * dt)]))
        assert env.observation_space.contains(obs)
        alphas.append(obs[5])
    d = w * dt / 2
    exact = A**2 * w**2 * (math.sin(d) / d) ** 2 * (1 - math.sin(d) ** 2)
    assert alphas[-1] == pytest.approx(exact, rel=1e-6)
    assert alphas[-1] == pytest.approx(A**2 * w**2, rel=1e-3)
    assert info["alpha_raw"] == pytest.approx(exact, rel=1e-9)
    obs, _ = env.reset(seed=0)
    assert obs[5] == 0.0


# --- error paths --------------------------------------------------------------------------
@pytest.mark.parametrize("options,match", [
    ({"gamma1_set_deg": 120.0}, "shoulder angle 120 deg is outside"),
    ({"gamma2_set_deg": 10.0}, "elbow angle 10 deg is outside"),
    ({"gamma1_set_deg": float("nan")}, "gamma1_set_deg must be finite"),
    ({"frequency_hz": -2.0}, "frequency_hz must be finite and > 0"),
    ({"frequency_hz": 0.0}, "frequency_hz must be finite and > 0"),
    ({"amplitude_rad": float("nan")}, "amplitude_rad"),
    ({"amplitude_rad": 1.5}, "amplitude_rad"),
    ({"reference": "triangle"}, "reference must be one of"),
    ({"reference": [0.0, 2.0]}, "leaves the yaw joint range"),
    ({"reference": [[0.0]]}, "1-D"),
    ({"reference": [0.0] * 10, "duration_s": 1.0}, "longer than the array"),
    ({"duration_s": 0.0}, "duration_s"),
    ({"noise_rad": 0.5}, "noise_rad"),
    ({"friction_scale": -1.0}, "friction_scale"),
    ({"velocity": "magic"}, "velocity must be one of"),
    ({"effort_weight": -0.1}, "effort_weight"),
    ({"theta0_rad": 2.0}, "theta0_rad"),
    ({"gain": 2.0}, "unknown option 'gain'"),
])
def test_bad_options_raise(options, match):
    with pytest.raises(ValueError, match=match) as make_err:
        OmniYawEnv(**options)
    assert isinstance(make_err.value, UserError)
    env = OmniYawEnv()
    with pytest.raises(InvalidOptionError, match=match):
        env.reset(options=options)


def test_make_only_options_and_bad_model(tmp_path):
    env = OmniYawEnv()
    with pytest.raises(ValueError, match="only be given when the environment is made"):
        env.reset(options={"model_path": om.DEFAULT_SCENE})
    with pytest.raises(ValueError, match="model file not found"):
        OmniYawEnv(model_path=tmp_path / "missing.xml")
    with pytest.raises(ValueError, match="render_mode"):
        OmniYawEnv(render_mode="video")
    with pytest.raises(ValueError, match="no camera named"):
        OmniYawEnv(camera="top")


@pytest.mark.parametrize("action,match", [
    (np.array([0.1, 0.2]), "shape"),
    (np.zeros((1, 1, 2)), "shape"),
    (np.array([np.nan]), "finite"),
    (np.array([np.inf]), "finite"),
])
def test_bad_actions_raise(action, match):
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.unwrapped.step(action)


# --- rendering (in a subprocess: MUJOCO_GL must be set before mujoco is imported) ----------
_RENDER_SCRIPT = textwrap.dedent("""
    import json, sys
    import mujoco
    import numpy as np
    try:  # is there a working GL backend at all?
        m = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
        mujoco.Renderer(m, 8, 8).close()
    except Exception as exc:
        print(repr(exc), file=sys.stderr)
        sys.exit(77)
    import gymnasium as gym
    import omni_sim  # noqa: F401
    out = {}
    for g1, g2 in [(25.0, 70.0), (65.0, 115.0)]:
        env = gym.make("omni_sim/OmniYaw-v0", render_mode="rgb_array",
                       gamma1_set_deg=g1, gamma2_set_deg=g2)
        env.reset(seed=0)
        img = env.render()
        u = env.unwrapped
        # the same view without the robot (geom group 2): the robot's pixels are those that change
        r = mujoco.Renderer(u.model, *img.shape[:2])
        opt = mujoco.MjvOption()
        opt.geomgroup[2] = 0
        r.update_scene(u.data, camera="side", scene_option=opt)
        bare = r.render()
        r.close()
        # project the gimbal centre (site "tip") through the "side" camera
        cam = mujoco.mj_name2id(u.model, mujoco.mjtObj.mjOBJ_CAMERA, "side")
        tip = u.data.site("tip").xpos
        pc = u.data.cam_xmat[cam].reshape(3, 3).T @ (tip - u.data.cam_xpos[cam])
        h, w = img.shape[:2]
        f = 0.5 * h / np.tan(np.radians(u.model.cam_fovy[cam]) / 2)
        col, row = int(round(w / 2 + f * pc[0] / -pc[2])), int(round(h / 2 - f * pc[1] / -pc[2]))
        robot = np.any(img != bare, axis=2)
        win = robot[max(row - 3, 0):row + 4, max(col - 3, 0):col + 4]
        out[f"{g1:g},{g2:g}"] = dict(shape=list(img.shape), dtype=str(img.dtype),
                                     std=float(img.std()), robot_px=int(robot.sum()),
                                     tip_px=[row, col], tip_on_robot=bool(win.any()))
        np.save(sys.argv[1] + f"_{g1:g}.npy", img)
        env.close()
    print(json.dumps(out))
""")


def test_render_rgb_array(tmp_path):
    errors = []
    for backend in ("egl", "osmesa"):
        proc = subprocess.run([sys.executable, "-c", _RENDER_SCRIPT, str(tmp_path / "img")],
                              env={**os.environ, "MUJOCO_GL": backend}, capture_output=True,
                              text=True, timeout=120)
        if proc.returncode == 77:
            errors.append(f"{backend}: {proc.stderr.strip().splitlines()[-1:]}")
            continue
        assert proc.returncode == 0, proc.stderr
        break
    else:
        pytest.skip("no headless GL backend works here (tried MUJOCO_GL=egl, osmesa): "
                    + "; ".join(errors))
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    for pose, r in res.items():
        assert r["shape"] == [480, 640, 3] and r["dtype"] == "uint8", (pose, r)
        assert r["std"] > 10, f"blank image at pose {pose}: {r}"
        assert r["robot_px"] > 2000, f"robot not visible at pose {pose}: {r}"
        assert r["tip_on_robot"], f"the arm's tip is not where the pose puts it ({pose}): {r}"
    a, b = (np.load(tmp_path / f"img_{g:g}.npy") for g in (25.0, 65.0))
    assert np.mean(np.any(a != b, axis=2)) > 0.005  # the two poses look different


def headless_env(mujoco_gl):
    """This process's environment without a display (and MUJOCO_GL as given; None: unset)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL")}
    return env if mujoco_gl is None else {**env, "MUJOCO_GL": mujoco_gl}


#: Run in a fresh process (argv: env id): which render modes the instance advertises, the error
#: of making each one it does not, then gymnasium's full checker, which makes, resets and renders
#: every advertised mode.  Exit 77 when MUJOCO_GL names a backend that cannot make a context.
HEADLESS_CHECK = textwrap.dedent("""
    import json, os, sys
    import mujoco
    if os.environ.get("MUJOCO_GL"):
        try:
            mujoco.GLContext(8, 8).free()
        except Exception as exc:
            print(repr(exc), file=sys.stderr)
            sys.exit(77)
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env
    import omni_sim  # registers the environments
    env_id = sys.argv[1]
    env = gym.make(env_id)
    modes = list(env.unwrapped.metadata["render_modes"])
    refused = {}
    for mode in ("human", "rgb_array"):
        if mode not in modes:
            try:
                gym.make(env_id, render_mode=mode)
            except ValueError as exc:
                refused[mode] = str(exc)
    check_env(env.unwrapped)
    print(json.dumps({"modes": modes, "refused": refused}))
""")


def run_headless_check(env_id, mujoco_gl):
    """:data:`HEADLESS_CHECK` without a display; skips when MUJOCO_GL's backend cannot work."""
    proc = subprocess.run([sys.executable, "-c", HEADLESS_CHECK, env_id], capture_output=True,
                          text=True, timeout=300, env=headless_env(mujoco_gl))
    if proc.returncode == 77:
        pytest.skip(f"MUJOCO_GL={mujoco_gl} cannot make an OpenGL context here: "
                    f"{proc.stderr.strip().splitlines()[-1:]}")
    # a GLFW failure ends the process (exit 1, "could not initialize GLFW"), not an exception
    assert proc.returncode == 0, proc.stderr[-2000:]
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert "human" not in res["modes"]
    assert "needs a display" in res["refused"]["human"]
    if mujoco_gl is None:  # MuJoCo's default backend, GLFW, needs a display too
        assert res["modes"] == []
        assert "MUJOCO_GL=egl" in res["refused"]["rgb_array"]
    else:  # the checker rendered an image
        assert res["modes"] == ["rgb_array"]
    return res


@pytest.mark.parametrize("mujoco_gl", [None, "egl"], ids=["MUJOCO_GL-unset", "egl"])
def test_check_env_headless_tries_every_mode(mujoco_gl):
    """Without a display, gymnasium's full check_env (render modes included) passes: the env
    advertises only the modes that can work and refuses the others when made, with a reason."""
    run_headless_check(ENV_ID, mujoco_gl)


def test_human_mode_needs_a_display(monkeypatch):
    """Without a display "human" is refused when made (it used to end the process at the first
    render: GLFW's failure); with one it is offered (no window is opened here)."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(InvalidOptionError, match="needs a display .*MUJOCO_GL=egl"):
        gym.make(ENV_ID, render_mode="human")
    assert "human" not in OmniYawEnv().metadata["render_modes"]
    monkeypatch.setenv("DISPLAY", ":0")
    assert "human" in OmniYawEnv().metadata["render_modes"]
    assert OmniYawEnv.metadata["render_modes"] == ["human", "rgb_array"]  # what the class offers


def test_readme_env_ids_work_as_written():
    """Every environment id the README writes makes an environment, as written, in a fresh
    process that imports only gymnasium (gymnasium loads no plugins: a bare id needs omni_sim
    imported first, the ``omni_sim:`` form imports it)."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    ids = sorted(set(re.findall(r"(?:[A-Za-z_][\w.]*:)?omni_sim/\w+-v\d+", readme)))
    assert {i.split(":")[-1] for i in ids} == {"omni_sim/OmniYaw-v0", "omni_sim/OmniWall-v0"}, ids
    code = ("import sys, gymnasium\n"
            "for env_id in sys.argv[1:]:\n"
            "    gymnasium.make(env_id).close()\n")
    out = subprocess.run([sys.executable, "-c", code, *ids], capture_output=True, text=True,
                         timeout=120, env=headless_env(None))
    assert out.returncode == 0, out.stderr[-2000:]


@pytest.mark.parametrize("order", ["omni_sim first", "gymnasium first"])
def test_environment_registered_in_either_import_order(order):
    """``import omni_sim`` registers the environment with gymnasium (``gymnasium.register`` in
    the package, as gymnasium documents), whether gymnasium was imported before or after."""
    import subprocess
    import sys

    imports = ("import omni_sim; import gymnasium as gym" if order == "omni_sim first"
               else "import gymnasium as gym; import omni_sim")
    code = (f"{imports}\n"
            "env = gym.make('omni_sim/OmniYaw-v0')\n"
            "print(type(env.unwrapped).__name__)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "OmniYawEnv"
