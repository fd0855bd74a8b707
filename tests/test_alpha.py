"""Tests of identification.alpha: (33)-(36)."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from identification.alpha import (
    alpha_cycle_average,
    alpha_from_samples,
    alpha_invariant,
    alpha_sine,
    derivatives_from_samples,
    sine_command,
)

amp = st.floats(0.01, 10.0)
freq = st.floats(0.1, 20.0)
phase = st.floats(-np.pi, np.pi)


@settings(max_examples=50, deadline=None)
@given(A=amp, f=freq, ph=phase)
def test_alpha_constant_for_any_sine(A, f, ph):
    """(33) of v = A sin(ωt + φ) with exact derivatives is A²ω² at every t."""
    w = 2 * np.pi * f
    t = np.linspace(0.0, 3.0 / f, 200)
    v = A * np.sin(w * t + ph)
    a = alpha_invariant(v, A * w * np.cos(w * t + ph), -A * w**2 * np.sin(w * t + ph))
    np.testing.assert_allclose(a, (A * w) ** 2, rtol=1e-9, err_msg=f"A={A} f={f} ph={ph}")


@settings(max_examples=50, deadline=None)
@given(A1=st.floats(-0.2, 0.2), A2=st.floats(-0.2, 0.2), Ar=st.floats(0.01, 0.2), f=freq,
       kp=st.floats(0.5, 5.0))
def test_closed_form_36_equals_33_of_35(A1, A2, Ar, f, kp):
    w = 2 * np.pi * f
    t = np.linspace(0.0, 2.0 / f, 100)
    v, vd, vdd = sine_command(t, kp, w, A1, A2, Ar)
    # (35) as written: v = kp(r - θ) with r = Ar sin ωt, θ = A1 cos ωt + A2 sin ωt (14)
    np.testing.assert_allclose(
        v, kp * (Ar * np.sin(w * t) - (A1 * np.cos(w * t) + A2 * np.sin(w * t))), atol=1e-12)
    expected = alpha_sine(kp, w, A1, A2, Ar)
    np.testing.assert_allclose(alpha_invariant(v, vd, vdd), expected,
                               rtol=1e-9, atol=1e-12 * max(1.0, expected))


def test_alpha_sine_hand_value():
    # kp=2, ω=10, A1=0.03, A2=0.06, Ar=0.1: 4·100·(0.0009 + 0.0016) = 1.0
    assert alpha_sine(2.0, 10.0, 0.03, 0.06, 0.1) == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("f", [0.37, 1.5, 3.4, 7.0])
def test_cycle_average_of_sine_exact_derivative(f):
    dt = 1e-3
    t = np.arange(0.0, 4.0, dt)
    w = 2 * np.pi * f
    v = 0.3 * np.sin(w * t + 0.4)
    vd = 0.3 * w * np.cos(w * t + 0.4)
    # trapezoid rule on 1 kHz samples: relative error O((ω dt)²) < 2e-4 at 7 Hz
    assert alpha_cycle_average(t, v, 1 / f, v_dot=vd) == pytest.approx((0.3 * w) ** 2, rel=2e-4)


def test_cycle_average_of_non_sine_is_mean_of_33():
    """For v = sin + harmonic the cycle average (34) equals the average of (33) over a period."""
    f, dt = 1.0, 1e-4
    w = 2 * np.pi * f
    t = np.arange(0.0, 2.0 + dt / 2, dt)
    v = np.sin(w * t) + 0.3 * np.sin(3 * w * t + 0.2)
    vd = w * np.cos(w * t) + 0.9 * w * np.cos(3 * w * t + 0.2)
    # mean of v̇² − v v̈ over a period: ω²/2 + (0.9ω)²/2 + ω²/2 + 0.3·(9ω²)·0.3/2
    expected = w**2 * (0.5 + 0.405 + 0.5 + 0.405)
    assert alpha_cycle_average(t, v, 1 / f, v_dot=vd) == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("f, tol_interior, tol_ends", [(1.5, 1e-4, 1e-3), (3.4, 5e-4, 5e-3),
                                                       (7.0, 5e-3, 3e-2)])
def test_sampled_differentiator_recovers_sine_alpha(f, tol_interior, tol_ends):
    """Savitzky-Golay (40 ms, degree 4) on 1 kHz samples: stated relative tolerances."""
    dt = 1e-3
    t = np.arange(0.0, 3.0, dt)
    w = 2 * np.pi * f
    v = 0.3 * np.sin(w * t + 0.4)
    a = alpha_from_samples(t, v)
    exact = (0.3 * w) ** 2
    err = np.abs(a - exact) / exact
    assert err[30:-30].max() < tol_interior, f"f={f}: interior {err[30:-30].max()}"
    assert err.max() < tol_ends, f"f={f}: ends {err.max()}"
    # the cycle average from samples (no derivative given)
    assert alpha_cycle_average(t, v, 1 / f) == pytest.approx(exact, rel=tol_interior)


def test_sampled_with_encoder_quantisation_cycle_average():
    """Quantised to the encoder step (8.4e-4 V at kp=2): 3-cycle average within 0.5 %."""
    dt = 1e-3
    t = np.arange(0.0, 4.0, dt)
    f = 2.0
    w = 2 * np.pi * f
    v = 0.3 * np.sin(w * t)
    vq = np.round(v / 8.4e-4) * 8.4e-4
    assert alpha_cycle_average(t, vq, 1 / f, n_cycles=3) == pytest.approx((0.3 * w) ** 2, rel=5e-3)


def test_polynomial_derivatives_exact():
    """Savitzky-Golay of degree 4 differentiates a cubic exactly (window fits the polynomial)."""
    t = np.arange(0.0, 1.0, 1e-3)
    v = 1.0 - 2.0 * t + 3.0 * t**2 - 0.5 * t**3
    _, vd, vdd = derivatives_from_samples(t, v)
    np.testing.assert_allclose(vd, -2 + 6 * t - 1.5 * t**2, atol=1e-8)
    np.testing.assert_allclose(vdd, 6 - 3 * t, atol=1e-6)


def test_bad_inputs():
    t = np.arange(10) * 1e-3
    with pytest.raises(ValueError):
        alpha_from_samples(t, np.zeros(10), window_s=1.0)  # window longer than record
    with pytest.raises(ValueError):
        alpha_cycle_average(t, np.zeros(10), period_s=1.0, v_dot=np.zeros(10))
