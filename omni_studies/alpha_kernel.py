"""The α-model simulation's time loop compiled with numba.

:func:`identification.simulate.simulate_alpha_batch` runs a per-time-step recursion (the
quasilinear iteration (44)–(46) and its bisection fallback, then an exact ZOH step) that numpy
can only vectorise over runs: ~200 k sequential steps of a few small-array calls each.  This
module is the same loop, operation for operation, in compiled code: the arguments and the
numbers (to a few ulps per step, see below) of ``identification.simulate.batch_loop_numpy``,
which is its reference.  The method layer stays numpy/scipy only: the application registers the kernel
(:func:`omni_studies.accel.install`), and the numpy loop is used wherever it is not registered or
numba cannot compile.

Every floating-point operation is the numpy loop's, in the same order, without fast-math (no
reassociation): ``np.interp``'s formula (slope·(x − x_j) + f_j, with its NaN and end rules),
``np.maximum``/``np.clip``'s NaN rules, ``exp`` and ``expm1``, and the bisection of each batch
(``groups``) run to the batch's common stopping step.  The numbers are not the same bits on
every CPU: numpy evaluates ``exp`` with SIMD code chosen for the CPU (AVX-512, AVX2, or its
baseline), this loop with the C library's, as LLVM compiled it for the host (which may also
fuse a multiply-add); these differ by a few ulps.  On a CPU where numpy runs its baseline code
the two loops have given the same bits; on an AVX-512 CPU they differ by <= 4e-14 of a run's
scale, and the iteration's decisions are the same (``tests/test_alpha_kernel.py``: within
4 ulp per step of each run's scale).

This module imports numba; :mod:`omni_studies.accel` registers it lazily (numba is imported and
the loop compiled or loaded at the first α simulation; the numpy loop is kept if that fails).
Compiled functions are cached on disk (``cache=True``): in ``__pycache__`` next to this file
when that folder is writable, else in numba's user cache (``NUMBA_CACHE_DIR``, or
``~/.cache/numba``); where no cache can be written they are compiled in memory each run.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_SERIES_BELOW = 0.02
_N_SERIES = 7
_G1 = np.array([1.0 / math.factorial(n + 1) for n in range(_N_SERIES)][::-1])
_G2 = np.array([1.0 / math.factorial(n + 2) for n in range(_N_SERIES)][::-1])
_MAX_BISECT = 200
_MAX_CREEP = 61


#: the functions Python calls (the loop, and ``interp`` for the tests); the others are called
#: only from compiled code and get no Python or C entry wrapper: a first run compiles ~16 %
#: less (2.6 s instead of 3.1 s of one core, measured in a fresh process with an empty cache)
_ENTRY_POINTS = ("loop", "interp")


def _jit(fn):
    """numba.njit with IEEE semantics (no fast-math; division by zero gives inf/NaN as in
    numpy) and an on-disk cache where one can be written."""
    internal = fn.__name__ not in _ENTRY_POINTS
    options = dict(error_model="numpy", nogil=True, no_cpython_wrapper=internal,
                   no_cfunc_wrapper=True)
    try:
        return numba.njit(cache=True, **options)(fn)
    except RuntimeError:  # no cache locator (nothing writable): compile in memory
        return numba.njit(**options)(fn)


@_jit
def interp(x, xp, fp):
    """np.interp(x, xp, fp) for one x (numpy's arr_interp, default left/right)."""
    n = xp.shape[0]
    if n == 1:
        return fp[0]
    if math.isnan(x):
        return x
    if x > xp[n - 1]:
        return fp[n - 1]
    if x < xp[0]:
        return fp[0]
    j = 0
    while j < n - 1 and xp[j + 1] <= x:
        j += 1
    if j == n - 1:
        return fp[j]
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    res = slope * (x - xp[j]) + fp[j]
    if math.isnan(res):
        res = slope * (x - xp[j + 1]) + fp[j + 1]
        if math.isnan(res) and fp[j] == fp[j + 1]:
            res = fp[j]
    return res


@_jit
def npmax(a, b):
    """np.maximum for two floats."""
    return a if (a >= b or math.isnan(a)) else b


@_jit
def npmin(a, b):
    """np.minimum for two floats."""
    return a if (a <= b or math.isnan(a)) else b


@_jit
def tol(a):
    """The stopping tolerance of (46): max(1e-6, 1e-3·|α|)."""
    return npmax(1e-6, 1e-3 * abs(a))


@_jit
def beta(a, inv_i, b0, a0, a1, b_slope, b_floor, clamp):
    x = a
    if clamp:
        x = npmin(npmax(x, a0), a1)
    x = b0 + b_slope * (x - a0)
    return npmax(x, b_floor) * inv_i


@_jit
def g(a, v, vd2, kr, ph, inv_i, kp, breaks, c_inv, b0, a0, a1, b_slope, b_floor, clamp):
    Ca = interp(a, breaks, c_inv) * inv_i
    return vd2 - v * (kr - kp * (beta(a, inv_i, b0, a0, a1, b_slope, b_floor, clamp) * v
                                 - Ca * ph))


@_jit
def argmin_masked(A, H, last, negative):
    """np.argmin of |A − last| where H ≤ 0 (``negative``) or H ≥ 0, +inf elsewhere: the
    first minimum, or the first NaN."""
    best = 0
    bv = np.inf
    for j in range(A.shape[0]):
        sel = H[j] <= 0 if negative else H[j] >= 0
        d = abs(A[j] - last) if sel else np.inf
        if math.isnan(d):
            return j
        if j == 0 or d < bv:
            bv = d
            best = j
    return best


@_jit
def _iterate(x, vj, vd2j, krj, phj, inv_i, kp, breaks, c_inv, b0, a0, a1, b_slope, b_floor,
             clamp, max_iter, hist_row):
    """The fixed-point iteration (44) from the first iterate ``x`` until (46) holds or
    ``max_iter``; every iterate is kept in ``hist_row``.  Returns ``(α, iterations, met)``."""
    hist_row[0] = x
    for i in range(2, max_iter + 1):
        xn = g(x, vj, vd2j, krj, phj, inv_i, kp, breaks, c_inv, b0, a0, a1, b_slope, b_floor,
               clamp)
        hist_row[i - 1] = xn
        if abs(xn - x) < tol(xn):
            return xn, i, True
        x = xn
    return x, max_iter, False


@_jit
def _bracket(A, Hs, vj, vd2j, krj, phj, inv_i, kp, breaks, c_inv, b0, a0, a1, b_slope,
             b_floor, clamp):
    """A bracket of the root of h(α) = α − g(α) from the iterates ``A`` (the numpy loop's
    _bisect_fallback for one run): the nearest iterates to the last with h ≤ 0 and h ≥ 0, or,
    with no sign change among them, a step on in the direction of travel doubled up to
    _MAX_CREEP times.  Returns ``(found, lo, hi, h(lo))``."""
    L = A.shape[0]
    last = A[L - 1]
    for q in range(L - 1):
        Hs[q] = A[q] - A[q + 1]
    h_last = last - g(last, vj, vd2j, krj, phj, inv_i, kp, breaks, c_inv, b0, a0, a1, b_slope,
                      b_floor, clamp)
    Hs[L - 1] = h_last
    # np.bool_(...), not a bare True/False: numba types a bare constant as a literal and would
    # compile argmin_masked once per value (a cold start's compile time)
    neg = argmin_masked(A, Hs, last, np.bool_(True))
    pos = argmin_masked(A, Hs, last, np.bool_(False))
    okj = Hs[neg] <= 0 and Hs[pos] >= 0
    a_n, a_p, h_n, h_p = A[neg], A[pos], Hs[neg], Hs[pos]
    if not okj:
        # no sign change among the iterates: step on in the direction of travel
        step = last - A[L - 2]
        for mm in range(_MAX_CREEP):
            if step == 0:
                break
            xx = last + step * 2.0 ** mm
            hx = xx - g(xx, vj, vd2j, krj, phj, inv_i, kp, breaks, c_inv, b0, a0, a1, b_slope,
                        b_floor, clamp)
            if hx * h_last <= 0:
                a_n, h_n, a_p, h_p = last, h_last, xx, hx
                okj = True
                break
    return okj, npmin(a_n, a_p), npmax(a_n, a_p), (h_n if a_n <= a_p else h_p)


@_jit
def _zoh_step(C, b, vj, thj, phj, dt):
    """The exact ZOH step of θ'' + C θ' = b v (identification.simulate.zoh_coefficients)."""
    x = C * dt
    if abs(x) < _SERIES_BELOW:
        s1 = 0.0
        s2 = 0.0
        for c in range(_N_SERIES):
            s1 = s1 * (-x) + _G1[c]
            s2 = s2 * (-x) + _G2[c]
        G1 = s1
        G2 = s2
    else:
        em1 = math.expm1(-x)
        G1 = -em1 / x
        G2 = (1.0 - G1) / x
    E = math.exp(-x)
    g1 = dt * G1
    g2 = dt * dt * G2
    u = b * vj
    return thj + g1 * phj + g2 * u, E * phj + g1 * u


@_jit
def _bisect_pending(pending, n_pending, grp, hist, Hs, v, vd2, kr, ph, invI_, kp_, breaks, c_inv,
                    b0, a0, a1, b_slope, b_floor, clamp, max_iter, ok, lo, hi, h_lo, a, bracketed,
                    not_conv):
    """The runs ``pending[:n_pending]`` that did not meet (46): bracketed (:func:`_bracket`),
    then bisected batch by batch -- all runs of a batch (``grp``) until every one of them meets
    the tolerance, as the numpy loop bisects a batch -- into ``a``; a run with no bracket keeps
    its last iterate and counts as not converged."""
    for p0 in range(n_pending):
        gid = grp[pending[p0]]
        first = True
        for p1 in range(p0):
            if grp[pending[p1]] == gid:
                first = False
                break
        if not first:
            continue
        for p in range(p0, n_pending):
            j = pending[p]
            if grp[j] == gid:
                ok[j], lo[j], hi[j], h_lo[j] = _bracket(
                    hist[j], Hs, v[j], vd2[j], kr[j], ph[j], invI_[j], kp_[j], breaks,
                    c_inv, b0, a0, a1, b_slope, b_floor, clamp)
        for _ in range(_MAX_BISECT):
            all_done = True
            for p in range(p0, n_pending):
                j = pending[p]
                if grp[j] == gid and ok[j]:
                    mid = 0.5 * (lo[j] + hi[j])
                    if not (hi[j] - lo[j] < tol(mid)):
                        all_done = False
                        break
            if all_done:
                break
            for p in range(p0, n_pending):
                j = pending[p]
                if grp[j] != gid or not ok[j]:
                    continue
                mid = 0.5 * (lo[j] + hi[j])
                h_mid = mid - g(mid, v[j], vd2[j], kr[j], ph[j], invI_[j], kp_[j],
                                breaks, c_inv, b0, a0, a1, b_slope, b_floor, clamp)
                if h_lo[j] * h_mid <= 0:
                    hi[j] = mid
                else:
                    lo[j] = mid
                    h_lo[j] = h_mid
        for p in range(p0, n_pending):
            j = pending[p]
            if grp[j] != gid:
                continue
            if ok[j]:
                a[j] = 0.5 * (lo[j] + hi[j])
                bracketed[j] += 1
            else:
                a[j] = hist[j, max_iter - 1]
                not_conv[j] += 1


@_jit
def loop(Rt, RDt, RDDt, alive, kp_, invI_, Cl_, bl_, th, ph, grp, breaks, c_inv, b0, b1,
         a0, a1, b_slope, b_floor, clamp, dt, max_iter, out_th, out_ph, out_v, out_a, out_C,
         out_b, out_it, not_conv, bracketed):
    """The time loop: at each step every live run iterates (44)–(46) (:func:`_iterate`); runs
    that do not meet (46) within ``max_iter`` are bracketed (:func:`_bracket`) and bisected
    batch by batch (``grp``: all runs of a batch to the batch's common stopping step, as the
    numpy loop does); then every run takes its exact ZOH step (:func:`_zoh_step`)."""
    n, R = Rt.shape
    hist = np.empty((R, max_iter))
    Hs = np.empty(max_iter)
    a = np.empty(R)
    v = np.empty(R)
    vd2 = np.empty(R)
    kr = np.empty(R)
    pending = np.empty(R, dtype=np.int64)
    ok = np.zeros(R, dtype=np.bool_)
    lo = np.empty(R)
    hi = np.empty(R)
    h_lo = np.empty(R)
    for k in range(n):
        m = alive[k]
        n_pending = np.int64(0)  # not a literal 0: _bisect_pending is compiled once, not twice
        for j in range(m):
            out_th[k, j] = th[j]
            out_ph[k, j] = ph[j]
            kp = kp_[j]
            v[j] = kp * (Rt[k, j] - th[j])
            vd = kp * (RDt[k, j] - ph[j])
            vd2[j] = vd * vd
            kr[j] = kp * RDDt[k, j]
            # (45'): first iterate from the linear model's acceleration; α^(1) by (44)
            x0 = vd2[j] - v[j] * (kr[j] - kp * (bl_[j] * v[j] - Cl_[j] * ph[j]))
            a[j], out_it[k, j], done = _iterate(x0, v[j], vd2[j], kr[j], ph[j], invI_[j], kp,
                                                breaks, c_inv, b0, a0, a1, b_slope, b_floor,
                                                clamp, max_iter, hist[j])
            if not done:
                pending[n_pending] = j
                n_pending += 1
        # (46) not met within max_iter: bisection, batch by batch
        _bisect_pending(pending, n_pending, grp, hist, Hs, v, vd2, kr, ph, invI_, kp_, breaks,
                        c_inv, b0, a0, a1, b_slope, b_floor, clamp, max_iter, ok, lo, hi, h_lo, a,
                        bracketed, not_conv)
        for j in range(m):
            aj = a[j]
            C = interp(aj, breaks, c_inv) * invI_[j]
            b = beta(aj, invI_[j], b0, a0, a1, b_slope, b_floor, clamp)
            out_v[k, j] = v[j]
            out_a[k, j] = aj
            out_C[k, j] = C
            out_b[k, j] = b
            if k + 1 < n:
                th[j], ph[j] = _zoh_step(C, b, v[j], th[j], ph[j], dt)
