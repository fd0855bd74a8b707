"""Yaw inertia model, paper equations (5)–(8), and its fit (27)–(29).

Angles: γ1, γ2 [deg] are the arm's *actual* angles (the paper's "True Angle"); γoffs [deg].
Inertia is in the paper's units, where the torque constant β̄ is fixed to 1 (section 2.1.2), so
that (7) ``β̃ = 1/I`` [rad/(V·s²)] and (8) ``C = 1/(C̄0 I)`` [1/s]; C̄0 [-] is the damping ratio
``β̄ / C̄``.

The basic model (5) of two uniform thin rods expands exactly into the minimal model (6) with
``I1 = m1 L1²/3 + m2 L1²``, ``I2 = m2 L2²/3`` and ``I3 = m2 L1 L2``
(:func:`minimal_from_analytic`).

Fit method (:func:`fit_inertia_model`)
--------------------------------------
Residuals are *relative*, one per pose for each of (28) and (29):

    r_β = (1/I) / β̃_linear − 1,     r_C = (1/(C̄0 I)) / C_linear − 1

so the C and β̃ data (≈ 5 1/s vs ≈ 200) weigh equally and each pose weighs by its relative
error (measurement error of both scales with the value).  The I terms are bounded ≥ 0 (the
paper's physical-validity condition).  For fixed γoffs, I is linear in (I_base, I1, I2, I3); the
global minimum is found by profiling: on a grid of γoffs over the whole circle (2° steps) a
non-negative least squares of the linearised β̃ residuals ``I β̃ − 1`` starts a bounded
non-linear least squares in (I_base, I1, I2, I3, C̄0); the best few grid minima are then polished
with γoffs free.  γoffs has period 360° (a 180° shift flips the sign of the I3 term, which
the bound I3 ≥ 0 forbids).

How well each parameter is determined: the Jacobian J of the residuals at the optimum gives the
approximate covariance ``s² (JᵀJ)⁻¹`` with ``s² = Σr² / (2n − 6)``, and 95% intervals with
Student's t.  The singular values and condition number are of the *scaled* Jacobian (columns:
I terms per unit of the median data inertia, γoffs per radian, C̄0 per unit relative change).
A parameter is flagged poorly determined when its 95% half-width exceeds 50% of its value (I
terms, C̄0) or 10° (γoffs), or when it sits on its bound (the interval is then not meaningful).

Poses: 6 parameters; β̃ alone carries the 5 parameters of I, so at least
:data:`MIN_POSES` = 6 poses are required (one degree of freedom for the β̃ part, 6 for all).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import UserError

#: Minimum number of poses for the inertia fit (see module docstring).
MIN_POSES = 6
#: Grid step of the γoffs profile [deg].
GRID_STEP_DEG = 2.0
#: Relative 95% half-width above which an I term or C̄0 is "poorly determined" [-].
POOR_REL = 0.5
#: 95% half-width above which γoffs is "poorly determined" [deg].
POOR_GAMMA_DEG = 10.0

PARAM_NAMES = ("I_base", "I1", "I2", "I3", "gamma_offs_deg", "C0_bar")


def _link2_angle(gamma1_deg, gamma2_deg, gamma_offs_deg):
    """π − γ1 − γ2 − γoffs [rad], the angle of Link 2 in (5)–(6)."""
    return math.pi - np.radians(gamma1_deg) - np.radians(gamma2_deg) - np.radians(gamma_offs_deg)


def inertia_analytic(gamma1_deg, gamma2_deg, m1, L1, m2, L2, I_base, gamma_offs_deg=0.0):
    """Basic thin-rod yaw inertia (5).

    Parameters
    ----------
    gamma1_deg, gamma2_deg : float or array [deg]
        Actual shoulder and elbow angles.
    m1, m2 : float [kg]
        Masses of Link 1 and Link 2.
    L1, L2 : float [m]
        Lengths of Link 1 and Link 2.
    I_base : float [kg·m²]
        Inertia of the base about the yaw axis.
    gamma_offs_deg : float [deg]
        Offset angle γoffs.

    Returns
    -------
    I : float or array [kg·m²]
    """
    c1 = np.cos(np.radians(gamma1_deg))
    c2 = np.cos(_link2_angle(gamma1_deg, gamma2_deg, gamma_offs_deg))
    return (I_base + m1 * L1**2 * c1**2 / 3.0 + m2 * (L1 * c1 + 0.5 * L2 * c2) ** 2
            + m2 * L2**2 * c2**2 / 12.0)


def minimal_from_analytic(m1, L1, m2, L2, I_base):
    """Coefficients of (6) equivalent to (5): returns ``(I_base, I1, I2, I3)`` [kg·m²]."""
    return I_base, m1 * L1**2 / 3.0 + m2 * L1**2, m2 * L2**2 / 3.0, m2 * L1 * L2


def _basis(gamma1_deg, gamma2_deg, gamma_offs_deg):
    c1 = np.cos(np.radians(np.asarray(gamma1_deg, dtype=float)))
    c2 = np.cos(_link2_angle(np.asarray(gamma1_deg, dtype=float), gamma2_deg, gamma_offs_deg))
    return np.column_stack([np.ones_like(c1), c1**2, c2**2, c1 * c2])


def inertia_minimal(gamma1_deg, gamma2_deg, I_base, I1, I2, I3, gamma_offs_deg):
    """Minimal yaw inertia model (6) / (27).

    ``I = I_base + I1 cos²γ1 + I2 cos²(π−γ1−γ2−γoffs) + I3 cos γ1 cos(π−γ1−γ2−γoffs)``

    Parameters
    ----------
    gamma1_deg, gamma2_deg : float or array [deg]
    I_base, I1, I2, I3 : float [inertia units]
    gamma_offs_deg : float [deg]

    Returns
    -------
    I : float or array [same units as the I terms]
    """
    scalar = np.ndim(gamma1_deg) == 0 and np.ndim(gamma2_deg) == 0
    g1, g2 = np.broadcast_arrays(np.atleast_1d(gamma1_deg), np.atleast_1d(gamma2_deg))
    val = _basis(g1.astype(float), g2.astype(float), gamma_offs_deg) @ np.array(
        [I_base, I1, I2, I3], dtype=float)
    return float(val[0]) if scalar else val


@dataclass(frozen=True)
class InertiaParameters:
    """Parameters of (6)–(8): ``I_base, I1, I2, I3`` [β̄ = 1 units], γoffs [deg], C̄0 [-]."""

    I_base: float
    I1: float
    I2: float
    I3: float
    gamma_offs_deg: float
    C0_bar: float

    def inertia(self, gamma1_deg, gamma2_deg):
        """Inertia (6) at the given actual angles [β̄ = 1 units]."""
        return inertia_minimal(gamma1_deg, gamma2_deg, self.I_base, self.I1, self.I2, self.I3,
                               self.gamma_offs_deg)

    def beta_tilde(self, gamma1_deg, gamma2_deg):
        """β̃_linear = 1/I (7), (28) [rad/(V·s²)]."""
        return 1.0 / self.inertia(gamma1_deg, gamma2_deg)

    def C(self, gamma1_deg, gamma2_deg):
        """C_linear = 1/(C̄0 I) (8), (29) [1/s]."""
        return 1.0 / (self.C0_bar * self.inertia(gamma1_deg, gamma2_deg))

    def to_dict(self) -> dict:
        return {k: float(getattr(self, k)) for k in PARAM_NAMES}

    @classmethod
    def from_dict(cls, d: dict) -> "InertiaParameters":
        return cls(*(float(d[k]) for k in PARAM_NAMES))


@dataclass
class InertiaFit:
    """Result of :func:`fit_inertia_model`.

    Attributes
    ----------
    params : InertiaParameters
    ci95 : dict of (low, high)
        Approximate 95% confidence intervals (linearised, Student's t) per parameter.
    poorly_determined : list of str
        Parameter names flagged by the rule in the module docstring.
    at_bound : list of str
        I terms that sit on the bound 0.
    singular_values : list of float
        Of the scaled Jacobian (see module docstring).
    condition_number : float
    weakest_direction : dict
        Right singular vector of the smallest singular value (scaled parameters).
    rel_residual_beta, rel_residual_C : array [-]
        Per pose ``model/data − 1``.
    rms_rel_beta, rms_rel_C : float [-]
    cost : float
        ``½ Σ r²`` of the relative residuals.
    C0_bar_regression : float [-]
        C̄0 "by simple regression" (:func:`c0_bar_regression`).
    n_poses, dof : int
    profile_gamma_deg, profile_cost : array
        The γoffs profile (cost minimised over the other parameters on the grid).
    """

    params: InertiaParameters
    ci95: dict
    poorly_determined: list
    at_bound: list
    singular_values: list
    condition_number: float
    weakest_direction: dict
    rel_residual_beta: np.ndarray
    rel_residual_C: np.ndarray
    rms_rel_beta: float
    rms_rel_C: float
    cost: float
    C0_bar_regression: float
    n_poses: int
    dof: int
    profile_gamma_deg: np.ndarray = field(repr=False)
    profile_cost: np.ndarray = field(repr=False)

    def diagnostics(self) -> dict:
        """JSON-friendly fit diagnostics (everything except the parameters themselves)."""
        return {
            "ci95": {k: [float(lo), float(hi)] for k, (lo, hi) in self.ci95.items()},
            "poorly_determined": list(self.poorly_determined),
            "at_bound": list(self.at_bound),
            "singular_values": [float(s) for s in self.singular_values],
            "condition_number": float(self.condition_number),
            "weakest_direction": {k: float(v) for k, v in self.weakest_direction.items()},
            "rms_rel_residual_beta_tilde": float(self.rms_rel_beta),
            "rms_rel_residual_C": float(self.rms_rel_C),
            "cost": float(self.cost),
            "C0_bar_regression": float(self.C0_bar_regression),
            "n_poses": int(self.n_poses),
            "dof": int(self.dof),
            "weighting": "relative residuals model/data-1 of C_linear and beta_tilde_linear, equal weight",
        }


def c0_bar_regression(C_linear, beta_tilde_linear) -> float:
    """C̄0 "by simple linear regression" (Table 3): slope of β̃ = C̄0·C through the origin.

    ``C̄0 = Σ β̃ C / Σ C²``.  On Table 3 this gives 36.726 against the paper's 36.727 (the
    other candidate regressions are further off; see ``identification/data/REPRODUCTION.md``).

    Parameters
    ----------
    C_linear : array [1/s]
    beta_tilde_linear : array [rad/(V·s²)]
    """
    c = np.asarray(C_linear, dtype=float)
    b = np.asarray(beta_tilde_linear, dtype=float)
    return float(b @ c / (c @ c))


def _check_inputs(g1, g2, c, b):
    arrays = [np.asarray(x, dtype=float).ravel() for x in (g1, g2, c, b)]
    n = arrays[0].size
    if any(a.size != n for a in arrays):
        raise UserError("inertia fit: gamma1_deg, gamma2_deg, C_linear, beta_tilde_linear differ in length")
    names = ("gamma1_deg", "gamma2_deg", "C_linear", "beta_tilde_linear")
    for name, a in zip(names, arrays):
        if not np.all(np.isfinite(a)):
            raise UserError(f"inertia fit: {name} has a non-finite value (row {int(np.argmin(np.isfinite(a)))})")
    for name, a in zip(names[2:], arrays[2:]):
        if np.any(a <= 0):
            raise UserError(f"inertia fit: {name} must be > 0 (row {int(np.argmax(a <= 0))} is {a[a <= 0][0]:g})")
    if n < MIN_POSES:
        raise UserError(f"inertia fit: {n} pose(s); the inertia model (6) with C0_bar has 6 parameters "
                        f"and needs >= {MIN_POSES} poses")
    return arrays


def _start_fixed_gamma(a, b, c, c0_reg):
    """Start of the fixed-γoffs problem: a non-negative least squares of the linearised β̃
    residuals ``I β̃ − 1`` for the I terms, then the C̄0 factor that closes the C residuals in
    the least-squares sense; ``a``: the basis times the inertia scale at that γoffs."""
    from scipy import optimize

    n = b.size
    x4, _ = optimize.nnls(a * b[:, None], np.ones(n))
    if not np.any(x4 > 0):
        x4 = np.full(4, 0.25)
    inert = a @ x4
    u = 1.0 / (inert * c * c0_reg)
    k = float(u @ u / u.sum()) if u.sum() > 0 else 1.0  # C̄0/c0_reg closing r_C in LS sense
    x0 = np.r_[x4, k]
    return np.maximum(x0, [0, 0, 0, 0, 1e-6]) + [1e-9, 1e-9, 1e-9, 1e-9, 0]


def _solve_fixed_gamma(g1, g2, b, c, s, c0_reg, gam):
    """The fit at fixed γoffs = ``gam`` [deg] by scipy's bounded trust-region least squares
    (the reference of :func:`_profile_costs`): returns (cost, x = [I terms/s, γoffs, C̄0/c0_reg])."""
    from scipy import optimize

    basis = _basis(g1, g2, gam)
    x0 = _start_fixed_gamma(s * basis, b, c, c0_reg)

    def f5(y):
        inert = s * (basis @ np.ascontiguousarray(y[:4]))
        return np.concatenate([1.0 / (inert * b) - 1.0, 1.0 / (y[4] * c0_reg * inert * c) - 1.0])

    r = optimize.least_squares(f5, x0, bounds=([0, 0, 0, 0, 1e-6], np.full(5, np.inf)),
                               method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return r.cost, np.r_[r.x[:4], gam, r.x[4]]


#: Relative closeness to both neighbours below which a profile point may be a local minimum and
#: is solved again by the reference (the two solvers agree to ~2e-13 on the paper's data).
PROFILE_TIE = 1e-9
#: Iteration limit of :func:`_profile_costs` (it converges in ~20-60 at the paper's data).
PROFILE_MAX_ITER = 500


def _profile_costs(g1, g2, b, c, s, c0_reg, grid):
    """The γoffs profile: at every grid value the minimum of the fit's cost over (I_base, I1,
    I2, I3) ≥ 0 and C̄0 > 0, all grid points at once.

    A projected Levenberg–Marquardt with the exact Jacobian, vectorised over the grid (each
    point its own damping; a variable at its bound with the gradient pushing outwards is held
    there); the same problem and starting points as :func:`_solve_fixed_gamma` (scipy's
    bounded trust-region solver, kept for the minima that are polished and as the reference of
    the tests), many times faster.  Iterates until every point's
    step and cost change are at the level of rounding."""
    m = grid.size
    n = b.size
    A = np.stack([s * _basis(g1, g2, gam) for gam in grid])            # (m, n, 4)
    y = np.stack([_start_fixed_gamma(A[j], b, c, c0_reg) for j in range(m)])  # (m, 5)
    lo = np.array([0.0, 0.0, 0.0, 0.0, 1e-6])

    def residuals(y, A):
        inert = np.einsum("mnk,mk->mn", A, y[:, :4])
        with np.errstate(divide="ignore", invalid="ignore"):
            r1 = 1.0 / (inert * b) - 1.0
            r2 = 1.0 / (y[:, 4:5] * c0_reg * inert * c) - 1.0
        return inert, np.concatenate([r1, r2], axis=1)

    def cost_of(r):
        cst = 0.5 * np.einsum("mi,mi->m", r, r)
        return np.where(np.isfinite(cst), cst, np.inf)

    inert, r = residuals(y, A)
    cost = cost_of(r)
    mu = np.full(m, 1e-3)
    active = np.ones(m, dtype=bool)
    eye = np.eye(5)
    for _ in range(PROFILE_MAX_ITER):
        if not active.any():
            break
        idx = np.flatnonzero(active)
        yy, ii, rr = y[idx], inert[idx], r[idx]
        Aa = A[idx]
        J = np.zeros((idx.size, 2 * n, 5))
        J[:, :n, :4] = -(1.0 / (ii**2 * b))[:, :, None] * Aa
        J[:, n:, :4] = -(1.0 / (yy[:, 4:5] * c0_reg * c * ii**2))[:, :, None] * Aa
        J[:, n:, 4] = -1.0 / (yy[:, 4:5] ** 2 * c0_reg * ii * c)
        grad = np.einsum("mik,mi->mk", J, rr)
        held = (yy <= lo) & (grad > 0)
        H = np.einsum("mik,mil->mkl", J, J)
        d = np.diagonal(H, axis1=1, axis2=2)
        H = H + mu[idx, None, None] * (d[:, :, None] * eye)
        # held variables: an identity row/column and no step
        free = ~held
        H = H * (free[:, :, None] & free[:, None, :]) + held[:, :, None] * eye
        with np.errstate(all="ignore"):
            step = np.linalg.solve(H, -(grad * free)[:, :, None])[:, :, 0]
        y_new = np.maximum(yy + step, lo)
        inert_new, r_new = residuals(y_new, Aa)
        ii_ok = np.all(inert_new > 0, axis=1)
        c_new = np.where(ii_ok, cost_of(r_new), np.inf)
        better = c_new < cost[idx]
        take = idx[better]
        dc = cost[take] - c_new[better]
        dy = np.abs(y_new[better] - yy[better]).max(axis=1)
        y[take], inert[take], r[take], cost[take] = y_new[better], inert_new[better], r_new[better], c_new[better]
        mu[take] = np.maximum(mu[take] / 3.0, 1e-12)
        mu[idx[~better]] *= 4.0
        # converged: an accepted step that changes the cost and the parameters only at the
        # level of rounding, or a damping so large that no step is possible any more
        done = np.zeros(m, dtype=bool)
        done[take] = (dc <= 1e-15 * np.maximum(cost[take], 1e-300)) & (dy <= 1e-13 * np.maximum(np.abs(y[take]).max(axis=1), 1.0))
        done[idx[~better]] = mu[idx[~better]] > 1e12
        active &= ~done
    return cost


def fit_inertia_model(gamma1_deg, gamma2_deg, C_linear, beta_tilde_linear, *,
                      grid_step_deg: float = GRID_STEP_DEG, n_polish: int = 4) -> InertiaFit:
    """Fit (6)–(8) to per-pose global linear coefficients by the method of (27)–(29).

    Parameters
    ----------
    gamma1_deg, gamma2_deg : array [deg]
        Actual angles of each pose.
    C_linear : array [1/s]
    beta_tilde_linear : array [rad/(V·s²)]
    grid_step_deg : float [deg]
        Step of the γoffs profile grid.
    n_polish : int
        Number of best profile minima polished with γoffs free.

    Returns
    -------
    InertiaFit

    Raises
    ------
    UserError
        Fewer than :data:`MIN_POSES` poses, non-finite or non-positive coefficients.
    """
    from scipy import optimize, special  # here: the results' classes load without scipy

    g1, g2, c, b = _check_inputs(gamma1_deg, gamma2_deg, C_linear, beta_tilde_linear)
    n = g1.size
    s = float(np.median(1.0 / b))  # inertia scale [β̄ = 1 units]
    c0_reg = c0_bar_regression(c, b)

    def resid(x):  # x = [Ib, I1, I2, I3]/s, γoffs [deg], C̄0/c0_reg
        inert = s * (_basis(g1, g2, x[4]) @ x[:4])
        return np.concatenate([1.0 / (inert * b) - 1.0, 1.0 / (x[5] * c0_reg * inert * c) - 1.0])

    grid = np.arange(-180.0, 180.0, grid_step_deg)
    costs, starts = _profile_minima(g1, g2, b, c, s, c0_reg, grid, n_polish)
    best = None
    for x0 in starts:  # each profile minimum polished with γoffs free
        r = optimize.least_squares(resid, x0, bounds=(np.array([0, 0, 0, 0, -np.inf, 1e-6]), np.full(6, np.inf)),
                                   method="trf", x_scale=np.r_[np.maximum(x0[:4], 0.1), 1.0, 1.0],
                                   xtol=1e-12, ftol=1e-12, gtol=1e-12)
        if best is None or r.cost < best.cost:
            best = r
    x = best.x.copy()
    x[4] = (x[4] + 180.0) % 360.0 - 180.0
    params = InertiaParameters(*(x[:4] * s), float(x[4]), float(x[5] * c0_reg))
    r = resid(x)
    jac = optimize.approx_fprime(x, resid, epsilon=1e-7 * np.maximum(np.abs(x), 1.0))
    rb, rc = r[:n], r[n:]
    return InertiaFit(
        params=params, **_uncertainty(params, x, r, jac, s, c0_reg, special),
        rel_residual_beta=rb, rel_residual_C=rc,
        rms_rel_beta=float(np.sqrt(np.mean(rb**2))), rms_rel_C=float(np.sqrt(np.mean(rc**2))),
        cost=float(0.5 * r @ r), C0_bar_regression=c0_reg, n_poses=n,
        profile_gamma_deg=grid, profile_cost=costs)


def _profile_minima(g1, g2, b, c, s, c0_reg, grid, n_polish: int):
    """The γoffs profile's costs and the starting points of the polish: its ``n_polish`` best
    local minima, as :func:`_solve_fixed_gamma` solves them.

    The profile is computed at all grid points at once (:func:`_profile_costs`, equal to
    :func:`_solve_fixed_gamma` at each point to ~1e-12 relative, many times faster).  Points
    that may be local minima of the (circular) profile (within PROFILE_TIE of both neighbours,
    far above the two solvers' ~1e-13 difference), and their neighbours, are then solved by the
    reference: the minima, their order and the polish's starting points are the reference's
    exactly (on a flat stretch of the profile which points count as minima is decided by the
    last bits of the costs)."""
    costs = _profile_costs(g1, g2, b, c, s, c0_reg, grid)
    left, right = np.roll(costs, 1), np.roll(costs, -1)
    maybe = np.flatnonzero(costs <= np.minimum(left, right) * (1.0 + PROFILE_TIE))
    solved = {}
    for i in np.unique(np.concatenate([maybe, (maybe - 1) % grid.size, (maybe + 1) % grid.size])):
        solved[int(i)] = _solve_fixed_gamma(g1, g2, b, c, s, c0_reg, grid[i])
        costs[i] = solved[int(i)][0]
    left, right = np.roll(costs, 1), np.roll(costs, -1)
    minima = maybe[(costs[maybe] <= left[maybe]) & (costs[maybe] <= right[maybe])]
    order = minima[np.argsort(costs[minima])][:n_polish]
    return costs, [solved[int(i)][1] for i in order]


def _uncertainty(params, x, r, jac, s: float, c0_reg: float, special) -> dict:
    """95 % intervals (Student t on the Jacobian's covariance), the poorly determined and
    at-bound parameters, and the conditioning of the fit at its solution ``x`` (fit units:
    [Ib, I1, I2, I3]/s, γoffs [deg], C̄0/c0_reg)."""
    m, p = jac.shape
    dof = m - p
    s2 = float(r @ r) / dof if dof > 0 else math.nan
    # Covariance in x units, then physical units.
    u_, sv, vt = np.linalg.svd(jac, full_matrices=False)
    with np.errstate(divide="ignore"):
        inv_sv2 = np.where(sv > sv[0] * 1e-12, 1.0 / sv**2, np.inf)
    cov_x = (vt.T * inv_sv2) @ vt if np.all(np.isfinite(inv_sv2)) else np.full((p, p), np.inf)
    cov_x = cov_x * s2
    to_phys = np.array([s, s, s, s, 1.0, c0_reg])
    # Student t quantile: scipy.stats.t.ppf(0.975, dof) is special.stdtrit(dof, 0.975)
    # (without importing scipy.stats, ~1 s)
    tq = float(special.stdtrit(dof, 0.975)) if dof > 0 else math.inf
    half = tq * np.sqrt(np.abs(np.diag(cov_x))) * to_phys
    values = np.array([getattr(params, k) for k in PARAM_NAMES])
    ci = {k: (float(v - h), float(v + h)) for k, v, h in zip(PARAM_NAMES, values, half)}
    at_bound = [k for k, v in zip(PARAM_NAMES[:4], x[:4]) if v <= 1e-8]
    poor = []
    for k, v, h in zip(PARAM_NAMES, values, half):
        if k in at_bound:
            poor.append(k)
        elif k == "gamma_offs_deg":
            if not h <= POOR_GAMMA_DEG:
                poor.append(k)
        elif not h <= POOR_REL * abs(v):
            poor.append(k)
    # Scaled Jacobian for conditioning: γoffs per radian, C̄0 per relative change.
    scale = np.array([1, 1, 1, 1, 180.0 / math.pi, x[5]])
    sv_scaled = np.linalg.svd(jac * scale, compute_uv=False)
    _, _, vt_s = np.linalg.svd(jac * scale)
    weakest = dict(zip(PARAM_NAMES, vt_s[-1] * np.sign(vt_s[-1][np.argmax(np.abs(vt_s[-1]))])))
    return dict(ci95=ci, poorly_determined=poor, at_bound=at_bound, singular_values=list(sv_scaled),
                condition_number=float(sv_scaled[0] / sv_scaled[-1]), weakest_direction=weakest,
                dof=dof)
