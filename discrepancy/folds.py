"""Held-out folds of a search's runs and the fits on them.

A :class:`Fold` says which samples it holds out; the fold's parameters are fitted on every
other sample (:func:`fit_folds`), each from a start found without its
held-out samples (:func:`fold_grid_starts`), and predict the held-out ones
(:func:`heldout`, :func:`heldout_replays`).  Used by :class:`discrepancy.select.Scorer`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fit import Problem
from .runs import ReplayRun

#: Short records [s] on which a fold's start is moved to its grid's best point (the prescreen's
#: length, :data:`discrepancy.prescreen.PRESCREEN_S`).
START_GRID_S = 1.0


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


def fold_problem(problem: Problem, fold: Fold) -> tuple[Problem, list[int]]:
    """``problem`` restricted to ``fold``'s training samples (its runs with any, masked), and
    those runs' indices in ``problem.runs``."""
    idx, masks = fold.train()
    pf = Problem(problem.builder, problem.fixed, problem.free, [problem.runs[j] for j in idx], problem.rep,
                 masks=masks)
    return pf, idx


#: Least-squares evaluations of a fold's fit (:func:`fit_folds`): those of the all-runs fit
#: it stands for, the screening fit's 8 (:meth:`discrepancy.select.Scorer.score_round`) and the
#: confirming fit's :data:`discrepancy.select.CONFIRM_NFEV` (10).
FOLD_NFEV = 18


def fit_folds(problem: Problem, folds: list[Fold], start: list[np.ndarray]) -> list[np.ndarray]:
    """Per-fold fits, each on the fold's own training samples only, from ``start[f]`` (a point
    found without the fold's held-out samples), by the estimator of the all-runs fit: the
    trust-region fit (:meth:`Problem.fit`: :data:`FOLD_NFEV` evaluations, its own tests
    ``xtol`` 1e-3, ``ftol`` 1e-4), then :meth:`Problem.polish` (the basin of any rough
    parameter).  The held-out score is then the score of the estimator the report uses, and
    the folds' spread is that estimator's (the jackknife's)."""
    out = []
    for fold, x0 in zip(folds, start):
        pf, _ = fold_problem(problem, fold)
        fit = pf.polish(pf.fit(np.asarray(x0, float), None, max_nfev=FOLD_NFEV))
        problem.nsim += pf.nsim
        problem.unstable += pf.unstable
        out.append(fit.x)
    return out


def fold_grid_starts(problem: Problem, folds: list[Fold], starts: list, grid_from: int = 0,
                     seconds: float = START_GRID_S) -> list[np.ndarray]:
    """Each fold's start with the free effects of ``problem`` from index ``grid_from`` on moved,
    one after the other, to the best point of their grid (:meth:`Problem.grid_start`, the others
    held) on the fold's training samples of the first ``seconds`` of each run
    (:func:`fold_records`): a local fit cannot find a delay or a friction level the data never
    "feel" at the nominal values, and the fold's held-out samples must not choose its start."""
    out = []
    for fold, x0 in zip(folds, starts):
        runs, masks = fold_records(problem.runs, fold, seconds)
        pf = Problem(problem.builder, problem.fixed, problem.free, runs, problem.rep, masks=masks)
        x = np.clip(np.asarray(x0, float), problem.lower, problem.upper)
        for i in range(grid_from, len(problem.free)):
            x = pf.grid_start(x, i)
        problem.nsim += pf.nsim
        problem.unstable += pf.unstable
        out.append(x)
    return out


def fold_records(runs: list[ReplayRun], fold: Fold | None, seconds: float) -> tuple[list[ReplayRun], list]:
    """The prescreen's short records of ``fold``'s training samples: per run with any, the
    shortest start of the run (a replay always starts at the run's start) that holds
    ``seconds`` worth of its training samples, and the training mask over it (None: every
    sample).  ``fold`` None: the first ``seconds`` of every run, all samples used."""
    if fold is None:
        return [r.first_seconds(seconds) for r in runs], [None] * len(runs)
    idx, masks = fold.train()
    out, out_masks = [], []
    for j, m in zip(idx, masks):
        n_s = runs[j].first_seconds(seconds).n
        if m is None:
            out.append(runs[j].truncated(n_s))
            out_masks.append(None)
            continue
        end = min(int(np.searchsorted(np.cumsum(m), n_s)) + 1, runs[j].n)
        out.append(runs[j].truncated(end))
        out_masks.append(m[:len(out[-1].theta)])
    return out, out_masks
