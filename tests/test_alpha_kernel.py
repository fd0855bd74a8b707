"""The compiled α-simulation loop (omni_studies.alpha_kernel, numba) against the numpy loop
(identification.simulate.batch_loop_numpy, its reference): the same numbers to the stated
tolerance of two code paths (test_simulate_fast.ULP_PER_STEP: LLVM's exp against numpy's SIMD
exp) and the same decisions of the iteration (bisection fallback, batches of ragged runs and
the paper campaign included), and its registration (omni_studies.accel)."""

import numpy as np
import pytest

from identification import simulate as sim
from identification.nonlinear import AlphaModel, paper_alpha_model
from identification.simulate import simulate_alpha, simulate_alpha_batch, square_wave_reference
from omni_studies import accel
from omni_studies.alpha_kernel import interp, loop

from test_simulate_fast import DT, IDENTIFIED, KP, _assert_paths_agree, _numpy, _sines


@pytest.fixture
def kernel():
    """The compiled loop registered for the test (the previous loop restored after)."""
    previous = sim.set_kernel(loop)
    yield loop
    sim.set_kernel(previous)


def test_interp_is_numpys():
    """The kernel's interp computes np.interp's formula in its order; the results may differ
    in the last bit only where LLVM fuses the multiply-add of the segment (an FMA, on a CPU that
    has one), so within 1 ulp; outside the breakpoints, at them, NaN and ±inf: identical."""
    xp = np.array(IDENTIFIED["alpha_breaks"])
    fp = np.array([0.3, 0.1, 0.0, 0.05])
    rng = np.random.default_rng(0)
    x = np.concatenate([xp, np.nextafter(xp, -np.inf), np.nextafter(xp, np.inf),
                        rng.uniform(-5, 20, 2000), rng.normal(0, 1e-3, 200),
                        [np.nan, np.inf, -np.inf, -0.0, 1e300, -1e300]])
    got = np.array([interp(v, xp, fp) for v in x])
    want = np.interp(x, xp, fp)
    np.testing.assert_array_max_ulp(got, want, maxulp=1)
    exact = ~((x > xp[0]) & (x < xp[-1])) | np.isin(x, xp)
    np.testing.assert_array_equal(got[exact], want[exact])
    one = np.array([2.0])
    got1 = np.array([interp(v, one, np.array([7.0])) for v in x])
    np.testing.assert_array_equal(got1, np.interp(x, one, [7.0]))


@pytest.mark.parametrize("model", [AlphaModel.from_dict(IDENTIFIED), paper_alpha_model()],
                         ids=["identified", "paper"])
def test_kernel_equals_numpy_loop_sines(kernel, model):
    r, rd, rdd = _sines([1.5, 2.5, 3.5, 5.0, 7.0], 1500)
    I = np.array([0.0038, 0.0045, 0.005, 0.0055, 0.0067])
    kw = dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, theta0=0.001, phi0=0.02,
              r_dot=rd, r_ddot=rdd)
    ref = _numpy(simulate_alpha, model, I, r, DT, KP, **kw)
    fast = simulate_alpha(model, I, r, DT, KP, **kw)
    _assert_paths_agree(fast, ref)
    if model.options.get("beta_clamp"):
        assert np.sum(ref.n_bracketed) > 0  # the fallback is exercised


def test_kernel_equals_numpy_loop_step_and_unclamped_floor(kernel):
    """Square waves (zero reference derivatives), and a model whose β̃ line is not clamped and
    reaches its floor."""
    model = paper_alpha_model()
    t = np.arange(3000) * DT
    r = np.tile(square_wave_reference(t, 0.25, 0.07), (3, 1))
    I = np.array([0.004, 0.005, 0.006])
    kw = dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, theta0=-0.07, r_dot=0.0,
              r_ddot=0.0)
    _assert_paths_agree(simulate_alpha(model, I, r, DT, KP, **kw),
                        _numpy(simulate_alpha, model, I, r, DT, KP, **kw))
    falling = AlphaModel.from_dict({**IDENTIFIED, "alpha_bar": [0.0, 20.0],
                                    "beta_k1": [100.0, 300.0],
                                    "options": {**IDENTIFIED["options"], "beta_clamp": False,
                                                "beta_floor_fraction": 0.95}})
    rs, rds, rdds = _sines([2.0, 4.5], 1200, amp=0.08)
    I2 = np.array([0.0042, 0.006])
    kw2 = dict(C_linear=1 / (36.693 * I2), beta_tilde_linear=1 / I2, r_dot=rds, r_ddot=rdds)
    ref = _numpy(simulate_alpha, falling, I2, rs, DT, KP, **kw2)
    _assert_paths_agree(simulate_alpha(falling, I2, rs, DT, KP, **kw2), ref)
    assert np.all(np.isfinite(ref.theta))
    floor = 0.95 * min(falling.beta_inv)
    assert np.any(np.isclose(ref.beta_tilde * I2[:, None], floor, rtol=1e-12))  # floor reached


def test_kernel_dropped_term_is_caught(kernel):
    """The tolerance between the two loops catches a broken compiled path: the kernel with the
    r̈ term of v̈ dropped (r_ddot = 0), or with kp off by 1e-9, fails it."""
    model = AlphaModel.from_dict(IDENTIFIED)
    r, rd, rdd = _sines([2.5, 5.0], 1500)
    I = np.array([0.0045, 0.0055])
    kw = dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, r_dot=rd)
    ref = _numpy(simulate_alpha, model, I, r, DT, KP, r_ddot=rdd, **kw)
    _assert_paths_agree(simulate_alpha(model, I, r, DT, KP, r_ddot=rdd, **kw), ref)
    with pytest.raises(AssertionError):
        _assert_paths_agree(simulate_alpha(model, I, r, DT, KP, r_ddot=0.0 * rdd, **kw), ref)
    with pytest.raises(AssertionError):
        _assert_paths_agree(simulate_alpha(model, I, r, DT, KP * (1 + 1e-9), r_ddot=rdd, **kw), ref)


def test_kernel_ragged_groups_equal_numpy_loop(kernel):
    """Runs of different lengths, gains and batches in one call: the kernel equals the numpy
    loop (itself tested against per-batch calls in test_simulate_fast)."""
    model = AlphaModel.from_dict(IDENTIFIED)
    ra, rda, rdda = _sines([2.0, 3.5, 6.0], 1200)
    rb, rdb, rddb = _sines([2.5, 5.0], 900)
    rs = [rb[0], ra[0], ra[1], rb[1], ra[2]]
    rds = [rdb[0], rda[0], rda[1], rdb[1], rda[2]]
    rdds = [rddb[0], rdda[0], rdda[1], rddb[1], rdda[2]]
    I = np.array([0.0045, 0.004, 0.005, 0.0055, 0.006])
    kw = dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, theta0=0.0, r_dot=rds,
              r_ddot=rdds, groups=[1, 0, 0, 1, 0])
    kps = [2.5, KP, KP, 2.5, KP]
    fast = simulate_alpha_batch(model, I, rs, DT, kps, **kw)
    slow = _numpy(simulate_alpha_batch, model, I, rs, DT, kps, **kw)
    assert sum(x.n_bracketed for x in slow) > 0
    for a, b in zip(fast, slow):
        _assert_paths_agree(a, b)


def test_install_registers_lazily_and_falls_back(monkeypatch):
    """install() registers a stand-in that loads the compiled loop at the first α simulation
    and puts it in its place; where numba is unavailable, a warning and the numpy loop."""
    previous = sim.set_kernel(None)
    try:
        accel.install()
        assert sim.current_kernel() is accel._first_call                      # not loaded yet
        model = paper_alpha_model()
        r = np.sin(np.arange(300) * 0.02) * 0.05
        kw = dict(C_linear=5.0, beta_tilde_linear=200.0)
        a = simulate_alpha(model, 0.005, r, DT, KP, **kw)
        assert sim.current_kernel() is loop                                   # loaded, in its place
        accel.install()                                               # one is registered
        assert sim.current_kernel() is loop
        # numba unavailable: a warning, and the numpy loop (the same numbers, to the tolerance
        # of two code paths)
        sim.set_kernel(None)
        monkeypatch.setitem(__import__("sys").modules, "omni_studies.alpha_kernel", None)
        accel.install()
        with pytest.warns(RuntimeWarning, match="unavailable"):
            b = simulate_alpha(model, 0.005, r, DT, KP, **kw)
        assert sim.current_kernel() is None
        _assert_paths_agree(a, b)
    finally:
        sim.set_kernel(previous)


@pytest.mark.slow
def test_kernel_paper_campaign_equals_numpy_per_group(kernel):
    """All 106 runs of the paper campaign through validation with the compiled loop: equal to
    the numpy loop called per batch, within 1e-12, with the same counts of bisected and
    unconverged steps."""
    from test_simulate_fast import test_validation_paper_campaign_equals_per_group_calls

    test_validation_paper_campaign_equals_per_group_calls()


@pytest.mark.parametrize("compiled", [False, True], ids=["numpy", "kernel"])
def test_keep_only_theta(compiled):
    """``keep=("theta",)`` (validation's call): the same θ, the other arrays None."""
    previous = sim.set_kernel(loop if compiled else None)
    try:
        model = AlphaModel.from_dict(IDENTIFIED)
        r, rd, rdd = _sines([2.0, 3.5, 6.0], 1000)
        I = np.array([0.004, 0.005, 0.006])
        kw = dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, r_dot=list(rd),
                  r_ddot=list(rdd), groups=[0, 0, 0])
        full = simulate_alpha_batch(model, I, list(r), DT, KP, **kw)
        some = simulate_alpha_batch(model, I, list(r), DT, KP, keep=("theta",), **kw)
        for a, b in zip(full, some):
            np.testing.assert_array_equal(b.theta, a.theta)
            assert b.phi is None and b.alpha is None and b.n_iter is None
            assert (b.n_bracketed, b.n_not_converged) == (a.n_bracketed, a.n_not_converged)
        assert sum(x.n_bracketed for x in full) > 0
        with pytest.raises(ValueError, match="unknown"):
            simulate_alpha_batch(model, I, list(r), DT, KP, keep=("thetta",), **kw)
    finally:
        sim.set_kernel(previous)
