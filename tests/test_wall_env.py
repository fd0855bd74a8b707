"""omni_sim/OmniWall-v0: a virtual wall on the yaw, pushed by a hand model."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import omni_sim  # noqa: F401
from omni_sim.wall_env import GRASPS, TIP_RADIUS_M, OmniWallEnv


def _run(env, n=None, seed=0):
    u = env.unwrapped
    env.reset(seed=seed)
    out = []
    for _ in range(n or u.n):
        obs, r, te, tr, info = env.step(u.wall_command())
        out.append((obs.copy(), r, info["energy"], info["penetration"]))
        if te or tr:
            break
    return out


def test_check_env_and_registration():
    env = gym.make("omni_sim/OmniWall-v0")
    check_env(env.unwrapped, skip_render_check=True)


def test_seeded_episode_is_deterministic():
    a = _run(gym.make("omni_sim/OmniWall-v0", friction="coulomb", duration_s=0.3))
    b = _run(gym.make("omni_sim/OmniWall-v0", friction="coulomb", duration_s=0.3))
    assert all(np.array_equal(x[0], y[0]) and x[1:] == y[1:] for x, y in zip(a, b))


def test_hand_push_settles_at_the_spring_balance():
    """Ideal-ish check: with the renderer, the hand spring k_h (push p behind the wall) and the
    wall spring K balance at penetration k_h p / (k_h + K) (exact encoder, no dry friction)."""
    env = OmniWallEnv(quantize=False, stiffness=5.0, damping=0.002, duration_s=2.0)
    env.device.scale_friction(0.0)
    pen = _run(env)[-1][3]
    k_h = GRASPS["medium"][2] * TIP_RADIUS_M ** 2
    assert pen == pytest.approx(k_h * 0.02 / (k_h + 5.0), rel=1e-3)


def test_observer_sign_passive_and_active_wall():
    """Passive wall: the observer's energy into the device never exceeds what the wall's spring
    stores (1/2 K pen^2), ends negative (the wall absorbed energy) and the oscillation decays.
    Without a grasp's damping and with K above Colgate & Schenkel's 2 b / T (b = 0.0069,
    2b/T = 13.9 N*m/rad) the wall puts energy in (E grows positive) and the stylus keeps bouncing off it."""
    passive = _run(OmniWallEnv(grasp=(0.0, 0.0, 50.0), stiffness=5.0, damping=0.0,
                               quantize=False, friction="lugre"))
    E = np.array([e for _, _, e, _ in passive])
    pen = np.array([p for *_, p in passive])
    assert E.max() <= 0.5 * 5.0 * pen.max() ** 2 and E[-1] < 0
    assert np.ptp(pen[-200:]) < 0.5 * np.ptp(pen[200:400])  # the oscillation decays
    env = OmniWallEnv(grasp=(0.0, 0.0, 50.0), stiffness=30.0, damping=0.0, quantize=False,
                      duration_s=1.0)
    env.device.scale_friction(0.0)
    active = _run(env)
    assert active[-1][2] > 1e-4
    assert min(p for *_, p in active[-500:]) < 0  # it keeps bouncing off the wall
    assert min(pen[-500:]) > 0  # the passive one stays in contact


def test_sync_vector_env_rows_are_single_envs_seeded_seed_plus_i():
    venv = gym.make_vec("omni_sim/OmniWall-v0", num_envs=2, vectorization_mode="sync",
                        duration_s=0.05, stiffness=8.0)
    obs, _ = venv.reset(seed=3)
    rows = []
    for _ in range(40):
        u = [e.unwrapped.wall_command() for e in venv.envs]
        obs, r, te, tr, info = venv.step(np.stack(u))
        rows.append(obs.copy())
    single = _run(gym.make("omni_sim/OmniWall-v0", duration_s=0.05, stiffness=8.0), 40, seed=4)
    assert np.array_equal(np.array([s[0] for s in single]), np.array(rows)[:, 1])


@pytest.mark.parametrize("kw", [{"grasp": "iron"}, {"delay": -1}, {"stiffness": float("nan")},
                                {"gamma1_set_deg": 500.0}])
def test_bad_options_raise_value_error(kw):
    with pytest.raises(ValueError):
        OmniWallEnv(**kw)
