"""Which of a family's nested variants to keep: a rule fixed before any result was seen.

The friction family (:mod:`discrepancy.effects.family`) is one law with nested variants: a
richer variant holds its parent's parameters and more, so on the training data it never fits
worse.  Held-out runs judge it fairly, but a held-out gap is still an estimate: a variant whose
extra parameters fit nothing real scores within chance of its parent, now a little better, now
a little worse.  The rule keeps the simplest variant the held-out data cannot tell from the
best one.

The rule (:func:`choose_variant`), written down with the family, before any variant was
scored on any data, and not to be tuned on results:

1. ``best`` = the variant with the lowest mean held-out gap over the held-out runs.
2. A variant *ties* the best when its mean exceeds the best's by no more than
   ``max(SE, TIE_SHARE * mean_best)``, with ``SE`` the standard error of the two variants'
   per-run difference (paired: the same runs; ``std(d, ddof=1) / sqrt(R)``, 0 for one run).
3. Of the tying variants (the best among them), keep the one with the fewest parameters;
   equal counts: the lower mean gap, then the caller's order.

Why these two thresholds, from first principles rather than from results:

* one standard error: the one-standard-error rule of model selection by cross-validation
  (Breiman, Friedman, Olshen and Stone 1984, *Classification and Regression Trees*; Hastie,
  Tibshirani and Friedman, *The Elements of Statistical Learning*, 2nd ed., section 7.10): a
  difference smaller than the run-to-run spread of the difference is not evidence, so the
  parsimonious variant stands.  Paired over the same runs, since the runs' own difficulty is
  shared by both variants and cancels;
* a share of the gap, :data:`TIE_SHARE` = 0.1: the project's own definition of two candidates
  that "explain the data equally well" (``discrepancy.select.TIE_MARGIN``, a held-out gap
  within 10 % of the other's), so a variant must buy more than what the workflow already calls
  a tie.  It also holds when the runs agree too well for the SE to mean anything (an extra
  parameter that shaves 1 % off every run is consistent but not worth naming).

The complexity is counted in free parameters (``Effect.nparam``); the rule penalises it only
through the order in step 3, never by a weight that would need tuning.  It is pure (no MuJoCo,
no state): the search calls it with the variants' held-out gaps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

#: A richer variant must lower the best tying mean held-out gap by more than this share of it
#: (the workflow's tie margin, ``discrepancy.select.TIE_MARGIN``).
TIE_SHARE = 0.1


def choose_variant(scores: Mapping[str, Sequence[float]], complexity: Mapping[str, int]) -> str:
    """The variant to keep among nested variants scored on the same held-out runs.

    Parameters
    ----------
    scores : mapping
        ``{variant name: its held-out gap [rad] on each held-out run}``, the runs in the same
        order for every variant.  A non-finite gap (an unstable replay, a failed fit) makes the
        variant's mean infinite: it never ties a finite best.
    complexity : mapping
        ``{variant name: number of free parameters}`` (e.g.
        :data:`discrepancy.effects.family.COMPLEXITY`).

    Returns
    -------
    str
        The chosen variant (see the module docstring for the rule).

    Raises
    ------
    ValueError
        No scores, runs of different counts, no run at all, a variant without a complexity, or
        every variant non-finite.
    """
    if not scores:
        raise ValueError("no variant scored")
    names = list(scores)
    missing = [n for n in names if n not in complexity]
    if missing:
        raise ValueError(f"no complexity for variant(s) {', '.join(missing)}")
    gaps = {n: np.asarray(scores[n], dtype=float).ravel() for n in names}
    counts = {len(g) for g in gaps.values()}
    if len(counts) != 1 or 0 in counts:
        raise ValueError(f"every variant needs its gap on the same held-out runs, got counts {sorted(counts)}")
    mean = {n: (float(np.mean(g)) if np.all(np.isfinite(g)) else math.inf) for n, g in gaps.items()}
    best = min(names, key=lambda n: (mean[n], complexity[n], names.index(n)))
    if not math.isfinite(mean[best]):
        raise ValueError("every variant's held-out gap is non-finite")

    def ties(n: str) -> bool:
        if not math.isfinite(mean[n]):
            return False
        d = gaps[n] - gaps[best]
        se = float(np.std(d, ddof=1) / math.sqrt(len(d))) if len(d) > 1 else 0.0
        return mean[n] - mean[best] <= max(se, TIE_SHARE * mean[best])

    return min((n for n in names if ties(n)), key=lambda n: (complexity[n], mean[n], names.index(n)))
