"""The whole workflow: replay, localise, name (held-out scoring), fit, show the gap shrink.

:func:`run_discrepancy` runs the steps in order, each a function of its own:

1. :func:`replay_nominal`: the nominal model's replay of every run, its gap and the noise floor;
2. :func:`select_effects`: forward selection, one round per effect (every candidate screened
   and scored on held-out runs, :mod:`.select`), with the pair search of the first round and
   the backward step of floating selection;
3. :func:`estimate`: the named effects' uncertainty (:mod:`.uncertainty`) and the held-out
   replay of the patched model;
4. :func:`assemble_report`: the content of ``report.json`` (with the localisation of the gap
   before and after, :mod:`.localise`).

This module joins the MuJoCo side (the model, the effect library, the replay) to the
statistics, which get the model through an :class:`~discrepancy.effects.ModelBuilder`
and the simulations through the :class:`~discrepancy.replay.Replayer`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from identification.dataset import Run, spacing
from identification.errors import UserError

from omni_sim import model as om
from omni_sim.device import ENCODER_STEP_RAD, Device
from . import effects as fx
from . import select as sel
from . import uncertainty as un
from .evidence import of_outcome as evidence_of
from .fit import gap
from .localise import describe, localise
from .replay import Replayer, control_period_of, prepare_runs
from .runs import ReplayRun
from .select import Scored

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
    evidence: object = None  # the missing torque under the corrected nominal (evidence.Evidence)


#: The nominal's uncertain constants refitted by default (library names): rotor inertia, viscous
#: damping, Coulomb level, torque constant and a constant drive offset (which a P loop turns into
#: a position offset) -- what a datasheet or a CAD model gets "a little wrong everywhere".
DEFAULT_CORRECTIONS = ("armature", "viscous_damping", "coulomb_friction", "torque_gain", "position_offset")
#: A correction that moves its parameter by more than this factor from the user's value is
#: flagged in the report (a 3x inertia change is a finding, not a correction).  This factor and
#: the parameter's bounds are the only checks behind a correction's ``plausible``: it does not
#: say the fitted value is right (its interval may exclude the true one).
PLAUSIBLE_FACTOR = 2.0


def correction_names(corrections, spec: mujoco.MjSpec, target: om.Target, own_device: bool) -> tuple[str, ...]:
    """The library effects refitted as corrections of the nominal: ``"auto"`` is
    :data:`DEFAULT_CORRECTIONS` on a user's own device (``--joint``/``--actuator``) and none on
    the virtual Omni (whose calibrated scene is the nominal the bank hides effects against);
    ``"default"`` the default set; ``"none"`` or an empty tuple none; else the names given.
    Only those that can be written into the model are kept, and of the default set only the
    constants the nominal states (a value other than zero): a zero means the nominal lacks
    that structure (no dry friction, no offset), which the library names as an effect.

    Raises
    ------
    UserError
        An unknown name."""
    if corrections in (None, "auto"):
        names = DEFAULT_CORRECTIONS if own_device else ()
    elif corrections == "default":
        names = DEFAULT_CORRECTIONS
    elif corrections == "none":
        names = ()
    else:
        names = tuple(corrections)
    unknown = [c for c in names if c not in fx.NAMES]
    if unknown:
        raise UserError(f"unknown correction(s): {', '.join(unknown)} (library: {', '.join(fx.NAMES)})")
    writable = fx.applicable(spec, target)
    names = tuple(c for c in names if c in writable)
    if corrections in (None, "auto", "default"):
        names = tuple(c for c in names if np.all(np.asarray(fx.get(c).read(spec, target), float) != 0))
    return names


#: The workflow's stages, in order (the report's ``timings`` and ``physics_steps_per_stage``).
STAGES = ("replay_nominal", "corrections", "naming", "uncertainty_and_evaluation", "other_fold_scheme")


def run_discrepancy(runs: list[Run], model_path=None, *, jobs: int | None = None, k: int = 5,
                    max_effects: int = 3, max_fit_samples: int = MAX_FIT_SAMPLES,
                    candidates: tuple[str, ...] | None = None, log=None,
                    target: om.Target | None = None, folds: str = "blocked",
                    corrections="auto", progress=None) -> Outcome:
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
        Folds for held-out scoring.
    folds : str
        The verdict's fold scheme (:data:`discrepancy.select.FOLD_SCHEMES`): ``"blocked"``
        (time blocks within every run) or ``"runs"`` (whole runs); the report gives the other
        scheme's held-out gaps beside.
    corrections : str or tuple of str
        The nominal's constants refitted jointly with every candidate (:func:`correction_names`).
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
    progress : callable, optional
        ``progress(index, name, physics_steps)`` at the start of each of :data:`STAGES` (index
        0-4) and once more at the end (index ``len(STAGES)``, name ``"done"``): a front end's
        stage bar.

    Raises
    ------
    UserError
        Model without the contract's names, runs the model cannot replay, too little data.
    """
    t_start = time.perf_counter()
    spec, model, path = _load_spec(model_path, target)
    period = control_period_of(runs)
    try:
        device = Device(model, period, target=target)
    except UserError as exc:
        raise UserError(f"measured data: {exc} (metadata control_period_s, default the sample "
                        "period)") from None
    replay_runs = prepare_runs(runs, device)
    effect_target = om.OMNI if target is None else target  # where the effects are written
    if folds not in sel.FOLD_SCHEMES:
        raise UserError(f"unknown fold scheme {folds!r} (one of {', '.join(sel.FOLD_SCHEMES)})")
    fixed = correction_names(corrections, spec, effect_target, target is not None and target != om.OMNI)
    candidates = tuple(c for c in _usable_candidates(candidates, spec, effect_target, path) if c not in fixed)
    if len(replay_runs) < 2:
        raise UserError("measured data: at least 2 runs are needed (candidates are scored on runs "
                        "held out of their fit)")
    fit_runs, fit_samples = _fit_runs(replay_runs, max_fit_samples)
    builder = fx.ModelBuilder(spec, effect_target)
    log = log or (lambda s: None)
    timings, stage_steps = {}, {}

    progress = progress or (lambda index, name, steps: None)

    def begin(name: str) -> tuple[str, float, int]:
        progress(STAGES.index(name), name, rep.steps)
        return name, time.perf_counter(), rep.steps

    def end(started: tuple[str, float, int]) -> None:
        name, t0, steps0 = started
        timings[f"{name}_s"] = time.perf_counter() - t0
        stage_steps[name] = rep.steps - steps0

    with Replayer(jobs, target, period) as rep:
        st = begin("replay_nominal")
        nominal = replay_nominal(model, replay_runs, fit_runs, rep)
        end(st)
        log(f"gap before {nominal.gap:.3e} rad, noise floor {nominal.noise:.2e} rad, {len(replay_runs)} runs, "
            f"{sum(r.n for r in replay_runs)} samples"
            + (f" (fits use the first {fit_samples} of each run)" if fit_samples else ""))
        st = begin("corrections")
        start = refit_nominal(builder, fixed, fit_runs, rep, nominal.fit_gap, k, folds, log)
        end(st)
        evidence = evidence_of(builder, start, fit_runs, candidates, log)
        st = begin("naming")
        selection = select_effects(builder, candidates, fit_runs, rep, nominal.fit_gap, nominal.noise,
                                   k=k, max_effects=max_effects, log=log, scheme=folds, start=start)
        end(st)
        st = begin("uncertainty_and_evaluation")
        unc, theta_after = estimate(builder, selection.best, fit_runs, replay_runs, rep, nominal.theta)
        end(st)
        st = begin("other_fold_scheme")
        gaps = both_schemes(builder, selection, start, fit_runs, rep, nominal.fit_gap, k, folds, log)
        end(st)
        progress(len(STAGES), "done", rep.steps)
        steps = rep.steps
        warnings = {"unstable_simulations": rep.unstable_replays, "instability_warnings": rep.unstable_warnings,
                    "first": rep.first_warning}
    settings = {"folds": k, "fold_scheme": folds, "corrections": list(fixed),
                "pair_search": not fixed, "max_effects": max_effects, "min_share": sel.MIN_SHARE,
                "noise_factor": sel.NOISE_FACTOR, "tie_margin": sel.TIE_MARGIN,
                "fit_samples_per_run": fit_samples, "model": path, "joint": effect_target.joint,
                "actuator": effect_target.actuator, "candidates": list(candidates),
                "prescreen_s": sel.PRESCREEN_S, "n_screen": sel.N_SCREEN,
                "mujoco": mujoco.__version__}
    report = assemble_report(builder, replay_runs, nominal, theta_after, selection, unc, settings,
                             fixed=fixed, actuator_limit=device.voltage_limit)
    report["gaps"] = gaps
    report["mujoco_warnings"] = warnings
    timings["total_s"] = time.perf_counter() - t_start
    report["timings"] = {**timings, "physics_steps": steps, "physics_steps_per_stage": stage_steps,
                         "steps_per_s": steps / max(timings["total_s"], 1e-9)}
    report["timings"]["evidence"], report["evidence"] = evidence.cost, evidence.to_json()
    return Outcome(report, _patched_spec(builder, selection.best), replay_runs, nominal.theta, theta_after,
                   selection.rounds, evidence)


# -- inputs ------------------------------------------------------------------------------------
def _load_spec(model_path, target: om.Target | None = None) -> tuple[mujoco.MjSpec, mujoco.MjModel, str]:
    path = Path(model_path) if model_path is not None else om.DEFAULT_SCENE
    # UserError on a missing file, bad XML or missing names (the Omni's, or the target's)
    model = om.load_model(path, target=target)
    spec = mujoco.MjSpec.from_file(str(path))
    return spec, model, str(path)


def _usable_candidates(candidates: tuple[str, ...] | None, spec: mujoco.MjSpec, target: om.Target,
                       path: str) -> tuple[str, ...]:
    """The asked-for library names (default: all) that can be written into this model."""
    unknown = [c for c in (candidates or ()) if c not in fx.NAMES]
    if unknown:
        raise UserError(f"unknown candidate effect(s): {', '.join(unknown)} (library: {', '.join(fx.NAMES)})")
    writable = fx.applicable(spec, target)
    usable = tuple(c for c in (candidates or fx.NAMES) if c in writable)
    if not usable:
        raise UserError(f"{path}: none of the candidate effects can be written into this model")
    return usable


def _fit_runs(runs: list[ReplayRun], max_fit_samples: int) -> tuple[list[ReplayRun], int | None]:
    """The runs the fits use and their length per run: the whole runs, or, when all of them
    hold more than ``max_fit_samples`` samples, the start of each (at least
    :data:`MIN_FIT_RUN_SAMPLES`; None: whole runs)."""
    if sum(r.n for r in runs) <= max_fit_samples:
        return runs, None
    n = max(MIN_FIT_RUN_SAMPLES, max_fit_samples // len(runs))
    return [r.truncated(n) for r in runs], n


# -- 1. the nominal model ----------------------------------------------------------------------
@dataclass
class NominalReplay:
    """The nominal model's replay of the runs.

    Attributes
    ----------
    theta : list of ndarray [rad]
        The replayed yaw angle of each run.
    gap : float [rad]
        Its gap to the measured runs (whole runs).
    fit_gap : float [rad]
        Its gap on the samples the fits use (where the first round starts).
    noise : float [rad]
        The measurement noise floor (:func:`discrepancy.select.noise_floor`).
    """

    theta: list
    gap: float
    fit_gap: float
    noise: float


def replay_nominal(model: mujoco.MjModel, runs: list[ReplayRun], fit_runs: list[ReplayRun],
                   rep: Replayer) -> NominalReplay:
    """Replay every run on the nominal model: its gap, on whole runs and on the fits' samples,
    and the noise floor of its residuals."""
    theta = rep.simulate([model], runs)
    residuals = [th - r.theta for th, r in zip(theta, runs)]
    fit_gap = gap([res[: r.n] for res, r in zip(residuals, fit_runs)])
    return NominalReplay(theta, gap(residuals), fit_gap, sel.noise_floor(residuals))


# -- 1b. the nominal's corrections -------------------------------------------------------------
def refit_nominal(builder: fx.ModelBuilder, names: tuple[str, ...], runs: list[ReplayRun], rep: Replayer,
                  gap_start: float, k: int, scheme: str, log) -> Scored | None:
    """The nominal's constants ``names`` refitted together from the user's values and scored
    held out (None without corrections): the model every named effect must beat."""
    if not names:
        return None
    effects = [builder.effect(n) for n in names]
    x0 = np.concatenate([builder.nominal_values(e) for e in effects])
    log(f"corrections: refitting the nominal's {', '.join(names)}")
    sc = sel.score_set(builder, "corrections", effects, x0, runs, rep, gap_start,
                       sel.make_folds(runs, k, scheme), log)
    log(f"corrections: held-out gap {gap_start:.3e} -> {sc.heldout_gap:.3e} rad")
    return sc


def both_schemes(builder: fx.ModelBuilder, selection: "Selection", start: Scored | None,
                 runs: list[ReplayRun], rep: Replayer, gap_nominal: float, k: int, scheme: str,
                 log) -> dict:
    """The held-out gaps [rad] on the fits' samples under both fold schemes: the nominal (no
    parameter fitted: its replay gap), the corrected nominal and the final model (corrections
    plus named effects); the verdict's scheme from the selection, the other rescored."""
    out = {}
    for sch in sel.FOLD_SCHEMES:
        row = {"nominal": gap_nominal}
        for key, sc in (("corrected", start), ("after", selection.best)):
            if sc is None or (key == "after" and sc is start):  # nothing fitted, or nothing named
                row[key] = row.get("corrected", gap_nominal)
                if sc is not None:  # the corrected nominal is the final model: scored once
                    row["after_unstable_replays"] = row["corrected_unstable_replays"]
                continue
            if sch != scheme:
                sc = sel.rescore(builder, sc, runs, rep, sel.make_folds(runs, k, sch), gap_nominal)
            row[key] = sc.heldout_gap
            row[f"{key}_unstable_replays"] = sc.unstable
        row["share_removed_by_effects"] = sel.share_of(row["after"], row["corrected"])
        out[sch] = row
    if log:
        log("held-out gaps: " + "; ".join(f"{sch} folds {r['nominal']:.3e} -> {r['corrected']:.3e} (corrected) "
                                         f"-> {r['after']:.3e} rad" for sch, r in out.items()))
    return out


# -- 2. naming the effects ---------------------------------------------------------------------
@dataclass
class Selection:
    """The forward selection's state and record.

    Attributes
    ----------
    gap : float [rad]
        The held-out gap the next round starts from.
    best : Scored or None
        The accepted set of effects (its fit and folds), None before any is accepted.
    beam : list of (effects, values) or None
        The pair search's confirmed pairs, grown together in the next round.
    pairs_scored : list of Scored
        The pair search's scored pairs (alternatives for the members' runner-ups).
    rounds : list of list of Scored
        Every round's scored candidates (the report's ``candidates``).
    entries : list of dict
        The report's ``rounds``.
    effect_entries : list of dict
        One entry per accepted effect, in the order of ``best.effects`` (its share, runner-up,
        margin, tie).
    """

    gap: float
    best: Scored | None = None
    beam: list | None = None
    fixed: tuple = ()
    pairs_scored: list = field(default_factory=list)
    rounds: list = field(default_factory=list)
    entries: list = field(default_factory=list)
    effect_entries: list = field(default_factory=list)

    @property
    def accepted(self) -> list:
        """The accepted effects (free again in the next round)."""
        return self.best.effects if self.best is not None else []

    @property
    def accepted_x(self) -> np.ndarray:
        """Their fitted values."""
        return self.best.fit.x if self.best is not None else np.zeros(0)

    def accept(self, best: Scored) -> None:
        """Take ``best`` as the accepted set; the next round starts from its held-out gap."""
        self.best, self.gap = best, best.heldout_gap


def select_effects(builder: fx.ModelBuilder, candidates: tuple[str, ...], runs: list[ReplayRun],
                   rep: Replayer, gap_start: float, noise: float, *, k: int, max_effects: int,
                   log, scheme: str = "runs", start: Scored | None = None) -> Selection:
    """Forward selection: each round scores the candidates not yet accepted (with the accepted
    ones free) on held-out runs and accepts the best if it removes a clear share of the gap;
    the first round also searches pairs (:func:`_search_pairs`), a round whose set reaches
    three effects takes the backward step (:func:`_backward_step`).  Rounds: one per effect,
    plus one a backward step can free.

    ``start``: the nominal's corrections (:func:`refit_nominal`), accepted before round 1 and
    free in every round, so each candidate is fitted jointly with them and must beat their
    held-out gap; they are never removed and not counted in ``max_effects``, and the pair search
    is not run (its grid would have to span the corrections too)."""
    state = Selection(gap_start)
    fixed = ()
    if start is not None:
        state.accept(start)
        fixed = tuple(e.name for e in start.effects)
    state.fixed = fixed
    for rnd in range(max_effects + 1):
        if len(state.accepted) - len(fixed) >= max_effects or not _round_due(state, rnd, noise, log):
            break
        names = [c for c in candidates if c not in [e.name for e in state.accepted]]
        if not names:
            break
        log(f"round {rnd + 1}: scoring {len(names)} candidates")
        scored = sel.score_round(builder, state.accepted, state.accepted_x, runs, rep, state.gap, k=k,
                                 # a beam grows every confirmed pair by any candidate not in it
                                 # (the accepted pair's members included)
                                 candidates=tuple(candidates if state.beam else names), log=log,
                                 bases=state.beam, scheme=scheme)
        state.rounds.append(scored)
        _take_null(state, scored)
        entry = _round_entry(rnd, scored, state.gap, noise)
        state.entries.append(entry)
        best = scored[0]
        if (rnd == 0 and max_effects >= 2 and not fixed and _pair_search_due(best, state.gap, noise)
                and _search_pairs(state, builder, names, runs, rep, entry, scored, noise, k, log, scheme)):
            continue  # forward selection goes on from the pair
        if not entry["accepted"]:
            log(f"round {rnd + 1}: best {best.name} removes {best.share:.0%} of the gap: not accepted")
            break
        log(f"round {rnd + 1}: accepted {best.name} (removes {best.share:.0%}; runner-up "
            f"{entry['runner_up']}, margin {entry['margin']:.2f})")
        _accept_round(state, rnd, entry, scored, builder, runs, rep, log)
    return state


def _take_null(state: Selection, scored: list[Scored]) -> None:
    """The round's :data:`~discrepancy.select.NULL` candidate is the accepted set fitted
    again with the round's effort: it becomes the accepted set (its fit and folds) and its
    held-out gap the round's start, against which the candidates' shares were taken."""
    null = [s for s in scored if s.name == sel.NULL]
    if null and state.best is not None:
        n = null[0]
        state.best.fit, state.best.fold_x, state.best.folds = n.fit, n.fold_x, n.folds
        state.best.heldout_raw, state.best.heldout_gap = n.heldout_raw, n.heldout_gap
        state.best.unstable += n.unstable
        state.gap = n.heldout_gap


def _round_due(state: Selection, rnd: int, noise: float, log) -> bool:
    """Whether round ``rnd`` is worth scoring: a gap to explain, above the noise after round 1."""
    if state.gap <= 0:
        log("the model's replay equals the measured data exactly: nothing to name")
        return False
    if rnd > 0 and state.gap < sel.NOISE_FACTOR * noise:
        log(f"round {rnd + 1}: skipped, the held-out gap is at the noise floor")
        return False
    return True


def _round_entry(rnd: int, scored: list[Scored], gap_start: float, noise: float) -> dict:
    """The report's entry of a round: the best candidate, its runner-up and margin (the share of
    the runner-up's held-out gap the best removes on top), whether it is accepted, a tie."""
    best = scored[0]
    runner = scored[1] if len(scored) > 1 and math.isfinite(scored[1].heldout_gap) else None
    margin = sel.share_of(best.heldout_gap, runner.heldout_gap) if runner else 1.0
    ok = best.share >= sel.MIN_SHARE and gap_start >= sel.NOISE_FACTOR * noise
    entry = {"round": rnd + 1, "best": best.name, "share": best.share,
             "runner_up": runner.name if runner else None,
             "runner_up_share": runner.share if runner else None, "margin": margin,
             "gap_start_rad": gap_start, "gap_heldout_rad": best.heldout_gap,
             "accepted": bool(ok)}
    if runner and margin < sel.TIE_MARGIN and sel.NULL not in (best.name, runner.name):
        entry["tie"] = True
        entry["separating_experiment"] = fx.separating_experiment(best.name, runner.name)
    return entry


def _member_entry(rnd: int, best: Scored, name: str, runner_up: str | None, margin: float,
                  gap_start: float, note: str | None) -> dict:
    """The report's entry of one member ``name`` of an accepted set ``best`` (a pair, or a set
    grown from one), with the best alternative for it and the margin."""
    entry = {"round": rnd + 1, "pair": best.name, "best": name, "share": best.share,
             "runner_up": runner_up, "runner_up_share": None, "margin": margin,
             "gap_start_rad": gap_start, "gap_heldout_rad": best.heldout_gap, "accepted": True}
    if note:
        entry["runner_up_note"] = note
    # a tie only with a single alternative effect (not with a set named "a+b")
    if runner_up is not None and "+" not in runner_up and margin < sel.TIE_MARGIN:
        entry["tie"] = True
        entry["separating_experiment"] = fx.separating_experiment(name, runner_up)
    return entry


def _pair_search_due(best: Scored, gap_start: float, noise: float) -> bool:
    """Whether round 1 searches pairs: no single effect explains the gap down to the noise."""
    return (gap_start >= sel.REMAINDER_FACTOR * noise
            and (best.share < sel.PAIR_SEARCH_SHARE or best.heldout_gap >= sel.REMAINDER_FACTOR * noise))


def _search_pairs(state: Selection, builder: fx.ModelBuilder, names: list[str], runs: list[ReplayRun],
                  rep: Replayer, entry: dict, singles: list[Scored], noise: float, k: int, log,
                  scheme: str = "runs") -> bool:
    """Round 1's pair search; True if a pair was accepted (``state`` then holds it).

    Effects that mask each other (a loop delay takes damping away, dry friction adds it) are
    only visible together, and one effect at a time can settle on a stand-in for the pair (a
    Stribeck curve for delay + friction), so every pair is fitted jointly too (not only pairs
    of the round's best candidates: the delay alone explains nothing, and the friction can be
    outranked by a stand-in).  A pair is accepted when it removes a clear share of the gap and
    of what the best single candidate leaves."""
    best_single = singles[0]
    log(f"round 1: the best single candidate removes {best_single.share:.0%} and leaves "
        f"{best_single.heldout_gap / max(noise, 1e-300):.1f} x the noise floor: scoring pairs")
    pairs = sel.score_pairs(builder, runs, rep, state.gap, k=k, candidates=tuple(names), log=log, scheme=scheme)
    best_pair = pairs[0]
    gain = sel.share_of(best_pair.heldout_gap, best_single.heldout_gap)
    pair_ok = (best_pair.share >= sel.MIN_SHARE and gain >= sel.MIN_SHARE
               and state.gap >= sel.NOISE_FACTOR * noise)
    entry["pair_search"] = {"best": best_pair.name, "share": best_pair.share,
                            "gain_over_best_single": gain, "accepted": bool(pair_ok)}
    if not pair_ok:
        log(f"round 1: best pair {best_pair.name} removes {best_pair.share:.0%} ({gain:.0%} of what the "
            "best single leaves): not accepted")
        return False
    state.rounds.append(pairs)
    entry["accepted"] = False
    for eff, (runner_up, margin) in zip(best_pair.effects, sel.pair_runner_up(best_pair, pairs, singles)):
        note = (None if runner_up is not None else
                "no other scored pair keeps the other member; margin is against the other member alone")
        member = _member_entry(0, best_pair, eff.name, runner_up, margin, state.gap, note)
        state.entries.append(member)
        state.effect_entries.append(member)
    log(f"round 1: accepted the pair {best_pair.name} (removes {best_pair.share:.0%}; "
        f"{gain:.0%} of what the best single candidate leaves)")
    state.accept(best_pair)
    # a beam: the next round adds each candidate to each confirmed pair, not only to the
    # accepted one (with a third effect present the best pair can be a stand-in: armature +
    # LuGre explains more of delay + Coulomb + armature than Coulomb + delay, whose fit then
    # compensates the missing armature; the triple grows from Coulomb + delay)
    confirmed = [p for p in pairs if p.method == "refit" and math.isfinite(p.heldout_gap)]
    if len(confirmed) > 1:
        state.beam = [(p.effects, p.fit.x) for p in confirmed]
        state.pairs_scored = [p for p in pairs if math.isfinite(p.heldout_gap)]
    return True


def _accept_round(state: Selection, rnd: int, entry: dict, scored: list[Scored], builder: fx.ModelBuilder,
                  runs: list[ReplayRun], rep: Replayer, log) -> None:
    """Accept round ``rnd``'s best set (after the backward step for three or more effects) and
    record one entry per accepted effect."""
    best, removals = _backward_step(scored[0], entry, rnd, state.gap, builder, runs, rep, log, state.fixed)
    dropped_one = best is not scored[0]
    if state.beam or dropped_one:
        # every member's runner-up is the best scored set without it (this round's sets, the
        # pairs, the set without one member); the set may have grown from another pair than
        # the one accepted
        pool = scored + state.pairs_scored + removals
        note = ("the best scored set without this effect (named by what it holds instead; none: "
                "the effect dropped)")
        state.effect_entries = []
        for eff, (runner_up, margin) in zip(best.effects, sel.member_runner_up(best, pool)):
            if eff.name in state.fixed:  # a correction of the nominal, reported apart
                continue
            member = _member_entry(rnd, best, eff.name, runner_up, margin, state.gap, note)
            state.entries.append(member)
            state.effect_entries.append(member)
        state.beam = None
    else:
        state.effect_entries.append(entry)
    state.accept(best)


def _backward_step(best: Scored, entry: dict, rnd: int, gap_start: float, builder: fx.ModelBuilder,
                   runs: list[ReplayRun], rep: Replayer, log, fixed: tuple = ()) -> tuple[Scored, list[Scored]]:
    """Floating selection's backward step for a set of three or more effects: a member accepted
    earlier may be a stand-in the new member made redundant (a spring fitted with Coulomb
    friction to part of a backlash's gap); each member is removed in turn, the rest refitted,
    and a member whose removal the full set does not clearly improve on is dropped.  Returns
    the set kept and the scored removals (recorded in ``entry["backward_step"]``)."""
    if len([e for e in best.effects if e.name not in fixed]) < 3:
        return best, []
    removals = sel.score_removals(builder, best, runs, rep, gap_start, log=log, keep=fixed)
    without = removals[0]
    contribution = sel.share_of(best.heldout_gap, without.heldout_gap)
    entry["backward_step"] = {"best_without_one": without.name,
                              "share_of_its_gap_removed_by_the_set": contribution}
    if contribution >= sel.MIN_SHARE:
        return best, removals
    dropped = [e.name for e in best.effects if e.name not in [f.name for f in without.effects]][0]
    log(f"round {rnd + 1}: {dropped} dropped (without it the held-out gap is "
        f"{without.heldout_gap:.3e} rad; with it {contribution:.0%} of that is removed, "
        f"less than {sel.MIN_SHARE:.0%})")
    entry["backward_step"]["dropped"] = dropped
    return without, removals


# -- 3. uncertainty and the held-out replay ----------------------------------------------------
def estimate(builder: fx.ModelBuilder, best: Scored | None, fit_runs: list[ReplayRun],
             runs: list[ReplayRun], rep: Replayer, theta_before: list) -> tuple[dict | None, list]:
    """The accepted set's uncertainty (:func:`discrepancy.uncertainty.uncertainty`, on
    the fits' runs) and the held-out replay of the whole runs (each with its fold's
    parameters); with nothing accepted, no uncertainty and the nominal replay."""
    if best is None:
        return None, theta_before
    unc = un.uncertainty(builder, best, fit_runs, rep, ENCODER_STEP_RAD)
    return unc, _heldout_theta(builder, best, runs, rep)


def whole_run_folds(folds: list[sel.Fold], runs: list[ReplayRun]) -> list[sel.Fold]:
    """The folds of the fits' (possibly shortened, :func:`_fit_runs`) runs carried over to the
    whole runs: a run held out whole stays held out whole; a run's samples past the fits'
    records, which no fit saw, are cut into as many blocks as there are folds, fold ``f``
    holding out block ``f`` (so every sample is held out by exactly one fold)."""
    k = len(folds)
    out = []
    for f, fold in enumerate(folds):
        held = []
        for h, r in zip(fold.held, runs):
            if h is None or len(h) >= r.n:
                held.append(h)
                continue
            tail = np.zeros(r.n - len(h), bool)
            if h.all():
                tail[:] = True
            else:
                tail[(f * len(tail)) // k:((f + 1) * len(tail)) // k] = True
            held.append(np.concatenate([h, tail]))
        out.append(sel.Fold(tuple(held)))
    return out


def _heldout_theta(builder: fx.ModelBuilder, scored: Scored, runs: list[ReplayRun],
                   rep: Replayer) -> list[np.ndarray]:
    models = [builder.compile(_split(scored.effects, fold_x)) for fold_x in scored.fold_x]
    return sel.heldout_replays(rep, models, runs, whole_run_folds(scored.folds, runs))


def _split(effects, x) -> list[tuple]:
    """``[(effect, its values in x), ...]`` of effects whose values are concatenated in ``x``."""
    out, i = [], 0
    for e in effects:
        out.append((e, np.asarray(x[i:i + e.nparam], float)))
        i += e.nparam
    return out


def _patched_spec(builder: fx.ModelBuilder, best: Scored | None) -> mujoco.MjSpec:
    """The nominal model with the accepted effects at their all-runs fit (a copy)."""
    if best is None:
        return builder.spec.copy()
    return fx.apply(builder.spec, _split(best.effects, best.fit.x), builder.target)


# -- 4. the report -----------------------------------------------------------------------------
def assemble_report(builder: fx.ModelBuilder, runs: list[ReplayRun], nominal: NominalReplay,
                    theta_after: list, selection: Selection, unc: dict | None, settings: dict,
                    fixed: tuple[str, ...] = (), actuator_limit: float = math.inf) -> dict:
    """The content of ``report.json`` (the run-time fields ``mujoco_warnings`` and ``timings``
    are added by :func:`run_discrepancy`).  ``actuator_limit``: the actuator's command limit
    (its ``ctrlrange``, inf if unlimited), which with each run's ``command_limit`` says when
    the command is near its limit (:func:`~discrepancy.localise.command_bins`)."""
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
        effects = [_none_item(selection.entries, gap_before, noise)]
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
               for c in (rounds[0] if rounds else []) if c.method != "prescreen" and c.name != sel.NULL][:3]
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
            "parameters": {p.name: float(v) for e, x in _split(s.effects, s.fit.x)
                           for p, v in zip(e.params, x)}}


def _none_item(entries: list[dict], gap_before: float, noise: float) -> dict:
    """The report's effect ``none``: nothing named, the best candidate and why."""
    first = entries[0] if entries else {"best": None, "share": None, "runner_up": None, "margin": None}
    if gap_before <= 0:
        reason = "the model's replay equals the measured data exactly (gap 0): nothing is missing"
    elif gap_before >= sel.REMAINDER_FACTOR * noise:
        reason = (f"no library candidate removes a clear share of the held-out gap, which stands at "
                  f"{gap_before / max(noise, 1e-300):.0f} x the noise floor: the gap is UNEXPLAINED (an "
                  "effect outside the library, or several), the model is not confirmed")
    elif gap_before >= sel.NOISE_FACTOR * noise:
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
    for eff, x in _split(best.effects, best.fit.x):
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


def _correction_items(builder: fx.ModelBuilder, best: Scored, unc: dict, fixed: tuple[str, ...]) -> list[dict]:
    """The report's ``corrections``: each refitted constant of the nominal with the user's value,
    the fitted one, its 95 % half-width (as the effects'), the factor moved, and a warning when
    it moved by more than :data:`PLAUSIBLE_FACTOR` or sits on a bound.

    ``within_factor`` (bool) says the fitted value lies within :data:`PLAUSIBLE_FACTOR` of the
    user's value, ``plausible_factor`` is that factor, ``at_bound`` the bound it sits on (or
    None); ``plausible`` (kept for compatibility) is ``within_factor and not at_bound``: those
    two checks only, not a test of the value against the truth."""
    cover = un.coverage_factor(len(best.folds))
    se, bias = unc["se"], unc["measurement_bias"]
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
            if notes:
                item["warning"] = "; ".join(notes)
            out.append(item)
    return out


def _effect_items(builder: fx.ModelBuilder, best: Scored, effect_entries: list[dict], unc: dict,
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
