"""Name the missing effect: score every candidate on held-out runs, accept the best if it
removes a clear share of the gap, repeat once for a second effect.

Scoring (per round):

1. fit each candidate on all runs (grid start, then least squares; earlier accepted effects stay
   free in the fit so two effects can trade off);
2. *screen*: held-out gap with k-fold over runs, each fold's parameters from one Gauss-Newton
   step from the all-runs fit with the held-out runs' rows removed (cheap: one Jacobian);
3. *confirm*: the best candidates (``n_confirm``) are refitted exactly on each fold's training
   runs (warm start) and their held-out runs simulated with those parameters; this held-out gap
   decides.  The fold fits also give a jackknife spread of each parameter.

Acceptance: the best candidate's held-out gap must fall by at least ``min_share`` of the gap it
started from, and that starting gap must stand clearly above the measurement noise floor
(``noise_factor`` times the noise estimated from the residual's sample-to-sample roughness).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from . import effects as fx
from .fit import FitResult, Problem, gap
from .replay import Replayer, ReplayRun

#: Least share of the round's starting held-out gap the best candidate must remove.
MIN_SHARE = 0.2
#: The round's starting gap must exceed this many noise standard deviations.
NOISE_FACTOR = 2.0
#: Margin = 1 - (best's held-out gap / runner-up's held-out gap).  Below this the two
#: candidates explain the data equally well; "high" confidence needs twice this.
TIE_MARGIN = 0.1
#: Remaining excess over noise above this share of the initial excess: part of the gap stays
#: unexplained by the library.
UNEXPLAINED_SHARE = 0.3
#: A held-out gap left above this many noise standard deviations after the named effects: the
#: library does not explain the data down to the noise, so no name is given "high" confidence.
REMAINDER_FACTOR = 3.0

def share_of(g: float, gap_start: float) -> float:
    """Share ``1 - g / gap_start`` of the starting gap removed; 0 when there was no gap (the
    data equal the model's replay exactly: nothing to remove)."""
    if gap_start > 0:
        return 1 - g / gap_start
    return 0.0 if g <= 0 else -math.inf


def separating_experiment(a: str, b: str) -> str:
    """The experiment that would separate candidate ``a`` from ``b``."""
    return fx.SEPARATING_EXPERIMENTS.get(frozenset({a, b}), fx.DEFAULT_SEPARATION)


def kfolds(runs: list[ReplayRun], k: int) -> list[list[int]]:
    """Split run indices into ``k`` folds, interleaved after sorting by (kind, pose, frequency,
    amplitude) so every fold holds a mix of the experiment design."""
    order = sorted(range(len(runs)), key=lambda j: (runs[j].kind, runs[j].gamma_set_deg,
                                                    runs[j].frequency_hz, runs[j].amplitude_rad,
                                                    runs[j].name))
    k = max(2, min(k, len(runs)))
    return [[order[i] for i in range(f, len(order), k)] for f in range(k)]


def noise_floor(residuals: list[np.ndarray]) -> float:
    """Measurement noise std [rad] from the residual's roughness.

    White noise of std ``s`` gives second differences of std ``s*sqrt(6)``; model error is
    smooth at the sample rate.  A robust (MAD) estimate, so transients do not inflate it.
    """
    d2 = np.concatenate([np.diff(r, 2) for r in residuals if len(r) > 3])
    if len(d2) == 0:
        return 0.0
    mad = np.median(np.abs(d2 - np.median(d2))) / 0.6745
    # a quantised encoder at rest gives exactly zero differences: use the RMS as a fallback floor
    rms = np.sqrt(np.mean(d2**2))
    return float(max(mad, 0.5 * rms) / math.sqrt(6))


@dataclass
class Scored:
    """One candidate of one round.

    Attributes
    ----------
    name : str
    effects : list of Effect
        Free effects of the fit (earlier accepted ones + this candidate).
    fit : FitResult
        All-runs fit.
    heldout_gap : float [rad]
    share : float
        ``1 - heldout_gap / gap_start`` of the round.
    method : str
        ``"one-step"`` or ``"refit"`` (how the fold parameters were obtained).
    heldout_raw : list of ndarray
        Held-out residual [rad] per run.
    fold_x : list of ndarray
        Fold parameters.
    """

    name: str
    effects: list
    fit: FitResult
    heldout_gap: float = math.inf
    share: float = -math.inf
    method: str = ""
    heldout_raw: list = field(default_factory=list, repr=False)
    fold_x: list = field(default_factory=list, repr=False)
    folds: list = field(default_factory=list, repr=False)
    seconds: float = 0.0
    target: fx.Target = fx.OMNI


def _heldout(problem: Problem, fold_x: list[np.ndarray], folds: list[list[int]]) -> list[np.ndarray]:
    """Held-out residuals: each run simulated with its own fold's parameters, one batch."""
    models = [problem.model(x) for x in fold_x]
    pairs = [(f, j) for f, idx in enumerate(folds) for j in idx]
    th = problem.rep.simulate(models, problem.runs, pairs)
    problem.nsim += len(folds)
    out: list = [None] * len(problem.runs)
    for (f, j), t in zip(pairs, th):
        out[j] = t - problem.runs[j].theta
    return out


def _onestep_folds(problem: Problem, fit: FitResult, folds: list[list[int]]) -> list[np.ndarray]:
    J = fit.jac
    r = fit.resid
    rows = np.cumsum([0] + [run.n for run in problem.runs])
    out = []
    for idx in folds:
        keep = np.ones(len(r), bool)
        for j in idx:
            keep[rows[j]:rows[j + 1]] = False
        Js = J[keep] * problem.scale
        dz, *_ = np.linalg.lstsq(Js, -r[keep], rcond=1e-10)
        out.append(np.clip(fit.x + dz * problem.scale, problem.lower, problem.upper))
    return out


def _refit_folds(problem: Problem, fit: FitResult, folds: list[list[int]], start: list[np.ndarray],
                 iterations: int = 4) -> list[np.ndarray]:
    """Exact per-fold refits, all folds in lockstep.

    Each iteration simulates every fold's current parameters and their finite-difference
    perturbations on that fold's training runs in ONE batch, then each fold takes a bounded
    Gauss-Newton step on its own training runs only (halving the step while it does not lower
    the training error).  The held-out runs never enter their fold's step, so they are not
    simulated.
    """
    runs = problem.runs
    # each fold's training runs (in run order); its held-out runs are not simulated at all
    train = [[j for j in range(len(runs)) if j not in set(idx)] for idx in folds]
    xs = [np.asarray(x, float).copy() for x in start]
    p = len(fit.x)
    lam = [1e-6] * len(folds)
    for _ in range(iterations):
        batch, steps = [], []
        for x in xs:
            st = problem._steps(x)
            steps.append(st)
            batch += [x] + [x + h * e for h, e in zip(st, np.eye(p))]
        models = [problem.model(x) for x in batch]
        pairs = [(f * (p + 1) + i, j) for f in range(len(folds)) for i in range(p + 1)
                 for j in train[f]]
        th = problem.rep.simulate(models, runs, pairs)
        problem.nsim += len(batch)
        raws, b = [], 0
        for f in range(len(folds)):
            for i in range(p + 1):
                raws.append([th[b + k] - runs[j].theta for k, j in enumerate(train[f])])
                b += len(train[f])
        for f in range(len(folds)):
            base = f * (p + 1)
            f0 = problem.weighted(raws[base], train[f])
            J = np.column_stack([(problem.weighted(raws[base + 1 + i], train[f]) - f0) / steps[f][i]
                                 for i in range(p)])
            r, Jt = f0, J * problem.scale
            A = Jt.T @ Jt
            dz = np.linalg.solve(A + lam[f] * np.trace(A) / p * np.eye(p) + 1e-300 * np.eye(p), -Jt.T @ r)
            xs[f] = np.clip(xs[f] + dz * problem.scale, problem.lower, problem.upper)
    return xs


def score_round(spec: mujoco.MjSpec, accepted: list[fx.Effect], accepted_x: np.ndarray,
                runs: list[ReplayRun], rep: Replayer, gap_start: float, k: int = 5,
                n_confirm: int = 3, candidates: tuple[str, ...] | None = None,
                screen_nfev: int = 4, log=None, target: fx.Target = fx.OMNI) -> list[Scored]:
    """Fit and score every candidate not yet accepted; best first.

    Parameters
    ----------
    spec : MjSpec
        The nominal model.
    accepted, accepted_x : list of Effect, ndarray
        Effects accepted in earlier rounds and their fitted values (free again in this round).
    runs : list of ReplayRun
    gap_start : float [rad]
        Held-out gap of the model the round starts from.
    k : int
        Folds over runs.
    n_confirm : int
        Candidates refitted exactly per fold after screening.
    screen_nfev : int
        Least-squares evaluations of the screening fit (the confirmed candidates are then
        fitted to convergence).
    candidates : tuple of str, optional
        Library names to try (default: all).
    """
    names = candidates or fx.NAMES
    folds = kfolds(runs, k)
    scored: list[Scored] = []
    for name in names:
        if name in [e.name for e in accepted]:
            continue
        t0 = time.perf_counter()
        eff = fx.get(name)
        effects = list(accepted) + [eff]
        prob = Problem(spec, [], effects, runs, rep, target)
        x0 = np.concatenate([np.asarray(accepted_x, float), fx.nominal_values(eff, spec, target)])
        fit = prob.fit(x0, grid_effect_index=len(effects) - 1, max_nfev=screen_nfev)
        scored.append(_screened(name, effects, prob, fit, folds, gap_start, t0, log, width=18))
    return _confirm_best(scored, n_confirm, spec, runs, rep, folds, gap_start, log)


def _screened(name: str, effects, prob, fit, folds, gap_start: float, t0: float, log=None,
              width: int = 18) -> Scored:
    """Score an all-runs fit on held-out runs with one Gauss-Newton step per fold."""
    fold_x = _onestep_folds(prob, fit, folds)
    raw = _heldout(prob, fold_x, folds)
    g = gap(raw)
    s = Scored(name, effects, fit, g, share_of(g, gap_start), "one-step", raw, fold_x, folds,
               time.perf_counter() - t0, prob.target)
    if log:
        log(f"  {name:{width}s} screen held-out gap {g:.3e} rad (share {s.share:+.2f}) "
            f"x={np.array2string(fit.x, precision=4)} [{s.seconds:.1f} s]")
    return s


def _confirm_best(scored: list[Scored], n_confirm: int, spec, runs, rep, folds, gap_start: float,
                  log=None) -> list[Scored]:
    """Confirm the ``n_confirm`` best screened candidates with exact refits; best first."""
    scored.sort(key=lambda s: s.heldout_gap)
    for s in scored[:n_confirm]:
        _confirm(spec, s, runs, rep, folds, gap_start, log)
    confirmed = sorted(scored[:n_confirm], key=lambda s: s.heldout_gap)
    return confirmed + scored[n_confirm:]


def _confirm(spec, s: Scored, runs, rep, folds, gap_start: float, log=None) -> None:
    """Converge the all-runs fit of ``s`` and score it with exact per-fold refits (in place)."""
    t0 = time.perf_counter()
    prob = Problem(spec, [], s.effects, runs, rep, s.target)
    # the screening fit already simulated its end point (same model, runs and effects): the
    # converging fit starts there without simulating it again
    prob.seed(s.fit)
    s.fit = prob.fit(s.fit.x, None, max_nfev=20)  # converge the all-runs fit
    s.fold_x = _onestep_folds(prob, s.fit, folds)
    s.fold_x = _refit_folds(prob, s.fit, folds, s.fold_x)
    s.heldout_raw = _heldout(prob, s.fold_x, folds)
    s.heldout_gap = gap(s.heldout_raw)
    s.share = share_of(s.heldout_gap, gap_start)
    s.method = "refit"
    s.seconds += time.perf_counter() - t0
    if log:
        log(f"  {s.name:18s} refit  held-out gap {s.heldout_gap:.3e} rad (share {s.share:+.2f})")


#: Samples per run on which the pairs' starting grids are evaluated (a coarse start only).
PAIR_GRID_SAMPLES = 700
#: Pairs (best by their grid) fitted and screened; the best ``n_confirm`` of them confirmed.
PAIR_FITS = 8
#: Pairs are searched when the best single candidate removes less than this share of the gap.
PAIR_SEARCH_SHARE = 0.5


def score_pairs(spec: mujoco.MjSpec, runs: list[ReplayRun], rep: Replayer, gap_start: float,
                k: int = 5, n_confirm: int = 3, n_fit: int = PAIR_FITS,
                grid_samples: int = PAIR_GRID_SAMPLES, candidates: tuple[str, ...] | None = None,
                screen_nfev: int = 8, log=None, target: fx.Target = fx.OMNI) -> list[Scored]:
    """Fit and score every *pair* of candidates jointly; best first.

    Two effects can mask each other: a loop delay takes damping away, dry friction adds it, so
    neither alone explains the data (fitted alone, the delay even stays at zero) while together
    they explain it down to the noise.  One effect at a time, as :func:`score_round` adds them,
    cannot find such a pair.  Here every pair starts from the best point of the product of the
    two effects' grids (one batch per pair, on the first ``grid_samples`` samples of each run),
    the ``n_fit`` best pairs are fitted on all runs and screened on held-out runs like the single
    candidates, and the best ``n_confirm`` are confirmed with exact per-fold refits.
    """
    import itertools
    names = candidates or fx.NAMES
    folds = kfolds(runs, k)
    grid_runs = [r.truncated(grid_samples) for r in runs]
    starts = []
    t0 = time.perf_counter()
    for a, b in itertools.combinations(names, 2):
        effects = [fx.get(a), fx.get(b)]
        prob = Problem(spec, [], effects, grid_runs, rep, target)
        ga = effects[0].grid(fx.nominal_values(effects[0], spec, target))
        gb = effects[1].grid(fx.nominal_values(effects[1], spec, target))
        x0 = np.concatenate([fx.nominal_values(e, spec, target) for e in effects])
        pts = [np.clip(np.concatenate([effects[0].clip(np.asarray(u, float)),
                                       effects[1].clip(np.asarray(v, float))]), prob.lower, prob.upper)
               for u in ga for v in gb] + [x0]
        scores = [gap(raw) for raw in prob.simulate(pts)]
        i = int(np.argmin(scores))
        starts.append((scores[i], a, b, pts[i]))
    starts.sort(key=lambda t: t[0])
    if log:
        log(f"  pair grids: {len(starts)} pairs in {time.perf_counter() - t0:.1f} s; best "
            + ", ".join(f"{a}+{b} ({g:.2e})" for g, a, b, _ in starts[:n_fit]))
    scored = []
    for _, a, b, x0 in starts[:n_fit]:
        t0 = time.perf_counter()
        effects = [fx.get(a), fx.get(b)]
        prob = Problem(spec, [], effects, runs, rep, target)
        fit = prob.fit(x0, None, max_nfev=screen_nfev)
        scored.append(_screened(f"{a}+{b}", effects, prob, fit, folds, gap_start, t0, log, width=36))
    return _confirm_best(scored, n_confirm, spec, runs, rep, folds, gap_start, log)


def pair_runner_up(best: Scored, pairs: list[Scored], singles: list[Scored]) -> list[tuple[str | None, float]]:
    """For each member of the best pair: the best alternative for it and the margin.

    The alternative is the best other scored pair that keeps the other member (the member
    replaced by another candidate); without one, the other member alone (the member dropped,
    runner-up ``None``).  Margin = ``1 - best gap / alternative's gap``.
    """
    names = [e.name for e in best.effects]
    out = []
    for m, other in ((names[0], names[1]), (names[1], names[0])):
        alt = [p for p in pairs if p is not best and other in [e.name for e in p.effects]
               and m not in [e.name for e in p.effects]]
        if alt:
            a = min(alt, key=lambda p: p.heldout_gap)
            out.append(([e.name for e in a.effects if e.name != other][0], share_of(best.heldout_gap, a.heldout_gap)))
            continue
        single = [s for s in singles if s.name == other]
        g = single[0].heldout_gap if single else math.inf
        out.append((None, share_of(best.heldout_gap, g) if math.isfinite(g) else 1.0))
    return out
