"""Tests of identification.simulate: (43)-(46) and (26) with exact ZOH steps."""

import math

import numpy as np
import pytest
from scipy.signal import cont2discrete

from identification.nonlinear import AlphaModel, paper_alpha_model
from identification.simulate import (
    bench_simulation,
    simulate_alpha,
    simulate_linear,
    square_wave_reference,
    zoh_coefficients,
)

DT = 1e-3
KP = 2.0


# -- slow, obviously correct references -------------------------------------------------------
def ref_step(th, ph, C, u, h):
    """Exact step of θ'' + Cθ' = u, scalar, closed form (exact double integrator if C == 0)."""
    if C == 0.0:
        return th + ph * h + u * h * h / 2, ph + u * h
    if abs(C * h) < 1e-3:  # expansions to 5th order, independent of the module's series
        x = C * h
        g1 = h * (1 - x / 2 + x**2 / 6 - x**3 / 24 + x**4 / 120 - x**5 / 720)
        g2 = h * h * (0.5 - x / 6 + x**2 / 24 - x**3 / 120 + x**4 / 720 - x**5 / 5040)
    else:
        g1 = (1 - math.exp(-C * h)) / C
        g2 = (h - g1) / C
    return th + ph * g1 + u * g2, ph * math.exp(-C * h) + u * g1


def ref_alpha_sim(model, I, r, rd, rdd, dt, kp, C_lin, b_lin, th0, ph0, max_iter=50):
    """Single-run pure-Python version of (44)-(46) with (45') and exact ZOH steps."""
    br, ci = list(model.alpha_breaks), list(model.C_inv)
    b0, b1 = model.beta_inv
    a0, a1 = model.alpha_bar
    floor = model.options["beta_floor_fraction"] * min(b0, b1)

    def C_of(a):
        if a <= br[0]:
            return ci[0] / I
        if a >= br[3]:
            return ci[3] / I
        k = 0 if a < br[1] else (1 if a < br[2] else 2)
        w = (a - br[k]) / (br[k + 1] - br[k])
        return (ci[k] + w * (ci[k + 1] - ci[k])) / I

    def b_of(a):
        return max(b0 + (b1 - b0) / (a1 - a0) * (a - a0), floor) / I

    th, ph = th0, ph0
    thetas, alphas, bad, bracketed = [], [], 0, 0
    for k in range(len(r)):
        thetas.append(th)
        v = kp * (r[k] - th)
        vd = kp * (rd[k] - ph)

        def g(a):
            return vd * vd - v * kp * (rdd[k] - (-C_of(a) * ph + b_of(a) * v))

        vdd = kp * (rdd[k] - (-C_lin * ph + b_lin * v))
        a = vd * vd - v * vdd
        iterates = [a]
        converged = False
        for _ in range(2, max_iter + 1):
            a_new = g(a)
            stop = abs(a_new - a) < max(1e-6, 1e-3 * abs(a_new))
            a = a_new
            iterates.append(a)
            if stop:
                converged = True
                break
        if not converged:  # bisection in a bracket of iterates (h known at each)
            hs = [x - y for x, y in zip(iterates, iterates[1:])] + [a - g(a)]
            neg = min((j for j in range(len(hs)) if hs[j] <= 0),
                      key=lambda j: (abs(iterates[j] - a), j), default=None)
            pos = min((j for j in range(len(hs)) if hs[j] >= 0),
                      key=lambda j: (abs(iterates[j] - a), j), default=None)
            pair = None
            if neg is not None and pos is not None:
                pair = [(iterates[neg], hs[neg]), (iterates[pos], hs[pos])]
            elif iterates[-1] != iterates[-2]:  # creeping: step on in the direction of travel
                step = iterates[-1] - iterates[-2]
                for m in range(61):
                    x = a + step * 2.0**m
                    hx = x - g(x)
                    if hx * hs[-1] <= 0:
                        pair = [(a, hs[-1]), (x, hx)]
                        break
            if pair is not None:
                (lo, h_lo), (hi, _) = sorted(pair, key=lambda x: x[0])
                for _ in range(200):
                    mid = 0.5 * (lo + hi)
                    if hi - lo < max(1e-6, 1e-3 * abs(mid)):
                        break
                    h_mid = mid - g(mid)
                    if h_lo * h_mid <= 0:
                        hi = mid
                    else:
                        lo, h_lo = mid, h_mid
                a = 0.5 * (lo + hi)
                converged = True
                bracketed += 1
        bad += not converged
        alphas.append(a)
        th, ph = ref_step(th, ph, C_of(a), b_of(a) * v, dt)
    return np.array(thetas), np.array(alphas), bad, bracketed


# -- tests --------------------------------------------------------------------------------------
@pytest.mark.parametrize("C", [0.0, 1e-9, 5.0, 19.99, 20.01, 300.0, -4.0])
def test_zoh_coefficients_match_closed_form(C):
    E, g1, g2 = zoh_coefficients(np.array([C]), DT)
    th, ph = ref_step(0.0, 1.0, C, 0.0, DT)
    assert g1[0] == pytest.approx(th, rel=1e-13) and E[0] == pytest.approx(ph, rel=1e-13)
    th, ph = ref_step(0.0, 0.0, C, 1.0, DT)
    assert g2[0] == pytest.approx(th, rel=1e-11) and g1[0] == pytest.approx(ph, rel=1e-13)


def test_linear_matches_cont2discrete_zoh():
    """Independent discrete reference: scipy's ZOH discretisation of the plant, v_k fed back."""
    t = np.arange(3000) * DT
    r = np.stack([square_wave_reference(t, 0.25, 0.07), 0.05 * np.sin(2 * np.pi * 3 * t)])
    C = np.array([6.275, 4.3])
    b = np.array([222.8, 149.4])
    th0 = np.array([-0.07, 0.01])
    res = simulate_linear(C, b, r, DT, KP, theta0=th0, phi0=[0.0, 0.2])
    for j in range(2):
        sys = (np.array([[0.0, 1.0], [0.0, -C[j]]]), np.array([[0.0], [b[j]]]),
               np.array([[1.0, 0.0]]), np.array([[0.0]]))
        Ad, Bd, *_ = cont2discrete(sys, DT, "zoh")
        x = np.array([th0[j], [0.0, 0.2][j]])
        th = np.empty(t.size)
        for k in range(t.size):
            th[k] = x[0]
            x = Ad @ x + Bd[:, 0] * KP * (r[j, k] - x[0])
        np.testing.assert_allclose(res.theta[j], th, atol=1e-13, err_msg=f"run {j}")


def test_linear_step_settles_on_reference():
    t = np.arange(5000) * DT  # decay e^{-ζω_n t} = e^{-3.14·5} ≈ 1.5e-7
    res = simulate_linear(6.275, 222.8, np.full(t.size, 0.07), DT, KP, theta0=-0.07)
    assert abs(res.theta[-1] - 0.07) < 1e-6 and res.theta.ndim == 1


def test_alpha_with_constant_coefficients_equals_linear():
    """A degenerate α model (C and β̃ independent of α) reproduces the linear model exactly."""
    I = np.array([1 / 222.8, 1 / 149.4])
    C_k1 = 36.693
    m = AlphaModel([0.0, 1.0, 10.0, 100.0], C_k1=[C_k1] * 4, beta_k1=[1.0, 1.0])
    t = np.arange(2000) * DT
    r = np.tile(square_wave_reference(t, 0.5, 0.07), (2, 1))
    a = simulate_alpha(m, I, r, DT, KP, C_linear=1 / (C_k1 * I), beta_tilde_linear=1 / I,
                       theta0=-0.07, r_dot=0.0, r_ddot=0.0)
    lin = simulate_linear(1 / (C_k1 * I), 1 / I, r, DT, KP, theta0=-0.07)
    np.testing.assert_allclose(a.theta, lin.theta, atol=1e-14, rtol=0)
    assert np.all(a.n_iter == 2) and np.all(a.n_not_converged == 0)


def test_batched_alpha_equals_pure_python_reference():
    """Runs with different I, references, initial states and derivatives: to 1e-12."""
    model = paper_alpha_model()
    t = np.arange(2500) * DT
    w = 2 * np.pi * 2.0
    sq = square_wave_reference(t, 0.5, 0.07)
    r = np.stack([sq, 0.1 * np.sin(w * t), sq])
    rd = np.stack([0 * t, 0.1 * w * np.cos(w * t), 0 * t])
    rdd = np.stack([0 * t, -0.1 * w**2 * np.sin(w * t), 0 * t])
    I = np.array([1 / 275.3, 1 / 222.8, 1 / 149.4])
    C_lin = 1 / (36.693 * I)
    th0 = np.array([-0.07, 0.0, 0.02])
    res = simulate_alpha(model, I, r, DT, KP, C_linear=C_lin, beta_tilde_linear=1 / I,
                         theta0=th0, r_dot=rd, r_ddot=rdd)
    for j in range(3):
        th, al, bad, brk = ref_alpha_sim(model, I[j], r[j], rd[j], rdd[j], DT, KP, C_lin[j],
                                         1 / I[j], th0[j], 0.0)
        np.testing.assert_allclose(res.theta[j], th, atol=1e-12, rtol=0, err_msg=f"run {j}")
        np.testing.assert_allclose(res.alpha[j], al, atol=1e-9, rtol=1e-9, err_msg=f"run {j}")
        assert res.n_not_converged[j] == bad and res.n_bracketed[j] == brk
    # the single-run call gives the same as its row of the batch
    one = simulate_alpha(model, I[1], r[1], DT, KP, C_linear=C_lin[1], beta_tilde_linear=1 / I[1],
                         r_dot=rd[1], r_ddot=rdd[1])
    np.testing.assert_array_equal(one.theta, res.theta[1])
    assert isinstance(one.n_not_converged, int)


def test_cycling_iteration_is_solved_by_bisection():
    """β̃ falling steeply in α (slope −1/I per V²/s², floored) makes the iteration cycle:
    dα^(i+1)/dα^(i) = kp·v²·β̃'(α) ≈ −35 after an edge.  The fallback bisects between the last
    two iterates: counts and trajectory match the scalar reference, and every step's α is a root
    of h(α) = α − g(α) to the stopping tolerance (checked from the returned state alone)."""
    I = 1 / 222.8
    m = AlphaModel([0.0, 5.0, 10.0, 40.0], C_k1=[36.0] * 4, alpha_bar=[0.0, 1.0], beta_k1=[0.5, 1.0])
    t = np.arange(600) * DT
    r = square_wave_reference(t, 2.0, 0.07)
    for max_iter in (2, 5, 50):
        res = simulate_alpha(m, I, r, DT, KP, C_linear=6.0, beta_tilde_linear=1 / I,
                             theta0=-0.07, r_dot=0.0, r_ddot=0.0, max_iter=max_iter)
        th, _, bad, brk = ref_alpha_sim(m, I, r, 0 * t, 0 * t, DT, KP, 6.0, 1 / I, -0.07, 0.0,
                                        max_iter)
        assert res.n_bracketed == brk > 0, max_iter
        assert res.n_not_converged == bad, max_iter
        assert res.n_iter.max() == max_iter
        np.testing.assert_allclose(res.theta, th, atol=1e-12, rtol=0)
        # (44) at the returned alpha, from the returned state (r' = r'' = 0 between edges)
        g = (KP * res.phi) ** 2 - res.v * KP * (res.C * res.phi - res.beta_tilde * res.v)
        tol = np.maximum(1e-6, 1e-3 * np.abs(res.alpha))
        resid = np.abs(res.alpha - g)
        ok = resid <= 40 * tol  # bisection leaves alpha within tol; |h'| <= 1 + |g'| ~ 36
        assert ok.sum() >= len(t) - res.n_not_converged, np.sort(resid / tol)[-5:]


def test_creeping_iteration_is_bracketed_ahead():
    """Cut short (max_iter = 2, 3) the iteration on the paper's model stops while still creeping
    monotonically toward its fixed point; the fallback steps on in the direction of travel to
    bracket the root.  Matches the scalar reference; no step is left unsolved."""
    t = np.arange(2000) * DT
    r = square_wave_reference(t, 0.5, 0.07)
    I = 1 / 229.0
    for max_iter in (2, 3):
        res = simulate_alpha(paper_alpha_model(), I, r, DT, KP, C_linear=6.242,
                             beta_tilde_linear=229.0, theta0=-0.07, r_dot=0.0, r_ddot=0.0,
                             max_iter=max_iter)
        th, _, bad, brk = ref_alpha_sim(paper_alpha_model(), I, r, 0 * t, 0 * t, DT, KP, 6.242,
                                        229.0, -0.07, 0.0, max_iter)
        assert res.n_bracketed == brk > 100 and res.n_not_converged == bad == 0, (brk, bad)
        np.testing.assert_allclose(res.theta, th, atol=1e-12, rtol=0)


def test_paper_model_step_converges_and_settles():
    t = np.arange(4000) * DT
    r = square_wave_reference(t, 0.25, 0.07)
    I = 1 / 229.0
    res = simulate_alpha(paper_alpha_model(), I, r, DT, KP, C_linear=6.242, beta_tilde_linear=229.0,
                         theta0=-0.07, r_dot=0.0, r_ddot=0.0)
    assert res.n_not_converged == 0
    assert abs(res.theta[1999] - 0.07) < 1e-3 and abs(res.theta[-1] + 0.07) < 1e-3
    assert res.n_iter.mean() < 5


def test_numerical_reference_derivatives_for_smooth_reference():
    """Without r_dot/r_ddot the numerical derivatives give nearly the analytic result."""
    t = np.arange(2000) * DT
    w = 2 * np.pi * 1.5
    r = 0.1 * np.sin(w * t)
    kw = dict(C_linear=6.242, beta_tilde_linear=229.0)
    exact = simulate_alpha(paper_alpha_model(), 1 / 229.0, r, DT, KP, r_dot=0.1 * w * np.cos(w * t),
                           r_ddot=-0.1 * w**2 * np.sin(w * t), **kw)
    num = simulate_alpha(paper_alpha_model(), 1 / 229.0, r, DT, KP, **kw)
    assert np.max(np.abs(num.theta - exact.theta)) < 1e-5


def test_square_wave_reference_matches_47():
    t = np.arange(8000) * DT
    r = square_wave_reference(t, 0.25, 0.07)
    assert r[0] == 0.07 and r[1999] == 0.07 and r[2000] == -0.07 and r[4000] == 0.07
    assert np.count_nonzero(np.diff(r)) == 3


def test_bench_runs_small():
    out = bench_simulation(n_runs=2, duration_s=0.5)
    assert out["n_samples"] == 500 and out["n_not_converged"] == 0 and out["alpha_s"] > 0


@pytest.mark.slow
def test_speed_within_3x_lsim():
    out = bench_simulation(repeat=3)
    assert out["ratio_alpha_to_lsim"] <= 3.0, out


def test_sine_steady_state_is_a_fixed_point_of_the_model():
    """Chain check (36), (19)-(20), (43)-(46): the simulated sinusoidal steady state of the α
    model, analysed like measured data, gives back C(α) and β̃(α) at its own α.

    The ZOH holds v for one sample, a delay of dt/2 on the whole loop; matching coefficients
    with it gives C_data = C·cos(ωτ) − ω·sin(ωτ) ≈ C − ω²·dt/2, which is added back here
    (it is −0.97 1/s at 7 Hz for dt = 1 ms, so 0.2 ms steps keep the residual small).
    """
    from identification.alpha import alpha_sine
    from identification.sine_fit import fit_sine

    model, I, Ar, dt = paper_alpha_model(), 1 / 229.0, 0.05, 2e-4
    fs = np.array([1.5, 3.5, 7.0])
    w = 2 * np.pi * fs[:, None]
    t = np.arange(int(3.0 / dt)) * dt
    res = simulate_alpha(model, I, Ar * np.sin(w * t), dt, KP, C_linear=6.242,
                         beta_tilde_linear=229.0, r_dot=Ar * w * np.cos(w * t),
                         r_ddot=-Ar * w**2 * np.sin(w * t))
    assert np.all(res.n_not_converged == 0)
    last = slice(-int(round(1.0 / dt)), None)  # the last second: whole cycles of every f
    for j, f in enumerate(fs):
        wj = 2 * np.pi * f
        fit = fit_sine(t[last], res.theta[j, last], f)
        A1, A2 = fit.A1, fit.A2
        den = A1**2 + A2 * (A2 - Ar)
        C_data = -wj * Ar * A1 / den + wj**2 * dt / 2                     # (19) + ZOH term
        beta_tilde_data = wj**2 * (A1**2 + A2**2) / den / KP                # (20) / kp
        a = alpha_sine(KP, wj, A1, A2, Ar)                                  # (36)
        assert C_data == pytest.approx(model.C(a, I), rel=5e-3), f
        assert beta_tilde_data == pytest.approx(model.beta_tilde(a, I), rel=5e-3), f
        # α is (nearly) invariant over the steady-state cycle
        al = res.alpha[j, last]
        assert (al.max() - al.min()) < 0.05 * a, f
