"""Tests of the steady-state sine fit (14)–(15) against synthetic sinusoids with known coefficients."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from identification.dataset import Run
from identification.errors import UserError
from identification.sine_fit import fit_run, fit_sine, steady_state_window


@settings(max_examples=200, deadline=None)
@given(a1=st.floats(-1, 1), a2=st.floats(-1, 1), offset=st.floats(-2, 2), f=st.floats(0.5, 10),
       cycles=st.integers(3, 12), t0=st.floats(-5, 5))
def test_exact_recovery_with_offset(a1, a2, offset, f, cycles, t0):
    t = t0 + np.arange(int(cycles * 1000 / f)) / 1000.0
    w = 2 * math.pi * f
    y = offset + a1 * np.cos(w * t) + a2 * np.sin(w * t)
    fit = fit_sine(t, y, f)
    assert fit.A1 == pytest.approx(a1, abs=1e-9)
    assert fit.A2 == pytest.approx(a2, abs=1e-9)
    assert fit.offset == pytest.approx(offset, abs=1e-9)
    if math.hypot(a1, a2) > 1e-3:
        assert fit.explained_fraction == pytest.approx(1.0, abs=1e-9)
        assert fit.A0 == pytest.approx(math.hypot(a1, a2), abs=1e-9)
        # θ = A0 sin(ωt + φ) (16)
        assert np.allclose(fit.A0 * np.sin(w * t + fit.phase) + offset, y, atol=1e-8)


def test_distortion_is_visible():
    f = 2.0
    t = np.arange(4000) / 1000.0
    w = 2 * math.pi * f
    y = np.sin(w * t) + 0.1 * np.sin(3 * w * t) + 0.05 * np.cos(2 * w * t)
    fit = fit_sine(t, y, f)
    assert fit.harmonic3_ratio == pytest.approx(0.1, rel=1e-9)
    assert fit.harmonic2_ratio == pytest.approx(0.05, rel=1e-9)
    # energy: fundamental 1/2, harmonics (0.01 + 0.0025)/2
    assert fit.explained_fraction == pytest.approx(1 / 1.0125, rel=1e-9)
    assert fit.A2 == pytest.approx(1.0, abs=1e-9)


def test_window_rule_last_whole_cycles_after_half_or_2s():
    t = np.arange(10000) / 1000.0  # 10 s at 1 kHz
    win, n = steady_state_window(t, 1.5)
    # first 5 s discarded, 5 s left -> 7 whole cycles of 1.5 Hz = 4.6667 s, ending at the last sample
    assert n == 7
    assert win.stop == 10000 and win.stop - win.start == round(7 / 1.5 * 1000)
    t = np.arange(3000) / 1000.0  # 3 s: 2 s discarded (more than half), 1 s left
    win, n = steady_state_window(t, 7.0)
    assert n == 7


def test_too_few_cycles_names_the_run():
    t = np.arange(4000) / 1000.0  # 4 s: 2 s left; at 1 Hz only 2 cycles
    with pytest.raises(UserError, match="myrun.*2 whole steady-state cycle"):
        steady_state_window(t, 1.0, name="myrun")


def _run(t, r, theta, f, ar=0.1):
    meta = {"kind": "sine", "gamma1_deg": 0, "gamma2_deg": 0, "kp": 2.0, "frequency_hz": f,
            "amplitude_rad": ar}
    return Run("r1", t, r, theta, 2 * (r - theta), meta)


def test_fit_run_refers_to_reference_phase_and_ignores_time_origin():
    f, ar, a1, a2 = 3.0, 0.1, -0.04, 0.07
    w = 2 * math.pi * f
    for t0 in (0.0, 123.4567):
        t = t0 + np.arange(6000) / 1000.0
        tau = t - t0  # the reference starts at t0
        r = ar * np.sin(w * tau)
        theta = 0.01 + a1 * np.cos(w * tau) + a2 * np.sin(w * tau)
        fit = fit_run(_run(t, r, theta, f, ar))
        assert fit.A1 == pytest.approx(a1, abs=1e-10)
        assert fit.A2 == pytest.approx(a2, abs=1e-10)


def test_reference_without_the_frequency_is_an_error():
    t = np.arange(6000) / 1000.0
    with pytest.raises(UserError, match="r1: the reference r has no component at 3 Hz"):
        fit_run(_run(t, 0 * t, np.sin(t), 3.0))


@settings(max_examples=25, deadline=None)
@given(f=st.sampled_from([1.5, 2.5, 4.0, 7.0]), lag=st.floats(0.0, 1.2),
       gain=st.floats(0.3, 1.5), dist=st.floats(0.0, 0.3), seed=st.integers(0, 10_000))
def test_fundamentals_equal_fit_run_bit_for_bit(f, lag, gain, dist, seed):
    """Validation's fundamental-only fits (the reference fitted once for several θ) give
    fit_run's A1, A2 exactly, on distorted, noisy, lagging responses.  Exactly, on any CPU: the
    two compute the same columns the same way and make the same LAPACK call on equal inputs
    (the same arithmetic by construction, not two methods that agree)."""
    from identification.sine_fit import fundamentals

    rng = np.random.default_rng(seed)
    t = np.arange(0, 6.0, 1e-3)
    r = 0.1 * np.sin(2 * math.pi * f * t)
    thetas = [gain * 0.1 * np.sin(2 * math.pi * f * t - lag) + dist * 0.01 * np.sin(6 * math.pi * f * t)
              + 1e-4 * rng.standard_normal(t.size) for _ in range(3)]
    run = _run(t, r, thetas[0], f)
    got = fundamentals(run, thetas)
    for theta, (a1, a2) in zip(thetas, got):
        ref = fit_run(Run(run.name, t, r, theta, run.v, run.meta))
        assert (a1, a2) == (ref.A1, ref.A2)


def test_fundamentals_reject_what_fit_run_rejects():
    from identification.sine_fit import fundamentals

    t = np.arange(0, 6.0, 1e-3)
    run = _run(t, 0.1 * np.sin(2 * math.pi * 3.0 * t), np.zeros_like(t), 2.0)
    with pytest.raises(UserError, match="no component"):
        fundamentals(run, [run.theta])
