"""Tests of the local/global linear models (18)–(22) and α (36) against independent truth.

Truth: the exact closed-loop frequency response of (13), ``H(jω) = β / (β − ω² + jCω)``, and
responses of (13) integrated with ``scipy.integrate.solve_ivp`` at tight tolerances.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from identification.dataset import Run
from identification.linear import alpha_sine, fit_pose, global_coefficients, local_coefficients
from identification.sine_fit import fit_run

FS_HZ = 1000.0


def exact_A(C, beta, omega, ar):
    """(A1, A2) of the steady state of (13) for r = A_r sin(ωt), from the frequency response."""
    h = beta / (beta - omega**2 + 1j * C * omega)
    return ar * h.imag, ar * h.real


def simulate_sine_run(name, C, beta, f_hz, ar, *, duration_s=8.0, kp=2.0, g1=60.0, g2=87.0,
                      set_angles=None, t0=0.0):
    """Integrate (13) from rest with solve_ivp and sample at 1 kHz as a contract run."""
    w = 2 * math.pi * f_hz
    t = t0 + np.arange(int(round(duration_s * FS_HZ))) / FS_HZ

    def rhs(tt, y):
        return [y[1], -C * y[1] - beta * y[0] + beta * ar * math.sin(w * (tt - t0))]

    sol = solve_ivp(rhs, (t[0], t[-1]), [0.0, 0.0], t_eval=t, method="DOP853", rtol=1e-11, atol=1e-13)
    theta = sol.y[0]
    r = ar * np.sin(w * (t - t0))
    meta = {"kind": "sine", "gamma1_deg": g1, "gamma2_deg": g2, "kp": kp, "frequency_hz": f_hz,
            "amplitude_rad": ar}
    if set_angles:
        meta["gamma1_set_deg"], meta["gamma2_set_deg"] = set_angles
    return Run(name, t, r, theta, kp * (r - theta), meta)


@settings(max_examples=200, deadline=None)
@given(C=st.floats(0.5, 30), beta=st.floats(20, 3000), f=st.floats(0.2, 15), ar=st.floats(0.005, 1.0))
def test_inversion_19_20_recovers_C_beta(C, beta, f, ar):
    w = 2 * math.pi * f
    a1, a2 = exact_A(C, beta, w, ar)
    c, b = local_coefficients(a1, a2, ar, w)
    assert c == pytest.approx(C, rel=1e-8), (C, beta, f, ar)
    assert b == pytest.approx(beta, rel=1e-8), (C, beta, f, ar)


@settings(max_examples=100, deadline=None)
@given(C=st.floats(0.5, 30), beta=st.floats(20, 3000),
       fs=st.lists(st.floats(0.2, 15), min_size=1, max_size=9), ar=st.floats(0.005, 1.0))
def test_global_22_recovers_C_beta_of_a_linear_system(C, beta, fs, ar):
    w = 2 * math.pi * np.array(fs)
    a1, a2 = exact_A(C, beta, w, ar)
    c, b = global_coefficients(a1, a2, ar, w)
    assert c == pytest.approx(C, rel=1e-7)
    assert b == pytest.approx(beta, rel=1e-7)


def test_negative_coefficients_when_response_lags_too_much():
    # A_r A2 > A1² + A2²: the paper's non-physical case.
    c, b = local_coefficients(-0.01, 0.05, 0.1, 2 * math.pi)
    assert c < 0 and b < 0


def test_alpha_36_equals_numerical_invariant_of_the_voltage():
    kp, ar, f, a1, a2 = 2.0, 0.07, 2.5, -0.03, 0.05
    w = 2 * math.pi * f
    t = np.linspace(0, 1, 20001)
    v = kp * (ar * np.sin(w * t) - (a1 * np.cos(w * t) + a2 * np.sin(w * t)))
    vd = np.gradient(v, t, edge_order=2)
    vdd = np.gradient(vd, t, edge_order=2)
    alpha_num = np.median((vd**2 - v * vdd)[100:-100])  # (33), constant for a sine
    assert alpha_sine(a1, a2, ar, w, kp) == pytest.approx(alpha_num, rel=1e-5)


@pytest.mark.parametrize("f_hz", [1.5, 3.0, 7.0])
def test_local_model_from_simulated_ode(f_hz):
    C, beta, ar = 5.9, 463.06, 0.05
    run = simulate_sine_run("sim", C, beta, f_hz, ar)
    fit = fit_run(run)
    c, b = local_coefficients(fit.A1, fit.A2, ar, fit.omega)
    assert abs(c / C - 1) < 0.005, (f_hz, c)
    assert abs(b / beta - 1) < 0.005, (f_hz, b)


def test_fit_pose_from_simulated_ode_and_beta_tilde():
    C, beta, ar, kp = 6.275, 445.6, 0.05, 2.0
    runs = [simulate_sine_run(f"s{f}", C, beta, f, ar, kp=kp) for f in (1.5, 3.5, 6.0)]
    pose = fit_pose([fit_run(r) for r in runs], kp, 60.08, 87.0, label="test")
    assert abs(pose.C_linear / C - 1) < 0.005
    assert abs(pose.beta_linear / beta - 1) < 0.005
    assert pose.beta_tilde_linear == pytest.approx(pose.beta_linear / kp)
    assert all(p.used for p in pose.frequencies)
    assert pose.frequencies[0].alpha == pytest.approx(
        kp**2 * (2 * math.pi * 1.5) ** 2 * (pose.frequencies[0].A1**2 + (ar - pose.frequencies[0].A2) ** 2))
