"""Name the missing effect: score every candidate on held-out runs, accept the best if it
removes a clear share of the gap, repeat (forward selection, up to three effects).

Scoring (per round):

1. *prescreen* every candidate on short records (the first :data:`PRESCREEN_S` seconds
   of each run): its grid, then a few damped Gauss-Newton steps, all candidates in lockstep so
   each iteration is one batch of rollouts (earlier accepted effects stay free so effects can
   trade off).  A candidate costs a few short batches, not a campaign;
2. *screen* the :data:`N_SCREEN` best on all runs: least squares from the prescreen's point,
   then the held-out gap with k-fold over runs, each fold's parameters from one Gauss-Newton
   step from the all-runs fit with the held-out runs' rows removed (cheap: one Jacobian; a
   ranking only, of which candidates to confirm);
3. *confirm*: the best candidates (``n_confirm``) are refitted on each fold's training samples,
   from a start that never saw the fold's held-out samples and to a stated convergence
   (:func:`~discrepancy.folds.fold_starts`, :func:`~discrepancy.folds.refit_folds`), and their
   held-out samples simulated with those parameters; this held-out gap decides.  The fold fits
   also give a jackknife spread of each parameter.

Acceptance (held-out stopping): the best candidate's held-out gap must fall by at least
``min_share`` of the gap it started from, and that starting gap must stand clearly above the
measurement noise floor (``noise_factor`` times the noise estimated from the residual's
sample-to-sample roughness).

The scores share one bundle, held by a :class:`Scorer` (its rounds, pairs, given sets,
removals and rescoring as methods; :class:`discrepancy.search.Search` holds one).  The MuJoCo
side comes in from the caller: ``builder`` (:class:`~discrepancy.effects.ModelBuilder`:
effects by name, their nominal values, compiled models) and ``rep``
(:class:`~discrepancy.replay.Replayer`: simulates models on runs); this module only
fits, scores and compares; the folds and the fits on them are in :mod:`.folds`, the prescreen
and the pairs' starting grids in :mod:`.prescreen`.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .fit import FitResult, Problem, gap, rough
from .nesting import choose_variant
# the folds and the prescreen are named here too, where the search and the studies read them
from .folds import (CONFIRM_NFEV, FOLD_SCHEMES, Fold, block_folds,  # noqa: F401
                    fold_starts, heldout, heldout_replays, make_folds, onestep_folds, polish_folds, refit_folds,
                    run_folds)
from .prescreen import (N_SCREEN, NULL, PAIR_FITS, PAIR_GRID_POINTS, PAIR_GRID_S, PRESCREEN_ITERATIONS,  # noqa: F401
                        PRESCREEN_S, Prescreened, grid_minima, lockstep_gauss_newton, prescreen, thin_grid)
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


#: Candidates (best by the screen's held-out gap) confirmed with per-fold refits, at most.
N_CONFIRM = 2
#: After the best, a screened candidate is confirmed only when its screen held-out gap is below
#: this many times the best confirmed gap: one further behind changes neither the verdict nor
#: the confidence (a "high" needs the runner-up's gap >= 1.25 x the best's, a margin of
#: 2 x :data:`TIE_MARGIN`) unless its refit lands 37.5 % below its screen.  Fixed before the
#: bank's run that logged every confirmation's screen and refit gaps (its check: no runner-up
#: screened at >= 2 x the best's gap came within 1.25 x of it after its refit; 23 of 38, the
#: closest at 2.33 x: docs/studies/discrepancy/confirmation_log.json).
CONFIRM_WITHIN = 2.0
#: Pairs are searched when the best single candidate removes less than this share of the gap.
PAIR_SEARCH_SHARE = 0.5


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
        ``"one-step"`` or ``"refit"`` (how the fold parameters were obtained).
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
    unconverged: int = 0  # per-fold refits stopped by their step limit (still moving)
    #: A nested family's variants confirmed in its place ({name: held-out gap}), empty otherwise.
    variants: dict = field(default_factory=dict)
    #: Its screen's held-out gap before its per-fold refits (a nested variant: the record of what a
    #: gate on the screen would have decided), NaN otherwise.
    screen_gap: float = math.nan


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
    #: Sets scored on these folds whose fold values start the fold refits of the sets that hold
    #: them (:func:`~discrepancy.folds.fold_starts`): the corrections, the accepted set, the beam's pairs.
    known: tuple = ()

    def on(self, folds: list[Fold], known: tuple = ()) -> "Scorer":
        """This scorer on other ``folds`` (the same runs), with the sets ``known`` there."""
        return dataclasses.replace(self, folds=folds, known=tuple(known))

    def problem(self, effects: list, runs: list[ReplayRun] | None = None) -> Problem:
        """The least-squares problem of ``effects`` free on ``runs`` (default: all the runs)."""
        return Problem(self.builder, [], effects, self.runs if runs is None else runs, self.rep)

    # -- one round ---------------------------------------------------------------------------------
    def score_round(self, accepted: list, accepted_x: np.ndarray, gap_start: float, *,
                    candidates: tuple[str, ...] | None = None, bases: list | None = None,
                    n_confirm: int = N_CONFIRM, screen_nfev: int = 4, n_screen: int | None = None,
                    prescreen_s: float | None = None, null: Scored | None = None,
                    starts: dict | None = None) -> list[Scored]:
        """Fit and score every candidate not yet accepted; best first.

        With ``bases`` (a beam: several sets of effects with their fitted values, e.g. the pairs
        the pair search confirmed), every candidate is added to every base it is not in, all of
        them prescreened in one lockstep; the scored sets are named ``"a+b+c"`` (base, then the
        candidate) and the best set wins, whichever base it grew from.

        Parameters
        ----------
        accepted, accepted_x : list of Effect, ndarray
            Effects accepted in earlier rounds and their fitted values (free again in this round).
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
        null : Scored, optional
            The accepted set already fitted and scored with a confirmed candidate's effort (the
            nominal's corrections in round 1, :meth:`score_set`): it stands as the round's
            :data:`NULL` instead of being fitted again.
        starts : dict, optional
            ``{name: values}``: one more starting point of a candidate's prescreen (its own
            parameters, e.g. its equation-error fit).
        """
        names = [n for n in (candidates or self.builder.names) if n not in [e.name for e in accepted]]
        jobs = None
        if bases:
            jobs = [(list(b), bx, n) for b, bx in bases for n in (candidates or self.builder.names)
                    if n not in [e.name for e in b]]
        given = null is not None and accepted and not bases  # the set so far, confirmed already
        if accepted and not bases:  # the set so far, fitted and scored exactly as every candidate
            jobs = [(list(accepted), accepted_x, n) for n in names]
            if not given:
                jobs.append((list(accepted), accepted_x, None))
        pre = prescreen(self.builder, accepted, accepted_x, names, self.runs, self.rep,
                        seconds=PRESCREEN_S if prescreen_s is None else prescreen_s, log=self.log, jobs=jobs,
                        starts=starts, beam=bool(bases))
        scored = self._screen_all(pre, gap_start, N_SCREEN if n_screen is None else n_screen,
                                  screen_nfev=screen_nfev, width=36 if bases else 18)
        if given:  # no replay spent on it again
            scored.append(dataclasses.replace(null, name=NULL, seconds=0.0, unstable=0, prescreen_gap=math.nan))
            if self.log:
                self.log(f"  {NULL:18s} refit  held-out gap {null.heldout_gap:.3e} rad (as confirmed before)")
        nulls = [sc for sc in scored if sc.name == NULL]
        # the set so far is always confirmed, and each share is against its held-out gap: a
        # candidate must beat the set re-fitted with the same effort, not the set as the last
        # round left it
        if nulls and not given:
            self._confirm(nulls[0], gap_start)
        out = self.confirm_best([sc for sc in scored if sc.name != NULL], gap_start, n_confirm)
        out = out if bases else nested_variants(self, out, gap_start, starts=starts, accepted_x=accepted_x)
        if not nulls:
            return out
        for sc in out + nulls:
            sc.share = share_of(sc.heldout_gap, nulls[0].heldout_gap)
        return sorted(out + nulls, key=lambda sc: sc.heldout_gap)

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
            sc = self._screened(c.name, c.effects, prob, fit, gap_start, t0, width=width)
            sc.prescreen_gap = c.gap
            sc.unstable += c.unstable
            scored.append(sc)
        return scored

    # -- screening and confirmation --------------------------------------------------------------
    def _screened(self, name: str, effects: list, prob: Problem, fit: FitResult, gap_start: float,
                  t0: float, *, width: int = 18) -> Scored:
        """Score an all-runs fit on held-out samples with one Gauss-Newton step per fold."""
        fold_x = onestep_folds(prob, fit, self.folds)
        raw = heldout(prob, fold_x, self.folds)
        g = gap(raw)
        s = Scored(name, effects, fit, g, share_of(g, gap_start), "one-step", raw, fold_x, self.folds,
                   time.perf_counter() - t0, unstable=prob.unstable)
        if self.log:
            self.log(f"  {name:{width}s} screen held-out gap {g:.3e} rad (share {s.share:+.2f}) "
                     f"x={np.array2string(fit.x, precision=4)} [{s.seconds:.1f} s]")
        return s

    def confirm_best(self, scored: list[Scored], gap_start: float, n_confirm: int,
                     within: float = CONFIRM_WITHIN) -> list[Scored]:
        """Refit the best screened candidate per fold, and each next of the ``n_confirm`` best
        screened below ``within`` (:data:`CONFIRM_WITHIN`; inf: all) times the best refitted
        gap; the refitted first (best first), then the others as screened."""
        scored.sort(key=lambda s: s.heldout_gap)
        done = []
        for s in scored[:n_confirm]:
            best = min((c.heldout_gap for c in done), default=math.inf)
            if done and not s.heldout_gap < within * best:
                if self.log:
                    self.log(f"  {s.name:18s} not confirmed: screened at {s.heldout_gap / best:.1f}x the best")
                continue
            self._confirm(s, gap_start)
            done.append(s)
        return sorted(done, key=lambda s: s.heldout_gap) + [s for s in scored if all(s is not c for c in done)]

    def _confirm(self, s: Scored, gap_start: float, nfev: int | None = None, new_at=None) -> None:
        """Converge the all-runs fit of ``s`` and score it with per-fold refits to convergence,
        each from a start that never saw its held-out samples (:func:`~discrepancy.folds.fold_starts`; ``new_at``
        as there), in place."""
        t0 = time.perf_counter()
        prob = self.problem(s.effects)
        # the screening fit already simulated its end point (same model, runs and effects): the
        # converging fit starts there without simulating it again
        prob.seed(s.fit)
        s.fit = prob.fit(s.fit.x, None, max_nfev=nfev or CONFIRM_NFEV)  # converge the all-runs fit
        # a rough parameter (a backlash's slack): the trust-region fit stops in a jagged local
        # minimum wherever it started; the basin search moves it to the basin's centre
        s.fit = prob.polish(s.fit)
        s.fold_x = self._refit_folds(prob, s.effects, new_at)
        s.heldout_raw = heldout(prob, s.fold_x, self.folds)
        s.heldout_gap = gap(s.heldout_raw)
        s.share = share_of(s.heldout_gap, gap_start)
        s.method = "refit"
        s.unstable += prob.unstable
        s.unconverged = prob.unconverged
        s.seconds += time.perf_counter() - t0
        if self.log:
            late = f"; {prob.unconverged} fold(s) unconverged" if prob.unconverged else ""
            self.log(f"  {s.name:18s} refit  held-out gap {s.heldout_gap:.3e} rad (share {s.share:+.2f}{late})")

    def _refit_folds(self, prob: Problem, effects: list, new_at=None) -> list[np.ndarray]:
        """Each fold's parameters, fitted on its training samples from :func:`~discrepancy.folds.fold_starts`:
        to convergence (:func:`refit_folds`), or, for a set with a rough parameter, by the basin
        search (:func:`polish_folds`, the same estimator as the all-runs fit, so the jackknife
        sees its spread)."""
        start = fold_starts(prob, self.folds, self.known, new_at)
        return polish_folds(prob, self.folds, start) if rough(effects) else refit_folds(prob, self.folds, start)

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
        all pairs' grid points simulated together on the first ``grid_s`` seconds of each run;
        the ``n_fit`` best pairs are fitted on all runs and screened on held-out samples like the
        single candidates, and the best ``n_confirm`` all confirmed with per-fold refits.
        """
        starts = self._pair_starts(candidates or self.builder.names, grid_s, grid_points, n_fit)
        scored = []
        for _, a, b, x0 in starts[:n_fit]:
            t0 = time.perf_counter()
            effects = [self.builder.effect(a), self.builder.effect(b)]
            prob = self.problem(effects)
            fit = prob.fit(x0, None, max_nfev=screen_nfev)
            scored.append(self._screened(f"{a}+{b}", effects, prob, fit, gap_start, t0, width=36))
        # all refitted: they are the next round's beam (the best pair may be a stand-in)
        return self.confirm_best(scored, gap_start, n_confirm, within=math.inf)

    def _pair_starts(self, names, grid_s: float, grid_points: int, n_fit: int) -> list[tuple]:
        """Every pair of ``names`` at the best point of its grid on the first ``grid_s`` seconds
        of each run: ``(gap, a, b, point)``, best first (the ``n_fit`` best logged)."""
        builder = self.builder
        grid_runs = [r.first_seconds(grid_s) for r in self.runs]
        t0 = time.perf_counter()
        combos = list(itertools.combinations(names, 2))
        probs, grids = [], []
        for a, b in combos:
            effects = [builder.effect(a), builder.effect(b)]
            prob = self.problem(effects, grid_runs)
            ga = thin_grid(effects[0].grid(builder.nominal_values(effects[0])), grid_points)
            gb = thin_grid(effects[1].grid(builder.nominal_values(effects[1])), grid_points)
            x0 = np.concatenate([builder.nominal_values(e) for e in effects])
            grids.append([np.clip(np.concatenate([effects[0].clip(np.asarray(u, float)),
                                                  effects[1].clip(np.asarray(v, float))]), prob.lower, prob.upper)
                          for u in ga for v in gb] + [np.clip(x0, prob.lower, prob.upper)])
            probs.append(prob)
        minima = grid_minima(self.rep, probs, grids, grid_runs)
        starts = [(g, a, b, x) for (a, b), (g, x) in zip(combos, minima)]
        starts.sort(key=lambda t: t[0])
        if self.log:
            self.log(f"  pair grids: {len(starts)} pairs in {time.perf_counter() - t0:.1f} s; best "
                     + ", ".join(f"{a}+{b} ({g:.2e})" for g, a, b, _ in starts[:n_fit]))
        return starts

    # -- given sets ------------------------------------------------------------------------------
    def score_set(self, name: str, effects: list, x0: np.ndarray, gap_start: float) -> Scored:
        """Fit a given set of effects from ``x0`` on all runs and score it held out like a
        confirmed candidate (per-fold refits): e.g. the nominal's corrections alone, the
        start every named effect must beat."""
        t0 = time.perf_counter()
        prob = self.problem(effects)
        fit = prob.fit(np.asarray(x0, float), None, max_nfev=8)
        sc = self._screened(name, effects, prob, fit, gap_start, t0, width=18)
        self._confirm(sc, gap_start, new_at=np.asarray(x0, float))
        return sc

    def rescore(self, s: Scored, gap_start: float, new_at=None) -> Scored:
        """``s``'s all-runs fit scored held out on this scorer's folds (per-fold refits from
        :func:`~discrepancy.folds.fold_starts`, ``new_at`` as there; the all-runs fit is kept): e.g. the named set
        under the fold scheme the verdict did not use (:meth:`on`)."""
        prob = self.problem(s.effects)
        prob.seed(s.fit)
        fold_x = self._refit_folds(prob, s.effects, new_at)
        raw = heldout(prob, fold_x, self.folds)
        g = gap(raw)
        return Scored(s.name, s.effects, s.fit, g, share_of(g, gap_start), "refit", raw, fold_x, self.folds,
                      unstable=prob.unstable, unconverged=prob.unconverged)

    def score_removals(self, best: Scored, gap_start: float, keep: tuple[str, ...] = ()) -> list[Scored]:
        """The backward step of floating selection: ``best`` without each of its members,
        refitted jointly from ``best``'s values and screened on ``best``'s folds, the
        :data:`N_CONFIRM` best screened confirmed (per-fold refits) as a round's
        candidates are; best first.

        A member whose removal leaves a held-out gap that the full set lowers by less than
        :data:`MIN_SHARE` removes no clear share of the gap: a stand-in accepted early (a spring
        fitted with Coulomb friction to part of a backlash's gap) that a later member made
        redundant.  The caller drops it.  Members named in ``keep`` (the nominal's corrections)
        are never removed."""
        scorer = self.on(best.folds, known=(best,))
        out = []
        for m in range(len(best.effects)):
            if best.effects[m].name in keep:
                continue
            effects = [e for i, e in enumerate(best.effects) if i != m]
            x0 = np.concatenate([x for i, (_, x) in enumerate(best.fit.split()) if i != m])
            t0 = time.perf_counter()
            prob = scorer.problem(effects)
            fit = prob.fit(x0, None, max_nfev=8)
            out.append(scorer._screened("+".join(e.name for e in effects), effects, prob, fit, gap_start, t0,
                                        width=36))
        # the caller reads the best removal: like a round's candidates, the best N_CONFIRM by
        # their screen are confirmed (each confirm of a rough set is a minute of replays)
        return scorer.confirm_best(out, gap_start, N_CONFIRM)



# -- a nested family's variants ------------------------------------------------------------------
def nested_variants(scorer: Scorer, out: list[Scored], gap_start: float, *, starts: dict | None = None,
                    accepted_x=None) -> list[Scored]:
    """Each confirmed candidate with nested variants (:data:`discrepancy.effects.family.NESTED`:
    ``load_friction`` and the friction family's Stribeck and smooth-sign variants): the variants
    fitted from its fit (their own parameters over their grid's best point on the prescreen's
    short records) and, when ``starts`` holds equation-error fits of the variant or its parent,
    from those beside the round's accepted values ``accepted_x`` too (:func:`_confirm_child`:
    two starts, the lower training gap kept), screened and confirmed as it was, and the one :func:`~discrepancy.nesting.choose_variant`
    picks on the per-run held-out gaps put in its place, the variants' held-out gaps recorded in
    its :attr:`Scored.variants` (the one not kept is not listed: a richer variant the rule judged
    a tie must not outrank the one it kept).  Returns ``out`` so changed, as
    :meth:`Scorer.confirm_best` orders it: the refitted best first, then the others as screened."""
    res = list(out)
    for s in out:
        kids = scorer.builder.nested(s.effects[-1].name) if s.method == "refit" and s.effects else ()
        if not kids or s.name == NULL:
            continue
        tried = [s] + [_confirm_child(scorer, s, kid, gap_start, _shape_starts(scorer, s, kid, starts), accepted_x)
                       for kid in kids]
        # each run's held-out gap (the rule pairs them run by run)
        gaps = {t.effects[-1].name: [gap([r]) for r in t.heldout_raw] for t in tried}
        pick = choose_variant(gaps, {t.effects[-1].name: t.effects[-1].nparam for t in tried})
        chosen = [t for t in tried if t.effects[-1].name == pick][0]
        chosen.variants = {t.effects[-1].name: {"heldout_gap_rad": t.heldout_gap, "screen_gap_rad": t.screen_gap}
                           for t in tried}
        if scorer.log:
            scorer.log(f"  friction family: {', '.join(f'{t.effects[-1].name} {t.heldout_gap:.3e}' for t in tried)} "
                       f"rad held out; kept {pick} (nesting.choose_variant)")
        res = [t for t in res if t is not s] + [chosen]
    refit = sorted((t for t in res if t.method == "refit"), key=lambda t: t.heldout_gap)
    return refit + [t for t in res if t.method != "refit"]


def _shape_starts(scorer: Scorer, parent: Scored, kid: str, starts: dict | None) -> list:
    """``kid``'s own values from the equation-error fits in ``starts``: its own fit, and its
    parent's fit with the kid's further parameters over the kid's grid (equation error need not
    pin every parameter of the richer law: the smooth load law's back-driven coefficient, on
    tests/test_torque.py's runs)."""
    starts = starts or {}
    out = [np.asarray(starts[kid], float)] if starts.get(kid) is not None else []
    mine = starts.get(parent.effects[-1].name)
    if mine is not None:
        out += _grid_about(scorer.builder.effect(kid), mine)
    return out


def _grid_about(kid, mine: np.ndarray) -> list[np.ndarray]:
    """Nested variant ``kid``'s grid about its parent's values ``mine``: those values kept in
    every point, the kid's further parameters over its grid."""
    about = np.concatenate([mine, np.zeros(kid.nparam - len(mine))])
    return [np.concatenate([mine, g[len(mine):]]) for g in kid.grid(about)]


def _confirm_child(scorer: Scorer, parent: Scored, kid: str, gap_start: float, shapes=(),
                   accepted_x=None) -> Scored:
    """Nested variant ``kid`` of ``parent``'s candidate, fitted from ``parent``'s fit and
    confirmed as ``parent`` was, each fold from ``parent``'s values on it (a round of single
    candidates names each by its candidate: ``kid``).

    ``shapes``: ``kid``'s values from the equation-error fits (:func:`_shape_starts`), each beside
    ``accepted_x`` (the round's start values of the other members): a second start (the best on
    the short records, then the prescreen's Gauss-Newton steps there, as a candidate's), fitted
    on all runs as the first; the fit with the lower training gap is kept (a multi-start of a local
    fit: no held-out sample chooses).  Why: a parent whose fit slid along a ridge (the sticking
    load law on a smooth one, gear +18 %) hands its slide to every start about its values, and
    the variant's fit stays in that basin.  When the second start's fit is kept, each fold's
    refit starts as a new candidate's does (the known set's fold values, the variant's own
    parameters searched on the fold's training windows), not from the parent's fold values."""
    t0 = time.perf_counter()
    effects = parent.effects[:-1] + [scorer.builder.effect(kid)]
    *rest, (_, mine) = parent.fit.split()
    base = np.concatenate([x for _, x in rest]) if rest else np.zeros(0)
    grid_runs = [r.first_seconds(PRESCREEN_S) for r in scorer.runs]
    short = scorer.problem(effects, grid_runs)

    def distinct(points):  # a grid about given values repeats points: each is replayed once, in order
        seen = set()
        return [p for p in points if not (p.tobytes() in seen or seen.add(p.tobytes()))]
    # the variant's grid about the parent's values
    grids = [distinct([np.clip(np.concatenate([base, effects[-1].clip(x)]), short.lower, short.upper)
                       for x in _grid_about(effects[-1], mine)])]
    if shapes and accepted_x is not None and len(accepted_x) == len(base):
        grids.append(distinct([np.clip(np.concatenate([accepted_x, effects[-1].clip(x)]), short.lower, short.upper)
                               for x in shapes]))
    gaps, starts = (list(v) for v in zip(*grid_minima(scorer.rep, [short] * len(grids), grids, grid_runs)))
    if len(starts) > 1:  # the second start is far from any fit: a prescreen's steps on the short records
        (starts[1],), _ = lockstep_gauss_newton(scorer.rep, [short], starts[1:], gaps[1:], grid_runs,
                                                PRESCREEN_ITERATIONS)
    fits = []
    for x0 in starts:
        prob = scorer.problem(effects)
        fits.append((prob, prob.fit(x0, None, max_nfev=4, chord=True)))
    pick = min(range(len(fits)), key=lambda k: (fits[k][1].gap_train, k))
    prob, fit = fits[pick]
    child = scorer._screened(kid, effects, prob, fit, gap_start, t0)
    child.unstable += short.unstable + sum(p.unstable for k, (p, _) in enumerate(fits) if k != pick)
    child.screen_gap = child.heldout_gap
    if scorer.log and len(fits) > 1:
        scorer.log(f"  {kid}: all-runs fits from the parent's values {fits[0][1].gap_train:.3e}, from equation "
                   f"error {fits[1][1].gap_train:.3e} rad; kept the {('parent', 'equation-error')[pick]} start's")
    # each fold's refit starts from the parent's fold values (fold_starts: a nested variant of a
    # known set's member), its own parameters searched on the fold's training windows; from the
    # equation-error start, as a new candidate (the parent's fold values hold its slide)
    known = tuple(scorer.known) + ((parent,) if pick == 0 else ())
    scorer.on(scorer.folds, known=known)._confirm(child, gap_start)
    return child
