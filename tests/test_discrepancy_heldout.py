"""Held out means held out: a fold's refit never sees its held-out samples, neither in its
steps nor in its start, and it runs to its stated convergence (discrepancy.folds)."""

import mujoco
import numpy as np
import pytest

from discrepancy import effects as fx
from discrepancy import experiment_set
from discrepancy import select as sel
from discrepancy.fit import Problem
from discrepancy.folds import fold_starts, refit_folds, training_window
from discrepancy.lockstep import lockstep_fit
from discrepancy.replay import Replayer, prepare_runs
from discrepancy.runs import ReplayRun
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device

#: The hidden damping [N*m*s/rad] of the truth below (about three times the Omni's nominal yaw
#: damping, 6.9e-3: the effect's grid must find it from the nominal).
TRUE_DAMPING = 0.02


def _run(n: int, dt: float = 0.01) -> ReplayRun:
    t = np.arange(n) * dt
    z = np.zeros(n)
    return ReplayRun("r", "sine", t, z, z, z, dt, 1.0, (), 1.0, 0.1)


def test_training_window_skips_the_held_out_block():
    """The window of the fold that holds out a run's first block starts after it (replayed
    through it, not scored); a fold that holds out a later block takes the run's first second."""
    run = _run(1000)  # 10 s at 100 Hz; blocks of 2 s
    folds = sel.block_folds([run], 5)
    w0, m0 = training_window(run, folds[0].held[0], 1.0)
    assert w0.n == 300 and not m0[:200].any() and m0[200:].all()
    w2, m2 = training_window(run, folds[2].held[0], 1.0)
    assert w2.n == 100 and m2 is None
    whole, m = training_window(_run(50), None, 1.0)  # shorter than the window: the whole run
    assert whole.n == 50 and m is None


@pytest.fixture(scope="module")
def damped_runs():
    """The Omni with its yaw damping at TRUE_DAMPING, logged noise-free: the nominal misses
    one viscous term, whose least-squares value on any subset of samples is the truth."""
    spec = mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))
    truth = fx.compile_with(spec, [(fx.get("viscous_damping"), np.array([TRUE_DAMPING]))])
    exps = experiment_set.experiments(poses=((65.0, 90.0),), frequencies_hz=(2.0,), amplitudes_rad=(0.1,),
                                      step_amplitudes_rad=(0.1,), duration_s=1.5)
    runs = prepare_runs(ex.simulate(Device(truth), exps, jobs=1), Device(truth))
    return spec, runs


def _fold_fits(spec, runs, folds):
    with Replayer(1) as rep:
        prob = Problem(fx.ModelBuilder(spec), [], [fx.get("viscous_damping")], runs, rep)
        start = fold_starts(prob, folds)
        return start, refit_folds(prob, folds, start), prob.unconverged


def test_a_fold_never_sees_its_held_out_samples(damped_runs):
    """Fold 1's start and fit are bit for bit the same when its held-out samples are replaced by
    anything; the folds that train on those samples move."""
    spec, runs = damped_runs
    folds = sel.block_folds(runs, 3)
    start, fit, _ = _fold_fits(spec, runs, folds)
    spoiled = []
    for r, h in zip(runs, folds[1].held):
        th = r.theta.copy()
        th[h] += 0.05 * np.sin(np.arange(int(h.sum())))
        spoiled.append(ReplayRun(r.name, r.kind, r.t, r.r, th, r.v, r.dt, r.kp, r.gamma_set_deg,
                                 r.frequency_hz, r.amplitude_rad, r.meta, r.control_period_s, r.enabled))
    start2, fit2, _ = _fold_fits(spec, spoiled, sel.block_folds(spoiled, 3))
    np.testing.assert_array_equal(start2[1], start[1])
    np.testing.assert_array_equal(fit2[1], fit[1])
    assert not np.array_equal(fit2[0], fit[0]) and not np.array_equal(fit2[2], fit[2])


def test_fold_refits_converge_to_the_hidden_value(damped_runs):
    """From the nominal (a grid search on the training windows, then the steps), every fold's
    refit reaches the hidden damping: noise-free data of the same structure, so each fold's
    least-squares optimum is the truth.  1e-3 relative: the convergence test stops at a cost
    decrease below 1e-3 of the cost, and near an exact fit the cost falls by orders of
    magnitude per Gauss-Newton step, so the last step leaves far less than that."""
    spec, runs = damped_runs
    nominal = fx.nominal_values(fx.get("viscous_damping"), spec)[0]
    assert nominal < 0.5 * TRUE_DAMPING
    for scheme in sel.FOLD_SCHEMES:
        _, fit, unconverged = _fold_fits(spec, runs, sel.make_folds(runs, 3, scheme))
        assert unconverged == 0, scheme
        for x in fit:
            assert x[0] == pytest.approx(TRUE_DAMPING, rel=1e-3), (scheme, fit)


def test_a_fold_goes_on_from_its_start_with_the_lowest_training_cost(damped_runs):
    """From several starts (discrepancy.folds.FOLD_STARTS) a fold goes on from the one whose
    training cost is lowest, whichever order the starts come in (no pass of the fit: the start
    chosen is returned as it is)."""
    spec, runs = damped_runs
    folds = sel.block_folds(runs, 3)
    far, near = np.array([4 * TRUE_DAMPING]), np.array([TRUE_DAMPING])  # the bound is 5 times
    with Replayer(1) as rep:
        prob = Problem(fx.ModelBuilder(spec), [], [fx.get("viscous_damping")], runs, rep)
        alone = refit_folds(prob, folds, [[far] for _ in folds], passes=0)
        both = refit_folds(prob, folds, [[far, near] for _ in folds], passes=0)
        other = refit_folds(prob, folds, [[near, far] for _ in folds], passes=0)
    for a, b, c in zip(alone, both, other):
        assert a[0] == pytest.approx(4 * TRUE_DAMPING)  # the far start alone stays there
        assert b[0] == pytest.approx(TRUE_DAMPING) and c[0] == pytest.approx(TRUE_DAMPING)


def test_lockstep_fit_stops_on_a_pass_from_a_fresh_jacobian(damped_runs):
    """lockstep_fit from four times the hidden damping, beside a second problem started at the
    truth (one replay batch per evaluation): both converged (a pass from a fresh Jacobian that
    tried a step changed the cost by < FTOL or moved < XTOL) at the truth, to the 1e-3 of the
    test above, and each as it ends alone; one evaluation per pass (a Jacobian, no step) never
    converges."""
    spec, runs = damped_runs
    idx = list(range(len(runs)))
    far, near = np.array([4 * TRUE_DAMPING]), np.array([1.01 * TRUE_DAMPING])
    with Replayer(1) as rep:
        prob = Problem(fx.ModelBuilder(spec), [], [fx.get("viscous_damping")], runs, rep)
        x, cost, converged = lockstep_fit(rep, [prob, prob], [idx, idx], runs, [far, near])
        assert converged == [True, True]
        assert x[0][0] == pytest.approx(TRUE_DAMPING, rel=1e-3) and x[1][0] == pytest.approx(TRUE_DAMPING, rel=1e-3)
        alone, _, ok = lockstep_fit(rep, [prob], [idx], runs, [far])
        assert ok == [True] and alone[0][0] == pytest.approx(x[0][0], rel=1e-6)  # the batch changes nothing
        _, _, converged = lockstep_fit(rep, [prob], [idx], runs, [far], passes=3, nfev=1)
        assert converged == [False]


def test_pair_search_with_one_candidate_scores_no_pair():
    """Round 1's pair search when the candidates cannot make a pair (a study restricted to one
    effect, as the coverage study is): nothing accepted, one log line, no pair scored (it raised
    an IndexError when the best single effect left enough of the gap to ask for pairs)."""
    from types import SimpleNamespace

    from discrepancy.search import Search

    logged, asked = [], []
    single = SimpleNamespace(share=0.3, heldout_gap=1e-2)
    fake = SimpleNamespace(selection=SimpleNamespace(gap=2e-2), noise=1e-4, log=logged.append,
                           scorer=SimpleNamespace(score_pairs=lambda gap, candidates: asked.append(candidates) or []))
    entry = {}
    assert Search._search_pairs(fake, ["drive_compliance"], entry, [single]) is False
    assert asked == [] and entry == {} and logged[-1] == "round 1: no pair of candidates to score"
    assert Search._search_pairs(fake, ["a", "b"], entry, [single]) is False  # the scorer found no pair
    assert asked == [("a", "b")] and entry == {}


def test_a_runner_up_far_behind_on_the_screen_is_not_confirmed():
    """After the best screened candidate is confirmed, the next is confirmed (per-fold refits)
    only when its screen gap is below CONFIRM_WITHIN times the best confirmed gap; the pair
    search confirms all of its best (``within=inf``: they are the next round's beam)."""
    from types import SimpleNamespace

    refit = {"a": 1.0, "b": 2.5, "c": 0.5}  # the gap each would have after its refits

    def scorer(gaps: dict, refits: dict):
        done = []

        def confirm(s, gap_start):
            done.append(s.name)
            s.heldout_gap, s.method = refits[s.name], "refit"

        return SimpleNamespace(_confirm=confirm, log=None), done, [
            SimpleNamespace(name=n, heldout_gap=g, method="one-step") for n, g in gaps.items()]

    assert sel.CONFIRM_WITHIN == 2.0
    fake, done, scored = scorer({"a": 1.0, "b": 2.0 * 1.0}, refit)  # b at exactly 2x the best's refit
    out = sel.Scorer.confirm_best(fake, scored, 1.0, 2)
    assert done == ["a"] and [s.name for s in out] == ["a", "b"] and out[1].method == "one-step"
    fake, done, scored = scorer({"a": 0.8, "b": 1.9}, refit)  # b below 2x a's refit (1.0): confirmed
    out = sel.Scorer.confirm_best(fake, scored, 1.0, 2)
    assert done == ["a", "b"] and [s.name for s in out] == ["a", "b"]
    fake, done, scored = scorer({"b": 0.9, "c": 1.5}, refit)  # the best's refit got worse (2.5):
    out = sel.Scorer.confirm_best(fake, scored, 1.0, 2)  # c is within 2x of it, confirmed, and leads
    assert done == ["b", "c"] and [s.name for s in out] == ["c", "b"]
    fake, done, scored = scorer({"a": 1.0, "b": 5.0, "c": 9.0}, refit)
    out = sel.Scorer.confirm_best(fake, scored, 1.0, 2, within=float("inf"))
    assert done == ["a", "b"] and [s.name for s in out] == ["a", "b", "c"]


def test_the_friction_familys_variant_is_confirmed_with_load_friction_and_chosen_by_the_rule(monkeypatch):
    """A confirmed load_friction brings its nested Stribeck variant (confirmed beside it); the
    variant stands in its place only when nesting.choose_variant picks it (clearly better on the
    held-out runs), and it is recorded with both gaps; a candidate only screened, or one without
    variants, is left as it was; the order stays confirm_best's (refitted best first) and the
    variant not kept is not listed (a tie must not outrank the one kept)."""
    from types import SimpleNamespace

    runs = np.linspace(1.0, 2.0, 6)  # six held-out runs' rms gaps of the parent [rad * 1e-3]

    def scored(name, factor, method="refit"):
        raw = [np.full(10, 1e-3 * g * factor) for g in runs]
        effect = SimpleNamespace(name=name, nparam=fx.get(name).nparam)
        return sel.Scored(name, [effect], None, sel.gap(raw), 0.0, method, raw)

    def with_child(factors):
        monkeypatch.setattr(sel, "_confirm_child",
                            lambda scorer, s, kid, g0, *rest: scored(kid, factors[kid]))
        return SimpleNamespace(log=None, builder=fx.ModelBuilder(None))

    other = scored("coulomb_friction", 1.3)
    screened = scored("armature", 0.5, method="one-step")
    out = sel.nested_variants(with_child({"friction_family_stribeck": 0.7, "load_friction_smooth": 1.2}),
                              [scored("load_friction", 1.0), other, screened], 1.0)
    assert [s.name for s in out] == ["friction_family_stribeck", "coulomb_friction", "armature"]
    parent_gap = sel.gap([np.full(10, 1e-3 * g) for g in runs])
    gaps = {k: v["heldout_gap_rad"] for k, v in out[0].variants.items()}
    assert gaps == pytest.approx({"load_friction": parent_gap, "friction_family_stribeck": 0.7 * parent_gap,
                                  "load_friction_smooth": 1.2 * parent_gap})
    # 5 and 3 % better: ties, the simpler kept
    out = sel.nested_variants(with_child({"friction_family_stribeck": 0.95, "load_friction_smooth": 0.97}),
                              [scored("load_friction", 1.0), other], 1.0)
    assert [s.name for s in out] == ["load_friction", "coulomb_friction"]
    # both richer variants better by more than the tie: the one with fewer parameters among them
    out = sel.nested_variants(with_child({"friction_family_stribeck": 0.7, "load_friction_smooth": 0.72}),
                              [scored("load_friction", 1.0), other], 1.0)
    assert out[0].name == "load_friction_smooth"
    asked = []
    monkeypatch.setattr(sel, "_confirm_child", lambda *a: asked.append(a))
    same = [other, scored("load_friction", 1.0, method="one-step")]  # as confirm_best orders them
    assert sel.nested_variants(SimpleNamespace(log=None, builder=fx.ModelBuilder(None)), same, 1.0) == same
    assert not asked


def test_a_nested_variant_starts_each_fold_at_its_parents_fold_values():
    """fold_starts for the friction family's Stribeck variant, with a confirmed set holding its
    parent load_friction known: each fold starts at that set's fold values (the corrections' and
    load_friction's coefficients, fitted without the fold's held-out samples), the variant's own
    parameters where the caller puts them (``new_at``: no replay needed here)."""
    from types import SimpleNamespace

    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    builder = fx.ModelBuilder(spec, om.Target("pivot", "servo"))
    damping, load, child = (builder.effect(n) for n in ("viscous_damping", "load_friction", "friction_family_stribeck"))
    runs = [_run(100), _run(100)]
    folds = sel.block_folds(runs, 2)
    fold_x = [np.array([0.36, 0.10, 0.40, 0.33]), np.array([0.38, 0.20, 0.60, 0.35])]  # damping; mu_drive, mu_back, b_emf
    known = SimpleNamespace(method="refit", folds=folds, effects=[damping, load], fold_x=fold_x)
    prob = Problem(builder, [], [damping, child], runs, None)
    new = np.array([0.0, 0.0, 0.0, 0.0, 0.02, 0.3, 1.5])
    starts = fold_starts(prob, folds, known=(known,), new_at=new)
    for f in range(2):
        np.testing.assert_array_equal(starts[f], [*fold_x[f], 0.02, 0.3, 1.5])
    alone = fold_starts(prob, folds, known=(), new_at=new)  # no parent known: all from new_at
    np.testing.assert_array_equal(alone[0], np.clip(new, prob.lower, prob.upper))
