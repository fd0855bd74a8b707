"""examples/rl_controller: the residual wrapper adds the agent's correction to the PD's volts,
and the committed README section is results.json rendered (no hand-copied figures).  Needs no
stable-baselines3 (the core install has none)."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "examples" / "rl_controller"


@pytest.fixture(scope="module")
def train():
    spec = importlib.util.spec_from_file_location("rl_train", HERE / "train.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["rl_train"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_residual_wrapper_adds_the_correction_to_the_pd(train):
    env = train.ResidualPD(gym.make(train.ENV_ID, **train.ENV_KW), kp=8.0, kd=0.02)
    obs, _ = env.reset(seed=0, options={"reference": "sine", "frequency_hz": 2.0, "amplitude_rad": 0.05})
    assert obs.shape == (6,) and env.observation_space.contains(obs)
    for a in (0.0, 1.0, -0.5):
        inner = env._obs
        obs, _, _, _, info = env.step(np.array([a], np.float32))
        want = train.pd_voltage(inner, 8.0, 0.02) + train.RESIDUAL_V * a
        assert info["voltage"] == pytest.approx(np.clip(want, -1.3, 1.3), rel=1e-6)
        assert obs[5] == pytest.approx((obs[2] - inner[2]) / env.unwrapped.dt)


def test_committed_results_are_complete_and_the_readme_quotes_them(train):
    res = json.loads((HERE / "results.json").read_text())
    assert not res["quick"] and len(res["training"]) >= 3
    for key in ("zero", "best_p", "best_pd"):
        assert {"return", "rms_mrad", "per_case"} <= set(res["held_out"][key])
    assert len(res["held_out"]["residual_ppo"]["per_seed"]) == len(res["training"])
    for run in res["training"]:
        assert run["timesteps"] > 0 and run["wall_s"] > 0 and run["env_steps_per_s"] > 0
    assert {"stable_baselines3", "torch", "gymnasium"} <= set(res["versions"])
    text = (HERE / "README.md").read_text()
    block = re.search(r"<!-- results -->\n(.*?)\n<!-- /results -->", text, re.S).group(1)
    assert block == train.results_markdown(res)
    assert (HERE / "learning_curve.png").is_file()
