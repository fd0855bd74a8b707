"""The native vector environment: N virtual Omnis in one call, each equal to the single
environment seeded ``seed + i``, step for step, across autoresets.

Compared bit for bit: both environments step MuJoCo's ``mj_step`` (``mujoco.rollout`` row by
row, or on its own ``MjData``) and compute the observation, filter and reward with the same
elementwise formulas (+, -, *, /, clip: correctly rounded by IEEE 754 on every SIMD path), the
references and noise from the same generators; a difference would be a bug, not rounding."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import omni_sim  # noqa: F401  (registers the environments)
from omni_sim.env import OmniYawEnv
from omni_sim.vector_env import OmniYawVectorEnv

ENV_ID = "omni_sim/OmniYaw-v0"
KP = 2.0


def _p(obs):
    """The paper's P controller on observations of shape (..., 5)."""
    return KP * (obs[..., 2:3] - obs[..., 0:1])


def test_make_vec_gives_the_native_vector_env():
    venv = gym.make_vec(ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", duration_s=0.1)
    assert isinstance(venv.unwrapped, OmniYawVectorEnv)
    assert venv.num_envs == 4
    assert venv.action_space.shape == (4, 1) and venv.observation_space.shape == (4, 5)
    obs, info = venv.reset(seed=0)
    assert obs.shape == (4, 5) and venv.observation_space.contains(obs)
    venv.close()


@pytest.mark.parametrize("options", [
    dict(reference="steps", step_period_s=0.05, noise_rad=2e-4, quantize=True, velocity="estimated"),
    dict(reference="sine", frequency_hz=3.0, gamma1_set_deg=25, gamma2_set_deg=115),
])
def test_sub_env_i_is_the_single_env_seeded_seed_plus_i(options):
    """Same reference, noise, start state and trajectory, step for step, through an autoreset
    (gymnasium's NextStep mode: the step after the end returns the new episode's first
    observation, reward 0)."""
    N, seed, n = 3, 7, 250  # 0.2 s episodes: the run crosses one autoreset
    venv = OmniYawVectorEnv(num_envs=N, duration_s=0.2, nthread=2, **options)
    singles = [OmniYawEnv(duration_s=0.2, **options) for _ in range(N)]
    vobs, _ = venv.reset(seed=seed)
    sobs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    np.testing.assert_array_equal(vobs, np.array(sobs))
    ended = np.zeros(N, dtype=bool)
    resets = 0
    for k in range(n):
        act = _p(vobs)
        vobs, vrew, vterm, vtrunc, vinfo = venv.step(act)
        for i, env in enumerate(singles):
            if ended[i]:  # NextStep autoreset of the single env, by hand
                o, _ = env.reset()
                r, term, trunc = 0.0, False, False
                resets += 1
            else:
                o, r, term, trunc, info = env.step(act[i])
                assert vinfo["voltage"][i] == info["voltage"]
                assert vinfo["time"][i] == info["time"]
            np.testing.assert_array_equal(vobs[i], o, err_msg=f"step {k}, sub-env {i}")
            assert vrew[i] == r and vterm[i] == term and vtrunc[i] == trunc
            ended[i] = term or trunc
    assert resets == N  # every sub-environment went through one autoreset
    if options.get("reference") == "steps":  # random levels: different seeds, different episodes
        assert not np.array_equal(vobs[0], vobs[1])
    venv.close()


def test_bad_actions_and_options():
    venv = OmniYawVectorEnv(num_envs=2, duration_s=0.05)
    venv.reset(seed=0)
    for bad in (np.zeros(2), np.zeros((2, 2)), np.zeros((3, 1))):
        with pytest.raises(ValueError, match="shape"):
            venv.step(bad)
    with pytest.raises(ValueError, match="finite"):
        venv.step(np.array([[0.0], [np.nan]]))
    with pytest.raises(ValueError, match="num_envs"):
        OmniYawVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="amplitude"):
        OmniYawVectorEnv(num_envs=2, amplitude_rad=-1.0)
    venv.close()


def test_reset_mask_resets_only_those():
    venv = OmniYawVectorEnv(num_envs=3, duration_s=0.5, reference="steps")
    obs0, _ = venv.reset(seed=1)
    for _ in range(20):
        obs, *_ = venv.step(_p(obs0 if _ == 0 else obs))
    mask = np.array([False, True, False])
    obs2, info = venv.reset(seed=1, options={"reset_mask": mask})
    np.testing.assert_array_equal(obs2[1], obs0[1])  # back to the start of the same episode
    np.testing.assert_array_equal(obs2[[0, 2]], obs[[0, 2]])  # the others untouched
    assert info["time"][1] == 0.0 and info["time"][0] > 0
    venv.close()
