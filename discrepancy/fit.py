"""Fit effect parameters by closed-loop simulation error, with uncertainties.

The objective is the replay error ``theta_model - theta_measured`` [rad] of every run, each run
weighted by ``1/sqrt(n_samples)`` so that every run counts equally (a long step record does not
drown a short sine).  The *gap* of a set of runs is the root of the mean over runs of each run's
mean-square error [rad].

Fits use :func:`scipy.optimize.least_squares` (trust region, box bounds) with a forward-
difference Jacobian whose columns are simulated together: the perturbed models form one batch of
the :class:`~discrepancy.replay.Replayer`.  A coarse grid over the new effect's
parameters (one batch) picks the starting point, because a local fit cannot find a torque limit
or a friction level the data never "feels" at the nominal values.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .runs import ReplayRun


#: Parameters whose replay error is piecewise (rough) at small scales, by effect name: the
#: trust-region fit stalls on them wherever it starts, so :meth:`Problem.polish` locates the
#: basin of the objective first.  backlash's slack: measured on the bank's backlash+coulomb data
#: (scripts: see ``Problem.polish``): with Coulomb fixed at its truth the training gap jumps by
#: 10-20 % between slacks 5 urad apart (contact events at discrete samples) inside a basin
#: centred at the true 1.0 mrad (gap 3.2e-4 at 0.85 and 1.15 mrad, 1.7-2.1e-4 near 1.0).
ROUGH_PARAMETERS = {"backlash": (0,)}
#: Basin search of a rough parameter (:meth:`Problem.polish`): points per bracket (9: a
#: parabola fitted by least squares to 9 jagged values; on the scan above a symmetric bracket of
#: 7-61 points put the vertex at 0.98-0.99 mrad), the bracket's first half-width as a share of
#: ``max(|x|, scale)`` (20 %: the stalled fits ended 12-38 % off), its smallest (5 %: several
#: of the 1-2 % spaced jagged minima inside, so the parabola averages them) and the most
#: brackets (10: from a start 50 % off, two doublings reach the basin, then 2 halvings to the
#: smallest bracket and a few moves of the centre).
BASIN_POINTS = 9
BASIN_START = 0.2
BASIN_SMALLEST = 0.05
BASIN_ROUNDS = 10
#: Cycles of :meth:`Problem.polish` (basin of the rough parameters, then the smooth ones
#: refitted): 2, the smooth ones move little (Coulomb 0.01504 -> 0.01500 N*m on the bank data).
POLISH_CYCLES = 2


def rough(effects: list) -> list[int]:
    """Indices (into the concatenated parameter vector) of the rough parameters of ``effects``
    (:data:`ROUGH_PARAMETERS`)."""
    out, i = [], 0
    for e in effects:
        out += [i + k for k in ROUGH_PARAMETERS.get(e.name, ())]
        i += e.nparam
    return out


#: Weighted residual [rad] a fit sees for every sample of a replay MuJoCo found unstable
#: (returned as NaN by the replay): a barrier that steers the fit back, never a score (the gap
#: of such a replay is inf, :func:`gap`).  1 rad: more than any stable replay's error of a
#: P-controlled joint (the real geared servo's nominal gap is 0.07-0.12 rad).
UNSTABLE_PENALTY_RAD = 1.0


def gap(residuals: list[np.ndarray]) -> float:
    """Root of the mean over runs of each run's mean-square error [rad]; inf if any replay was
    unstable (a NaN residual: excluded, never scored)."""
    if not residuals:
        return float("nan")
    ms = [np.mean(r**2) for r in residuals]
    if not np.all(np.isfinite(ms)):
        return float("inf")
    return float(np.sqrt(np.mean(ms)))


def unstable_count(residuals: list[np.ndarray]) -> int:
    """Replays among ``residuals`` that MuJoCo found unstable (NaN)."""
    return sum(1 for r in residuals if len(r) and not np.isfinite(r[0]))


def correlation_time(residuals: list[np.ndarray], max_lag: int = 2000) -> float:
    """Integrated autocorrelation time [samples] of the residuals (>= 1).

    Samples 1 ms apart are far from independent; the Jacobian covariance is inflated by this
    factor (an effective sample size ``N / tau``).
    """
    taus = []
    for r in residuals:
        r = r - r.mean()
        n = len(r)
        if n < 10 or not np.any(r):
            continue
        f = np.fft.rfft(r, 2 * n)
        ac = np.fft.irfft(f * np.conj(f))[: min(n, max_lag)]
        ac /= ac[0]
        neg = np.nonzero(ac <= 0)[0]
        cut = neg[0] if len(neg) else len(ac)
        taus.append(max(1.0, 2 * np.sum(ac[:cut]) - 1))
    return float(np.median(taus)) if taus else 1.0


@dataclass
class FitResult:
    """Outcome of fitting a set of effects.

    Attributes
    ----------
    effects : list of Effect
        The effects whose parameters were free, in order.
    x : ndarray
        Fitted parameters, concatenated in effect order.
    x_start : ndarray
        Starting point of the local fit (best grid point).
    gap_train : float [rad]
        Gap on the runs used in the fit.
    jac : ndarray or None
        Jacobian of the weighted residual vector at ``x`` [rad per unit of parameter].
    resid : ndarray or None
        Weighted residual vector at ``x``.
    nfev : int
        Simulation batches used.
    jac_at_x : bool
        Whether ``jac`` was computed at ``x`` (False: a chord fit's, at its start).
    """

    effects: list
    x: np.ndarray
    x_start: np.ndarray
    gap_train: float
    jac: np.ndarray | None = None
    resid: np.ndarray | None = None
    nfev: int = 0
    raw_residuals: list = field(default_factory=list, repr=False)
    jac_at_x: bool = True

    def split(self) -> list[tuple]:
        """``[(effect, its parameter values), ...]``."""
        out, i = [], 0
        for e in self.effects:
            out.append((e, self.x[i:i + e.nparam]))
            i += e.nparam
        return out


def split_values(effects: list, x) -> list[tuple]:
    """``[(effect, its values in x), ...]`` of effects whose values are concatenated in ``x``
    (each a float array of its own)."""
    out, i = [], 0
    for e in effects:
        out.append((e, np.asarray(x[i:i + e.nparam], float)))
        i += e.nparam
    return out


class Problem:
    """Simulation-error least squares of some effects' parameters on some runs.

    Parameters
    ----------
    builder : discrepancy.effects.ModelBuilder
        Compiles the model the effects are added to (``builder.compile(changes)``).
    fixed : list of (Effect, values)
        Changes already accepted and held fixed.
    free : list of Effect
        Effects whose parameters are fitted.
    runs : list of ReplayRun
    replayer : discrepancy.replay.Replayer
        Simulates models on runs (``replayer.simulate(models, runs, pairs)``).
    """

    def __init__(self, builder, fixed: list, free: list, runs: list[ReplayRun], replayer,
                 masks: list | None = None):
        self.builder, self.fixed, self.free, self.runs, self.rep = builder, list(fixed), list(free), runs, replayer
        #: per run, the samples the objective uses (bool array; None: all) -- a fold of time
        #: blocks fits on the other blocks of every run
        self.masks = list(masks) if masks is not None else [None] * len(runs)
        lo, hi, sc = [], [], []
        for e in self.free:
            l, h = e.bounds()
            lo += list(l)
            hi += list(h)
            sc += list(e.scales())
        self.lower, self.upper, self.scale = np.array(lo), np.array(hi), np.array(sc)
        self.weights = [1.0 / np.sqrt(max(1, r.n if m is None else int(np.count_nonzero(m))))
                        for r, m in zip(runs, self.masks)]
        self.nsim = 0
        self.unstable = 0  # replays of this problem MuJoCo found unstable (excluded)
        self.unconverged = 0  # per-fold refits stopped by their step limit (discrepancy.folds)
        self._cache: dict = {}
        self._fcache: dict = {}  # the last point replayed alone (:meth:`residual`)

    # --- models and residuals --------------------------------------------------------------
    def changes(self, x: np.ndarray) -> list:
        out, i = list(self.fixed), 0
        for e in self.free:
            out.append((e, x[i:i + e.nparam]))
            i += e.nparam
        return out

    def model(self, x: np.ndarray):
        """The compiled model with the free effects at ``x`` (and the fixed ones)."""
        return self.builder.compile(self.changes(np.asarray(x, float)))

    def simulate(self, xs: list[np.ndarray], run_idx: list[int] | None = None) -> list[list[np.ndarray]]:
        """Raw residuals ``theta_model - theta`` per parameter vector, per run."""
        run_idx = list(range(len(self.runs))) if run_idx is None else run_idx
        models = [self.model(x) for x in xs]
        runs = [self.runs[j] for j in run_idx]
        th = self.rep.simulate(models, runs)
        self.nsim += len(xs)
        out = []
        for i in range(len(xs)):
            out.append([th[i * len(runs) + k] - runs[k].theta for k in range(len(runs))])
            self.unstable += unstable_count(out[-1])
        return out

    def weighted(self, raw: list[np.ndarray], run_idx: list[int] | None = None) -> np.ndarray:
        """The objective's residual vector: each run's residual on its used samples
        (:attr:`masks`) times its weight; an unstable replay's samples at
        :data:`UNSTABLE_PENALTY_RAD`."""
        run_idx = list(range(len(self.runs))) if run_idx is None else run_idx
        parts = []
        for k, j in enumerate(run_idx):
            r = raw[k] if self.masks[j] is None else raw[k][self.masks[j]]
            if len(r) and not np.isfinite(r[0]):
                r = np.full(len(r), UNSTABLE_PENALTY_RAD)
            parts.append(r * self.weights[j])
        return np.concatenate(parts)

    def used(self, raw: list[np.ndarray]) -> list[np.ndarray]:
        """Each run's residual on the samples the objective uses (all runs, in order)."""
        return [r if m is None else r[m] for r, m in zip(raw, self.masks)]

    def _key(self, x):
        return tuple(np.round(np.asarray(x, float), 15))

    def steps(self, x: np.ndarray) -> list[float]:
        """The forward-difference steps at ``x``: 0.05 of each parameter's scale, backwards at
        its upper bound."""
        steps = []
        for i in range(len(x)):
            h = 0.05 * self.scale[i]
            steps.append(-h if x[i] + h > self.upper[i] else h)
        return steps

    def perturbed(self, x: np.ndarray) -> tuple[list[np.ndarray], list[float]]:
        """``x`` and its ``p`` forward-difference perturbations (one parameter moved by its
        :meth:`steps` each), and the steps."""
        h = self.steps(x)
        return [x] + [x + hi * e for hi, e in zip(h, np.eye(len(x)))], h

    def jacobian(self, raws: list, steps: list[float]) -> tuple[np.ndarray, np.ndarray]:
        """The weighted residual and the forward-difference Jacobian from the raw residuals of
        :meth:`perturbed`'s points (``raws[0]`` at ``x``, then one per step)."""
        f0 = self.weighted(raws[0])
        J = (np.column_stack([(self.weighted(r) - f0) / h for r, h in zip(raws[1:], steps)])
             if len(steps) else np.zeros((len(f0), 0)))
        return f0, J

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, list]:
        """Weighted residual, forward-difference Jacobian and raw residuals at ``x``.

        ``x`` and its ``p`` perturbations are simulated in ONE batch: a step of the closed-loop
        replay costs about the same for 16 or 48 trajectories, so the Jacobian comes almost free.
        """
        x = np.asarray(x, float)
        k = self._key(x)
        if k not in self._cache:
            xs, steps = self.perturbed(x)
            raws = self.simulate(xs)
            f0, J = self.jacobian(raws, steps)
            self._cache = {k: (f0, J, raws[0])}
        return self._cache[k]

    def seed(self, fit: FitResult) -> None:
        """Take ``fit``'s residual and Jacobian at ``fit.x`` as this problem's evaluation there
        (``fit`` must come from a problem with the same model, effects and runs; a chord fit's
        residual only: its Jacobian is its start's)."""
        if fit.jac is not None and fit.resid is not None and fit.jac_at_x:
            self._cache = {self._key(fit.x): (fit.resid, fit.jac, fit.raw_residuals)}
        elif fit.resid is not None:  # the residual at x only (a chord fit's Jacobian is its start's)
            self._fcache = {self._key(fit.x): (fit.resid, fit.raw_residuals)}

    def jacobian_at(self, fit: FitResult) -> np.ndarray:
        """The Jacobian at ``fit.x`` on this problem's runs: ``fit``'s own when it was computed
        there (not a chord fit's start) on as many samples, else evaluated (``p + 1`` replays)."""
        n = sum(r.n for r in self.runs)
        if fit.jac is not None and fit.jac_at_x and fit.jac.shape == (n, len(fit.x)):
            return fit.jac
        return self.evaluate(fit.x)[1]

    def fun(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x)[0]

    def jac(self, x: np.ndarray, f0: np.ndarray | None = None) -> np.ndarray:
        """Forward-difference Jacobian (computed with the residual, see :meth:`evaluate`)."""
        return self.evaluate(x)[1]

    # --- fitting -----------------------------------------------------------------------------
    def grid_start(self, x0: np.ndarray, grid_effect_index: int) -> np.ndarray:
        """Best point of the grid of one free effect (others at ``x0``); one batch."""
        e = self.free[grid_effect_index]
        i0 = sum(f.nparam for f in self.free[:grid_effect_index])
        pts = []
        for g in e.grid(x0[i0:i0 + e.nparam]):
            xp = x0.copy()
            xp[i0:i0 + e.nparam] = e.clip(np.asarray(g, float))
            pts.append(xp)
        pts.append(np.clip(x0, self.lower, self.upper))
        raws = self.simulate(pts)
        scores = [gap(self.used(raw)) for raw in raws]
        return pts[int(np.argmin(scores))]

    def residual(self, x: np.ndarray) -> tuple[np.ndarray, list]:
        """Weighted residual and raw residuals at ``x`` alone (one replay of every run; the
        evaluation's cache is used when it holds ``x``)."""
        key = self._key(x)
        if key in self._cache:
            f, _, raw = self._cache[key]
            return f, raw
        if key not in self._fcache:
            raw = self.simulate([np.asarray(x, float)])[0]
            self._fcache = {key: (self.weighted(raw), raw)}
        return self._fcache[key]

    def fit(self, x0: np.ndarray, grid_effect_index: int | None = None, max_nfev: int = 20,
            chord: bool = False) -> FitResult:
        """Fit from ``x0`` (after a grid over one effect if asked).

        ``chord``: the Jacobian at the start serves every step (each evaluation then replays the
        point alone, not its ``p`` perturbations too): for a screening fit of a few steps from a
        start near the optimum, whose end point only ranks candidates; the result's ``jac`` is
        the start's."""
        x0 = np.clip(np.asarray(x0, float), self.lower, self.upper)
        if grid_effect_index is not None:
            x0 = self.grid_start(x0, grid_effect_index)
        # keep the start strictly inside the bounds (trf requirement)
        eps = 1e-9 * (self.upper - self.lower)
        x0 = np.clip(x0, self.lower + eps, self.upper - eps)
        if chord:
            J0 = self.evaluate(x0)[1]
            fun, jac = (lambda x: self.residual(x)[0]), (lambda x: J0)
        else:
            fun, jac = self.fun, self.jac
        sol = least_squares(fun, x0, jac=jac, bounds=(self.lower, self.upper),
                            x_scale=self.scale, method="trf", max_nfev=max_nfev,
                            xtol=1e-3, ftol=1e-4, gtol=1e-8)
        self.converged = sol.status > 0  # 0: stopped by max_nfev
        x = sol.x
        if chord:
            (f, raw), J = self.residual(x), J0
        else:
            f, J, raw = self.evaluate(x)
        return FitResult(list(self.free), x, x0, gap(self.used(raw)), J, f, self.nsim, raw, jac_at_x=not chord)

    def _cost(self, raw: list) -> float:
        return float(np.sum(self.weighted(raw) ** 2))

    def basin(self, x: np.ndarray, i: int, start: float = BASIN_START, smallest: float = BASIN_SMALLEST,
              rounds: int = BASIN_ROUNDS, points: int = BASIN_POINTS) -> float:
        """Centre of the objective's basin along parameter ``i`` (the others fixed at ``x``).

        Each round simulates ``points`` values of the parameter evenly over a bracket
        ``c +- w`` (one batch) and fits a parabola to the objective by least squares.  A convex
        parabola whose vertex lies inside the bracket moves the centre ``c`` to the vertex, and
        the bracket halves once the centre moved by less than a quarter of it (down to
        ``smallest`` times ``max(|c|, scale_i)``; then the search stops); otherwise (vertex
        outside, or not convex: the basin lies beyond the bracket) the centre moves to the
        bracket's best point and the bracket doubles.  The regression averages the jagged local
        minima of a rough objective (:data:`ROUGH_PARAMETERS`), which a local fit stops in; on a
        smooth objective it returns the minimum up to the bracket's cubic term, so it is used
        only for rough parameters."""
        c = float(x[i])
        w = start * max(abs(c), self.scale[i])
        for _ in range(rounds):
            vals = np.unique(np.clip(c + w * np.linspace(-1, 1, points), self.lower[i], self.upper[i]))
            pts = []
            for v in vals:
                xp = np.asarray(x, float).copy()
                xp[i] = v
                pts.append(xp)
            costs = np.array([self._cost(r) for r in self.simulate(pts)])
            vertex = None
            if len(vals) >= 3:
                t = (vals - c) / w
                a2, a1, _ = np.polyfit(t, costs, 2)
                if a2 > 0 and vals[0] <= c - w * a1 / (2 * a2) <= vals[-1]:
                    vertex = float(c - w * a1 / (2 * a2))
            if vertex is None:  # the basin lies beyond the bracket: follow it, wider
                c = float(vals[int(np.argmin(costs))])
                w = min(2 * w, 0.5 * (self.upper[i] - self.lower[i]))
                continue
            moved = abs(vertex - c)
            c = vertex
            w_min = smallest * max(abs(c), self.scale[i])
            if moved < 0.25 * w:
                if w <= w_min:
                    break
                w = max(w / 2, w_min)
        return c

    def fit_subset(self, x: np.ndarray, free_idx: list[int], max_nfev: int = 10) -> np.ndarray:
        """Trust-region fit of the parameters ``free_idx`` only, the others held at ``x``."""
        x = np.asarray(x, float).copy()
        if not free_idx:
            return x
        sel = np.array(free_idx)

        def full(z):
            xf = x.copy()
            xf[sel] = z
            return xf

        lo, hi = self.lower[sel], self.upper[sel]
        eps = 1e-9 * (hi - lo)
        z0 = np.clip(x[sel], lo + eps, hi - eps)
        sol = least_squares(lambda z: self.fun(full(z)), z0, jac=lambda z: self.jac(full(z))[:, sel],
                            bounds=(lo, hi), x_scale=self.scale[sel], method="trf",
                            max_nfev=max_nfev, xtol=1e-3, ftol=1e-4, gtol=1e-8)
        return full(sol.x)

    def polish(self, fit: FitResult, cycles: int = POLISH_CYCLES, refit_nfev: int = 10,
               basin_start: float = BASIN_START) -> FitResult:
        """Move a fit with rough parameters (:data:`ROUGH_PARAMETERS`) into its objective's basin.

        The trust-region fit follows a forward-difference Jacobian; where the replay error is
        piecewise in a parameter (a backlash's contact events: the slack decides at which sample
        each impact happens) that Jacobian is a secant across events, the steps give tiny
        decreases and ``least_squares`` stops on ``ftol`` wherever it started (measured on the
        bank's backlash+coulomb data, Coulomb refitted at each slack: the training gap is
        1.87e-4 rad at the true 1.0 mrad and 2.63e-4 at 0.875 mrad, yet fits started at 0.6,
        0.875 and 1.3 mrad stopped at 0.62, 0.88 and 1.29 mrad; the workflow's start, the best
        grid point 0.84 mrad, ended at 0.875).  So, ``cycles`` times: each rough parameter goes
        to the centre of its basin (:meth:`basin`, the others fixed), then the smooth parameters
        are refitted with the rough ones held (their objective is smooth, the trust-region fit
        works).  The result is the basin's centre, not the lowest of its jagged local minima
        (which one that is depends on the noise at single contact events).  Fits without a rough
        parameter are returned unchanged; ``basin_start`` is the first bracket's half-width
        (:meth:`basin`)."""
        idx = rough(self.free)
        x = np.asarray(fit.x, float).copy()
        if not idx:
            return fit
        smooth = [i for i in range(len(x)) if i not in idx]
        for _ in range(cycles):
            for i in idx:
                x[i] = self.basin(x, i, start=basin_start)
            x = self.fit_subset(x, smooth, refit_nfev)
        f, J, raw = self.evaluate(x)
        return FitResult(list(self.free), x, fit.x_start, gap(self.used(raw)), J, f, self.nsim, raw)


def damped_step(J: np.ndarray, r: np.ndarray, damping: float = 1e-6) -> np.ndarray:
    """The Gauss-Newton step ``dz`` of residual ``r`` with Jacobian ``J``, Levenberg-damped by
    ``damping`` times the mean diagonal of ``J'J`` (and 1e-300, so an all-zero Jacobian solves
    to no step): ``(J'J + damping tr(J'J)/p I) dz = -J' r``."""
    p = J.shape[1]
    A = J.T @ J
    return np.linalg.solve(A + damping * np.trace(A) / p * np.eye(p) + 1e-300 * np.eye(p), -J.T @ r)


def jacobian_se(problem: Problem, fit: FitResult) -> np.ndarray:
    """Standard errors of the fitted parameters from the Jacobian at the optimum
    (:func:`standard_errors` of :func:`jacobian_cov`)."""
    return standard_errors(jacobian_cov(problem, fit))


def standard_errors(cov: np.ndarray) -> np.ndarray:
    """The square roots of a covariance's diagonal (negative round-off clipped to 0)."""
    return np.sqrt(np.maximum(np.diag(cov), 0.0))


def correlation(cov: np.ndarray) -> np.ndarray:
    """The correlation matrix of a covariance ``cov`` (e.g. :func:`jacobian_cov`'s): ``cov_ij /
    sqrt(cov_ii cov_jj)``; NaN where a variance is 0 or not finite."""
    sd = standard_errors(cov)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr[~np.isfinite(corr)] = np.nan
    return corr


def jacobian_cov(problem: Problem, fit: FitResult) -> np.ndarray:
    """Covariance of the fitted parameters (in their own units) from the Jacobian at the optimum.

    ``cov = s^2 tau (J'WJ)^-1 J'W^2J (J'WJ)^-1`` (sandwich for the run weights ``W``) with the
    residual variance ``s^2`` and the residuals' correlation time ``tau`` [samples]; the
    residual includes any remaining model error, which makes the estimate conservative.
    """
    J = fit.jac if fit.jac is not None else problem.jac(fit.x)
    raw = problem.used(fit.raw_residuals)
    n = sum(len(r) for r in raw)
    p = len(fit.x)
    s2 = sum(float(np.sum(r**2)) for r in raw) / max(n - p, 1)
    tau = correlation_time(raw)
    w = np.concatenate([np.full(len(r), problem.weights[j]) for j, r in enumerate(raw)])
    Ju = J / w[:, None]  # unweighted sensitivities
    A = (Ju * (w**2)[:, None]).T @ Ju
    B = (Ju * (w**4)[:, None]).T @ Ju
    try:
        Ai = np.linalg.pinv(A)
    except np.linalg.LinAlgError:
        return np.diag(np.full(p, np.inf))
    return s2 * tau * Ai @ B @ Ai
