"""The compiled α-simulation loop (omni_app.alpha_kernel, numba) against the numpy loop and
simulate_alpha_reference: the same numbers to the stated tolerance of two code paths
(test_simulate_fast.ULP_PER_STEP: LLVM's exp against numpy's SIMD exp) and the same decisions
of the iteration (bisection fallback, batches of ragged runs and the paper campaign included),
and its registration (omni_app.accel)."""

import numpy as np
import pytest

from identification import csvformat
from identification import simulate as sim
from identification.nonlinear import AlphaModel, paper_alpha_model
from identification.simulate import (
    simulate_alpha,
    simulate_alpha_batch,
    simulate_alpha_reference,
    square_wave_reference,
)
from omni_app import accel
from omni_app.alpha_kernel import interp, loop

from test_simulate_fast import DT, IDENTIFIED, KP, _assert_paths_agree, _sines


@pytest.fixture
def kernel():
    """The compiled loop registered for the test (the numpy loop restored after)."""
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
def test_kernel_equals_reference_sines(kernel, model):
    r, rd, rdd = _sines([1.5, 2.5, 3.5, 5.0, 7.0], 1500)
    I = np.array([0.0038, 0.0045, 0.005, 0.0055, 0.0067])
    kw = dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, theta0=0.001, phi0=0.02,
              r_dot=rd, r_ddot=rdd)
    ref = simulate_alpha_reference(model, I, r, DT, KP, **kw)
    fast = simulate_alpha(model, I, r, DT, KP, **kw)
    _assert_paths_agree(fast, ref)
    if model.options.get("beta_clamp"):
        assert np.sum(ref.n_bracketed) > 0  # the fallback is exercised


def test_kernel_equals_reference_step_and_unclamped_floor(kernel):
    """Square waves (zero reference derivatives), and a model whose β̃ line is not clamped and
    reaches its floor (the branches the numpy loop may skip)."""
    model = paper_alpha_model()
    t = np.arange(3000) * DT
    r = np.tile(square_wave_reference(t, 0.25, 0.07), (3, 1))
    I = np.array([0.004, 0.005, 0.006])
    kw = dict(C_linear=1 / (36.693 * I), beta_tilde_linear=1 / I, theta0=-0.07, r_dot=0.0,
              r_ddot=0.0)
    _assert_paths_agree(simulate_alpha(model, I, r, DT, KP, **kw),
                 simulate_alpha_reference(model, I, r, DT, KP, **kw))
    falling = AlphaModel.from_dict({**IDENTIFIED, "alpha_bar": [0.0, 20.0],
                                    "beta_k1": [100.0, 300.0],
                                    "options": {**IDENTIFIED["options"], "beta_clamp": False,
                                                "beta_floor_fraction": 0.95}})
    rs, rds, rdds = _sines([2.0, 4.5], 1200, amp=0.08)
    I2 = np.array([0.0042, 0.006])
    kw2 = dict(C_linear=1 / (36.693 * I2), beta_tilde_linear=1 / I2, r_dot=rds, r_ddot=rdds)
    ref = simulate_alpha_reference(falling, I2, rs, DT, KP, **kw2)
    _assert_paths_agree(simulate_alpha(falling, I2, rs, DT, KP, **kw2), ref)
    assert np.all(np.isfinite(ref.theta))
    floor = 0.95 * min(falling.beta_inv)
    assert np.any(np.isclose(ref.beta_tilde * I2[:, None], floor, rtol=1e-12))  # floor reached

def test_kernel_ragged_groups_equal_numpy_loop(kernel):
    """Runs of different lengths, gains and batches in one call: the kernel equals the numpy
    loop (itself tested against the per-batch reference in test_simulate_fast)."""
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
    sim.set_kernel(None)
    slow = simulate_alpha_batch(model, I, rs, DT, kps, **kw)
    assert sum(x.n_bracketed for x in slow) > 0
    for a, b in zip(fast, slow):
        _assert_paths_agree(a, b)


def test_install_registers_lazily_and_falls_back(monkeypatch):
    previous = sim.set_kernel(None)
    previous_csv = csvformat.set_kernel(None)
    try:
        monkeypatch.setattr(accel, "_loaded", {})
        accel.install()
        assert sim._KERNEL is not None and sim._KERNEL is not loop   # not loaded yet
        model = paper_alpha_model()
        r = np.sin(np.arange(300) * 0.02) * 0.05
        kw = dict(C_linear=5.0, beta_tilde_linear=200.0)
        a = simulate_alpha(model, 0.005, r, DT, KP, **kw)
        assert sim._KERNEL is loop                                    # loaded, in its place
        # numba unavailable: a warning, and the numpy loop (the same numbers, to the tolerance
        # of two code paths)
        sim.set_kernel(None)
        monkeypatch.setattr(accel, "_loaded", {})
        monkeypatch.setitem(__import__("sys").modules, "omni_app.alpha_kernel", None)
        accel.install()
        with pytest.warns(RuntimeWarning, match="unavailable"):
            b = simulate_alpha(model, 0.005, r, DT, KP, **kw)
        assert sim._KERNEL is None
        _assert_paths_agree(a, b)
        accel.install()                                               # not retried
        assert sim._KERNEL is None
    finally:
        sim.set_kernel(previous)
        csvformat.set_kernel(previous_csv)


@pytest.mark.slow
def test_kernel_paper_campaign_equals_per_group_reference(kernel):
    """All 106 runs of the paper campaign through validation with the compiled loop: equal to
    simulate_alpha_reference called per batch, within 1e-12 and in fact bit for bit, with the
    same counts of bisected and unconverged steps."""
    from test_simulate_fast import test_validation_paper_campaign_equals_per_group_reference

    test_validation_paper_campaign_equals_per_group_reference()


def test_prewarm_thread_loads_both_kernels(monkeypatch):
    from omni_app.csv_kernel import format_rows as csv_loop

    previous, previous_csv = sim.set_kernel(None), csvformat.set_kernel(None)
    try:
        monkeypatch.setattr(accel, "_loaded", {})
        accel.start_prewarm().join()
        assert sim._KERNEL is loop and csvformat._KERNEL is csv_loop
    finally:
        sim.set_kernel(previous)
        csvformat.set_kernel(previous_csv)


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
