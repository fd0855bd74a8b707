"""The content of ``report.json``: a pure function of what the search found.

:func:`assemble_report` turns the nominal replay, the selection's record, the accepted set's
uncertainty, the held-out replay of the patched model and the gaps under both fold schemes
(:class:`Findings`) into the report's dict; :func:`sampling` describes how each run was logged
and replayed.  Nothing here simulates: the localisation of the gap before and after
(:mod:`.localise`) works on the replays it is given, and the effects' nominal values come from
the caller's :class:`~discrepancy.effects.ModelBuilder`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from identification.dataset import spacing

from . import select as sel
from . import uncertainty as un
from .fit import gap, split_values
from .localise import describe, localise
from .runs import ReplayRun
from .select import Scored

#: A correction that moves its parameter by more than this factor from the user's value is
#: flagged in the report (a 3x inertia change is a finding, not a correction).  This factor and
#: the parameter's bounds are the only checks behind a correction's ``plausible``: it does not
#: say the fitted value is right (its interval may exclude the true one).
PLAUSIBLE_FACTOR = 2.0


@dataclass
class Findings:
    """What the search found: all the report needs beside the runs and the settings.

    Attributes
    ----------
    nominal : NominalReplay
        The nominal model's replay (``theta``, ``gap``, ``noise``; :mod:`.workflow`).
    selection : Selection
        The forward selection's state and record (:class:`discrepancy.search.Selection`).
    uncertainty : dict or None
        The accepted set's uncertainty (:func:`discrepancy.uncertainty.uncertainty`; None with
        nothing accepted).
    theta_after : list of ndarray [rad]
        The held-out replay of the patched model (the nominal replay with nothing accepted).
    gaps : dict
        The held-out gaps under both fold schemes (:meth:`discrepancy.search.Search.both_schemes`).
    """

    nominal: object
    selection: object
    uncertainty: dict | None
    theta_after: list
    gaps: dict


def assemble_report(builder, runs: list[ReplayRun], findings: Findings, settings: dict, *,
                    fixed: tuple[str, ...] = (), actuator_limit: float = math.inf) -> dict:
    """The content of ``report.json`` (the run-time fields ``mujoco_warnings`` and ``timings``
    are added by :func:`~discrepancy.workflow.run_discrepancy`).  ``builder``: the
    :class:`~discrepancy.effects.ModelBuilder` (the effects' nominal values); ``fixed``: the
    nominal's corrections (reported apart); ``actuator_limit``: the actuator's command limit
    (its ``ctrlrange``, inf if unlimited), which with each run's ``command_limit`` says when
    the command is near its limit (:func:`~discrepancy.localise.command_bins`)."""
    nominal, selection, unc = findings.nominal, findings.selection, findings.uncertainty
    theta_after = findings.theta_after
    noise = nominal.noise
    gap_before = nominal.gap
    gap_after = gap([th - r.theta for th, r in zip(theta_after, runs)])
    excess_before = math.sqrt(max(gap_before**2 - noise**2, 0.0))
    excess_after = math.sqrt(max(gap_after**2 - noise**2, 0.0))
    unexplained = excess_after / excess_before if excess_before > 0 else 0.0
    best = selection.best
    named = [] if best is None else [e for e in best.effects if e.name not in fixed]
    # "high" confidence needs the gap left at the noise: above it, as if nothing was explained
    left = unexplained if gap_after <= sel.REMAINDER_FACTOR * noise else 1.0
    if not named:
        effects = [_none_item(selection.entries, gap_before, gap_after, noise)]
        if fixed:
            effects[0]["reason"] += " (after the nominal's corrections, which are reported apart)"
    else:
        effects = _effect_items(builder, best, selection.effect_entries, unc, left, fixed)
    corrections = _correction_items(builder, best, unc, fixed) if fixed else []
    loc_before = localise(runs, nominal.theta, actuator_limit)
    loc_after = localise(runs, theta_after, actuator_limit)
    rounds = selection.rounds
    # the library's nearest candidates (round 1, held-out share), for a gap left unexplained
    nearest = [{"name": c.name, "share": c.share, "confidence": "low"}
               for c in (rounds[0] if rounds else []) if c.method in ("one-step", "refit") and c.name != sel.NULL][:3]
    return {
        "effects": effects,
        "corrections": corrections,
        "gap_before": gap_before,
        "gap_after": gap_after,
        "gap_units": "rad (root of the mean over runs of each run's mean-square replay error; "
                     "after = held-out, each run replayed with parameters fitted without it)",
        "shrink_factor": (gap_before / gap_after if gap_after > 0
                          else 1.0 if gap_before <= 0 else float("inf")),
        "noise_floor_rad": noise,
        "unexplained_share": unexplained,
        # True whenever the gap left (after the named effects, or with none named) stands well
        # above the noise floor: the library does not explain the data
        "unexplained": bool((best is not None and unexplained > sel.UNEXPLAINED_SHARE)
                            or gap_after > sel.REMAINDER_FACTOR * noise),
        "where": describe(loc_before, noise),
        "where_after": describe(loc_after, noise),
        "nearest_candidates": nearest,
        "rounds": selection.entries,
        "candidates": [[_candidate_row(s) for s in round_scored] for round_scored in rounds],
        "unstable_replays_per_candidate": {s.name: s.unstable for round_scored in rounds
                                           for s in round_scored if s.unstable},
        "localisation": {"before": loc_before, "after": loc_after},
        "sampling": [sampling(r) for r in runs],
        "settings": settings,
        "gaps": findings.gaps,
    }


def sampling(run: ReplayRun) -> dict:
    """How a run was logged and replayed: its name, samples, median ``period_s``, ``jitter_s``
    (standard deviation of the spacing), longest ``max_gap_s``, the device's
    ``control_period_s``, ``control_period_given`` (False: the metadata gave none, the loop
    period is the sample period) and the share of the run with the actuator off."""
    off = 0.0 if run.enabled is None else float(np.mean(~run.enabled))
    return {"run": run.name, "samples": int(run.n), **spacing(run.t),
            "control_period_s": float(run.period),
            "control_period_given": run.meta.get("control_period_s") is not None,
            "torque_off_share": off}


def _candidate_row(s: Scored) -> dict:
    """One scored candidate as the report lists it."""
    return {"name": s.name, "heldout_gap_rad": s.heldout_gap, "share": s.share,
            "method": s.method, "prescreen_gap_rad": s.prescreen_gap, "unstable_replays": s.unstable,
            "unconverged_folds": s.unconverged,
            "parameters": {p.name: float(v) for e, x in split_values(s.effects, s.fit.x)
                           for p, v in zip(e.params, x)}}


def _none_item(entries: list[dict], gap_before: float, gap_left: float, noise: float) -> dict:
    """The report's effect ``none``: nothing named, the best candidate and why.  ``gap_left``:
    the held-out gap nothing named explains (after the nominal's corrections, if any), judged
    against the noise floor as the report's ``unexplained`` flag judges it."""
    first = entries[0] if entries else {"best": None, "share": None, "runner_up": None, "margin": None}
    if gap_before <= 0:
        reason = "the model's replay equals the measured data exactly (gap 0): nothing is missing"
    elif gap_left > sel.REMAINDER_FACTOR * noise:
        reason = (f"no library candidate removes a clear share of the held-out gap, which stands at "
                  f"{gap_left / max(noise, 1e-300):.1f} x the noise floor: the gap is UNEXPLAINED (an "
                  "effect outside the library, or several), the model is not confirmed")
    elif gap_left >= sel.NOISE_FACTOR * noise:
        reason = "no candidate removes a clear share of the held-out gap"
    else:
        reason = "the gap is at the measurement noise floor"
    return {"name": "none", "parameters": {}, "uncertainty": {},
            "best_candidate": first["best"], "best_share": first["share"],
            "runner_up": first["runner_up"], "margin": first["margin"], "reason": reason}


def _confidence(margin: float, unexplained: float) -> str:
    """"high" when the effect beats its runner-up clearly (a margin of at least twice
    :data:`~discrepancy.select.TIE_MARGIN`) and the gap left is at the noise (an
    unexplained share of at most :data:`~discrepancy.select.UNEXPLAINED_SHARE`); else
    "low".  (Every named effect removed at least ``MIN_SHARE`` of its round's gap to be
    accepted, so its share does not enter.)"""
    return "high" if (margin >= 2 * sel.TIE_MARGIN and unexplained <= sel.UNEXPLAINED_SHARE) else "low"


def _by_param(effect, values) -> dict:
    """``{parameter name: value}`` of one effect."""
    return {p.name: float(v) for p, v in zip(effect.params, values)}


def _parts(best: Scored) -> list[tuple]:
    """``(effect, its values, its slice of the parameter vector)`` of every member of ``best``."""
    out, i = [], 0
    for eff, x in split_values(best.effects, best.fit.x):
        out.append((eff, x, slice(i, i + eff.nparam)))
        i += eff.nparam
    return out


def _bound_flags(eff, x) -> dict:
    """``{parameter: "lower"|"upper"}`` for each value within 1e-6 of its range of a bound."""
    out = {}
    for p, v in zip(eff.params, x):
        tol = 1e-6 * (p.upper - p.lower) if math.isfinite(p.upper - p.lower) else 0.0
        if v <= p.lower + tol:
            out[p.name] = "lower"
        elif v >= p.upper - tol:
            out[p.name] = "upper"
    return out


#: A correction's constant and a named effect's parameter the fit cannot tell apart: the
#: magnitude of their correlation at the all-runs optimum (:func:`discrepancy.fit.correlation`)
#: at least this.  0.9, fixed before any case was looked at: a variance inflation factor
#: 1 / (1 - r^2) of 5.3, past the usual rule of thumb for harmful collinearity (VIF > 5; James,
#: Witten, Hastie and Tibshirani, *An Introduction to Statistical Learning*, 2013, sect. 3.3.3).
CONFOUNDED_CORRELATION = 0.9


def multiple_correlation(corr: np.ndarray, i: int, others: list[int]) -> float:
    """The multiple correlation R of parameter ``i``'s estimate with the estimates ``others``
    together, from their correlation matrix: ``R^2 = r_iS R_SS^-1 r_Si`` (the share of its
    variance a linear combination of the others takes; 1 / (1 - R^2) is its variance inflation
    factor against them).  NaN where a correlation is undefined."""
    r = corr[i, others]
    sub = corr[np.ix_(others, others)]
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(sub))):
        return math.nan
    r2 = float(r @ np.linalg.pinv(sub) @ r)
    return math.sqrt(min(max(r2, 0.0), 1.0))


def confounded(best: Scored, corr: np.ndarray, fixed: tuple[str, ...]) -> dict:
    """``{(correction, parameter): [(effect, parameter, correlation), ...]}``: each refitted
    constant of the nominal whose correlation with a named effect's parameter reaches
    :data:`CONFOUNDED_CORRELATION` in magnitude (parameters on a bound left out: their
    correlation is not defined), or, when no single parameter of that effect does, whose
    multiple correlation with the effect's parameters together does (a ridge the effect's
    parameters span jointly, e.g. a torque gain traded against a load law's two coefficients
    at once; :func:`multiple_correlation`, the same threshold: the same variance inflation
    factor 5.3).  A joint entry's parameter is the effect's parameters joined by ``+``, its
    correlation the (positive) multiple correlation."""
    corrections, named = [], {}
    for eff, x, part in _parts(best):
        on_bound = _bound_flags(eff, x)
        for k, p in enumerate(eff.params):
            if p.name not in on_bound:
                if eff.name in fixed:
                    corrections.append((eff.name, p.name, part.start + k))
                else:
                    named.setdefault(eff.name, []).append((p.name, part.start + k))
    out: dict = {}
    for e1, p1, i in corrections:
        for e2, params in named.items():
            hits = [(e2, p2, float(corr[i, j])) for p2, j in params
                    if math.isfinite(corr[i, j]) and abs(corr[i, j]) >= CONFOUNDED_CORRELATION]
            if not hits and len(params) > 1:
                r = multiple_correlation(corr, i, [j for _, j in params])
                if math.isfinite(r) and r >= CONFOUNDED_CORRELATION:
                    hits = [(e2, "+".join(p2 for p2, _ in params), r)]
            if hits:
                out.setdefault((e1, p1), []).extend(hits)
    return out


def _correction_items(builder, best: Scored, unc: dict, fixed: tuple[str, ...]) -> list[dict]:
    """The report's ``corrections``: each refitted constant of the nominal with the user's value,
    the fitted one, its 95 % half-width (as the effects'), the factor moved, and a warning when
    it moved by more than :data:`PLAUSIBLE_FACTOR` or sits on a bound.

    ``within_factor`` (bool) says the fitted value lies within :data:`PLAUSIBLE_FACTOR` of the
    user's value, ``plausible_factor`` is that factor, ``at_bound`` the bound it sits on (or
    None); ``plausible`` (kept for compatibility) is ``within_factor and not at_bound``: those
    two checks only, not a test of the value against the truth.  ``confounded_with`` lists the
    named effects' parameters the fit trades it against (:func:`confounded`)."""
    cover = un.coverage_factor(len(best.folds))
    se, bias = unc["se"], unc["measurement_bias"]
    mixed = confounded(best, unc["correlation"], fixed)
    out = []
    for eff, x, part in _parts(best):
        if eff.name not in fixed:
            continue
        nominal = builder.nominal_values(eff)
        bounds = _bound_flags(eff, x)
        for p, v, v0, s_, b_ in zip(eff.params, x, nominal, se[part], bias[part]):
            ratio = float(v / v0) if v0 != 0 else None
            item = {"effect": eff.name, "parameter": p.name, "unit": p.unit, "nominal": float(v0),
                    "fitted": float(v), "half_width_95": float(cover * s_ + abs(b_)),
                    "ratio_to_nominal": ratio, "bounds": [p.lower, p.upper]}
            notes = []
            if ratio is not None and (ratio > PLAUSIBLE_FACTOR or ratio < 1 / PLAUSIBLE_FACTOR):
                notes.append(f"moved x{ratio:.2g} from your value: more than a factor {PLAUSIBLE_FACTOR:g}, "
                             "check the nominal (or a missing effect it stands in for)")
            if p.name in bounds:
                notes.append(f"on its {bounds[p.name]} bound: the interval is not a confidence interval")
            item["within_factor"] = not (ratio is not None and (ratio > PLAUSIBLE_FACTOR
                                                                or ratio < 1 / PLAUSIBLE_FACTOR))
            item["plausible_factor"] = PLAUSIBLE_FACTOR
            item["plausible"] = not notes  # = within_factor and not at_bound (the only checks)
            item["at_bound"] = bounds.get(p.name)
            item["confounded_with"] = [{"effect": e, "parameter": q, "correlation": r}
                                       for e, q, r in mixed.get((eff.name, p.name), [])]
            if notes:
                item["warning"] = "; ".join(notes)
            out.append(item)
    return out


def _effect_items(builder, best: Scored, effect_entries: list[dict], unc: dict,
                  unexplained: float, fixed: tuple[str, ...] = ()) -> list[dict]:
    """The report's entry of every named effect (the corrections apart): fitted values, nominal
    values, the 95 % half-width and its parts, the round's share, runner-up, margin and
    confidence."""
    cover = un.coverage_factor(len(best.folds))
    se, bias = unc["se"], unc["measurement_bias"]
    items = []
    named = [(eff, x, part) for eff, x, part in _parts(best) if eff.name not in fixed]
    for (eff, x, part), entry in zip(named, effect_entries):
        item = {
            "name": eff.name,
            "description": eff.description,
            "parameters": _by_param(eff, x),
            "nominal": _by_param(eff, builder.nominal_values(eff)),
            "uncertainty": _by_param(eff, (cover * s + abs(b) for s, b in zip(se[part], bias[part]))),
            "uncertainty_kind": f"95 % half-width: {cover:.2f} x standard error (Student t, "
                                f"{len(best.folds) - 1} dof of the fold jackknife) "
                                "+ |measurement bias|; the standard error includes the "
                                "optimiser's and the replay's numerical terms (Type B)",
            "standard_error": _by_param(eff, se[part]),
            **{f"standard_error_{kind}": _by_param(eff, unc[kind][part])
               for kind in ("jackknife", "jacobian", "measurement")},
            "measurement_bias": _by_param(eff, bias[part]),
            # numerical terms inside the standard error (GUM Type B half-widths, uniform:
            # b / sqrt(3) each; discrepancy/uncertainty.py)
            **{f"{kind}_half_width": _by_param(eff, unc[kind][part])
               for kind in ("optimiser", "numerical_floor")},
            "units": {p.name: p.unit for p in eff.params},
            "share_of_round_gap": entry["share"],
            "runner_up": entry["runner_up"],
            **({"runner_up_note": entry["runner_up_note"]} if "runner_up_note" in entry else {}),
            **({"fitted_jointly_with": [n for n in entry["pair"].split("+") if n != eff.name]}
               if "pair" in entry else {}),
            "runner_up_share": entry["runner_up_share"],
            "margin": entry["margin"],
            "confidence": _confidence(entry["margin"], unexplained),
            "at_bound": _bound_flags(eff, x),
        }
        if entry.get("tie"):
            item["indistinguishable_from"] = entry["runner_up"]
            item["separating_experiment"] = entry["separating_experiment"]
        items.append(item)
    return items
