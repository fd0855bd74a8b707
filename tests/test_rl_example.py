"""examples/rl_controller: the residual wrapper adds the agent's correction to the PD's volts;
the held-out episodes are distinct and unlike training's; the committed README section is
results.json's per-episode scores summarised (recomputed here, not read from a stored verdict);
the script writes outside the tracked files by default and refuses bad input in one line.
Needs no stable-baselines3 (the core install has none)."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "examples" / "rl_controller"


@pytest.fixture(scope="module")
def train():
    spec = importlib.util.spec_from_file_location("rl_train", HERE / "train.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["rl_train"] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def res():
    return json.loads((HERE / "results.json").read_text())


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


def _tracked_reference(train, case) -> np.ndarray:
    """The reference an episode of ``case`` shows the controller, read from the observations."""
    options, seed = train.env_case(case)
    env = gym.make(train.ENV_ID, **train.ENV_KW)
    obs, _ = env.reset(seed=seed, options=options)
    refs, done = [obs[2]], False
    while not done:
        obs, _, term, trunc, _ = env.step(np.zeros(1, np.float32))
        refs.append(obs[2])
        done = term or trunc
    env.close()
    return np.array(refs[:-1])


@pytest.mark.slow  # 10 s CPU: 24 whole episodes stepped through the env (end to end)
def test_held_out_episodes_are_many_distinct_and_unlike_training(train):
    cases = train.held_out_cases()
    assert len(cases) >= 20
    n = round(train.ENV_KW["duration_s"] / train.ENV_KW["control_period_s"])
    refs = [_tracked_reference(train, c) for c in cases]
    for c, r in zip(cases, refs):
        assert r.size == n
        if c["reference"] == "sine":  # the sine the case names, sample by sample
            t = np.arange(n) * train.ENV_KW["control_period_s"]
            want = c["amplitude_rad"] * np.sin(2 * np.pi * c["frequency_hz"] * t + c["phase_rad"])
            np.testing.assert_allclose(r, want, rtol=0, atol=1e-12)
            # training sines have phase 0 and a frequency in TRAIN_FREQ_HZ: differ in one of them
            lo, hi = train.TRAIN_FREQ_HZ
            phase = c["phase_rad"] % (2 * np.pi)
            assert not lo <= c["frequency_hz"] <= hi or min(phase, 2 * np.pi - phase) > 1e-3
    for i in range(len(refs)):
        for j in range(i):
            assert not np.array_equal(refs[i], refs[j]), f"held-out cases {j} and {i} are the same episode"
    assert {c["band"] for c in cases} == set(train.BANDS)


def _recompute(res: dict, band: str) -> dict:
    """The table's numbers for one band, from the per-episode rows, by hand."""
    def mean_rms(rows):
        return float(np.mean([r["rms_mrad"] for r in rows if band == "all" or r["band"] == band]))

    pd = mean_rms(res["held_out"]["best_pd"])
    ppo = np.array([mean_rms(rows) for rows in res["held_out"]["residual_ppo"]])
    gain = pd - ppo
    half = stats.t.ppf(0.975, gain.size - 1) * gain.std(ddof=1) / np.sqrt(gain.size)
    return {"zero": mean_rms(res["held_out"]["zero"]), "best_p": mean_rms(res["held_out"]["best_p"]),
            "best_pd": pd, "ppo": ppo.mean(), "gain": (gain.mean(), gain.mean() - half, gain.mean() + half),
            "better": int((gain > 0).sum())}


def test_committed_record_is_the_code_s_and_complete(train, res):
    assert not res["quick"] and len(res["training"]) >= 5
    assert res["held_out_cases"] == train.held_out_cases()  # the record was made with these episodes
    n_cases = len(res["held_out_cases"])
    digests = [r["reference_sha256"] for r in res["held_out"]["best_pd"]]
    assert n_cases >= 20 and len(set(digests)) == n_cases
    for rows in [res["held_out"][k] for k in ("zero", "best_p", "best_pd")] + res["held_out"]["residual_ppo"]:
        assert [r["case"] for r in rows] == list(range(n_cases))
        assert [r["reference_sha256"] for r in rows] == digests  # every controller saw the same episodes
    assert len(res["held_out"]["residual_ppo"]) == len(res["training"])
    for run in res["training"]:
        assert run["timesteps"] > 0 and run["wall_s"] > 0 and run["env_steps_per_s"] > 0
    assert {"stable_baselines3", "torch", "gymnasium"} <= set(res["versions"])
    assert (HERE / "learning_curve.png").is_file()


def test_readme_table_and_verdict_are_recomputed_from_the_episodes(train, res):
    text = (HERE / "README.md").read_text()
    block = re.search(r"<!-- results -->\n(.*?)\n<!-- /results -->", text, re.S).group(1)
    assert block == train.results_markdown(res)
    rows = {line.split(" | ")[0].lstrip("| "): line.split(" | ")[1:] for line in block.splitlines()
            if line.startswith("| ")}
    n = len(res["training"])
    calls = {}
    for col, band in enumerate(("all", *train.BANDS)):
        want = _recompute(res, band)
        assert rows["zero command"][col] == f"{want['zero']:.2f}"
        assert rows[next(k for k in rows if k.startswith("best P ("))][col] == f"{want['best_p']:.2f}"
        assert rows[next(k for k in rows if k.startswith("best PD"))][col] == f"{want['best_pd']:.2f}"
        assert rows["residual PPO on the best PD"][col].startswith(f"{want['ppo']:.2f} [")
        m, lo, hi = want["gain"]
        assert rows["gain over the best PD [mrad]"][col].startswith(f"{m:+.3f} [{lo:+.3f}, {hi:+.3f}]")
        assert rows["seeds better than the best PD"][col] == f"{want['better']} of {n}"
        calls[band] = "better" if lo > 0 else "worse" if hi < 0 else "not resolved"
    verdict = re.search(r"Verdict: (.*)", block).group(1)
    word = {"better": "lower than", "worse": "higher than", "not resolved": "not distinguishable from"}[calls["all"]]
    assert f"RMS error is {word} the best PD's" in verdict
    by_band = dict(part.split(": ", 1) for part in verdict.split("around zero): ")[1].rstrip(".").split("; "))
    for band in train.BANDS:
        assert train.band_heading(band) in by_band[calls[band]].split(", "), (band, calls[band], verdict)
    assert res["summary"] == json.loads(json.dumps(train.summarize(res["held_out"])))


def _refused(train, capsys, argv):
    with pytest.raises(SystemExit) as exc:
        train.main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    return err


def test_without_stable_baselines3_one_error_line_naming_the_extra(train, capsys, monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # find_spec / import: not installed
    err = _refused(train, capsys, ["--quick", "--out", str(tmp_path / "out")])
    assert ".[rl]" in err and "stable_baselines3" in err
    assert not (tmp_path / "out").exists()


def test_default_output_is_outside_the_tracked_files_and_bad_input_is_refused(train, capsys, tmp_path,
                                                                             monkeypatch):
    # the options are checked with the rl extra taken as installed (the README's test command
    # runs without it; its absence is the test above)
    real_find_spec = train.importlib.util.find_spec
    monkeypatch.setattr(train.importlib.util, "find_spec",
                        lambda name, *a: object() if name in ("stable_baselines3", "torch")
                        else real_find_spec(name, *a))
    out = train.parse_args([]).out
    assert not out.is_absolute() and HERE.resolve() not in (Path.cwd() / out).resolve().parents
    assert (Path.cwd() / out).resolve() != HERE.resolve()
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for argv in (["--seeds", "0", "0"], ["--timesteps", "0"], ["--seeds", "-1"], ["--out", str(blocker)],
                 ["--quick", "--out", str(HERE)]):
        _refused(train, capsys, argv + ([] if "--out" in argv else ["--out", str(tmp_path / "out")]))
        assert not (tmp_path / "out").exists() and blocker.read_text() == ""
