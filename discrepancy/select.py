"""Name the missing effect: score every candidate on held-out runs, accept the best if it
removes a clear share of the gap, repeat (forward selection, up to three effects).

Scoring (per round):

1. *prescreen* every candidate on short records of each fold's training samples (for every
   fold, the training samples of the first :data:`PRESCREEN_S` seconds of each run,
   :func:`fold_records`): its grid, then a few damped Gauss-Newton steps, all candidates in
   lockstep so each iteration is one batch of rollouts (earlier accepted effects stay free so
   effects can trade off).  The candidates are ranked by their training gap averaged over the
   folds: no held-out sample ranks a candidate.  A candidate costs a few short batches per
   fold, not a campaign;
2. *screen* the :data:`N_SCREEN` best: least squares on all runs from the prescreen's point
   (the values reported, never a held-out score), then the held-out gap with k folds, each
   fold's parameters from :data:`SCREEN_STEPS` Gauss-Newton step on its training samples from
   its own start;
3. *confirm*: the best candidates (``n_confirm``) are refitted on each fold's training samples
   to convergence (:func:`_refit_folds`) and their held-out samples simulated with those
   parameters; this held-out gap decides.  The fold fits also give a jackknife spread of each
   parameter.

Held out means held out: every fold's fit starts from a point found without the fold's
held-out samples -- the earlier effects at their own fit on that fold (the corrections of the
nominal, the set accepted so far), the new candidate at its prescreen point on that fold's
training samples, a given set (the corrections in the first round) at its given values -- and
never from the all-runs fit.  A fold's fit stops when a step lowers its training cost by less
than :data:`REFIT_FTOL` (1e-3) of it, or moves every parameter by less than :data:`REFIT_XTOL`
(1e-3) of its scale, or after :data:`REFIT_MAX_STEPS` (8) steps; the reasons are given at those
constants.

Acceptance (held-out stopping): the best candidate's held-out gap must fall by at least
``min_share`` of the gap it started from, and that starting gap must stand clearly above the
measurement noise floor (``noise_factor`` times the noise estimated from the residual's
sample-to-sample roughness).

The scores share one bundle, held by a :class:`Scorer` (its rounds, pairs, given sets,
removals and rescoring as methods; :class:`discrepancy.search.Search` holds one).  The MuJoCo
side comes in from the caller: ``builder`` (:class:`~discrepancy.effects.ModelBuilder`:
effects by name, their nominal values, compiled models) and ``rep``
(:class:`~discrepancy.replay.Replayer`: simulates models on runs); this module only
fits, scores and compares.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .fit import BASIN_SMALLEST, FitResult, Problem, damped_step, gap, rough, unstable_count
from .runs import ReplayRun

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
        ``"screen"`` (one Gauss-Newton step per fold), ``"refit"`` (per-fold fits to
        convergence) or ``"prescreen"`` (scored on the short records only).
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
    prescreen_gap: float = math.nan
    unstable: int = 0  # replays MuJoCo found unstable while fitting and scoring it (excluded)


def _values(effects: list, x: np.ndarray) -> list[np.ndarray]:
    """``x`` split into each effect's values."""
    out, i = [], 0
    for e in effects:
        out.append(np.asarray(x[i:i + e.nparam], float))
        i += e.nparam
    return out


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


def _heldout(problem: Problem, fold_x: list[np.ndarray], folds: list[Fold]) -> list[np.ndarray]:
    """Held-out residuals: each held-out sample from its own fold's parameters, one batch (an
    unstable replay: NaN over its held-out samples)."""
    models = [problem.model(x) for x in fold_x]
    th = heldout_replays(problem.rep, models, problem.runs, folds)
    problem.nsim += len(folds)
    out = [t - r.theta for t, r in zip(th, problem.runs)]
    problem.unstable += sum(1 for o in out if not np.all(np.isfinite(o)))
    return out


def _fold_problem(problem: Problem, fold: Fold) -> tuple[Problem, list[int]]:
    """``problem`` restricted to ``fold``'s training samples (its runs with any, masked), and
    those runs' indices in ``problem.runs``."""
    idx, masks = fold.train()
    pf = Problem(problem.builder, problem.fixed, problem.free, [problem.runs[j] for j in idx], problem.rep,
                 masks=masks)
    return pf, idx


#: The per-fold refits' convergence test (:func:`_refit_folds`): a fold stops when a step
#: lowers its training cost by less than :data:`REFIT_FTOL` of it, or its step is below
#: :data:`REFIT_XTOL` of every parameter's scale, or after :data:`REFIT_MAX_STEPS` steps.  Why
#: these numbers (fixed before any result was looked at): the held-out gap is reported to 3
#: digits and a 1e-3 relative change of the training cost moves the gap (its root) by 5e-4;
#: a step of 1e-3 of a parameter's scale is 50x below the finite-difference step (0.05 of the
#: scale), below which the Jacobian cannot resolve a change; 8 steps: from a start at the
#: nominal values (a 2x-off damping or a zero friction) a damped Gauss-Newton on a smooth
#: objective needs 3-6 steps, and 8 caps the cost at 8 Jacobian batches per fold.
REFIT_FTOL = 1e-3
REFIT_XTOL = 1e-3
REFIT_MAX_STEPS = 8
#: Gauss-Newton steps of the screen's per-fold fits (a ranking only; the confirmed candidates
#: are refitted to convergence).
SCREEN_STEPS = 1
#: Least-squares evaluations of a confirmed candidate's all-runs fit, from the screening fit's
#: end point (each evaluation simulates the point and its p perturbations in one batch).
CONFIRM_NFEV = 10
#: Candidates (best by the screen's held-out gap) confirmed with exact per-fold refits.
N_CONFIRM = 2


def _fold_jacobians(problem: Problem, fps: list, xs: list[np.ndarray],
                    with_jac: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each fold's weighted residual and forward-difference Jacobian (times the parameters'
    scale) at ``xs[f]`` on its training samples: every fold's point and its ``p``
    perturbations (:meth:`Problem.steps`) on the fold's training runs in ONE replay batch
    (``with_jac`` False: the points alone, the Jacobians empty)."""
    runs, p = problem.runs, len(problem.scale)
    points, steps, pairs = [], [], []
    for (_, idx), x in zip(fps, xs):
        pts, h = problem.perturbed(x) if with_jac else ([x], [])
        pairs += [(len(points) + m, j) for m in range(len(pts)) for j in idx]
        points += pts
        steps.append(h)
    th = problem.rep.simulate([problem.model(x) for x in points], runs, pairs)
    problem.nsim += len(points)
    out, b = [], 0
    for (pf, idx), h in zip(fps, steps):
        raws = []
        for _ in range(len(h) + 1):
            raws.append([th[b + k] - runs[j].theta for k, j in enumerate(idx)])
            b += len(idx)
            problem.unstable += unstable_count(raws[-1])
        f0, J = pf.jacobian(raws, h)
        out.append((f0, J * problem.scale if with_jac else J))
    return out


def _refit_folds(problem: Problem, folds: list[Fold], start: list[np.ndarray],
                 max_steps: int = REFIT_MAX_STEPS) -> list[np.ndarray]:
    """Per-fold fits from ``start`` (one point per fold, found without the fold's held-out
    samples), all folds in lockstep: each fold's parameters fitted on its own training samples
    only (the held-out samples never enter its steps or its start).

    Each fold takes Levenberg-damped Gauss-Newton steps with its own forward-difference
    Jacobian at its current point (every active fold's trial point and its ``p``
    perturbations on the fold's training runs, one batch per step).  A step that does not
    lower the fold's training cost is undone and the damping raised (x10; lowered /3 after a
    kept step).  A fold stops on the convergence test of :data:`REFIT_FTOL`,
    :data:`REFIT_XTOL`, ``max_steps``."""
    fps = [_fold_problem(problem, fold) for fold in folds]
    k = len(folds)
    x = [np.clip(np.asarray(s, float), problem.lower, problem.upper) for s in start]
    trial = [xi.copy() for xi in x]
    cost, f0, J = [math.inf] * k, [None] * k, [None] * k
    lam, steps, done = [1e-3] * k, [0] * k, [False] * k
    while not all(done):
        act = [f for f in range(k) if not done[f]]
        last = [steps[f] >= max_steps for f in act]
        evals = _fold_jacobians(problem, [fps[f] for f in act], [trial[f] for f in act], not all(last))
        for f, (r, Jf) in zip(act, evals):
            c = float(np.sum(r ** 2))
            dz_last = (trial[f] - x[f]) / problem.scale
            small = steps[f] > 0 and float(np.max(np.abs(dz_last), initial=0.0)) < REFIT_XTOL
            if c < cost[f]:  # kept
                drop = (cost[f] - c) / cost[f] if math.isfinite(cost[f]) else math.inf
                x[f], cost[f], f0[f], J[f] = trial[f], c, r, Jf
                lam[f] = max(lam[f] / 3, 1e-6)
                small = small or drop < REFIT_FTOL
            else:  # undone: step again from the kept point, damped more
                lam[f] *= 10
            if small or steps[f] >= max_steps or J[f].shape[1] == 0 or not J[f].any():
                done[f] = True
                continue
            dz = damped_step(J[f], f0[f], lam[f])
            trial[f] = np.clip(x[f] + dz * problem.scale, problem.lower, problem.upper)
            steps[f] += 1
    return x


def _polish_folds(problem: Problem, folds: list[Fold], start: list[np.ndarray]) -> list[np.ndarray]:
    """Per-fold fits of a candidate with rough parameters, estimated like the all-runs fit: on
    each fold's training samples, a trust-region fit from the fold's start
    (:data:`CONFIRM_NFEV` evaluations; its own tests ``xtol`` 1e-3, ``ftol`` 1e-4), then
    :meth:`Problem.polish` (the basin of the rough parameters)."""
    out = []
    for fold, x0 in zip(folds, start):
        pf, _ = _fold_problem(problem, fold)
        fit = pf.polish(pf.fit(np.asarray(x0, float), None, max_nfev=CONFIRM_NFEV))
        problem.nsim += pf.nsim
        problem.unstable += pf.unstable
        out.append(fit.x)
    return out


#: The candidate of a round that adds no effect: the set accepted so far, fitted and scored like
#: every candidate, the reference of the round's shares (:func:`score_round`).
NULL = "(no new effect)"
#: Length [s] of the short records on which every candidate is prescreened (1 s: a step edge and
#: its settling, or 1.5-3.5 cycles of a 1.5-3.5 Hz sine from the start; half of an Omni bank
#: run, a sixth of a paper-campaign sine, a fifth of a geared-servo bank run).  In seconds, not
#: logged samples: a log at 50 Hz holds 1 s in 50 samples, and the replay's cost is its control
#: periods.
PRESCREEN_S = 1.0
#: Candidates (best on the short records) that go on to the held-out screening on all samples.
N_SCREEN = 4
#: Lockstep Gauss-Newton iterations of the prescreen.
PRESCREEN_ITERATIONS = 3


@dataclass
class Prescreened:
    """A candidate fitted on the short records: its free effects, start, end point (the
    elementwise median of its folds' points), gap [rad] (the mean of its folds' training gaps)
    and each fold's point (``fold_x``, found on that fold's training samples only)."""

    name: str
    effects: list
    x_start: np.ndarray
    x: np.ndarray
    gap: float
    unstable: int = 0
    fold_x: list = field(default_factory=list, repr=False)


def fold_grid_starts(problem: Problem, folds: list[Fold], starts: list, grid_from: int = 0,
                     seconds: float = PRESCREEN_S) -> list[np.ndarray]:
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


def prescreen(builder, accepted: list, accepted_x: np.ndarray, names: list[str],
              runs: list[ReplayRun], rep,
              seconds: float = PRESCREEN_S, iterations: int = PRESCREEN_ITERATIONS,
              log=None, jobs: list | None = None, folds: list | None = None) -> list[Prescreened]:
    """Fit every candidate coarsely on short records of each fold's training samples; best
    first (by the mean over folds of the training gap: no held-out sample ranks a candidate).

    Per fold (:func:`fold_records`), all candidates advance together: their grid points form
    one batch (per group of models that can share one, :meth:`Replayer.simulate_grouped`),
    then each Gauss-Newton iteration simulates every candidate's point and its
    finite-difference perturbations in one batch and each candidate takes its own damped step.
    Each fold's point starts the candidate's fits for that fold.  The best :data:`N_SCREEN`
    go on to the held-out screening.

    ``jobs``: (base effects, their values, candidate name) per candidate -- several bases
    scored in one lockstep (the beam of :func:`score_round`); by default every name on
    ``accepted``.  A base's values are one array, or a list of one per fold (the base's own
    fold fits: the fold's start never saw its held-out samples).  ``folds`` None: one pass on
    the first ``seconds`` of every run.
    """
    t0 = time.perf_counter()
    beam = jobs is not None and not any(n is None for _, _, n in jobs)
    jobs = [(list(accepted), accepted_x, n) for n in names] if jobs is None else jobs
    labels = ["+".join([e.name for e in b] + [n]) if beam and n is not None else (n or NULL)
              for b, _, n in jobs]
    per_fold = [_prescreen_fold(builder, jobs, rep, fold_records(runs, fold, seconds), f, iterations)
                for f, fold in enumerate(folds or [None])]
    out = []
    for c, name in enumerate(labels):
        res = [pf[c] for pf in per_fold]  # (effects, x_start, x, gap, unstable) per fold
        xs = [r[2] for r in res]
        out.append(Prescreened(name, res[0][0], res[0][1], np.median(xs, axis=0), float(np.mean([r[3] for r in res])),
                               sum(r[4] for r in res), xs))
    out.sort(key=lambda c: c.gap)
    if log:
        log(f"  prescreen of {len(labels)} candidates on {seconds:g} s records: "
            f"{time.perf_counter() - t0:.1f} s; best " + ", ".join(f"{c.name} ({c.gap:.2e})" for c in out[:N_SCREEN]))
    return out


def _prescreen_fold(builder, jobs: list, rep, records: tuple, f: int, iterations: int) -> list[tuple]:
    """The prescreen on one fold's short records (``records``: runs and training masks): per
    job, ``(effects, start, best point, its training gap, unstable replays)``."""
    short, masks = records
    probs, x0s, grids, owner = [], [], [], []
    for c, (base, base_x, name) in enumerate(jobs):
        bx = base_x[f] if isinstance(base_x, (list, tuple)) else base_x
        prob, x0, per_base = _candidate_grid(builder, base, bx, name, short, rep, masks)
        x0s.append(x0)
        for pts in per_base:  # one start per base: each is stepped from its own best grid point
            probs.append(prob)
            grids.append(pts)
            owner.append(c)
    best_gap, starts = zip(*_grid_minima(rep, probs, grids, short))
    best_x, best_gap = _lockstep_gauss_newton(rep, probs, list(starts), list(best_gap), short, iterations)
    out = []
    for c in range(len(jobs)):
        k = min((i for i in range(len(owner)) if owner[i] == c), key=lambda i: best_gap[i])
        out.append((probs[k].free, x0s[c], best_x[k], best_gap[k], probs[k].unstable))
    return out


def _candidate_grid(builder, base: list, base_x: np.ndarray, name: str, runs: list[ReplayRun],
                    rep, masks: list | None = None) -> tuple[Problem, np.ndarray, list[np.ndarray]]:
    """The problem of ``base`` + candidate ``name`` on ``runs``, its start (``base_x``, the
    candidate at its nominal values) and its starting grids, one per base point: the
    candidate's grid with the base at ``base_x`` followed by the start itself, and, when the
    model's own values of the base differ from ``base_x``, the candidate's grid with the base
    there.  ``name`` None: the base alone (:data:`NULL`), from ``base_x``.  ``masks``: the
    samples of each run the problem's objective uses (:class:`Problem`).

    Why a second grid from the model's own values: ``base_x`` holds the corrections fitted
    *without* the candidate, which stand in for it where they can (on the bank's
    load_friction_nominal_off runs the torque gain drops 11 % to mimic the gearbox's drive
    losses); from there every grid point of the missing effect is worse than none and the
    prescreen's Gauss-Newton steps point its coefficient below its bound, while the steps from
    the best grid point about the user's values reach the truth (docs/method/discrepancy.md, "Why the
    load law is blended, and why the prescreen starts twice")."""
    if name is None:
        prob = Problem(builder, [], list(base), runs, rep, masks=masks)
        x0 = np.clip(np.asarray(base_x, float), prob.lower, prob.upper)
        return prob, x0, [[x0]]
    eff = builder.effect(name)
    prob = Problem(builder, [], list(base) + [eff], runs, rep, masks=masks)
    x0 = np.clip(np.concatenate([np.asarray(base_x, float), builder.nominal_values(eff)]),
                 prob.lower, prob.upper)
    i0 = len(x0) - eff.nparam
    bases = [x0]
    own = np.clip(np.concatenate([builder.nominal_values(e) for e in base] + [x0[i0:]]), prob.lower, prob.upper)
    if not np.array_equal(own, x0):
        bases.append(own)
    grids = []
    for b in bases:
        pts = []
        for g in eff.grid(x0[i0:]):
            xp = b.copy()
            xp[i0:] = eff.clip(np.asarray(g, float))
            pts.append(xp)
        grids.append(pts)
    grids[0].append(x0)
    return prob, x0, grids


def _grid_minima(rep, probs: list[Problem], grids: list[list[np.ndarray]],
                 runs: list[ReplayRun]) -> list[tuple[float, np.ndarray]]:
    """Each problem's best grid point on ``runs`` and its gap on the problem's samples
    (:meth:`Problem.used`), ``(gap, point)``: every point of every grid simulated together (one batch per group of models that can share one)."""
    nr = len(runs)
    models, pairs = [], []
    for prob, pts in zip(probs, grids):
        for x in pts:
            models.append(prob.model(x))
            pairs += [(len(models) - 1, j) for j in range(nr)]
    th = rep.simulate_grouped(models, runs, pairs)
    out, m = [], 0
    for prob, pts in zip(probs, grids):
        gaps = []
        for _ in pts:
            res = [th[m * nr + j] - runs[j].theta for j in range(nr)]
            prob.unstable += unstable_count(res)
            gaps.append(gap(prob.used(res)))
            m += 1
        i = int(np.argmin(gaps))
        out.append((gaps[i], pts[i].copy()))
    return out


def _lockstep_gauss_newton(rep, probs: list[Problem], starts: list[np.ndarray], best_gap: list[float],
                           runs: list[ReplayRun], iterations: int) -> tuple[list, list]:
    """Damped Gauss-Newton from each candidate's start (its best grid point, gap ``best_gap``),
    all candidates in lockstep: each iteration evaluates every candidate's point and its
    perturbations in one batch; a step that made the gap worse is undone and the damping
    raised.  Returns each candidate's best point and its gap."""
    nr = len(runs)
    xs = [x.copy() for x in starts]
    best_x = [x.copy() for x in starts]
    lam = [1e-3] * len(xs)
    for it in range(iterations + 1):
        last = it == iterations  # the last pass only scores the last step's end points
        models, pairs, spans = [], [], []
        for c, x in enumerate(xs):
            pts, h = ([x], []) if last else probs[c].perturbed(x)
            first = len(models)
            for xp in pts:
                models.append(probs[c].model(xp))
                pairs += [(len(models) - 1, j) for j in range(nr)]
            spans.append((first, h))
        th = rep.simulate_grouped(models, runs, pairs)
        for c, (first, h) in enumerate(spans):
            prob = probs[c]
            raws = [[th[(first + i) * nr + j] - runs[j].theta for j in range(nr)]
                    for i in range(len(h) + 1)]
            prob.unstable += sum(unstable_count(raw) for raw in raws)
            g0 = gap(prob.used(raws[0]))
            if g0 <= best_gap[c]:
                best_gap[c], best_x[c] = g0, xs[c].copy()
                lam[c] = max(lam[c] / 3, 1e-6)
            else:
                lam[c] *= 10
            if last:
                continue
            if g0 > best_gap[c]:  # this point is worse: step again from the best one, damped more
                xs[c] = best_x[c].copy()
                continue
            f0, J = prob.jacobian(raws, h)
            dz = damped_step(J * prob.scale, f0, lam[c])
            xs[c] = np.clip(xs[c] + dz * prob.scale, prob.lower, prob.upper)
    return best_x, best_gap


#: Length [s] of the records on which the pairs' starting grids are evaluated (a coarse start
#: only; 0.7 s, 700 samples of the Omni's 1 kHz log).
PAIR_GRID_S = 0.7
#: Pairs (best by their grid) fitted and screened; the best ``n_confirm`` of them confirmed.
PAIR_FITS = 8
#: Points per effect of a pair's starting grid (each effect's grid thinned to this many).
PAIR_GRID_POINTS = 5
#: Pairs are searched when the best single candidate removes less than this share of the gap.
PAIR_SEARCH_SHARE = 0.5


def _thin(grid: np.ndarray, m: int) -> np.ndarray:
    """At most ``m`` points of a starting grid, spread over it (ends kept)."""
    if len(grid) <= m:
        return grid
    return grid[np.unique(np.round(np.linspace(0, len(grid) - 1, m)).astype(int))]


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


def member_runner_up(best: Scored, scored: list[Scored]) -> list[tuple[str | None, float]]:
    """For each member of the set ``best``: the best alternative and the margin.

    The alternative is the best other scored set (finite held-out gap) that does not hold the
    member; it is named by what it holds instead of the member (its members not in ``best``,
    joined by ``+``; ``None`` when it holds nothing else: the member dropped).  Margin =
    ``1 - best gap / alternative's gap``; 1.0 when no scored set lacks the member."""
    names = [e.name for e in best.effects]
    out = []
    for m in names:
        alt = [s for s in scored if s is not best and math.isfinite(s.heldout_gap)
               and m not in [e.name for e in s.effects]]
        if not alt:
            out.append((None, 1.0))
            continue
        a = min(alt, key=lambda s: s.heldout_gap)
        instead = [e.name for e in a.effects if e.name not in names]
        out.append(("+".join(instead) if instead else None, share_of(best.heldout_gap, a.heldout_gap)))
    return out


@dataclass
class Scorer:
    """Scores sets of effects on held-out samples: what every score of the search shares.

    One round's candidates (:meth:`score_round`: prescreen, screening fits, held-out scoring,
    confirmation of the best), pairs fitted jointly (:meth:`score_pairs`), a given set
    (:meth:`score_set`), a set without each of its members (:meth:`score_removals`) and a
    set's fit on other folds (:meth:`rescore`).

    Attributes
    ----------
    builder : discrepancy.effects.ModelBuilder
        The nominal model and the library (effects by name, nominal values, compiled models).
    runs : list of ReplayRun
        The runs the fits use.
    rep : discrepancy.replay.Replayer
        Simulates models on runs.
    folds : list of Fold
        The held-out folds of ``runs`` (:func:`make_folds`).
    log : callable, optional
        ``log(line)``: each candidate's scores as they come.
    """

    builder: object
    runs: list
    rep: object
    folds: list
    log: object = None

    def on(self, folds: list[Fold]) -> "Scorer":
        """This scorer on other ``folds`` (the same runs)."""
        return dataclasses.replace(self, folds=folds)

    def problem(self, effects: list, runs: list[ReplayRun] | None = None) -> Problem:
        """The least-squares problem of ``effects`` free on ``runs`` (default: all the runs)."""
        return Problem(self.builder, [], effects, self.runs if runs is None else runs, self.rep)

    # -- one round ---------------------------------------------------------------------------------
    def score_round(self, accepted: list, accepted_x: np.ndarray, gap_start: float, *,
                    candidates: tuple[str, ...] | None = None, bases: list | None = None,
                    n_confirm: int = N_CONFIRM, screen_nfev: int = 4, n_screen: int | None = None,
                    prescreen_s: float | None = None, accepted_fold_x: list | None = None) -> list[Scored]:
        """Fit and score every candidate not yet accepted; best first.

        With ``bases`` (a beam: several sets of effects with their fitted values, e.g. the pairs
        the pair search confirmed), every candidate is added to every base it is not in, all of
        them prescreened in one lockstep; the scored sets are named ``"a+b+c"`` (base, then the
        candidate) and the best set wins, whichever base it grew from.

        Parameters
        ----------
        accepted, accepted_x : list of Effect, ndarray
            Effects accepted in earlier rounds and their fitted values (free again in this round).
        accepted_fold_x : list of ndarray, optional
            The accepted effects' own fold fits, one per fold: each fold's fits start there
            (default ``accepted_x`` for every fold, for a set given without fold fits).
        gap_start : float [rad]
            Held-out gap of the model the round starts from.
        candidates : tuple of str, optional
            Library names to try (default: all).
        n_confirm : int
            Candidates refitted exactly per fold after screening.
        screen_nfev : int
            Least-squares evaluations of the screening fit (the confirmed candidates are then
            fitted to convergence).
        n_screen : int
            Candidates, best on the short records (:func:`prescreen`), that are fitted on all runs
            and scored on held-out runs (default :data:`N_SCREEN`); the others keep their prescreen.
        prescreen_s : float [s]
            Length of the prescreen's short records (default :data:`PRESCREEN_S`).
        """
        names = [n for n in (candidates or self.builder.names) if n not in [e.name for e in accepted]]
        acc_x = list(accepted_fold_x) if accepted_fold_x is not None else accepted_x
        jobs = None
        if bases:
            jobs = [(list(b), bx, n) for b, bx in bases for n in (candidates or self.builder.names)
                    if n not in [e.name for e in b]]
        if accepted and not bases:  # the set so far, fitted and scored exactly as every candidate
            jobs = [(list(accepted), acc_x, n) for n in names] + [(list(accepted), acc_x, None)]
        pre = prescreen(self.builder, accepted, acc_x, names, self.runs, self.rep,
                        seconds=PRESCREEN_S if prescreen_s is None else prescreen_s, log=self.log, jobs=jobs,
                        folds=self.folds)
        scored = self._screen_all(pre, gap_start, N_SCREEN if n_screen is None else n_screen,
                                  screen_nfev=screen_nfev, width=36 if bases else 18)
        null = [sc for sc in scored if sc.name == NULL]
        if not null:
            return self._confirm_best(scored, gap_start, n_confirm)
        # the set so far is always confirmed, and each share is against its held-out gap: a
        # candidate must beat the set re-fitted with the same effort, not the set as the last
        # round left it
        self._confirm(null[0], gap_start)
        out = self._confirm_best([sc for sc in scored if sc.name != NULL], gap_start, n_confirm)
        for sc in out + null:
            sc.share = share_of(sc.heldout_gap, null[0].heldout_gap)
        return sorted(out + null, key=lambda sc: sc.heldout_gap)

    def _screen_all(self, pre: list[Prescreened], gap_start: float, n_screen: int, *,
                    screen_nfev: int, width: int) -> list[Scored]:
        """The prescreened candidates scored: the ``n_screen`` best (and :data:`NULL`) fitted on
        all runs and screened on held-out samples, the others with their prescreen only."""
        keep = {c.name for c in [c for c in pre if c.name != NULL][:n_screen]} | {NULL}
        scored: list[Scored] = []
        for c in pre:
            if c.name not in keep:
                # not among the n_screen best on the short records: scored there only
                scored.append(Scored(c.name, c.effects, FitResult(c.effects, c.x, c.x_start, c.gap), math.inf,
                                     -math.inf, "prescreen", prescreen_gap=c.gap, unstable=c.unstable))
                continue
            t0 = time.perf_counter()
            prob = self.problem(c.effects)
            # a screening fit only ranks the candidates (the best are confirmed with full fits):
            # the start's Jacobian serves its few steps
            fit = prob.fit(c.x, None, max_nfev=screen_nfev, chord=True)
            sc = self._screened(c.name, c.effects, prob, fit, gap_start, c.fold_x, t0=t0, width=width)
            sc.prescreen_gap = c.gap
            sc.unstable += c.unstable
            scored.append(sc)
        return scored

    # -- screening and confirmation --------------------------------------------------------------
    def _screened(self, name: str, effects: list, prob: Problem, fit: FitResult, gap_start: float,
                  starts: list, *, t0: float | None = None, width: int = 18) -> Scored:
        """Score a set of effects on held-out samples: each fold's parameters by
        :data:`SCREEN_STEPS` Gauss-Newton steps on its training samples from ``starts[f]``
        (found without the fold's held-out samples); ``fit`` (all runs) is kept as the set's
        fitted values, never used for a held-out score; ``t0``: when its scoring began (for its
        ``seconds``; default now)."""
        t0 = time.perf_counter() if t0 is None else t0
        fold_x = _refit_folds(prob, self.folds, starts, max_steps=SCREEN_STEPS)
        raw = _heldout(prob, fold_x, self.folds)
        g = gap(raw)
        s = Scored(name, effects, fit, g, share_of(g, gap_start), "screen", raw, fold_x, self.folds,
                   time.perf_counter() - t0, unstable=prob.unstable)
        if self.log:
            self.log(f"  {name:{width}s} screen held-out gap {g:.3e} rad (share {s.share:+.2f}) "
                     f"x={np.array2string(fit.x, precision=4)} [{s.seconds:.1f} s]")
        return s

    def _confirm_best(self, scored: list[Scored], gap_start: float, n_confirm: int) -> list[Scored]:
        """Confirm the ``n_confirm`` best screened candidates with exact refits; best first."""
        scored.sort(key=lambda s: s.heldout_gap)
        for s in scored[:n_confirm]:
            self._confirm(s, gap_start)
        confirmed = sorted(scored[:n_confirm], key=lambda s: s.heldout_gap)
        return confirmed + scored[n_confirm:]

    def _confirm(self, s: Scored, gap_start: float, nfev: int | None = None) -> None:
        """Converge the all-runs fit of ``s`` and score it with exact per-fold refits (in place)."""
        t0 = time.perf_counter()
        prob = self.problem(s.effects)
        # the screening fit already simulated its end point (same model, runs and effects): the
        # converging fit starts there without simulating it again
        prob.seed(s.fit)
        s.fit = prob.fit(s.fit.x, None, max_nfev=nfev or CONFIRM_NFEV)  # converge the all-runs fit
        # a rough parameter (a backlash's slack): the trust-region fit stops in a jagged local
        # minimum wherever it started; the basin search moves it to the basin's centre
        s.fit = prob.polish(s.fit)
        # each fold goes on from its screening point (never from the all-runs fit, which saw
        # the fold's held-out samples) to convergence on its training samples
        if rough(s.effects):
            # the folds are estimated the same way (so the jackknife sees the estimator's spread)
            s.fold_x = _polish_folds(prob, self.folds, s.fold_x)
        else:
            s.fold_x = _refit_folds(prob, self.folds, s.fold_x)
        s.heldout_raw = _heldout(prob, s.fold_x, self.folds)
        s.heldout_gap = gap(s.heldout_raw)
        s.share = share_of(s.heldout_gap, gap_start)
        s.method = "refit"
        s.unstable += prob.unstable
        s.seconds += time.perf_counter() - t0
        if self.log:
            self.log(f"  {s.name:18s} refit  held-out gap {s.heldout_gap:.3e} rad (share {s.share:+.2f})")

    # -- pairs -----------------------------------------------------------------------------------
    def score_pairs(self, gap_start: float, *, candidates: tuple[str, ...] | None = None,
                    n_confirm: int = N_CONFIRM, n_fit: int = PAIR_FITS, grid_s: float = PAIR_GRID_S,
                    screen_nfev: int = 8, grid_points: int = PAIR_GRID_POINTS) -> list[Scored]:
        """Fit and score *pairs* of candidates jointly; best first.

        Two effects can mask each other: a loop delay takes damping away, dry friction adds it,
        so neither alone explains the data (fitted alone, the delay even stays at zero) while
        together they explain it down to the noise.  One effect at a time, as
        :meth:`score_round` adds them, cannot find such a pair.  Here every pair starts from the
        best point of the product of the two effects' grids (each thinned to ``grid_points``),
        all pairs' grid points simulated together on each fold's training samples of the first
        ``grid_s`` seconds of each run (each fold's fits start from its own grid best);
        the ``n_fit`` best pairs are fitted on all runs and screened on held-out samples like the
        single candidates, and the best ``n_confirm`` are confirmed with exact per-fold refits.
        """
        starts = self._pair_starts(candidates or self.builder.names, grid_s, grid_points, n_fit)
        scored = []
        for _, a, b, x0, fold_x0 in starts[:n_fit]:
            t0 = time.perf_counter()
            effects = [self.builder.effect(a), self.builder.effect(b)]
            prob = self.problem(effects)
            fit = prob.fit(x0, None, max_nfev=screen_nfev)
            scored.append(self._screened(f"{a}+{b}", effects, prob, fit, gap_start, fold_x0, t0=t0, width=36))
        return self._confirm_best(scored, gap_start, n_confirm)

    def _pair_starts(self, names, grid_s: float, grid_points: int, n_fit: int) -> list[tuple]:
        """Every pair of ``names`` at the best point of its grid on each fold's training samples
        of the first ``grid_s`` seconds (:func:`fold_records`): ``(mean gap over folds, a, b,
        median point, each fold's point)``, best first (the ``n_fit`` best logged)."""
        builder = self.builder
        t0 = time.perf_counter()
        combos = list(itertools.combinations(names, 2))
        per_fold = []
        for fold in self.folds:
            grid_runs, masks = fold_records(self.runs, fold, grid_s)
            probs, grids = [], []
            for a, b in combos:
                effects = [builder.effect(a), builder.effect(b)]
                prob = Problem(builder, [], effects, grid_runs, self.rep, masks=masks)
                ga = _thin(effects[0].grid(builder.nominal_values(effects[0])), grid_points)
                gb = _thin(effects[1].grid(builder.nominal_values(effects[1])), grid_points)
                x0 = np.concatenate([builder.nominal_values(e) for e in effects])
                grids.append([np.clip(np.concatenate([effects[0].clip(np.asarray(u, float)),
                                                      effects[1].clip(np.asarray(v, float))]), prob.lower, prob.upper)
                              for u in ga for v in gb] + [np.clip(x0, prob.lower, prob.upper)])
                probs.append(prob)
            per_fold.append(_grid_minima(self.rep, probs, grids, grid_runs))
        starts = []
        for c, (a, b) in enumerate(combos):
            xs = [pf[c][1] for pf in per_fold]
            starts.append((float(np.mean([pf[c][0] for pf in per_fold])), a, b, np.median(xs, axis=0), xs))
        starts.sort(key=lambda t: t[0])
        if self.log:
            self.log(f"  pair grids: {len(starts)} pairs on {len(self.folds)} folds in {time.perf_counter() - t0:.1f} s; "
                     "best " + ", ".join(f"{a}+{b} ({g:.2e})" for g, a, b, _, _ in starts[:n_fit]))
        return starts

    # -- given sets ------------------------------------------------------------------------------
    def score_set(self, name: str, effects: list, x0: np.ndarray, gap_start: float) -> Scored:
        """Fit a given set of effects from ``x0`` on all runs and score it held out like a
        confirmed candidate (exact per-fold refits): e.g. the nominal's corrections alone, the
        start every named effect must beat."""
        t0 = time.perf_counter()
        prob = self.problem(effects)
        fit = prob.fit(np.asarray(x0, float), None, max_nfev=8)
        # every fold starts from x0 (the user's values: no data seen)
        sc = self._screened(name, effects, prob, fit, gap_start, [np.asarray(x0, float)] * len(self.folds),
                            t0=t0)
        self._confirm(sc, gap_start)
        return sc

    def rescore(self, s: Scored, gap_start: float, starts: list | None = None, grid_from: int = 0) -> Scored:
        """``s``'s set of effects scored held out on this scorer's folds (per-fold refits to
        convergence; the all-runs fit is kept): e.g. the named set under the fold scheme the
        verdict did not use (:meth:`on`).  Each fold starts from ``starts[f]`` (default the
        builder's nominal values of every effect: no data seen), the effects from index
        ``grid_from`` on moved to their grid's best point on the fold's training samples
        (:func:`fold_grid_starts`)."""
        prob = self.problem(s.effects)
        if starts is None:
            x0 = np.clip(np.concatenate([self.builder.nominal_values(e) for e in s.effects]), prob.lower, prob.upper)
            starts = [x0] * len(self.folds)
        starts = fold_grid_starts(prob, self.folds, starts, grid_from)
        fold_x = (_polish_folds(prob, self.folds, starts) if rough(s.effects)
                  else _refit_folds(prob, self.folds, starts))
        raw = _heldout(prob, fold_x, self.folds)
        g = gap(raw)
        return Scored(s.name, s.effects, s.fit, g, share_of(g, gap_start), "refit", raw, fold_x, self.folds,
                      unstable=prob.unstable)

    def score_removals(self, best: Scored, gap_start: float, keep: tuple[str, ...] = ()) -> list[Scored]:
        """The backward step of floating selection: ``best`` without each of its members,
        refitted jointly from ``best``'s values and scored like a confirmed candidate (exact
        per-fold refits on ``best``'s folds); best first.

        A member whose removal leaves a held-out gap that the full set lowers by less than
        :data:`MIN_SHARE` removes no clear share of the gap: a stand-in accepted early (a spring
        fitted with Coulomb friction to part of a backlash's gap) that a later member made
        redundant.  The caller drops it.  Members named in ``keep`` (the nominal's corrections)
        are never removed."""
        scorer = self.on(best.folds)
        out = []
        for m in range(len(best.effects)):
            if best.effects[m].name in keep:
                continue
            effects = [e for i, e in enumerate(best.effects) if i != m]
            x0 = np.concatenate([x for i, (_, x) in enumerate(best.fit.split()) if i != m])
            # each fold starts from best's own fold fit without the member
            starts = [np.concatenate([x for i, x in enumerate(_values(best.effects, fx)) if i != m])
                      for fx in best.fold_x]
            t0 = time.perf_counter()
            prob = scorer.problem(effects)
            fit = prob.fit(x0, None, max_nfev=8)
            sc = scorer._screened("+".join(e.name for e in effects), effects, prob, fit, gap_start, starts,
                                  t0=t0, width=36)
            scorer._confirm(sc, gap_start)
            out.append(sc)
        out.sort(key=lambda s: s.heldout_gap)
        return out

