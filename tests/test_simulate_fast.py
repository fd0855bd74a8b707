"""The α-model simulation's batching, with its numpy loop (the compiled loop against this one:
test_alpha_kernel): runs of different lengths, gains and batches (``groups``) in one time loop
give each run the numbers of its own batch's simulate_alpha call, to the stated tolerance of
two code paths (:func:`_assert_paths_agree`, which a dropped term fails), with the same
decisions of the iteration (bisection fallback included); and validation's batching of all
runs into one time loop."""

import math

import numpy as np
import pytest
from omni_sim.device import Device

from identification import simulate as sim
from identification.nonlinear import AlphaModel, paper_alpha_model
from identification.simulate import simulate_alpha, simulate_alpha_batch

DT = 1e-3
KP = 2.0
# the α model identified by `omni reproduce` on the virtual Omni (scene.xml): steep C(α), so
# sine runs need the bisection fallback on some steps
IDENTIFIED = {"alpha_breaks": [0.0, 1.035010695973506, 1.9760202041275334, 13.75089638086901],
              "C_k1": [3.404837223520829, 10.561623800367784, 23.904909140385307,
                       49.567424496642516],
              "alpha_bar": [0.0, 250.0], "beta_k1": [0.7271126937484368, 437.84316494230626],
              "options": {"beta_floor_fraction": 0.1, "beta_clamp": True,
                          "use": "up_to_resonance", "monotone": True, "method": "two_stage",
                          "breaks_from": "grid search"}}


def _sines(freqs, n, amp=0.0498256):
    t = np.arange(n) * DT
    w = 2 * math.pi * np.asarray(freqs)[:, None]
    return amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w * w * np.sin(w * t)


#: Per-step allowance [ulp of a run's scale] for two code paths of the α simulation.  The
#: paths (the numpy loop on a batch or on a part of it, the compiled loop) do the same
#: operations in the same order, except the exponentials e^{-C h} of the step: numpy evaluates
#: them with the SIMD code it picks for the CPU and the array (AVX-512, AVX2 or scalar; an
#: array's length decides which elements go through the vector loop and which through its
#: remainder), the compiled loop with the C library's exp as LLVM compiled it for the host;
#: these agree to a few ulps, not bit for bit.  The closed loop is stable, so a step's
#: difference is carried forward without growth: after N steps the paths differ by at most
#: ~N x a few ulps of the run's scale (4 ulp per step: 1.3e-12 after 1500 steps).  Measured on an AVX-512 CPU: <= 4e-14 of the
#: scale (C and α on the steep identified C(α)), ~1e-15 for θ.  A dropped term or a wrong
#: branch of the bisection moves the numbers by 1e-6 or more (test_a_dropped_term_is_caught).
ULP_PER_STEP = 4


def _assert_paths_agree(a, b):
    """``a`` and ``b`` (SimResults of two code paths, one run or a batch) agree: every
    continuous array within ULP_PER_STEP x n_steps ulps of its run's scale (max |b|), and
    the iteration's decisions (iterations per step, bisected and unconverged steps) equal.

    The decisions are compared exactly: for them to differ, an iterate would have to lie
    within ~1e-12 (relative) of the stopping threshold (46) or of a bisection's midpoint
    test, which a run of a few thousand steps meets with a probability of ~1e-8."""
    n_steps = np.shape(b.theta)[-1]
    rtol = ULP_PER_STEP * n_steps * np.finfo(float).eps
    for k in ("theta", "phi", "v", "C", "beta_tilde", "alpha"):
        x, y = np.atleast_2d(getattr(a, k)), np.atleast_2d(getattr(b, k))
        assert x.shape == y.shape, k
        scale = np.maximum(np.max(np.abs(y), axis=-1, keepdims=True), np.finfo(float).tiny)
        worst = np.max(np.abs(x - y) / scale)
        assert worst <= rtol, f"{k}: the paths differ by {worst:.2e} of the scale (allowed {rtol:.1e})"
    np.testing.assert_array_equal(a.n_iter, b.n_iter, err_msg="n_iter")
    np.testing.assert_array_equal(a.n_bracketed, b.n_bracketed)
    np.testing.assert_array_equal(a.n_not_converged, b.n_not_converged)


def _numpy(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` with the numpy loop (the registered one restored after)."""
    previous = sim.set_kernel(None)
    try:
        return fn(*args, **kwargs)
    finally:
        sim.set_kernel(previous)


@pytest.fixture(autouse=True)
def numpy_loop():
    """These tests check the numpy loop (the compiled one: test_alpha_kernel)."""
    previous = sim.set_kernel(None)
    yield
    sim.set_kernel(previous)


def test_batch_of_ragged_groups_equals_per_group_calls():
    """Runs of different lengths and gains in one call, ``groups`` = the batches of
    simulate_alpha calls."""
    model = AlphaModel.from_dict(IDENTIFIED)
    ra, rda, rdda = _sines([2.0, 3.5, 6.0], 1200)
    rb, rdb, rddb = _sines([2.5, 5.0], 900)
    Ia, Ib = np.array([0.004, 0.005, 0.006]), np.array([0.0045, 0.0055])
    kw = lambda I: dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, theta0=0.0)  # noqa: E731
    ref_a = simulate_alpha(model, Ia, ra, DT, KP, r_dot=rda, r_ddot=rdda, **kw(Ia))
    ref_b = simulate_alpha(model, Ib, rb, DT, 2.5, r_dot=rdb, r_ddot=rddb, **kw(Ib))
    # interleaved order, per-run gains
    order = [("b", 0), ("a", 0), ("a", 1), ("b", 1), ("a", 2)]
    src = {"a": (ra, rda, rdda, Ia, KP, ref_a), "b": (rb, rdb, rddb, Ib, 2.5, ref_b)}
    pick = lambda i: [src[s][i][j] if i < 4 else src[s][i] for s, j in order]  # noqa: E731
    I = np.array(pick(3))
    res = simulate_alpha_batch(model, I, pick(0), DT, pick(4), r_dot=pick(1), r_ddot=pick(2),
                               groups=[0 if s == "a" else 1 for s, _ in order], **kw(I))
    n_brk = 0
    for (s, j), out in zip(order, res):
        ref = src[s][5]
        _assert_paths_agree(out, _row(ref, j))
        n_brk += out.n_bracketed
    assert n_brk > 0


def _row(res, j):
    """Run ``j`` of a batch's SimResult, as simulate_alpha_batch returns a run."""
    from dataclasses import replace

    return replace(res, **{k: (getattr(res, k)[j] if np.ndim(getattr(res, k)) else getattr(res, k))
                           for k in ("theta", "phi", "v", "C", "beta_tilde", "alpha", "n_iter",
                                     "n_bracketed", "n_not_converged")})


def test_a_dropped_term_is_caught():
    """The tolerance of _assert_paths_agree is tight enough to catch a broken path: each run of
    a batch (in its own batch: ``groups``) agrees with its single-run call, and no longer with
    the r̈ term of v̈ dropped (r_ddot = 0), or with kp off by 1e-9."""
    model = AlphaModel.from_dict(IDENTIFIED)
    r, rd, rdd = _sines([2.5, 5.0], 1500)
    I = np.array([0.0045, 0.0055])

    def batch(kp=KP, r_ddot=rdd):
        return simulate_alpha_batch(model, I, list(r), DT, kp, C_linear=1 / (36.693 * I),
                                    beta_tilde_linear=1 / I, r_dot=list(rd), r_ddot=list(r_ddot),
                                    groups=[0, 1])

    singles = [simulate_alpha(model, I[j], r[j], DT, KP, C_linear=1 / (36.693 * I[j]),
                              beta_tilde_linear=1 / I[j], r_dot=rd[j], r_ddot=rdd[j])
               for j in range(2)]
    for a, b in zip(batch(), singles):
        _assert_paths_agree(a, b)
    for broken in (batch(r_ddot=0.0 * rdd), batch(kp=KP * (1 + 1e-9))):
        for a, b in zip(broken, singles):
            with pytest.raises(AssertionError):
                _assert_paths_agree(a, b)


def test_max_iter_checked():
    with pytest.raises(ValueError):
        simulate_alpha(paper_alpha_model(), 0.005, np.zeros(10), DT, KP, C_linear=1.0,
                       beta_tilde_linear=1.0, max_iter=1)


@pytest.mark.slow
def test_validation_paper_campaign_equals_per_group_calls():
    """All 106 runs of the paper campaign: validation's one-loop batch (with the registered
    loop: the numpy one here, the compiled one in test_alpha_kernel) equals simulate_alpha with
    the numpy loop called per batch (length, dt, gain), as validation did before; within
    1e-12 (in fact bit for bit on some CPUs), with the same count of bisected steps."""
    from identification.identify import identify_runs
    from identification.validation import Params, _initial_velocity, _reference_derivatives, simulate_runs
    from omni_sim import experiments as ex

    runs = ex.simulate(Device.load(), ex.campaign("paper"))
    ident = identify_runs(runs)
    params = Params(ident.inertia.params, ident.alpha_model, ident.to_params()["poses"])
    fast = simulate_runs(runs, params)
    groups = {}
    for run in runs:
        groups.setdefault((len(run.t), round(run.dt, 12), run.kp), []).append(run)
    n_brk = 0
    for (_, dt, kp), group in groups.items():
        I, Cl, bl = np.array([params.linear_coefficients(r) for r in group]).T
        d = [_reference_derivatives(r) for r in group]
        ref = _numpy(
            simulate_alpha, params.alpha, I, np.vstack([r.r for r in group]), dt, kp, C_linear=Cl,
            beta_tilde_linear=bl, theta0=[r.theta[0] for r in group],
            phi0=[_initial_velocity(r) for r in group], r_dot=np.vstack([x[0] for x in d]),
            r_ddot=np.vstack([x[1] for x in d]))
        for j, run in enumerate(group):
            # different code paths: see ULP_PER_STEP (|θ| <= ~0.1 rad, a few thousand steps)
            np.testing.assert_allclose(fast[run.name]["theta_alpha"], ref.theta[j], rtol=0, atol=1e-12)
            assert fast[run.name]["n_bracketed"] == ref.n_bracketed[j]
            assert fast[run.name]["n_not_converged"] == ref.n_not_converged[j]
            n_brk += ref.n_bracketed[j]
    assert len(fast) == 106 and n_brk > 0
