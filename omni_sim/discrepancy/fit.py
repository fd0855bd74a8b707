"""Fit effect parameters by closed-loop simulation error, with uncertainties.

The objective is the replay error ``theta_model - theta_measured`` [rad] of every run, each run
weighted by ``1/sqrt(n_samples)`` so that every run counts equally (a long step record does not
drown a short sine).  The *gap* of a set of runs is the root of the mean over runs of each run's
mean-square error [rad].

Fits use :func:`scipy.optimize.least_squares` (trust region, box bounds) with a forward-
difference Jacobian whose columns are simulated together: the perturbed models form one batch of
the :class:`~omni_sim.discrepancy.replay.Replayer`.  A coarse grid over the new effect's
parameters (one batch) picks the starting point, because a local fit cannot find a torque limit
or a friction level the data never "feels" at the nominal values.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy.optimize import least_squares

from . import effects as fx
from .replay import Replayer, ReplayRun


def gap(residuals: list[np.ndarray]) -> float:
    """Root of the mean over runs of each run's mean-square error [rad]."""
    if not residuals:
        return float("nan")
    return float(np.sqrt(np.mean([np.mean(r**2) for r in residuals])))


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
    """

    effects: list
    x: np.ndarray
    x_start: np.ndarray
    gap_train: float
    jac: np.ndarray | None = None
    resid: np.ndarray | None = None
    nfev: int = 0
    raw_residuals: list = field(default_factory=list, repr=False)

    def split(self) -> list[tuple[fx.Effect, np.ndarray]]:
        """``[(effect, its parameter values), ...]``."""
        out, i = [], 0
        for e in self.effects:
            out.append((e, self.x[i:i + e.nparam]))
            i += e.nparam
        return out


class Problem:
    """Simulation-error least squares of some effects' parameters on some runs.

    Parameters
    ----------
    spec : MjSpec
        The model the effects are added to (not modified).
    fixed : list of (Effect, values)
        Changes already accepted and held fixed.
    free : list of Effect
        Effects whose parameters are fitted.
    runs : list of ReplayRun
    replayer : Replayer
    target : effects.Target
        The controlled joint and actuator the effects are written into.
    """

    def __init__(self, spec: mujoco.MjSpec, fixed: list, free: list, runs: list[ReplayRun],
                 replayer: Replayer, target: fx.Target = fx.OMNI):
        self.spec, self.fixed, self.free, self.runs, self.rep = spec, list(fixed), list(free), runs, replayer
        self.target = target
        lo, hi, sc = [], [], []
        for e in self.free:
            l, h = e.bounds()
            lo += list(l)
            hi += list(h)
            sc += list(e.scales())
        self.lower, self.upper, self.scale = np.array(lo), np.array(hi), np.array(sc)
        self.weights = [1.0 / np.sqrt(r.n) for r in runs]
        self.nsim = 0
        self._cache: dict = {}

    # --- models and residuals --------------------------------------------------------------
    def changes(self, x: np.ndarray) -> list:
        out, i = list(self.fixed), 0
        for e in self.free:
            out.append((e, x[i:i + e.nparam]))
            i += e.nparam
        return out

    def model(self, x: np.ndarray) -> mujoco.MjModel:
        return fx.compile_with(self.spec, self.changes(np.asarray(x, float)), self.target)

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
        return out

    def weighted(self, raw: list[np.ndarray], run_idx: list[int] | None = None) -> np.ndarray:
        run_idx = list(range(len(self.runs))) if run_idx is None else run_idx
        return np.concatenate([raw[k] * self.weights[j] for k, j in enumerate(run_idx)])

    def _key(self, x):
        return tuple(np.round(np.asarray(x, float), 15))

    def _steps(self, x: np.ndarray) -> list[float]:
        steps = []
        for i in range(len(x)):
            h = 0.05 * self.scale[i]
            steps.append(-h if x[i] + h > self.upper[i] else h)
        return steps

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, list]:
        """Weighted residual, forward-difference Jacobian and raw residuals at ``x``.

        ``x`` and its ``p`` perturbations are simulated in ONE batch: a step of the closed-loop
        replay costs about the same for 16 or 48 trajectories, so the Jacobian comes almost free.
        """
        x = np.asarray(x, float)
        k = self._key(x)
        if k not in self._cache:
            steps = self._steps(x)
            xs = [x] + [x + h * e for h, e in zip(steps, np.eye(len(x)))]
            raws = self.simulate(xs)
            f0 = self.weighted(raws[0])
            J = np.column_stack([(self.weighted(r) - f0) / h for r, h in zip(raws[1:], steps)]) \
                if len(x) else np.zeros((len(f0), 0))
            self._cache = {k: (f0, J, raws[0])}
        return self._cache[k]

    def seed(self, fit: FitResult) -> None:
        """Take ``fit``'s residual and Jacobian at ``fit.x`` as this problem's evaluation there
        (``fit`` must come from a problem with the same spec, effects and runs)."""
        if fit.jac is not None and fit.resid is not None:
            self._cache = {self._key(fit.x): (fit.resid, fit.jac, fit.raw_residuals)}

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
        scores = [gap(raw) for raw in raws]
        return pts[int(np.argmin(scores))]

    def fit(self, x0: np.ndarray, grid_effect_index: int | None = None, max_nfev: int = 20) -> FitResult:
        """Fit from ``x0`` (after a grid over one effect if asked)."""
        x0 = np.clip(np.asarray(x0, float), self.lower, self.upper)
        if grid_effect_index is not None:
            x0 = self.grid_start(x0, grid_effect_index)
        # keep the start strictly inside the bounds (trf requirement)
        eps = 1e-9 * (self.upper - self.lower)
        x0 = np.clip(x0, self.lower + eps, self.upper - eps)
        sol = least_squares(self.fun, x0, jac=self.jac, bounds=(self.lower, self.upper),
                            x_scale=self.scale, method="trf", max_nfev=max_nfev,
                            xtol=1e-3, ftol=1e-4, gtol=1e-8)
        x = sol.x
        f, J, raw = self.evaluate(x)
        return FitResult(list(self.free), x, x0, gap(raw), J, f, self.nsim, raw)


def jacobian_se(problem: Problem, fit: FitResult) -> np.ndarray:
    """Standard errors of the fitted parameters from the Jacobian at the optimum.

    ``cov = s^2 tau (J'WJ)^-1 J'W^2J (J'WJ)^-1`` (sandwich for the run weights ``W``) with the
    residual variance ``s^2`` and the residuals' correlation time ``tau`` [samples]; the
    residual includes any remaining model error, which makes the estimate conservative.
    """
    J = fit.jac if fit.jac is not None else problem.jac(fit.x)
    raw = fit.raw_residuals
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
        return np.full(p, np.inf)
    cov = s2 * tau * Ai @ B @ Ai
    return np.sqrt(np.maximum(np.diag(cov), 0.0))
