"""Quasilinear simulation of the α-invariant model, paper section 2.4.1, (43)–(46), and of the
global linear model (26).

State space (43): θ' = Φ, Φ' = −C(α)·Φ + β̃(α)·v, α = v̇² − v·v̈, v = kp·(r − θ).

Discretisation
--------------
The device (and the MuJoCo simulator) apply the command with a zero-order hold at the sample
rate: v_k = kp·(r_k − θ_k) is held over [t_k, t_k + dt).  Over one step C and β̃ are frozen at
the values of the converged α_k, so the step is the linear ODE θ'' + C·θ' = u with constant
u = β̃·v_k, integrated exactly:

    Φ(t_k + h) = Φ_k·e^{−Ch} + u·g1,        g1 = (1 − e^{−Ch})/C        (→ h    as C → 0)
    θ(t_k + h) = θ_k + Φ_k·g1 + u·g2,       g2 = (h − g1)/C              (→ h²/2 as C → 0)

with h = dt; for |C·h| < 0.02 g1 and g2 come from their power series (7 terms, truncation
< 1e-17 relative) instead of the cancelling closed forms.  With constant C and β̃ this is the
exact sampled-data (ZOH) closed loop, identical to ``scipy.signal.cont2discrete(..., "zoh")``
of the plant with v_k fed back.

The α iteration (44)–(46) at t_k
--------------------------------
v = kp·(r − θ) and v̇ = kp·(ṙ − Φ) are known from the state; v̈ = kp·(r̈ − Φ̇) needs
Φ̇ = −C(α)Φ + β̃(α)v, which needs α, which needs v̈.  The fixed-point iteration is

    α^(i)  = v̇² − v·v̈^(i−1)                                                    (44)
    Φ̇^(i)  = −C(α^(i))·Φ + β̃(α^(i))·v
    v̈^(i)  = kp·(r̈ − Φ̇^(i)),        i = 1, 2, …

First iterate.  (45) as printed, v̈^(0) = −C_linear·Φ + β̃_linear·v, is the acceleration Φ̇ of
the linear model (26), not v̈ (the units differ by V/rad and the sign by −1).  Differentiating
v = kp·(r − θ) twice gives v̈ = kp·(r̈ − θ'') = kp·(r̈ − Φ̇), and the natural first guess
for Φ̇ is the linear model's, so the first iterate implemented is

    v̈^(0) = kp·(r̈ − (−C_linear·Φ + β̃_linear·v)).                               (45')

Stopping rule (46): stop at the first i ≥ 2 with |α^(i) − α^(i−1)| < max(1e-6, 1e-3·|α^(i)|)
and use C(α^(i)), β̃(α^(i)) for the step.

When (46) fails.  The iteration is α = g(α) with g piecewise linear and continuous (C and β̃
interpolate, and are held outside their breakpoints).  Where C(α) is steep, |g'| > 1 and the
iteration cycles between two values instead of converging (measured on the LuGre virtual
Omni's sine campaign: 1.3 % of steps).  The step's α is still defined — a root of
h(α) = α − g(α) — and the iterates bracket one: h(α^(j)) = α^(j) − α^(j+1) is known for every
iterate, and an oscillating sequence has iterates with h < 0 and with h > 0.  So if (46) has not
been met at i = ``max_iter``, h(α^(max_iter)) is evaluated, the iterate with h < 0 and the one
with h > 0 nearest to α^(max_iter) form a bracket, and h is bisected to the same tolerance
(``n_bracketed`` counts these steps).  A monotone sequence that is still creeping (g' close to
1; the common case on that campaign) has h of one sign at all iterates; its root lies further
on in the direction of travel, so the bracket is found by stepping from α^(max_iter) in that
direction by the last increment doubled up to 60 times.  Only a step with no bracket either way
keeps the last iterate and counts as not converged (per run).

Batching: r has shape (n_runs, n_samples); every run has its own inertia I (and linear
coefficients), and the iteration is vectorised over runs: at each step the runs iterate
together, a run that has converged is frozen, and the step ends when all have converged.

Reference derivatives: ṙ and r̈ enter v̇ and v̈.  Pass them when known (for a square wave
they are zero between edges: pass zeros; the jump of r is already applied through v_k).  If
omitted they are computed with ``numpy.gradient`` (second-order central differences, one-sided
second order at the ends) applied once for ṙ and again for r̈, which is only suitable for
smooth references (a jump would give a spike of Δr/dt).

Units: t [s], θ, r [rad], Φ [rad/s], v [V], kp [V/rad], C [1/s], β̃ [rad/(V·s²)], α [V²/s²].
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from . import paper
from .nonlinear import AlphaModel, paper_alpha_model

__all__ = [
    "SimResult",
    "simulate_alpha",
    "simulate_alpha_batch",
    "simulate_linear",
    "set_kernel",
    "zoh_coefficients",
    "square_wave_reference",
    "bench_simulation",
    "DEFAULT_MAX_ITER",
]

#: Bound on the iterations (44) per step.
DEFAULT_MAX_ITER = 50
_SERIES_BELOW = 0.02
# Taylor coefficients of G1(x) = (1 − e^{−x})/x = Σ (−x)^n/(n+1)! and
# G2(x) = (x − 1 + e^{−x})/x² = Σ (−x)^n/(n+2)!: coefficients of (−x)^n, highest power first
# (Horner in −x).
_N_SERIES = 7
_G1_COEF = [1.0 / math.factorial(n + 1) for n in range(_N_SERIES)][::-1]
_G2_COEF = [1.0 / math.factorial(n + 2) for n in range(_N_SERIES)][::-1]


def zoh_coefficients(C, h):
    """Exact one-step coefficients of θ'' + C·θ' = u (u constant over the step).

    Parameters
    ----------
    C : array_like [1/s]
        Damping (any sign; 0 allowed).
    h : float [s]
        Step.

    Returns
    -------
    E, g1, g2 : ndarray
        e^{−Ch} [-], (1 − e^{−Ch})/C [s], (h − g1)/C [s²], so that
        Φ⁺ = E·Φ + g1·u and θ⁺ = θ + g1·Φ + g2·u.
    """
    x = np.asarray(C, dtype=float) * h
    small = np.abs(x) < _SERIES_BELOW
    xs = np.where(small, 1.0, x)
    em1 = np.expm1(-xs)
    G1 = -em1 / xs
    G2 = (1.0 - G1) / xs
    if np.any(small):
        s1 = np.zeros_like(x)
        s2 = np.zeros_like(x)
        for c1, c2 in zip(_G1_COEF, _G2_COEF):
            s1 = s1 * (-x) + c1
            s2 = s2 * (-x) + c2
        G1 = np.where(small, s1, G1)
        G2 = np.where(small, s2, G2)
    return np.exp(-x), h * G1, h * h * G2


@dataclass
class SimResult:
    """Output of :func:`simulate_alpha` / :func:`simulate_linear`.

    All arrays have the shape of ``r`` ((n_runs, n_samples), or (n_samples,) for one run);
    entry k belongs to sample time t_k.  An array not asked for (``keep`` of
    :func:`simulate_alpha_batch`) is None.

    Attributes
    ----------
    theta : ndarray [rad]
        Angle θ_k.
    phi : ndarray [rad/s]
        Angular velocity Φ_k.
    v : ndarray [V]
        Command v_k = kp·(r_k − θ_k), held over [t_k, t_k + dt).
    alpha : ndarray [V²/s²] or None
        Converged α used on step k (None for the linear model).
    C, beta_tilde : ndarray
        Coefficients used on step k [1/s], [rad/(V·s²)].
    n_iter : ndarray of int or None
        Iterations (44) on step k (the index i of the accepted α^(i)).
    n_not_converged : ndarray of int or int
        Steps per run where (46) was not met within ``max_iter`` and the bisection fallback found
        no bracket (the last iterate was used).
    n_bracketed : ndarray of int or int
        Steps per run where (46) was not met within ``max_iter`` and α was found by bisection
        between the last two iterates (module docstring).
    """

    theta: np.ndarray
    phi: np.ndarray
    v: np.ndarray
    C: np.ndarray
    beta_tilde: np.ndarray
    alpha: np.ndarray | None = None
    n_iter: np.ndarray | None = None
    n_not_converged: np.ndarray | int = 0
    n_bracketed: np.ndarray | int = 0


def _prepare(r, dt, r_dot, r_ddot, *per_run):
    r = np.asarray(r, dtype=float)
    single = r.ndim == 1
    r2 = np.atleast_2d(r)
    if r2.ndim != 2 or r2.shape[1] < 2:
        raise ValueError(f"r must have shape (n_samples,) or (n_runs, n_samples), got {r.shape}")
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    R = r2.shape[0]

    def deriv(x, base):
        if x is None:
            return np.gradient(base, dt, axis=1, edge_order=2)
        return np.atleast_2d(np.broadcast_to(np.asarray(x, dtype=float), r.shape))

    rd = deriv(r_dot, r2)
    rdd = deriv(r_ddot, rd)
    vecs = [np.broadcast_to(np.asarray(p, dtype=float), (R,)).copy() for p in per_run]
    return single, r2, rd, rdd, vecs


def _finish(single, **arrays):
    if single:
        arrays = {k: (v[0] if isinstance(v, np.ndarray) else v) for k, v in arrays.items()}
    return SimResult(**arrays)


def simulate_linear(C_linear, beta_tilde_linear, r, dt, kp, theta0=0.0, phi0=0.0) -> SimResult:
    """Global linear model (26), θ'' + C_linear·θ' = β̃_linear·v, v = kp·(r − θ), exact ZOH.

    Parameters
    ----------
    C_linear : float or array_like (n_runs,) [1/s]
    beta_tilde_linear : float or array_like (n_runs,) [rad/(V·s²)]
    r : array_like (n_samples,) or (n_runs, n_samples) [rad]
        Reference, uniformly sampled.
    dt : float [s]
        Sample period (the hold interval).
    kp : float [V/rad]
    theta0, phi0 : float or array_like (n_runs,) [rad], [rad/s]
        Initial state.

    Returns
    -------
    SimResult
        ``alpha`` and ``n_iter`` are None.
    """
    single, r2, _, _, (C, b, th, ph) = _prepare(r, dt, 0.0, 0.0, C_linear, beta_tilde_linear,
                                                theta0, phi0)
    R, n = r2.shape
    E, g1, g2 = zoh_coefficients(C, dt)
    theta = np.empty((R, n))
    phi = np.empty((R, n))
    v = np.empty((R, n))
    for k in range(n):
        theta[:, k] = th
        phi[:, k] = ph
        vk = kp * (r2[:, k] - th)
        v[:, k] = vk
        u = b * vk
        th = th + g1 * ph + g2 * u
        ph = E * ph + g1 * u
    Cs = np.broadcast_to(C[:, None], (R, n)).copy()
    bs = np.broadcast_to(b[:, None], (R, n)).copy()
    return _finish(single, theta=theta, phi=phi, v=v, C=Cs, beta_tilde=bs)


#: A compiled implementation of :func:`batch_loop_numpy` (same arguments, the same numbers to
#: a few ulps per step), registered by an application with :func:`set_kernel`; None: the numpy
#: loop.  This package never imports a compiler itself (numpy/scipy only).
_KERNEL = None


def current_kernel():
    """The compiled time loop registered with :func:`set_kernel`, or ``None`` (the numpy loop,
    :func:`batch_loop_numpy`, runs)."""
    return _KERNEL


def set_kernel(kernel):
    """Register ``kernel``, a compiled implementation of the time loop of
    :func:`simulate_alpha_batch` (and so of :func:`simulate_alpha`) with the arguments of
    :func:`batch_loop_numpy`, giving the same numbers to a few ulps per step (e.g.
    ``omni_studies.alpha_kernel``); ``None`` restores the numpy loop.  Returns the previous one."""
    global _KERNEL
    previous, _KERNEL = _KERNEL, kernel
    return previous


def simulate_alpha(model: AlphaModel, I, r, dt, kp, *, C_linear, beta_tilde_linear, theta0=0.0,
                   phi0=0.0, r_dot=None, r_ddot=None, max_iter=DEFAULT_MAX_ITER) -> SimResult:
    """α-invariant model (37) by the quasilinear iteration (43)–(46) with exact ZOH steps.

    The runs (rows of ``r``) are one batch (:func:`simulate_alpha_batch`'s ``groups``).

    Parameters
    ----------
    model : AlphaModel
        C(α, I) and β̃(α, I).
    I : float or array_like (n_runs,) [paper units]
        Inertia of each run (from the inertia model (6)).
    r : array_like (n_samples,) or (n_runs, n_samples) [rad]
        Reference, uniformly sampled.
    dt : float [s]
        Sample period.
    kp : float [V/rad]
    C_linear, beta_tilde_linear : float or array_like (n_runs,)
        Global linear model of each run ((24)–(26)), used only by the first iterate (45').
    theta0, phi0 : float or array_like (n_runs,) [rad], [rad/s]
        Initial state.
    r_dot, r_ddot : array_like, optional [rad/s], [rad/s²]
        Reference derivatives, same shape as ``r``; numerical if omitted (module docstring).
    max_iter : int
        Bound on the iteration index i of (44).

    Returns
    -------
    SimResult
    """
    if max_iter < 2:
        raise ValueError(f"max_iter must be at least 2 (the rule (46) compares two iterates), got {max_iter}")
    single, r2, rd, rdd, (I, Cl, bl, th, ph) = _prepare(
        r, dt, r_dot, r_ddot, I, C_linear, beta_tilde_linear, theta0, phi0)
    res = simulate_alpha_batch(model, I, list(r2), dt, kp, C_linear=Cl, beta_tilde_linear=bl,
                               theta0=th, phi0=ph, r_dot=list(rd), r_ddot=list(rdd),
                               max_iter=max_iter)
    arrays = {k: np.stack([getattr(x, k) for x in res]) for k in
              ("theta", "phi", "v", "C", "beta_tilde", "alpha", "n_iter")}
    nc = np.array([x.n_not_converged for x in res], dtype=np.int64)
    nb = np.array([x.n_bracketed for x in res], dtype=np.int64)
    return _finish(single, **arrays, n_not_converged=(int(nc[0]) if single else nc),
                   n_bracketed=(int(nb[0]) if single else nb))


def simulate_alpha_batch(model: AlphaModel, I, r, dt, kp, *, C_linear, beta_tilde_linear,
                         theta0=0.0, phi0=0.0, r_dot=None, r_ddot=None, groups=None,
                         max_iter=DEFAULT_MAX_ITER, keep=None) -> list[SimResult]:
    """:func:`simulate_alpha` of runs of different lengths (and gains) in one time loop.

    Parameters
    ----------
    r : list of array_like (n_samples_j,) [rad]
        Reference of each run (lengths may differ); ``r_dot``, ``r_ddot`` likewise (or None).
    kp, I, C_linear, beta_tilde_linear, theta0, phi0 : float or array_like (n_runs,)
        Per run.
    groups : array_like of int (n_runs,), optional
        The runs that :func:`simulate_alpha` would simulate as one batch (default: all one
        batch).  The bisection fallback of a step stops when all the runs of a batch meet its
        tolerance, so the batch decides the last bits of a bisected α; with the groups given,
        each run's numbers are those of its own batch's :func:`simulate_alpha` call.
    keep : iterable of str, optional
        The arrays of :class:`SimResult` to return (e.g. ``("theta",)``); the others are
        None and not stored (less memory).  Default: all.

    Returns
    -------
    list of SimResult
        One single-run result per run, in the order of ``r`` (its arrays are views into
        arrays shared by the call's runs).
    """
    if max_iter < 2:
        raise ValueError(f"max_iter must be at least 2 (the rule (46) compares two iterates), got {max_iter}")
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    rs = [np.asarray(x, dtype=float) for x in r]
    R = len(rs)
    if R == 0:
        return []
    lens = np.array([x.size for x in rs])
    if any(x.ndim != 1 for x in rs) or lens.min() < 2:
        raise ValueError("each reference must be 1-D with at least 2 samples")

    def per_run(x):
        return np.broadcast_to(np.asarray(x, dtype=float), (R,)).copy()

    rds = _derivatives(r_dot, rs, dt)
    rdds = _derivatives(r_ddot, rds, dt)
    grp = np.zeros(R, dtype=np.int64) if groups is None else np.asarray(groups).astype(np.int64)
    # longest runs first: the runs still going at step k are a prefix
    order = np.argsort(-lens, kind="stable")
    n = int(lens.max())
    lens_s = lens[order]
    Rt, RDt, RDDt = (_padded([x[o] for o in order], n) for x in (rs, rds, rdds))
    I_, Cl_, bl_, th, ph, kp_ = (per_run(x)[order] for x in
                                 (I, C_linear, beta_tilde_linear, theta0, phi0, kp))
    grp = grp[order]
    invI_ = 1.0 / I_
    breaks, c_inv, b0, b1, a0, a1, b_slope, b_floor, clamp = _model_constants(model)
    names = _OUTPUTS
    keep = set(names) if keep is None else set(keep)
    if keep - set(names):
        raise ValueError(f"keep: unknown arrays {sorted(keep - set(names))}; known: {names}")
    out_th, out_ph, out_v, out_a, out_C, out_b, out_it = (
        _output(k in keep, R, n, np.int32 if k == "n_iter" else float) for k in names)
    not_conv = np.zeros(R, dtype=np.int64)
    bracketed = np.zeros(R, dtype=np.int64)
    alive = np.searchsorted(-lens_s, -np.arange(n), side="left")  # runs with length > k
    loop = batch_loop_numpy if _KERNEL is None else _KERNEL
    loop(Rt, RDt, RDDt, alive, kp_, invI_, Cl_, bl_, th.copy(), ph.copy(), grp, breaks, c_inv,
         float(b0), float(b1), float(a0), float(a1), float(b_slope), float(b_floor), clamp,
         float(dt), int(max_iter), out_th, out_ph, out_v, out_a, out_C, out_b, out_it, not_conv,
         bracketed)
    results = [None] * R
    for j, o in enumerate(order):
        L = lens_s[j]
        arrays = {k: (x[:L, j] if k in keep else None) for k, x in
                  zip(names, (out_th, out_ph, out_v, out_a, out_C, out_b, out_it))}
        results[o] = SimResult(**arrays, n_not_converged=int(not_conv[j]),
                               n_bracketed=int(bracketed[j]))
    return results


#: The arrays of a :class:`SimResult` the time loop writes, in the loop's order.
_OUTPUTS = ("theta", "phi", "v", "alpha", "C", "beta_tilde", "n_iter")


def _derivatives(x, base: list, dt: float) -> list:
    """The derivatives ``x`` of the runs ``base`` as arrays of each run's shape, or, with
    ``x`` None, numerical ones (second-order central differences)."""
    if x is None:
        return [np.gradient(b, dt, edge_order=2) for b in base]
    return [np.broadcast_to(np.asarray(d, dtype=float), b.shape) for d, b in zip(x, base)]


def _output(kept: bool, R: int, n: int, dtype) -> np.ndarray:
    """One output array of the time loop, (n, R) indexed [step, run], stored run-major so that
    each run's result is a contiguous view (no copies); not ``kept``: every element is one
    scratch value (zero strides; written, never read)."""
    if kept:
        return np.zeros((R, n), dtype=dtype).T
    return np.lib.stride_tricks.as_strided(np.zeros(1, dtype=dtype), (n, R), (0, 0))


def _padded(rows, n: int) -> np.ndarray:
    """The 1-D ``rows`` as the columns of an (n, len(rows)) array, zero past each row's end."""
    out = np.zeros((n, len(rows)))
    for j, x in enumerate(rows):
        out[:x.size, j] = x
    return out


def _model_constants(model: AlphaModel) -> tuple:
    """What the time loop needs of the α model: C's breakpoints and 1/C_k1, β̃'s line (its ends
    b0, b1 at ᾱ0, ᾱ1 and slope), its floor and whether it is clamped."""
    b0, b1 = model.beta_inv
    a0, a1 = model.alpha_bar
    return (np.asarray(model.alpha_breaks, dtype=float), np.asarray(model.C_inv, dtype=float),
            b0, b1, a0, a1, (b1 - b0) / (a1 - a0), model.options["beta_floor_fraction"] * min(b0, b1),
            bool(model.options.get("beta_clamp", False)))


def batch_loop_numpy(Rt, RDt, RDDt, alive, kp_, invI_, Cl_, bl_, th, ph, grp, breaks, c_inv,
                      b0, b1, a0, a1, b_slope, b_floor, clamp, dt, max_iter, out_th, out_ph,
                      out_v, out_a, out_C, out_b, out_it, not_conv, bracketed):
    """The time loop of :func:`simulate_alpha_batch` (numpy, vectorised over runs): the
    reference of a compiled implementation registered with :func:`set_kernel`, which takes
    these arguments and does these operations in this order.

    Runs are columns, sorted longest first; ``alive[k]`` runs (a prefix) are still going at
    step k.  Inputs: ``Rt``, ``RDt``, ``RDDt`` (n, R) reference and its derivatives; per run
    ``kp_``, ``invI_`` (1/I), ``Cl_``, ``bl_``, the initial state ``th``, ``ph`` (overwritten),
    the batch id ``grp`` (int64); the model: ``breaks``, ``c_inv`` (C(α)·I by np.interp),
    β̃(α)·I = max(b0 + b_slope·(clip(α, a0, a1) − a0), b_floor) (clip only if ``clamp``);
    ``dt``, ``max_iter``.  Outputs, filled in place for the alive runs: ``out_th``, ``out_ph``,
    ``out_v``, ``out_a``, ``out_C``, ``out_b`` (n, R) float64, ``out_it`` (n, R) int32,
    ``not_conv``, ``bracketed`` (R,) int64 (added to).
    """
    a_lo, a_hi = (a0, a1) if clamp else (-np.inf, np.inf)   # β̃ varies over [a_lo, a_hi]

    def coefficients(a, inv_i):
        """C(α), β̃(α) of the model for inertia 1/inv_i."""
        return (np.interp(a, breaks, c_inv) * inv_i,
                np.maximum(b0 + b_slope * (np.clip(a, a_lo, a_hi) - a0), b_floor) * inv_i)

    def g(a, v, vd2, kr, ph, inv_i, kp):
        """One application of (44) with Φ̇ from C(α), β̃(α): the map α -> α^(i+1)."""
        Ca, ba = coefficients(a, inv_i)
        return vd2 - v * (kr - kp * (ba * v - Ca * ph))

    with np.errstate(all="ignore"):
        for k in range(Rt.shape[0]):
            m = int(alive[k])
            kp, inv_i, gk = kp_[:m], invI_[:m], grp[:m]
            th_k, ph_k = th[:m].copy(), ph[:m].copy()
            out_th[k, :m] = th_k
            out_ph[k, :m] = ph_k
            v = kp * (Rt[k, :m] - th_k)
            vd = kp * (RDt[k, :m] - ph_k)
            vd2 = vd * vd
            kr = kp * RDDt[k, :m]
            args = (v, vd2, kr, ph_k, inv_i, kp)
            # (45'): first iterate of v̈ from the linear model's acceleration; α^(1) by (44)
            a = vd2 - v * (kr - kp * (bl_[:m] * v - Cl_[:m] * ph_k))
            its = np.ones(m, dtype=np.int32)
            active = np.ones(m, dtype=bool)   # runs still iterating (a converged run is frozen)
            hist = [a]
            for i in range(2, max_iter + 1):
                a_new = g(a, *args)
                done = np.abs(a_new - a) < _tolerance(a_new)
                a = np.where(active, a_new, a)
                hist.append(a)
                its = np.where(active, i, its)
                active &= ~done
                if not active.any():
                    break
            else:
                # (46) not met within max_iter: bisection, batch by batch (module docstring)
                hist = np.stack(hist, axis=1)
                for gid in np.unique(gk[active]):
                    batch = active & (gk == gid)
                    a_b, solved = _bisect_fallback(g, hist, batch, args)
                    a = np.where(batch, a_b, a)
                    bracketed[:m] += solved
                    not_conv[:m] += batch & ~solved
            C, b = coefficients(a, inv_i)
            out_v[k, :m] = v
            out_a[k, :m] = a
            out_C[k, :m] = C
            out_b[k, :m] = b
            out_it[k, :m] = its
            if k + 1 < Rt.shape[0]:
                E, g1, g2 = zoh_coefficients(C, dt)
                u = b * v
                th[:m] = th_k + g1 * ph_k + g2 * u
                ph[:m] = E * ph_k + g1 * u


def _tolerance(alpha):
    """The stopping tolerance of (46) at ``alpha`` [V²/s²]."""
    return np.maximum(1e-6, 1e-3 * np.abs(alpha))


def _bisect_fallback(g, hist, active, args):
    """Root of h(α) = α − g(α, *args) for the ``active`` runs, bracketed by their iterates
    ``hist`` (shape (runs, iterations); module docstring).  Returns the new α of all runs (the
    last iterate where no bracket exists) and the mask of those solved."""
    idx = np.flatnonzero(active)
    sub = tuple(x[idx] if np.ndim(x) else x for x in args)

    def h(x):
        return x - g(x, *sub)

    A = hist[idx]
    last = A[:, -1]
    H = np.empty_like(A)
    H[:, :-1] = A[:, :-1] - A[:, 1:]          # h(α^(j)) = α^(j) − α^(j+1)
    H[:, -1] = h(last)
    dist = np.abs(A - last[:, None])
    neg = np.where(H <= 0, dist, np.inf).argmin(axis=1)
    pos = np.where(H >= 0, dist, np.inf).argmin(axis=1)
    rows = np.arange(len(idx))
    ok = (H[rows, neg] <= 0) & (H[rows, pos] >= 0)
    a_n, a_p = A[rows, neg], A[rows, pos]
    h_n, h_p = H[rows, neg], H[rows, pos]
    # no sign change among the iterates: step on in the direction of travel
    creep = ~ok
    if creep.any():
        step = last - A[:, -2]
        h_last = H[:, -1]
        far = last.copy()
        h_far = h_last.copy()
        found = np.zeros_like(creep)
        for m in range(61):
            look = creep & ~found & (step != 0)
            if not look.any():
                break
            x = last + step * 2.0**m
            hx = h(x)
            hit = look & (hx * h_last <= 0)
            far = np.where(hit, x, far)
            h_far = np.where(hit, hx, h_far)
            found |= hit
        a_n = np.where(found, last, a_n)
        h_n = np.where(found, h_last, h_n)
        a_p = np.where(found, far, a_p)
        h_p = np.where(found, h_far, h_p)
        ok |= found
    lo, hi = np.minimum(a_n, a_p), np.maximum(a_n, a_p)
    h_lo = np.where(a_n <= a_p, h_n, h_p)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.all(~ok | (hi - lo < _tolerance(mid))):
            break
        h_mid = h(mid)
        left = h_lo * h_mid <= 0
        hi = np.where(left, mid, hi)
        lo = np.where(left, lo, mid)
        h_lo = np.where(left, h_lo, h_mid)
    a = hist[:, -1].copy()
    a[idx[ok]] = 0.5 * (lo + hi)[ok]
    solved = np.zeros_like(active)
    solved[idx[ok]] = True
    return a, solved


def square_wave_reference(t, frequency_hz, amplitude_rad):
    """Square-wave reference of the step experiments (47): +A_r on the first half period.

    r(t) = A_r·(2H(t) − 1) for the first half period and alternating after, i.e.
    +A_r on [0, T/2), −A_r on [T/2, T), …  With θ(0) = −A_r, θ'(0) = 0 this is (47).
    Its derivatives between edges are zero (pass ``r_dot = r_ddot = 0`` to the simulators).

    Parameters
    ----------
    t : array_like [s]
    frequency_hz : float [Hz]
    amplitude_rad : float [rad]

    Returns
    -------
    r : ndarray [rad]
    """
    t = np.asarray(t, dtype=float)
    half = np.floor(2.0 * frequency_hz * t + 1e-9).astype(np.int64)
    return amplitude_rad * (1.0 - 2.0 * (half % 2))


def bench_simulation(n_runs=25, duration_s=8.0, dt=1e-3, kp=2.0, model=None, repeat=1):
    """Time the batched α-model simulation against ``scipy.signal.lsim`` of the linear model.

    The workload is the paper's step campaign: ``n_runs`` square-wave runs (47) (0.25 Hz,
    0.07 rad, θ(0) = −0.07 rad at rest) of ``duration_s`` at 1/``dt`` Hz, with inertias spread
    over the range of the paper's Table 3 (β̃_linear 149–275, its extremes rounded to integers)
    and C_linear = 1/(C̄0·I), C̄0 = 36.693 (Table 4); both read from :mod:`identification.paper`.
    The α model defaults to :func:`paper_alpha_model`.

    Returns
    -------
    dict
        ``alpha_s`` (batched α simulation), ``linear_zoh_s`` (batched :func:`simulate_linear`),
        ``lsim_s`` (``scipy.signal.lsim`` of the continuous closed loop (21), one call per run),
        all best of ``repeat`` [s]; ``ratio_alpha_to_lsim`` [-]; ``n_not_converged`` (total
        steps); ``mean_iterations`` per step; the workload (``n_runs``, ``n_samples``).
    """
    from scipy.signal import lsim

    model = paper_alpha_model() if model is None else model
    t = np.arange(int(round(duration_s / dt))) * dt
    r1 = square_wave_reference(t, 0.25, 0.07)
    r = np.tile(r1, (n_runs, 1))
    b_table3 = [row["beta_tilde_linear"] for row in paper.table3()]
    I = 1.0 / np.linspace(float(round(min(b_table3))), float(round(max(b_table3))), n_runs)
    C_lin = 1.0 / (paper.table4()["C0_bar"] * I)
    b_lin = 1.0 / I

    def best(fn):
        out, times = None, []
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
        return out, min(times)

    res, t_alpha = best(lambda: simulate_alpha(model, I, r, dt, kp, C_linear=C_lin,
                                               beta_tilde_linear=b_lin, theta0=-0.07,
                                               r_dot=0.0, r_ddot=0.0))
    _, t_lin = best(lambda: simulate_linear(C_lin, b_lin, r, dt, kp, theta0=-0.07))

    def run_lsim():
        for j in range(n_runs):
            beta = kp * b_lin[j]
            A = [[0.0, 1.0], [-beta, -C_lin[j]]]
            lsim((A, [[0.0], [beta]], [[1.0, 0.0]], [[0.0]]), r1, t, X0=[-0.07, 0.0])

    _, t_lsim = best(run_lsim)
    return {
        "n_runs": n_runs,
        "n_samples": t.size,
        "alpha_s": t_alpha,
        "linear_zoh_s": t_lin,
        "lsim_s": t_lsim,
        "ratio_alpha_to_lsim": t_alpha / t_lsim,
        "n_not_converged": int(np.sum(res.n_not_converged)),
        "mean_iterations": float(res.n_iter.mean()),
    }
