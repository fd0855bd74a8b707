"""The search for the effects a model misses: one :class:`Search` per workflow run.

The search shares one bundle through all its steps: the :class:`~discrepancy.effects.ModelBuilder`
(the nominal model and the library), the runs the fits use, the
:class:`~discrepancy.replay.Replayer`, the folds (their number ``k`` and scheme), the noise
floor, the gap it starts from and the log.  :class:`Search` holds it, with a
:class:`~discrepancy.select.Scorer` (which scores sets of effects on the folds), and runs the
workflow's stages after the nominal replay:

1. :meth:`Search.refit_nominal`: the nominal's corrections, refitted and scored held out;
2. :meth:`Search.select`: forward selection, one round per effect (every candidate screened and
   scored on held-out samples), with the pair search of the first round and the backward step
   of floating selection; its state and record is a :class:`Selection`;
3. :meth:`Search.estimate`: the accepted set's uncertainty and the held-out replay of the
   patched model on the whole runs;
4. :meth:`Search.both_schemes`: the held-out gaps under both fold schemes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from omni_sim.device import ENCODER_STEP_RAD
from . import effects as fx
from . import select as sel
from . import uncertainty as un
from .fit import FitResult, split_values
from .replay import Replayer
from .runs import ReplayRun
from .select import Scored


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
    fixed : tuple of str
        The nominal's corrections (accepted before round 1, never removed).
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

    def take_null(self, scored: list[Scored]) -> None:
        """The round's :data:`~discrepancy.select.NULL` candidate is the accepted set fitted
        again with the round's effort: it becomes the accepted set (its fit and folds) and its
        held-out gap the round's start, against which the candidates' shares were taken."""
        null = [s for s in scored if s.name == sel.NULL]
        if null and self.best is not None:
            n = null[0]
            self.best.fit, self.best.fold_x, self.best.folds = n.fit, n.fold_x, n.folds
            self.best.heldout_raw, self.best.heldout_gap = n.heldout_raw, n.heldout_gap
            self.best.unstable += n.unstable
            self.gap = n.heldout_gap


class Search:
    """The search for the missing effects on the fits' runs, from the nominal's replay gap.

    Parameters
    ----------
    builder : discrepancy.effects.ModelBuilder
        The nominal model and the library.
    runs : list of ReplayRun
        The runs the fits use (possibly shortened to the sample budget).
    rep : discrepancy.replay.Replayer
    gap : float [rad]
        The nominal's replay gap on ``runs`` (where the search starts).
    noise : float [rad]
        The measurement noise floor (:func:`discrepancy.select.noise_floor`).
    k : int
        Folds for held-out scoring.
    scheme : str
        The verdict's fold scheme (:data:`discrepancy.select.FOLD_SCHEMES`).
    log : callable, optional
        ``log(line)``: the search's progress in words.

    Attributes
    ----------
    scorer : discrepancy.select.Scorer
        Scores sets of effects on the verdict's folds.
    start : Scored or None
        The nominal's corrections (:meth:`refit_nominal`; None without).
    selection : Selection
        The forward selection's state and record (:meth:`select`).
    """

    def __init__(self, builder: fx.ModelBuilder, runs: list[ReplayRun], rep: Replayer, *, gap: float,
                 noise: float, k: int = 5, scheme: str = "blocked", log=None):
        self.builder, self.runs, self.rep = builder, runs, rep
        self.gap_nominal, self.noise = gap, noise
        self.k, self.scheme = k, scheme
        self.log = log or (lambda s: None)
        self.scorer = sel.Scorer(builder, runs, rep, sel.make_folds(runs, k, scheme), self.log)
        self.start: Scored | None = None
        self.selection = Selection(gap)

    # -- the nominal's corrections ---------------------------------------------------------------
    def refit_nominal(self, names: tuple[str, ...]) -> Scored | None:
        """The nominal's constants ``names`` refitted together from the user's values and scored
        held out (None without corrections): the model every named effect must beat."""
        if not names:
            return None
        effects = [self.builder.effect(n) for n in names]
        x0 = np.concatenate([self.builder.nominal_values(e) for e in effects])
        self.log(f"corrections: refitting the nominal's {', '.join(names)}")
        self.start = self.scorer.score_set("corrections", effects, x0, self.gap_nominal)
        self.log(f"corrections: held-out gap {self.gap_nominal:.3e} -> {self.start.heldout_gap:.3e} rad")
        return self.start

    # -- naming the effects ----------------------------------------------------------------------
    def select(self, candidates: tuple[str, ...], max_effects: int, evidence=None) -> Selection:
        """Forward selection: each round scores the candidates not yet accepted (with the
        accepted ones free) on held-out samples and accepts the best if it removes a clear share
        of the gap; the first round also searches pairs (:meth:`_search_pairs`), a round whose
        set reaches three effects takes the backward step (:meth:`_backward_step`).  Rounds: one
        per effect, plus one a backward step can free.

        The nominal's corrections (:attr:`start`, :meth:`refit_nominal`) are accepted before
        round 1 and free in every round, so each candidate is fitted jointly with them and must
        beat their held-out gap; they are never removed and not counted in ``max_effects``, and
        the pair search is not run (its grid would have to span the corrections too).  Round 1
        takes their confirmed fit as its :data:`~discrepancy.select.NULL` (fitted with a
        candidate's effort already).

        ``evidence`` (:class:`~discrepancy.evidence.Evidence`, optional): the missing torque with
        the candidates fitted to it by equation error.  When some law has its shape
        (:attr:`~discrepancy.evidence.Evidence.explained_enough`), round 1 prescreens
        only the :data:`~discrepancy.select.N_SCREEN` candidates it ranks best among those it
        could judge, each with its equation-error fit as one more starting point, and every
        candidate it could not judge (:func:`shape_shortlist`); the others are listed with their
        equation-error fit only.  When none has (the best explains under half), its ranking says
        nothing of which law stands in best in the closed loop, and every candidate is
        prescreened as without evidence (a rule made after the bank's gain_slope case, a torque
        constant that varies with the angle, went from torque_gain to a spring started at its
        equation-error fit, its best law explaining 47 %)."""
        state = self.selection
        if self.start is not None:
            state.accept(self.start)
            state.fixed = tuple(e.name for e in self.start.effects)
        for rnd in range(max_effects + 1):
            if len(state.accepted) - len(state.fixed) >= max_effects or not self._round_due(rnd):
                break
            names = [c for c in candidates if c not in [e.name for e in state.accepted]]
            if not names:
                break
            self.log(f"round {rnd + 1}: scoring {len(names)} candidates")
            shortlist, left_out, starts = names, [], None
            if rnd == 0 and evidence is not None and evidence.explained_enough:
                shortlist, left_out = shape_shortlist(evidence, names, sel.N_SCREEN)
                # the candidates' equation-error fits, and their nested variants' (select.nested_variants)
                starts = {f.name: f.x for f in evidence.fits if f.x is not None
                          and (f.name in shortlist or self.builder.parent(f.name) in shortlist)}
                self.log(f"round 1: equation error leaves out {', '.join(left_out) or 'none'}; "
                         f"prescreening {', '.join(shortlist)}")
            # every fold refit of the round starts from the fold values of the largest set it
            # holds among the accepted one and the beam's confirmed pairs
            self.scorer.known = tuple(k for k in [state.best] + state.pairs_scored if k is not None)
            # a beam grows every confirmed pair by any candidate not in it (the accepted pair's
            # members included)
            scored = self.scorer.score_round(state.accepted, state.accepted_x, state.gap,
                                             candidates=tuple(candidates if state.beam else shortlist),
                                             bases=state.beam, starts=starts,
                                             null=self.start if rnd == 0 else None)
            scored += [self._by_shape_only(evidence.fit_of(n)) for n in left_out]
            state.rounds.append(scored)
            state.take_null(scored)
            entry = round_entry(rnd, scored, state.gap, self.noise)
            state.entries.append(entry)
            best = scored[0]
            if (rnd == 0 and max_effects >= 2 and not state.fixed and self._pair_search_due(best)
                    and self._search_pairs(names, entry, scored)):
                continue  # forward selection goes on from the pair
            if not entry["accepted"]:
                self.log(f"round {rnd + 1}: best {best.name} removes {best.share:.0%} of the gap: not accepted")
                break
            self.log(f"round {rnd + 1}: accepted {best.name} (removes {best.share:.0%}; runner-up "
                     f"{entry['runner_up']}, margin {entry['margin']:.2f})")
            self._accept_round(rnd, entry, scored)
        return state

    def _by_shape_only(self, shape_fit) -> Scored:
        """A candidate round 1 did not prescreen, as the round lists it: with the accepted set
        at its values and the candidate at its equation-error fit, no closed-loop score."""
        state = self.selection
        effects = list(state.accepted) + [self.builder.effect(shape_fit.name)]
        x = np.concatenate([state.accepted_x, shape_fit.x])
        return Scored(shape_fit.name, effects, FitResult(effects, x, x, math.nan), method="equation-error")

    def _round_due(self, rnd: int) -> bool:
        """Whether round ``rnd`` is worth scoring: a gap to explain, above the noise after round 1."""
        gap_start = self.selection.gap
        if gap_start <= 0:
            self.log("the model's replay equals the measured data exactly: nothing to name")
            return False
        if rnd > 0 and gap_start < sel.NOISE_FACTOR * self.noise:
            self.log(f"round {rnd + 1}: skipped, the held-out gap is at the noise floor")
            return False
        return True

    def _pair_search_due(self, best: Scored) -> bool:
        """Whether round 1 searches pairs: no single effect explains the gap down to the noise."""
        floor = sel.REMAINDER_FACTOR * self.noise
        return (self.selection.gap >= floor
                and (best.share < sel.PAIR_SEARCH_SHARE or best.heldout_gap >= floor))

    def _search_pairs(self, names: list[str], entry: dict, singles: list[Scored]) -> bool:
        """Round 1's pair search; True if a pair was accepted (:attr:`selection` then holds it).

        Effects that mask each other (a loop delay takes damping away, dry friction adds it) are
        only visible together, and one effect at a time can settle on a stand-in for the pair (a
        Stribeck curve for delay + friction), so every pair is fitted jointly too (not only pairs
        of the round's best candidates: the delay alone explains nothing, and the friction can be
        outranked by a stand-in).  A pair is accepted when it removes a clear share of the gap
        and of what the best single candidate leaves."""
        state, best_single = self.selection, singles[0]
        self.log(f"round 1: the best single candidate removes {best_single.share:.0%} and leaves "
                 f"{best_single.heldout_gap / max(self.noise, 1e-300):.1f} x the noise floor: scoring pairs")
        pairs = self.scorer.score_pairs(state.gap, candidates=tuple(names)) if len(names) > 1 else []
        if not pairs:  # one candidate (e.g. a study restricted to one effect), or none pairs with another
            self.log("round 1: no pair of candidates to score")
            return False
        best_pair = pairs[0]
        gain = sel.share_of(best_pair.heldout_gap, best_single.heldout_gap)
        pair_ok = (best_pair.share >= sel.MIN_SHARE and gain >= sel.MIN_SHARE
                   and state.gap >= sel.NOISE_FACTOR * self.noise)
        entry["pair_search"] = {"best": best_pair.name, "share": best_pair.share,
                                "gain_over_best_single": gain, "accepted": bool(pair_ok)}
        if not pair_ok:
            self.log(f"round 1: best pair {best_pair.name} removes {best_pair.share:.0%} ({gain:.0%} of what "
                     "the best single leaves): not accepted")
            return False
        state.rounds.append(pairs)
        entry["accepted"] = False
        for eff, (runner_up, margin) in zip(best_pair.effects, sel.pair_runner_up(best_pair, pairs, singles)):
            note = (None if runner_up is not None else
                    "no other scored pair keeps the other member; margin is against the other member alone")
            member = member_entry(0, best_pair, eff.name, (runner_up, margin), state.gap, note=note)
            state.entries.append(member)
            state.effect_entries.append(member)
        self.log(f"round 1: accepted the pair {best_pair.name} (removes {best_pair.share:.0%}; "
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

    def _accept_round(self, rnd: int, entry: dict, scored: list[Scored]) -> None:
        """Accept round ``rnd``'s best set (after the backward step for three or more effects)
        and record one entry per accepted effect."""
        state = self.selection
        best, removals = self._backward_step(scored[0], entry, rnd)
        dropped_one = best is not scored[0]
        if state.beam or dropped_one:
            # every member's runner-up is the best scored set without it (this round's sets, the
            # pairs, the set without one member); the set may have grown from another pair than
            # the one accepted
            pool = scored + state.pairs_scored + removals
            note = ("the best scored set without this effect (named by what it holds instead; none: "
                    "the effect dropped)")
            state.effect_entries = []
            for eff, alternative in zip(best.effects, sel.member_runner_up(best, pool)):
                if eff.name in state.fixed:  # a correction of the nominal, reported apart
                    continue
                member = member_entry(rnd, best, eff.name, alternative, state.gap, note=note)
                state.entries.append(member)
                state.effect_entries.append(member)
            state.beam = None
        else:
            state.effect_entries.append(entry)
        state.accept(best)

    def _backward_step(self, best: Scored, entry: dict, rnd: int) -> tuple[Scored, list[Scored]]:
        """Floating selection's backward step for a set of three or more effects: a member
        accepted earlier may be a stand-in the new member made redundant (a spring fitted with
        Coulomb friction to part of a backlash's gap); each member is removed in turn, the rest
        refitted, and a member whose removal the full set does not clearly improve on is
        dropped.  Returns the set kept and the scored removals (recorded in
        ``entry["backward_step"]``)."""
        fixed = self.selection.fixed
        if len([e for e in best.effects if e.name not in fixed]) < 3:
            return best, []
        removals = self.scorer.score_removals(best, self.selection.gap, keep=fixed)
        without = removals[0]
        contribution = sel.share_of(best.heldout_gap, without.heldout_gap)
        entry["backward_step"] = {"best_without_one": without.name,
                                  "share_of_its_gap_removed_by_the_set": contribution}
        if contribution >= sel.MIN_SHARE:
            return best, removals
        dropped = [e.name for e in best.effects if e.name not in [f.name for f in without.effects]][0]
        self.log(f"round {rnd + 1}: {dropped} dropped (without it the held-out gap is "
                 f"{without.heldout_gap:.3e} rad; with it {contribution:.0%} of that is removed, "
                 f"less than {sel.MIN_SHARE:.0%})")
        entry["backward_step"]["dropped"] = dropped
        return without, removals

    # -- uncertainty and the held-out replay -----------------------------------------------------
    def estimate(self, runs: list[ReplayRun], theta_before: list) -> tuple[dict | None, list]:
        """The accepted set's uncertainty (:func:`discrepancy.uncertainty.uncertainty`, on the
        fits' runs) and the held-out replay of the whole ``runs`` (each with its fold's
        parameters); with nothing accepted, no uncertainty and the nominal replay
        ``theta_before``."""
        best = self.selection.best
        if best is None:
            return None, theta_before
        unc = un.uncertainty(self.builder, best, self.runs, self.rep, ENCODER_STEP_RAD)
        models = [self.builder.compile(split_values(best.effects, fold_x)) for fold_x in best.fold_x]
        return unc, sel.heldout_replays(self.rep, models, runs, whole_run_folds(best.folds, runs))

    # -- the other fold scheme -------------------------------------------------------------------
    def both_schemes(self) -> dict:
        """The held-out gaps [rad] on the fits' samples under both fold schemes: the nominal (no
        parameter fitted: its replay gap), the corrected nominal and the final model
        (corrections plus named effects); the verdict's scheme from the selection, the other
        rescored."""
        start, gap_nominal = self.start, self.gap_nominal
        out = {}
        for sch in sel.FOLD_SCHEMES:
            row = {"nominal": gap_nominal}
            scorer = self.scorer.on(sel.make_folds(self.runs, self.k, sch))
            for key, sc in (("corrected", start), ("after", self.selection.best)):
                if sc is None or (key == "after" and sc is start):  # nothing fitted, or nothing named
                    row[key] = row.get("corrected", gap_nominal)
                    if sc is not None:  # the corrected nominal is the final model: scored once
                        row["after_unstable_replays"] = row["corrected_unstable_replays"]
                    continue
                if sch != self.scheme:
                    # the corrections from the user's values, the named set from the corrections'
                    # fold values there (:meth:`Scorer.fold_starts`)
                    users = (np.concatenate([self.builder.nominal_values(e) for e in sc.effects])
                             if key == "corrected" else None)
                    sc = scorer.rescore(sc, gap_nominal, new_at=users)
                    scorer = scorer.on(scorer.folds, known=(sc,))
                row[key] = sc.heldout_gap
                row[f"{key}_unstable_replays"] = sc.unstable
            row["share_removed_by_effects"] = sel.share_of(row["after"], row["corrected"])
            out[sch] = row
        self.log("held-out gaps: " + "; ".join(
            f"{sch} folds {r['nominal']:.3e} -> {r['corrected']:.3e} (corrected) -> {r['after']:.3e} rad"
            for sch, r in out.items()))
        return out


def shape_shortlist(evidence, names: list[str], n: int) -> tuple[list[str], list[str]]:
    """Round 1's candidates for the closed-loop prescreen, by the evidence's equation-error
    ranking (:attr:`~discrepancy.evidence.Evidence.fits`): of the candidates it scored, the ``n``
    that explain most of the missing torque; every candidate it could not judge (a filter,
    bristles, a delay, a two-mass drive: only a replay sees them) or did not fit.  Returns the
    shortlist (in the order of ``names``) and the candidates left out (by their ranking).

    Why ``n`` = :data:`~discrepancy.select.N_SCREEN`, fixed before any case was run with it: the
    prescreen passes that many candidates on to the held-out screening, so the equation error
    chooses among the laws it can judge no fewer than the prescreen would pass on."""
    judged = [f.name for f in evidence.fits if f.explained is not None and f.name in names]
    keep = set(judged[:n])
    return [c for c in names if c not in judged or c in keep], judged[n:]


def round_entry(rnd: int, scored: list[Scored], gap_start: float, noise: float) -> dict:
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
    if best.variants:  # a nested family's variants, confirmed and chosen among (select.nested_variants)
        entry["variants"] = {**best.variants, "chosen": best.effects[-1].name}
    if runner and margin < sel.TIE_MARGIN and sel.NULL not in (best.name, runner.name):
        entry["tie"] = True
        entry["separating_experiment"] = fx.separating_experiment(best.name, runner.name)
    return entry


def member_entry(rnd: int, best: Scored, name: str, alternative: tuple[str | None, float],
                 gap_start: float, *, note: str | None = None) -> dict:
    """The report's entry of one member ``name`` of an accepted set ``best`` (a pair, or a set
    grown from one), with ``alternative``: the best alternative for it (its runner-up, None
    when the member is dropped) and the margin."""
    runner_up, margin = alternative
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


def whole_run_folds(folds: list[sel.Fold], runs: list[ReplayRun]) -> list[sel.Fold]:
    """The folds of the fits' (possibly shortened, :func:`discrepancy.workflow._fit_runs`) runs carried over to the
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
