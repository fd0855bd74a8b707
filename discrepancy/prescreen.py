"""The prescreen: every candidate fitted coarsely on short records, all in lockstep, to choose
the few the held-out screening scores; and the starting grids of pairs of effects.  Used by
:class:`discrepancy.select.Scorer`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .fit import Problem, damped_step, gap, unstable_count
from .runs import ReplayRun


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
    """A candidate fitted on the short records: its free effects, start, end point, gap [rad]."""

    name: str
    effects: list
    x_start: np.ndarray
    x: np.ndarray
    gap: float
    unstable: int = 0


def prescreen(builder, accepted: list, accepted_x: np.ndarray, names: list[str],
              runs: list[ReplayRun], rep,
              seconds: float = PRESCREEN_S, iterations: int = PRESCREEN_ITERATIONS,
              log=None, jobs: list | None = None, starts: dict | None = None,
              beam: bool = False) -> list[Prescreened]:
    """Fit every candidate coarsely on the first ``seconds`` of each run; best first.

    All candidates advance together: their grid points form one batch (per group of models
    that can share one, :meth:`Replayer.simulate_grouped`), then each Gauss-Newton iteration
    simulates every candidate's point and its finite-difference perturbations in one batch and
    each candidate takes its own damped step.  A candidate thus costs a few short-record
    batches, not a full campaign; the best :data:`N_SCREEN` go on to the held-out screening.

    ``jobs``: (base effects, their values, candidate name) per candidate (name None: the base
    alone, :data:`NULL`); by default every name on ``accepted``.  ``beam``: the jobs grow several
    bases in one lockstep (the beam of :meth:`~discrepancy.select.Scorer.score_round`), each
    labelled ``"base+name"``.  ``starts``: ``{name: values}``, a further grid point of candidate ``name``
    (its own parameters; e.g. its equation-error fit, :mod:`.shape`).
    """
    t0 = time.perf_counter()
    short = [r.first_seconds(seconds) for r in runs]
    jobs = [(list(accepted), accepted_x, n) for n in names] if jobs is None else jobs
    labels = ["+".join([e.name for e in b] + [n]) if beam and n is not None else (n or NULL)
              for b, _, n in jobs]
    probs, x0s, grids, owner = [], [], [], []
    for c, (base, base_x, name) in enumerate(jobs):
        prob, x0, per_base = _candidate_grid(builder, base, base_x, name, short, rep,
                                             (starts or {}).get(name))
        x0s.append(x0)
        for pts in per_base:  # one start per base: each is stepped from its own best grid point
            probs.append(prob)
            grids.append(pts)
            owner.append(c)
    best_gap, starts = zip(*grid_minima(rep, probs, grids, short))
    best_x, best_gap = lockstep_gauss_newton(rep, probs, list(starts), list(best_gap), short, iterations)
    out = []
    for c, name in enumerate(labels):
        k = min((i for i in range(len(owner)) if owner[i] == c), key=lambda i: best_gap[i])
        out.append(Prescreened(name, probs[k].free, x0s[c], best_x[k], best_gap[k], probs[k].unstable))
    out.sort(key=lambda c: c.gap)
    if log:
        log(f"  prescreen of {len(labels)} candidates on {seconds:g} s records: "
            f"{time.perf_counter() - t0:.1f} s; best " + ", ".join(f"{c.name} ({c.gap:.2e})" for c in out[:N_SCREEN]))
    return out


def _candidate_grid(builder, base: list, base_x: np.ndarray, name: str, runs: list[ReplayRun],
                    rep, start=None) -> tuple[Problem, np.ndarray, list[np.ndarray]]:
    """The problem of ``base`` + candidate ``name`` on ``runs``, its start (``base_x``, the
    candidate at its nominal values) and its starting grids, one per base point: the
    candidate's grid with the base at ``base_x`` followed by the start itself, and, when the
    model's own values of the base differ from ``base_x``, the candidate's grid with the base
    there.  ``name`` None: the base alone (:data:`NULL`), from ``base_x``.  ``start``: the
    candidate's values of one more point of the first grid (the base at ``base_x``).

    Why a second grid from the model's own values: ``base_x`` holds the corrections fitted
    *without* the candidate, which stand in for it where they can (on the bank's
    load_friction_nominal_off runs the torque gain drops 11 % to mimic the gearbox's drive
    losses); from there every grid point of the missing effect is worse than none and the
    prescreen's Gauss-Newton steps point its coefficient below its bound, while the steps from
    the best grid point about the user's values reach the truth (docs/method/discrepancy.md, "Why the
    load law is blended, and why the prescreen starts twice")."""
    if name is None:
        prob = Problem(builder, [], list(base), runs, rep)
        x0 = np.clip(np.asarray(base_x, float), prob.lower, prob.upper)
        return prob, x0, [[x0]]
    eff = builder.effect(name)
    prob = Problem(builder, [], list(base) + [eff], runs, rep)
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
    if start is not None:
        xp = x0.copy()
        xp[i0:] = eff.clip(np.asarray(start, float))
        grids[0].append(np.clip(xp, prob.lower, prob.upper))
    return prob, x0, grids


def grid_ranked(rep, probs: list[Problem], grids: list[list[np.ndarray]],
                runs: list[ReplayRun]) -> list[list[tuple[float, np.ndarray]]]:
    """Each problem's grid points on ``runs`` with their gaps, ``(gap, point)``, best first
    (a stable sort: equal gaps keep the grid's order): every point of every grid simulated
    together (one batch per group of models that can share one)."""
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
            gaps.append(gap(prob.used(res)))  # on the samples the problem uses (its masks)
            m += 1
        order = np.argsort(gaps, kind="stable")
        out.append([(gaps[i], pts[i].copy()) for i in order])
    return out


def grid_minima(rep, probs: list[Problem], grids: list[list[np.ndarray]],
                runs: list[ReplayRun]) -> list[tuple[float, np.ndarray]]:
    """Each problem's best grid point on ``runs`` and its gap, ``(gap, point)``
    (:func:`grid_ranked`'s first)."""
    return [ranked[0] for ranked in grid_ranked(rep, probs, grids, runs)]


def lockstep_gauss_newton(rep, probs: list[Problem], starts: list[np.ndarray], best_gap: list[float],
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
#: only; every pair's fit then runs on the whole records).  0.35 s: one step edge and its
#: settling at the Omni's ~3.4 Hz resonance, or half a cycle of a 1.5 Hz sine with its first
#: reversal; was 0.7 s, halved for the cost (the grid was the largest part of a pair case's
#: replays: 85 of 152 s of the bank's delay+friction case), the choice made before the bank was
#: run with it.
PAIR_GRID_S = 0.35
#: Pairs (best by their grid) fitted and screened; the best ``n_confirm`` of them confirmed.
PAIR_FITS = 8
#: Points per effect of a pair's starting grid (each effect's grid thinned to this many).
PAIR_GRID_POINTS = 5


def thin_grid(grid: np.ndarray, m: int) -> np.ndarray:
    """At most ``m`` points of a starting grid, spread over it (ends kept)."""
    if len(grid) <= m:
        return grid
    return grid[np.unique(np.round(np.linspace(0, len(grid) - 1, m)).astype(int))]
