"""Held-out folds of a search's runs and the fits on them.

A :class:`Fold` says which samples it holds out; each fold's parameters are fitted on every
other sample (:func:`onestep_folds`, :func:`refit_folds`, :func:`polish_folds`) and predict
the held-out ones (:func:`heldout`, :func:`heldout_replays`).  Used by
:class:`discrepancy.select.Scorer`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fit import BASIN_SMALLEST, FitResult, Problem, damped_step, gap, unstable_count
from .runs import ReplayRun


@dataclass(frozen=True)
class Fold:
    """The samples one fold holds out: ``held[j]`` is run ``j``'s held-out mask (bool, one per
    sample), or None when the fold holds out nothing of run ``j``.  The fold's parameters are
    fitted on every other sample and predict the held-out ones (a run is always replayed
    whole, from its start: a held-out block's prediction runs through the training blocks
    before it, as the device did)."""

    held: tuple

    @property
    def runs(self) -> list[int]:
        """Runs with held-out samples (the ones the held-out replay simulates)."""
        return [j for j, h in enumerate(self.held) if h is not None]

    def train(self) -> tuple[list[int], list]:
        """The runs the fold's fit uses (those with any training sample) and their masks."""
        idx, masks = [], []
        for j, h in enumerate(self.held):
            if h is None:
                idx.append(j)
                masks.append(None)
            elif not h.all():
                idx.append(j)
                masks.append(~h)
        return idx, masks


#: Fold schemes.  ``blocked``: every run cut into k contiguous time blocks of equal length, fold
#: f holds out block f of every run, so every fold's fit sees every kind of experiment (four
#: runs of four different experiments can be scored).  ``runs``: k folds of whole runs
#: (:func:`run_folds`), each fold fitting some kinds of experiment and predicting others.
FOLD_SCHEMES = ("blocked", "runs")


def run_folds(runs: list[ReplayRun], k: int) -> list[Fold]:
    """``k`` folds of whole runs, interleaved after sorting by (kind, pose, frequency,
    amplitude) so every fold holds a mix of the experiment design."""
    order = sorted(range(len(runs)), key=lambda j: (runs[j].kind, runs[j].gamma_set_deg,
                                                    runs[j].frequency_hz, runs[j].amplitude_rad,
                                                    runs[j].name))
    k = max(2, min(k, len(runs)))
    out = []
    for f in range(k):
        held = set(order[i] for i in range(f, len(order), k))
        out.append(Fold(tuple(np.ones(runs[j].n, bool) if j in held else None for j in range(len(runs)))))
    return out


def block_folds(runs: list[ReplayRun], k: int) -> list[Fold]:
    """``k`` folds of time blocks: fold ``f`` holds out samples ``[f n / k, (f + 1) n / k)`` of
    every run (n its samples)."""
    k = max(2, k)
    out = []
    for f in range(k):
        held = []
        for r in runs:
            h = np.zeros(r.n, bool)
            h[(f * r.n) // k:((f + 1) * r.n) // k] = True
            held.append(h)
        out.append(Fold(tuple(held)))
    return out


def make_folds(runs: list[ReplayRun], k: int, scheme: str = "blocked") -> list[Fold]:
    """The folds of ``scheme`` (:data:`FOLD_SCHEMES`)."""
    if scheme == "blocked":
        return block_folds(runs, k)
    if scheme == "runs":
        return run_folds(runs, k)
    raise ValueError(f"unknown fold scheme {scheme!r} (one of {', '.join(FOLD_SCHEMES)})")


def heldout_replays(rep, models: list, runs: list[ReplayRun], folds: list[Fold]) -> list[np.ndarray]:
    """Each run's held-out replay [rad]: every held-out sample from the replay with its own
    fold's model (``models[f]``), all in one batch."""
    pairs = [(f, j) for f, fold in enumerate(folds) for j in fold.runs]
    th = rep.simulate(models, runs, pairs)
    out = [np.full(r.n, np.nan) for r in runs]
    for (f, j), t in zip(pairs, th):
        h = folds[f].held[j]
        out[j][h] = t[h]
    return out


def heldout(problem: Problem, fold_x: list[np.ndarray], folds: list[Fold]) -> list[np.ndarray]:
    """Held-out residuals: each held-out sample from its own fold's parameters, one batch (an
    unstable replay: NaN over its held-out samples)."""
    models = [problem.model(x) for x in fold_x]
    th = heldout_replays(problem.rep, models, problem.runs, folds)
    problem.nsim += len(folds)
    out = [t - r.theta for t, r in zip(th, problem.runs)]
    problem.unstable += sum(1 for o in out if not np.all(np.isfinite(o)))
    return out


def onestep_folds(problem: Problem, fit: FitResult, folds: list[Fold]) -> list[np.ndarray]:
    J = fit.jac
    r = fit.resid
    rows = np.cumsum([0] + [run.n for run in problem.runs])
    out = []
    for fold in folds:
        keep = np.ones(len(r), bool)
        for j in fold.runs:
            keep[rows[j]:rows[j + 1]] &= ~fold.held[j]
        Js = J[keep] * problem.scale
        dz, *_ = np.linalg.lstsq(Js, -r[keep], rcond=1e-10)
        out.append(np.clip(fit.x + dz * problem.scale, problem.lower, problem.upper))
    return out


def fold_problem(problem: Problem, fold: Fold) -> tuple[Problem, list[int]]:
    """``problem`` restricted to ``fold``'s training samples (its runs with any, masked), and
    those runs' indices in ``problem.runs``."""
    idx, masks = fold.train()
    pf = Problem(problem.builder, problem.fixed, problem.free, [problem.runs[j] for j in idx], problem.rep,
                 masks=masks)
    return pf, idx


#: Gauss-Newton iterations of the per-fold refits, from each fold's one-step start (2: the
#: one-step start is already a Gauss-Newton step from the all-runs optimum; two more steps on
#: the fold's own training samples take it the rest of the way on a smooth objective).
REFIT_ITERATIONS = 2
#: Least-squares evaluations of a confirmed candidate's all-runs fit, from the screening fit's
#: end point (each evaluation simulates the point and its p perturbations in one batch).
CONFIRM_NFEV = 10


def fold_jacobians(problem: Problem, fps: list, xs: list[np.ndarray]) -> list[np.ndarray]:
    """Each fold's forward-difference Jacobian at ``xs[f]`` on its training samples, in its own
    weighting, times the parameters' scale: every fold's point and its ``p`` perturbations
    (:meth:`Problem.steps`) on the fold's training runs in ONE replay batch."""
    runs, p = problem.runs, len(problem.scale)
    points, steps, pairs = [], [], []
    for (_, idx), x in zip(fps, xs):
        pts, h = problem.perturbed(x)
        pairs += [(len(points) + m, j) for m in range(p + 1) for j in idx]
        points += pts
        steps.append(h)
    th = problem.rep.simulate([problem.model(x) for x in points], runs, pairs)
    problem.nsim += len(points)
    out, b = [], 0
    for (pf, idx), h in zip(fps, steps):
        raws = []
        for _ in range(p + 1):
            raws.append([th[b + k] - runs[j].theta for k, j in enumerate(idx)])
            b += len(idx)
            problem.unstable += unstable_count(raws[-1])
        out.append(pf.jacobian(raws, h)[1] * problem.scale)
    return out


def refit_folds(problem: Problem, folds: list[Fold], start: list[np.ndarray],
                 iterations: int = REFIT_ITERATIONS) -> list[np.ndarray]:
    """Per-fold refits, all folds in lockstep: each fold's parameters fitted on its own
    training samples only (the held-out samples never enter its steps).

    Each fold takes damped Gauss-Newton steps with its OWN forward-difference Jacobian, taken
    once at its start (every fold's start and its ``p`` perturbations on the fold's training
    runs, one batch), then held for the steps (the chord method); each iteration simulates
    every fold's current parameters on that fold's training runs in one batch.  Why the fold's
    own and not the all-runs fit's rows of it: on the real servo of examples/real_servo the
    all-runs Jacobian's refits left the corrections 5 points of held-out gap behind fresh
    per-fold fits (27 % removed against 32 %); the fold's own Jacobian at its start gives 33 %
    for 23 % more physics steps (measured on that example).
    """
    runs = problem.runs
    # each fold's training runs (in run order; a run held out whole is not simulated at all)
    # and its objective on their training samples
    fps = [fold_problem(problem, fold) for fold in folds]
    train = [idx for _, idx in fps]
    xs = [np.asarray(x, float).copy() for x in start]
    Jf = fold_jacobians(problem, fps, xs)
    for _ in range(iterations):
        models = [problem.model(x) for x in xs]
        pairs = [(f, j) for f in range(len(folds)) for j in train[f]]
        th = problem.rep.simulate(models, runs, pairs)
        problem.nsim += len(xs)
        b = 0
        for f in range(len(folds)):
            raw = [th[b + k] - runs[j].theta for k, j in enumerate(train[f])]
            b += len(train[f])
            problem.unstable += unstable_count(raw)
            dz = damped_step(Jf[f], fps[f][0].weighted(raw))
            xs[f] = np.clip(xs[f] + dz * problem.scale, problem.lower, problem.upper)
    return xs


def polish_folds(problem: Problem, folds: list[Fold], start: list[np.ndarray]) -> list[np.ndarray]:
    """Per-fold fits of a candidate with rough parameters: each fold's training samples, from its
    one-step start, by :meth:`Problem.polish` (one cycle; the basin's first bracket at its
    smallest width, as the fold's basin lies near the all-runs one)."""
    out = []
    for fold, x0 in zip(folds, start):
        pf, _ = fold_problem(problem, fold)
        f, J, raw = pf.evaluate(x0)
        fit = pf.polish(FitResult(list(pf.free), np.asarray(x0, float), np.asarray(x0, float),
                                  gap(pf.used(raw)), J, f, pf.nsim, raw), cycles=1, basin_start=BASIN_SMALLEST)
        problem.nsim += pf.nsim
        problem.unstable += pf.unstable
        out.append(fit.x)
    return out
