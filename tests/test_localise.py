"""Where the gap lives, in words: residuals built with a known concentration (low speed,
reversals, a position band, the command near its limit, one frequency) must be described there,
and an evenly spread residual must not be pinned anywhere."""

import numpy as np
import pytest

from omni_sim.discrepancy.localise import describe, localise
from omni_sim.discrepancy.replay import ReplayRun

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


def _where(runs, residual_of, seed=0):
    rng = np.random.default_rng(seed)
    theta_model = [r.theta + residual_of(r) + 1e-6 * rng.normal(size=r.n) for r in runs]
    loc = localise(runs, theta_model)
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


def test_command_near_limit():
    where, _ = _where(_sine_runs(), lambda r: 1e-3 * (np.abs(r.v) > 0.85 * 0.06))
    assert "command near its limit" in where


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
