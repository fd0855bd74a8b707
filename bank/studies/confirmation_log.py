"""The evidence for the confirmation gate (:data:`discrepancy.select.CONFIRM_WITHIN`): every
confirmation of a bank case's search, with every runner-up refitted (the gate off), logged with
the screen's and the refits' held-out gaps of the candidates it confirmed.

:func:`case_log` runs one case of :data:`bank.hidden.CASES` as the bank does
(:func:`discrepancy.workflow.run_discrepancy` on its runs and nominal) and records, at each call
of the scorer's confirmation, the screened candidates best first (name, screen held-out gap,
method) and the refitted gap of each confirmed one.  :func:`summary` reads the record as the
gate would: for each confirmation of two, the runner-up's screen gap over the best's refitted
gap ``s2/r1``; a *violation* is a runner-up the gate would skip (``s2/r1 >=``
:data:`~discrepancy.select.CONFIRM_WITHIN`) that came within 1.25 times the best's gap after its
refit (``r2 < 1.25 r1``: a margin under twice the tie margin, the confidence "low").
"""

from __future__ import annotations

import math

from bank import hidden
from discrepancy import select as sel
from discrepancy import workflow as wf

#: The runner-up's refitted gap over the best's below which the confidence is "low": a margin
#: 1 - r1/r2 under 2 x TIE_MARGIN.
LOW_CONFIDENCE_RATIO = 1 / (1 - 2 * sel.TIE_MARGIN)


def case_log(name: str) -> dict:
    """One bank case's confirmations with every runner-up refitted (see the module)."""
    log = []
    orig = sel.Scorer.confirm_best

    def confirm_best(self, scored, gap_start, n_confirm, within=None):  # within: the caller's, overridden
        scored = sorted(scored, key=lambda s: s.heldout_gap)
        screen = [[s.name, s.heldout_gap, s.method] for s in scored]
        out = orig(self, scored, gap_start, n_confirm, within=math.inf)
        log.append({"gap_start": gap_start, "n_confirm": n_confirm, "screened": screen,
                    "refit": {s.name: s.heldout_gap for s in out if s.method == "refit"}})
        return out

    case = hidden.case(name)
    model, target = hidden.nominal(case)
    sel.Scorer.confirm_best = confirm_best
    try:
        rep = wf.run_discrepancy(hidden.generate(case), model, target=target).report
    finally:
        sel.Scorer.confirm_best = orig
    return {"case": name, "assess": list(hidden.assess(case, rep)), "steps": rep["timings"]["physics_steps"],
            "confirmations": log}


def summary(cases: list[dict], within: float = sel.CONFIRM_WITHIN) -> dict:
    """The gate read on the record (see the module): every confirmation of two as
    ``(case, best, runner-up, s1, r1, s2, r2)``; how many runner-ups the screen put at ``within``
    times the best's refitted gap or more (``far``: the gate skips those, the pair search's
    aside), the violations among them, their smallest ``r2/r1``, and the smallest ``r2/s2`` (a
    refit below its screen)."""
    events = []
    for c in cases:
        for k in c["confirmations"]:
            top = k["screened"][:k["n_confirm"]]
            if len(top) < 2:
                continue
            (n1, s1, _), (n2, s2, _) = top[0], top[1]
            r1, r2 = k["refit"][n1], k["refit"][n2]
            events.append({"case": c["case"], "best": n1, "runner_up": n2, "s1": s1, "r1": r1, "s2": s2, "r2": r2})
    far = [e for e in events if e["s2"] >= within * e["r1"]]
    violations = [e for e in far if e["r2"] < LOW_CONFIDENCE_RATIO * e["r1"]]
    worst = min(events, key=lambda e: e["r2"] / e["s2"])
    return {"confirmations_of_two": len(events), "far": len(far), "violations": len(violations),
            "closest_far_r2_over_r1": min(e["r2"] / e["r1"] for e in far),
            "lowest_r2_over_s2": worst["r2"] / worst["s2"], "lowest_r2_over_s2_at": worst,
            "events": events}
