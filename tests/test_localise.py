"""Where the gap lives, in words: residuals built with a known concentration (low speed,
reversals, a position band, the command near its limit, one frequency) must be described there,
and an evenly spread residual must not be pinned anywhere."""

import numpy as np
import pytest

from discrepancy.localise import command_lag, command_note, describe, lag_text, localise
from discrepancy.replay import ReplayRun

DT = 1e-3


def _sine_runs(freqs=(1.0, 2.0, 4.0), amps=(0.05, 0.2)):
    runs = []
    for f in freqs:
        for a in amps:
            t = np.arange(3000) * DT
            r = a * np.sin(2 * np.pi * f * t)
            th = 0.9 * a * np.sin(2 * np.pi * f * t - 0.2)
            v = 2.0 * (r - th)
            runs.append(ReplayRun(f"s{f}_{a}", "sine", t, r, th, v, DT, 2.0, (65.0, 90.0), f, a))
    return runs


def _where(runs, residual_of, seed=0, actuator_limit=np.inf):
    rng = np.random.default_rng(seed)
    theta_model = [r.theta + residual_of(r) + 1e-6 * rng.normal(size=r.n) for r in runs]
    loc = localise(runs, theta_model, actuator_limit)
    return [w["where"] for w in describe(loc, noise_rad=1e-6)], loc


def _speed(r):
    return np.gradient(r.theta, DT)


def test_low_speed():
    where, _ = _where(_sine_runs(), lambda r: 1e-3 * (np.abs(_speed(r)) < 0.03 * np.abs(_speed(r)).max()))
    assert "low speed" in where[:3] and "reversals" in where


def test_position_band():
    where, _ = _where(_sine_runs(), lambda r: 1e-3 * (np.abs(r.theta) > 0.12))
    # only the large sines reach |theta| > 0.12 rad: "large amplitudes" comes first, the band next
    assert where[:2] == ["large amplitudes", "position band"]
    assert "low speed" not in where


def test_one_frequency():
    where, _ = _where(_sine_runs(), lambda r: 1e-3 * np.sin(2 * np.pi * r.frequency_hz * r.t)
                      * (r.frequency_hz == 4.0))
    assert "frequency 4 Hz" in where


# the sines' largest |command| is 0.0857; 0.85 x 0.06 = 0.051 lies above 80 % of a 0.06 limit
def _large_command(r):
    return 1e-3 * (np.abs(r.v) > 0.85 * 0.06)


def test_command_near_limit():
    # the actuator's limit 0.06: the large commands are near it
    where, loc = _where(_sine_runs(), _large_command, actuator_limit=0.06)
    assert "command near its limit" in where and "largest commands" not in where
    assert loc["regimes"]["command_bins"] == "limit" and loc["regimes"]["command_limits"] == [0.06]
    assert command_note(loc["regimes"]) is None


def test_command_limit_from_the_runs_metadata():
    # a run's command_limit (the P law's saturation) is the limit when the actuator has none
    runs = _sine_runs()
    for r in runs:
        r.meta["command_limit"] = 0.06
    where, loc = _where(runs, _large_command)
    assert "command near its limit" in where and loc["regimes"]["command_limits"] == [0.06]


def test_largest_commands_are_not_called_a_limit():
    # a limit of 4 the commands never approach: no saturation bin, the largest commands named
    # for what they are, and the report's note says the limit was never approached
    where, loc = _where(_sine_runs(), _large_command, actuator_limit=4.0)
    reg = loc["regimes"]
    assert "command near its limit" not in where and "largest commands" in where
    assert "command: near its limit" not in reg["bins"] and reg["command_bins"] == "largest logged"
    thr = 0.8 * reg["command_max_v"]
    assert reg["command_threshold"] == pytest.approx(thr)
    text = [w["text"] for w in describe(loc, 1e-6) if w["where"] == "largest commands"][0]
    assert f"above 80 % of the largest logged, {thr:.3g}" in text and "limit" in text
    assert "never came near its limit" in text and "saturation" not in text
    note = command_note(reg)
    assert note.startswith("the command never came near its limit (largest |command| 0.0857 of ±4,")


def test_largest_commands_without_a_known_limit():
    # no limit known anywhere: the largest commands, and no claim about a limit
    where, loc = _where(_sine_runs(), _large_command)
    text = [w["text"] for w in describe(loc, 1e-6) if w["where"] == "largest commands"][0]
    assert "never" not in text and command_note(loc["regimes"]) is None


def test_command_near_limit_in_few_samples():
    # a limit the commands touch in a few samples only: too few to compare, said so
    runs = _sine_runs()
    top = max(float(np.max(np.abs(r.v))) for r in runs)
    _, loc = _where(runs, _large_command, actuator_limit=top / 0.8 * 0.99999)
    n = loc["regimes"]["command_near_limit_samples"]
    assert 0 < n <= 50
    assert f"in only {n} samples" in command_note(loc["regimes"])


def _slow_command_run(lag_samples):
    rng = np.random.default_rng(2)
    t = np.arange(4000) * DT
    v = np.convolve(rng.normal(size=4000 + 600), np.ones(300) / 300, mode="same")[300:-300]
    res = np.roll(v, lag_samples) * 1e-3
    return ReplayRun("x", "other", t, v * 0, v * 0, v, DT, 2.0, (65.0, 90.0), 0.0, 0.0), res


def test_lag_at_the_edge_of_the_search_is_said():
    # a 150 ms lag, beyond the 100 ms searched: the best lag is the edge, and the words say so
    run, res = _slow_command_run(150)
    cl = command_lag([run], [res])
    assert cl["at_edge"] and cl["lag_s"] == pytest.approx(0.1) and cl["max_lag_s"] == pytest.approx(0.1)
    assert lag_text(cl).endswith("at the edge of the search (±100 ms): the true lag may be larger")
    loc = localise([run, run], [run.theta + res, run.theta + res])
    follows = [w["text"] for w in describe(loc) if w["where"] == "follows the command"]
    assert follows and "at least +100 ms later (the edge of the lag search" in follows[0]


def test_lag_inside_the_search_is_not_called_an_edge():
    run, res = _slow_command_run(30)
    cl = command_lag([run], [res])
    assert not cl["at_edge"] and cl["lag_s"] == pytest.approx(0.03)
    assert lag_text(cl) == (f"best correlation {cl['correlation']:+.2f} at lag +30 ms "
                            f"(at zero lag {cl['correlation_at_zero']:+.2f})")


def test_spread_evenly_and_at_noise():
    rng = np.random.default_rng(1)
    runs = _sine_runs()
    theta_model = [r.theta + 1e-3 * rng.normal(size=r.n) for r in runs]
    loc = localise(runs, theta_model)
    # white noise is everywhere alike: nothing stands 1.3x above the rest
    assert describe(loc, noise_rad=0.0) == []
    # and a gap at the noise floor is not described at all
    assert describe(loc, noise_rad=1e-3) == []


@pytest.mark.parametrize("lag", [5, 12])
def test_follows_the_command(lag):
    runs = _sine_runs()
    where, loc = _where(runs, lambda r: 0.05 * np.roll(r.v - r.v.mean(), lag))
    assert "follows the command" in where
    # sine commands give a broad correlation peak (the lag itself is tested on broadband data
    # in test_discrepancy.py): here only its sign
    assert loc["command_lag"]["lag_s"] > 0
