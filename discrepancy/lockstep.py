"""Least squares of several problems in lockstep: every iteration one replay batch.

A fold's refit replays its ~10 training runs with one model per evaluation; the replay is bound
by its per-control-period Python, so such a batch costs nearly what a batch of 50 does
(measured on the bank's servo case: 0.126 M physics steps/s for batches of <= 12 trajectories,
0.37-0.44 M/s for 49 and more).  Here the folds (and the starts of a race) step together.

The iteration is a Levenberg-damped Gauss-Newton step in passes of chord steps, with a stated
convergence test: each pass takes the Jacobian at its start
(the point and its ``p`` forward-difference perturbations), then up to ``nfev - 1`` steps with
that Jacobian held (one replay each; a step that does not lower the cost is undone and the
damping raised tenfold, one that does lowers it threefold).  A pass ends when an accepted
step lowers the cost by less than ``FTOL`` of it or moves the point by less than ``XTOL``
(relative, scipy's step test), or its evaluations are spent; the problem has converged when a
pass from a fresh Jacobian that tried a step changed the cost by less than ``FTOL`` or moved the
point by less than ``XTOL``.  A problem whose replay goes unstable at a pass's start stops there,
unconverged.
"""

from __future__ import annotations

import numpy as np

from .fit import Problem, damped_step, unstable_count

FTOL = 1e-4
#: Trajectories per replay call at most (the memory of one batch grows with it).
MAX_BATCH = 96
#: Evaluations of a pass (its Jacobian, then up to ``NFEV - 1`` chord steps) and passes at most.
#: Why: a fold's refit from a good start took 4-5 trust-region evaluations with a fresh Jacobian
#: each (the bank's servo case, p = 4-6: 5-7 replays per evaluation); a held Jacobian costs one
#: replay per step.
NFEV = 6
PASSES = 6
XTOL = 1e-3


def _batch(rep, probs: list[Problem], points: list[list[np.ndarray]], run_sets: list[list[int]], runs) -> list:
    """Raw residuals of every problem's points, one replay batch: ``out[c][i]`` the residuals of
    problem ``c``'s point ``i`` on its runs (``run_sets[c]``: indices into ``runs``)."""
    models, pairs = [], []
    for c, pts in enumerate(points):
        for x in pts:
            models.append(probs[c].model(x))
            pairs += [(len(models) - 1, j) for j in run_sets[c]]
    th = []
    for k0 in range(0, len(pairs), MAX_BATCH):  # a model's runs may straddle two chunks: fine
        th += rep.simulate_grouped(models, runs, pairs[k0:k0 + MAX_BATCH])
    out, k = [], 0
    for c, pts in enumerate(points):
        raws = []
        for _ in pts:
            raw = [th[k + i] - runs[j].theta for i, j in enumerate(run_sets[c])]
            k += len(run_sets[c])
            probs[c].unstable += unstable_count(raw)
            raws.append(raw)
        probs[c].nsim += len(pts)
        out.append(raws)
    return out


def _cost(f: np.ndarray) -> float:
    return float(f @ f) if np.all(np.isfinite(f)) else np.inf


def lockstep_fit(rep, probs: list[Problem], run_sets: list[list[int]], runs, starts: list[np.ndarray],
                 passes: int = PASSES, nfev: int = NFEV) -> tuple[list[np.ndarray], list[float], list[bool]]:
    """Each problem fitted from its start, all in lockstep (module docstring); returns the end
    points, their costs and whether each converged.  ``probs[c]`` replays ``runs[j]`` for ``j``
    in ``run_sets[c]`` (in that order: the problem's own runs)."""
    n = len(probs)
    ok = [False] * n  # converged: a pass from a fresh Jacobian that tried a step changed little
    eps = [1e-9 * (p.upper - p.lower) for p in probs]
    x = [np.clip(np.asarray(s, float), p.lower + e, p.upper - e) for s, p, e in zip(starts, probs, eps)]
    cost = [np.inf] * n
    done = [False] * n
    lam = [1e-3] * n
    for _ in range(passes):
        active = [c for c in range(n) if not done[c]]
        if not active:
            break
        pert = {c: probs[c].perturbed(x[c]) for c in active}
        raws = _batch(rep, [probs[c] for c in active], [pert[c][0] for c in active],
                      [run_sets[c] for c in active], runs)
        J, f = {}, {}
        for c, r in zip(active, raws):
            f[c], J[c] = probs[c].jacobian(r, pert[c][1])
            cost[c] = _cost(f[c])
        x0 = {c: x[c].copy() for c in active}
        c0 = {c: cost[c] for c in active}
        for c in active:
            if not np.isfinite(cost[c]):  # its replay went unstable: stays where it is, unconverged
                done[c] = True
        stepping = [c for c in active if np.isfinite(cost[c])]
        tried = set(stepping) if nfev > 1 else set()  # a pass that tried no step proves nothing
        for _ in range(nfev - 1):
            if not stepping:
                break
            trial = {}
            for c in stepping:
                p = probs[c]
                dz = damped_step(J[c] * p.scale, f[c], lam[c])
                trial[c] = np.clip(x[c] + dz * p.scale, p.lower + eps[c], p.upper - eps[c])
            raws = _batch(rep, [probs[c] for c in stepping], [[trial[c]] for c in stepping],
                          [run_sets[c] for c in stepping], runs)
            still = []
            for c, r in zip(stepping, raws):
                ft = probs[c].weighted(r[0])
                ct = _cost(ft)
                if ct < cost[c]:
                    small = (cost[c] - ct <= FTOL * cost[c]
                             or np.linalg.norm(trial[c] - x[c]) <= XTOL * (XTOL + np.linalg.norm(trial[c])))
                    x[c], f[c], cost[c] = trial[c], ft, ct
                    lam[c] = max(lam[c] / 3, 1e-9)
                    if not small:
                        still.append(c)
                else:
                    lam[c] *= 10
                    if lam[c] < 1e6:
                        still.append(c)
            stepping = still
        for c in tried:
            if (c0[c] - cost[c] <= FTOL * c0[c]
                    or np.linalg.norm(x[c] - x0[c]) <= XTOL * (XTOL + np.linalg.norm(x[c]))):
                done[c] = ok[c] = True
    return x, cost, ok
