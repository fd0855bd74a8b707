"""The whole workflow: replay, localise, name (held-out scoring), fit, show the gap shrink."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from identification.dataset import Run
from identification.errors import UserError

from .. import model as om
from ..device import Device
from . import effects as fx
from . import select as sel
from . import uncertainty as un
from .fit import gap
from .localise import describe, localise
from .replay import Replayer, prepare_runs

#: Samples (all runs together) above which the fits use only the start of each run: the fit and
#: the candidate scoring cost scale with it; the before/after evaluation always uses whole runs.
MAX_FIT_SAMPLES = 300_000
#: Shortest per-run record [samples] kept for fitting when runs are cut to the budget.
MIN_FIT_RUN_SAMPLES = 3000


@dataclass
class Outcome:
    """Everything the report needs.

    Attributes
    ----------
    report : dict
        The ``report.json`` content.
    spec : MjSpec
        The patched model (nominal + accepted effects at their all-runs fit).
    runs : list of ReplayRun
    theta_before, theta_after : list of ndarray [rad]
        Replay of the nominal model; held-out replay of the patched model (each run with the
        parameters fitted without it).
    rounds : list of list of Scored
    """

    report: dict
    spec: mujoco.MjSpec
    runs: list
    theta_before: list
    theta_after: list
    rounds: list = field(default_factory=list)


def _load_spec(model_path, target: om.Target | None = None) -> tuple[mujoco.MjSpec, mujoco.MjModel, str]:
    path = Path(model_path) if model_path is not None else om.DEFAULT_SCENE
    # UserError on a missing file, bad XML or missing names (the Omni's, or the target's)
    model = om.load_model(path, target=target)
    spec = mujoco.MjSpec.from_file(str(path))
    return spec, model, str(path)


def _heldout_theta(spec, scored, runs, rep, target: om.Target = om.OMNI) -> list[np.ndarray]:
    models = [fx.compile_with(spec, [(e, x) for e, x in _split(scored.effects, fx_)], target)
              for fx_ in scored.fold_x]
    pairs = [(f, j) for f, idx in enumerate(scored.folds) for j in idx]
    th = rep.simulate(models, runs, pairs)
    out: list = [None] * len(runs)
    for (f, j), t in zip(pairs, th):
        out[j] = t
    return out


def _split(effects, x):
    out, i = [], 0
    for e in effects:
        out.append((e, np.asarray(x[i:i + e.nparam], float)))
        i += e.nparam
    return out


def _confidence(share, margin, unexplained) -> str:
    return "high" if (margin >= 2 * sel.TIE_MARGIN and unexplained <= sel.UNEXPLAINED_SHARE) else "low"


def run_discrepancy(runs: list[Run], model_path=None, *, jobs: int | None = None, k: int = 5,
                    max_effects: int = 3, max_fit_samples: int = MAX_FIT_SAMPLES,
                    candidates: tuple[str, ...] | None = None, log=None,
                    target: om.Target | None = None) -> Outcome:
    """Find, name, fit and check the effect(s) the model misses on these measured runs.

    Parameters
    ----------
    runs : list of Run
        Measured runs (the dataset contract).
    model_path : path, optional
        MJCF of the model to test (default: the built-in scene).
    jobs : int, optional
        Rollout threads (default: all cores).
    k : int
        Folds over runs for held-out scoring.
    max_effects : int
        Most effects named (rounds).
    max_fit_samples : int
        Sample budget of the fits (see :data:`MAX_FIT_SAMPLES`).
    candidates : tuple of str, optional
        Library names to consider (default: all that can be written into the model).
    target : omni_sim.model.Target, optional
        The controlled hinge and its actuator of a user's single-joint device (default None:
        the Omni's contract, ``yaw``/``yaw_motor`` with the arm).  Without the Omni's arm the
        runs need no pose metadata.

    Raises
    ------
    UserError
        Model without the contract's names, runs the model cannot replay, too little data.
    """
    t_start = time.perf_counter()
    spec, model, path = _load_spec(model_path, target)
    rr = prepare_runs(runs, Device(model, target=target))
    tgt = om.OMNI if target is None else target  # where the effects are written
    ok_names = fx.applicable(spec, tgt)  # only candidates that can be written into this model
    unknown = [c for c in (candidates or ()) if c not in fx.NAMES]
    if unknown:
        raise UserError(f"unknown candidate effect(s): {', '.join(unknown)} (library: {', '.join(fx.NAMES)})")
    candidates = tuple(c for c in (candidates or fx.NAMES) if c in ok_names)
    if not candidates:
        raise UserError(f"{path}: none of the candidate effects can be written into this model")
    if len(rr) < 2:
        raise UserError("measured data: at least 2 runs are needed (candidates are scored on runs "
                        "held out of their fit)")
    total = sum(r.n for r in rr)
    nfit = max(MIN_FIT_RUN_SAMPLES, max_fit_samples // len(rr)) if total > max_fit_samples else None
    fit_runs = [r.truncated(nfit) for r in rr] if nfit else rr
    log = log or (lambda s: None)
    timings = {}
    with Replayer(jobs, target) as rep:
        t0 = time.perf_counter()
        theta_before = rep.simulate([model], rr)
        timings["replay_nominal_s"] = time.perf_counter() - t0
        res_before = [th - r.theta for th, r in zip(theta_before, rr)]
        gap_before = gap(res_before)
        fit_before = gap([res[: r.n] for res, r in zip(res_before, fit_runs)])
        noise = sel.noise_floor(res_before)
        log(f"gap before {gap_before:.3e} rad, noise floor {noise:.2e} rad, {len(rr)} runs, "
            f"{total} samples" + (f" (fits use the first {nfit} of each run)" if nfit else ""))
        accepted, accepted_x, rounds, entries, effect_entries = [], np.zeros(0), [], [], []
        gap_start = fit_before
        best_accepted = None
        beam = None  # the pair search's confirmed pairs, grown together in the next round
        pairs_scored: list = []
        t0 = time.perf_counter()
        rnd = -1
        # rounds: one per effect, plus one a backward step can free (floating selection)
        while len(accepted) < max_effects and rnd + 1 < max_effects + 1:
            rnd += 1
            if gap_start <= 0:
                log("the model's replay equals the measured data exactly: nothing to name")
                break
            if rnd > 0 and gap_start < sel.NOISE_FACTOR * noise:
                log(f"round {rnd + 1}: skipped, the held-out gap is at the noise floor")
                break
            names = [c for c in candidates if c not in [e.name for e in accepted]]
            if not names:
                break
            log(f"round {rnd + 1}: scoring {len(names)} candidates")
            scored = sel.score_round(spec, accepted, accepted_x, fit_runs, rep, gap_start, k=k,
                                     # a beam grows every confirmed pair by any candidate
                                     # not in it (the accepted pair's members included)
                                     candidates=tuple(candidates if beam else names), log=log,
                                     target=tgt, bases=beam)
            rounds.append(scored)
            best = scored[0]
            runner = scored[1] if len(scored) > 1 and math.isfinite(scored[1].heldout_gap) else None
            # margin: share of the runner-up's remaining held-out gap the best removes on top
            margin = sel.share_of(best.heldout_gap, runner.heldout_gap) if runner else 1.0
            ok = best.share >= sel.MIN_SHARE and gap_start >= sel.NOISE_FACTOR * noise
            entry = {"round": rnd + 1, "best": best.name, "share": best.share,
                     "runner_up": runner.name if runner else None,
                     "runner_up_share": runner.share if runner else None, "margin": margin,
                     "gap_start_rad": gap_start, "gap_heldout_rad": best.heldout_gap,
                     "accepted": bool(ok)}
            if runner and margin < sel.TIE_MARGIN:
                entry["tie"] = True
                entry["separating_experiment"] = sel.separating_experiment(best.name, runner.name)
            entries.append(entry)
            if (rnd == 0 and max_effects >= 2 and gap_start >= sel.REMAINDER_FACTOR * noise
                    and (best.share < sel.PAIR_SEARCH_SHARE
                         or best.heldout_gap >= sel.REMAINDER_FACTOR * noise)):
                # no single effect explains the gap down to the noise: effects that mask each
                # other (a loop delay takes damping away, dry friction adds it) are only visible
                # together, and one effect at a time can settle on a stand-in for the pair (a
                # Stribeck curve for delay + friction), so every pair is fitted jointly too (not
                # only pairs of the round's best candidates: the delay alone explains nothing,
                # and the friction can be outranked by a stand-in)
                log(f"round 1: the best single candidate removes {best.share:.0%} and leaves "
                    f"{best.heldout_gap / max(noise, 1e-300):.1f} x the noise floor: scoring pairs")
                pairs = sel.score_pairs(spec, fit_runs, rep, gap_start, k=k, candidates=tuple(names),
                                        log=log, target=tgt)
                bp = pairs[0]
                gain = sel.share_of(bp.heldout_gap, best.heldout_gap)
                pair_ok = (bp.share >= sel.MIN_SHARE and gain >= sel.MIN_SHARE
                           and gap_start >= sel.NOISE_FACTOR * noise)
                entry["pair_search"] = {"best": bp.name, "share": bp.share,
                                        "gain_over_best_single": gain, "accepted": bool(pair_ok)}
                if pair_ok:
                    rounds.append(pairs)
                    entry["accepted"] = False
                    for (eff, (ru, mg)) in zip(bp.effects, sel.pair_runner_up(bp, pairs, scored)):
                        pe = {"round": 1, "pair": bp.name, "best": eff.name, "share": bp.share,
                              "runner_up": ru, "runner_up_share": None, "margin": mg,
                              "gap_start_rad": gap_start, "gap_heldout_rad": bp.heldout_gap,
                              "accepted": True}
                        if ru is None:
                            pe["runner_up_note"] = ("no other scored pair keeps the other member; "
                                                    "margin is against the other member alone")
                        if ru is not None and mg < sel.TIE_MARGIN:
                            pe["tie"] = True
                            pe["separating_experiment"] = sel.separating_experiment(eff.name, ru)
                        entries.append(pe)
                        effect_entries.append(pe)
                    log(f"round 1: accepted the pair {bp.name} (removes {bp.share:.0%}; "
                        f"{gain:.0%} of what the best single candidate leaves)")
                    accepted, accepted_x, best_accepted = bp.effects, bp.fit.x, bp
                    gap_start = bp.heldout_gap
                    # a beam: the next round adds each candidate to each confirmed pair, not
                    # only to the accepted one (with a third effect present the best pair can
                    # be a stand-in: armature + LuGre explains more of delay + Coulomb +
                    # armature than Coulomb + delay, whose fit then compensates the missing
                    # armature; the triple grows from Coulomb + delay)
                    confirmed = [p for p in pairs if p.method == "refit" and math.isfinite(p.heldout_gap)]
                    if len(confirmed) > 1:
                        beam = [(p.effects, p.fit.x) for p in confirmed]
                        pairs_scored = [p for p in pairs if math.isfinite(p.heldout_gap)]
                    continue  # forward selection goes on from the pair
                log(f"round 1: best pair {bp.name} removes {bp.share:.0%} ({gain:.0%} of what the best "
                    "single leaves): not accepted")
            if not ok:
                log(f"round {rnd + 1}: best {best.name} removes {best.share:.0%} of the gap: not accepted")
                break
            log(f"round {rnd + 1}: accepted {best.name} (removes {best.share:.0%}; runner-up "
                f"{entry['runner_up']}, margin {margin:.2f})")
            pool = scored + pairs_scored
            removed = None
            if len(best.effects) >= 3:
                # floating selection, the backward step: a member accepted earlier may be a
                # stand-in the new member made redundant (a spring fitted with Coulomb friction
                # to part of a backlash's gap); each member is removed in turn, the rest refitted
                rem = sel.score_removals(spec, best, fit_runs, rep, gap_start, log=log)
                pool = pool + rem
                contribution = sel.share_of(best.heldout_gap, rem[0].heldout_gap)
                entry["backward_step"] = {"best_without_one": rem[0].name,
                                          "share_of_its_gap_removed_by_the_set": contribution}
                if contribution < sel.MIN_SHARE:
                    removed = [e.name for e in best.effects if e.name not in [f.name for f in rem[0].effects]]
                    log(f"round {rnd + 1}: {removed[0]} dropped (without it the held-out gap is "
                        f"{rem[0].heldout_gap:.3e} rad; with it {contribution:.0%} of that is removed, "
                        f"less than {sel.MIN_SHARE:.0%})")
                    entry["backward_step"]["dropped"] = removed[0]
                    best = rem[0]
            if beam or removed:
                # every member's runner-up is the best scored set without it (this round's sets,
                # the pairs, the set without one member); the set may have grown from another
                # pair than the one accepted
                effect_entries = []
                for eff, (ru, mg) in zip(best.effects, sel.member_runner_up(best, pool)):
                    pe = {"round": rnd + 1, "pair": best.name, "best": eff.name, "share": best.share,
                          "runner_up": ru, "runner_up_share": None, "margin": mg,
                          "gap_start_rad": gap_start, "gap_heldout_rad": best.heldout_gap,
                          "accepted": True,
                          "runner_up_note": "the best scored set without this effect (named by "
                                            "what it holds instead; none: the effect dropped)"}
                    if ru is not None and "+" not in ru and mg < sel.TIE_MARGIN:
                        pe["tie"] = True
                        pe["separating_experiment"] = sel.separating_experiment(eff.name, ru)
                    entries.append(pe)
                    effect_entries.append(pe)
                beam = None
            else:
                effect_entries.append(entry)
            accepted, accepted_x, best_accepted = best.effects, best.fit.x, best
            gap_start = best.heldout_gap
        timings["naming_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        if best_accepted is not None:
            unc = un.uncertainty(spec, best_accepted, fit_runs, rep)
            se, bias = unc["se"], unc["measurement_bias"]
            cover = un.coverage_factor(len(best_accepted.folds))
            theta_after = _heldout_theta(spec, best_accepted, rr, rep, tgt)
        else:
            theta_after = theta_before
        timings["uncertainty_and_evaluation_s"] = time.perf_counter() - t0
        steps = rep.steps
        warnings = {"unstable_simulations": rep.unstable_warnings, "first": rep.first_warning}
    res_after = [th - r.theta for th, r in zip(theta_after, rr)]
    gap_after = gap(res_after)
    excess0 = math.sqrt(max(gap_before**2 - noise**2, 0.0))
    excess1 = math.sqrt(max(gap_after**2 - noise**2, 0.0))
    unexplained = excess1 / excess0 if excess0 > 0 else 0.0
    effects_out = []
    if best_accepted is None:
        e0 = entries[0] if entries else {"best": None, "share": None, "runner_up": None, "margin": None}
        effects_out.append({"name": "none", "parameters": {}, "uncertainty": {},
                            "best_candidate": e0["best"], "best_share": e0["share"],
                            "runner_up": e0["runner_up"], "margin": e0["margin"],
                            "reason": (
                                "the model's replay equals the measured data exactly (gap 0): "
                                "nothing is missing"
                                if gap_before <= 0 else
                                f"no library candidate removes a clear share of the held-out gap, "
                                f"which stands at {gap_before / max(noise, 1e-300):.0f} x the noise "
                                "floor: the gap is UNEXPLAINED (an effect outside the library, or "
                                "several), the model is not confirmed"
                                if gap_before >= sel.REMAINDER_FACTOR * noise else
                                "no candidate removes a clear share of the held-out gap"
                                if gap_before >= sel.NOISE_FACTOR * noise else
                                "the gap is at the measurement noise floor")})
        patched = spec.copy()
    else:
        i = 0
        for n_acc, (eff, x) in enumerate(_split(best_accepted.effects, best_accepted.fit.x)):
            ent = effect_entries[n_acc]
            sl = slice(i, i + eff.nparam)
            i += eff.nparam
            item = {
                "name": eff.name,
                "description": eff.description,
                "parameters": {p.name: float(v) for p, v in zip(eff.params, x)},
                "nominal": {p.name: float(v) for p, v in zip(eff.params, fx.nominal_values(eff, spec, tgt))},
                "uncertainty": {p.name: float(cover * s + abs(b))
                                for p, s, b in zip(eff.params, se[sl], bias[sl])},
                "uncertainty_kind": f"95 % half-width: {cover:.2f} x standard error (Student t, "
                                    f"{len(best_accepted.folds) - 1} dof of the fold jackknife) "
                                    "+ |measurement bias|; the standard error includes the "
                                    "optimiser's and the replay's numerical terms (Type B)",
                "standard_error": {p.name: float(s) for p, s in zip(eff.params, se[sl])},
                **{f"standard_error_{kind}": {p.name: float(s) for p, s in zip(eff.params, unc[kind][sl])}
                   for kind in ("jackknife", "jacobian", "measurement")},
                "measurement_bias": {p.name: float(b) for p, b in zip(eff.params, bias[sl])},
                # numerical terms inside the standard error (GUM Type B half-widths, uniform:
                # b / sqrt(3) each; omni_sim/discrepancy/uncertainty.py)
                **{f"{kind}_half_width": {p.name: float(b) for p, b in zip(eff.params, unc[kind][sl])}
                   for kind in ("optimiser", "numerical_floor")},
                "units": {p.name: p.unit for p in eff.params},
                "share_of_round_gap": ent["share"],
                "runner_up": ent["runner_up"],
                **({"runner_up_note": ent["runner_up_note"]} if "runner_up_note" in ent else {}),
                **({"fitted_jointly_with": [n for n in ent["pair"].split("+") if n != eff.name]}
                   if "pair" in ent else {}),
                "runner_up_share": ent["runner_up_share"],
                "margin": ent["margin"],
                "confidence": _confidence(ent["share"], ent["margin"],
                                          unexplained if gap_after <= sel.REMAINDER_FACTOR * noise else 1.0),
            }
            if ent.get("tie"):
                item["indistinguishable_from"] = ent["runner_up"]
                item["separating_experiment"] = ent["separating_experiment"]
            effects_out.append(item)
        patched = fx.apply(spec, _split(best_accepted.effects, best_accepted.fit.x), tgt)
    loc_before = localise(rr, theta_before)
    loc_after = localise(rr, theta_after)
    # the library's nearest candidates (round 1, held-out share), for a gap left unexplained
    nearest = [{"name": c.name, "share": c.share, "confidence": "low"}
               for c in (rounds[0] if rounds else []) if c.method != "prescreen"][:3]
    timings["total_s"] = time.perf_counter() - t_start
    report = {
        "effects": effects_out,
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
        "unexplained": bool((best_accepted is not None and unexplained > sel.UNEXPLAINED_SHARE)
                            or gap_after > sel.REMAINDER_FACTOR * noise),
        "where": describe(loc_before, noise),
        "where_after": describe(loc_after, noise),
        "nearest_candidates": nearest,
        "rounds": entries,
        "candidates": [[{"name": s.name, "heldout_gap_rad": s.heldout_gap, "share": s.share,
                         "method": s.method, "prescreen_gap_rad": s.prescreen_gap,
                         "parameters": {p.name: float(v) for e, x in _split(s.effects, s.fit.x)
                                        for p, v in zip(e.params, x)}} for s in rnd] for rnd in rounds],
        "localisation": {"before": loc_before, "after": loc_after},
        "settings": {"folds": k, "max_effects": max_effects, "min_share": sel.MIN_SHARE,
                     "noise_factor": sel.NOISE_FACTOR, "tie_margin": sel.TIE_MARGIN,
                     "fit_samples_per_run": nfit, "model": path, "joint": tgt.joint,
                     "actuator": tgt.actuator, "candidates": list(candidates),
                     "prescreen_samples": sel.PRESCREEN_SAMPLES, "n_screen": sel.N_SCREEN,
                     "mujoco": mujoco.__version__},
        "mujoco_warnings": warnings,
        "timings": {**timings, "physics_steps": steps,
                    "steps_per_s": steps / max(timings["naming_s"] + timings["replay_nominal_s"], 1e-9)},
    }
    return Outcome(report, patched, rr, theta_before, theta_after, rounds)
