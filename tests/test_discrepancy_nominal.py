"""The discrepancy workflow on a nominal that is uncertain too (docs/method/discrepancy.md, "Your own
robot"): the corrections of the nominal's constants, the folds of time blocks beside folds of
runs, replays that go unstable (excluded and counted, never scored), parameters on their bounds,
and the bank's check of the corrections.  The whole geared-servo cases run in the bank
(tests/test_discrepancy_bank.py, slow)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from identification.errors import UserError
from omni_app.cli import main
from omni_sim import model as om
from omni_sim.device import Device, Engine, run_p_loop
from discrepancy import effects as fx
from bank import hidden
from discrepancy import select as sel
from discrepancy.fit import UNSTABLE_PENALTY_RAD, Problem, gap
from discrepancy.replay import Replayer
from discrepancy.runs import ReplayRun
from discrepancy.report import _bound_flags
from discrepancy.search import whole_run_folds
from discrepancy.workflow import DEFAULT_CORRECTIONS, correction_names

PENDULUM = om.Target("pivot", "servo")


def _run(n: int, name: str = "r", period: float = 1e-3) -> ReplayRun:
    t = np.arange(n) * period
    r = 0.1 * np.sin(2 * np.pi * t)
    return ReplayRun(name, "other", t, r, r.copy(), np.zeros(n), period, 10.0, (), 0.0, 0.1, {}, period)


# -- folds ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("scheme", sel.FOLD_SCHEMES)
@pytest.mark.parametrize("lengths", [(100, 100, 100, 100), (37, 1000, 251), (10, 11)])
def test_every_sample_is_held_out_exactly_once(scheme, lengths):
    """Whatever the scheme, each sample of each run is held out by exactly one fold, and a fold
    never trains on what it holds out."""
    runs = [_run(n, f"r{i}") for i, n in enumerate(lengths)]
    folds = sel.make_folds(runs, 5, scheme)
    for j, r in enumerate(runs):
        count = np.zeros(r.n, int)
        for f in folds:
            if f.held[j] is not None:
                count += f.held[j]
        assert np.all(count == 1), (scheme, j)
    for f in folds:
        idx, masks = f.train()
        for j, m in zip(idx, masks):
            if m is not None:
                assert not np.any(m & f.held[j])


def test_blocked_folds_train_on_every_run():
    """Four runs of four kinds: every blocked fold's fit sees all four (a fold of runs sees three)."""
    runs = [_run(200, f"r{i}") for i in range(4)]
    assert all(len(f.train()[0]) == 4 for f in sel.block_folds(runs, 5))
    assert all(len(f.train()[0]) == 3 for f in sel.run_folds(runs, 4))


def test_block_folds_are_contiguous_blocks():
    held = sel.block_folds([_run(10)], 5)[2].held[0]
    assert held.tolist() == [False] * 4 + [True] * 2 + [False] * 4


@pytest.mark.parametrize("scheme", sel.FOLD_SCHEMES)
def test_whole_run_folds_extend_the_fits_records(scheme):
    """Folds made on the fits' shortened records, carried to the whole runs: still every sample
    held out once, and the fits' samples held out by the same fold as before."""
    whole = [_run(500, "a"), _run(300, "b"), _run(400, "c")]
    short = [r.truncated(120) for r in whole]
    folds = sel.make_folds(short, 3, scheme)
    ext = whole_run_folds(folds, whole)
    for j, r in enumerate(whole):
        count = sum(f.held[j].astype(int) for f in ext if f.held[j] is not None)
        assert np.all(count == 1)
        for f, g in zip(folds, ext):
            if f.held[j] is not None:
                assert np.array_equal(g.held[j][:120], f.held[j])


def test_first_seconds_counts_time_not_samples():
    """The prescreen's short records are one second of the run whatever the log rate: 1000
    samples at 1 kHz (the Omni's 1000), 50 at 50 Hz."""
    assert _run(3000).first_seconds(1.0).n == 1000
    assert _run(300, period=0.02).first_seconds(1.0).n == 50


# -- unstable replays -----------------------------------------------------------------------------
_UNSTABLE_XML = """<mujoco><option timestep="0.001" integrator="Euler"/><worldbody><body>
<joint name="pivot" type="hinge" axis="0 1 0" stiffness="{k}"/><geom size="0.02" mass="0.01" pos="0 0 -0.1"/>
</body></worldbody><actuator><motor name="servo" joint="pivot" ctrlrange="-1 1"/></actuator></mujoco>"""


def _models():
    stable = mujoco.MjModel.from_xml_string(_UNSTABLE_XML.format(k=1.0))
    unstable = mujoco.MjModel.from_xml_string(_UNSTABLE_XML.format(k=1e9))  # explodes at 1 ms
    return stable, unstable


def test_engine_flags_the_rows_mujoco_reset():
    """MuJoCo resets an unstable row and warns without naming it; the engine flags exactly that
    row (its time fell back), whether it steps a batch or one row."""
    stable, unstable = _models()
    devs = [Device(m, target=PENDULUM) for m in (stable, unstable, stable)]
    warned = []
    prev = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(warned.append)
    try:
        eng = Engine(devs, [0.05] * 3, [()] * 3, nthread=1)
        out = run_p_loop(eng, np.zeros((3, 50)), 10.0)
        one = Engine([devs[1]], [0.05], [()])
        out1 = run_p_loop(one, np.zeros((1, 50)), 10.0)
    finally:
        mujoco.set_mju_user_warning(prev)
    assert warned  # MuJoCo did find the instability
    assert out["unstable"].tolist() == [False, True, False]
    assert out1["unstable"].tolist() == [True]


def test_unstable_replays_are_excluded_never_scored():
    """The replay returns an unstable row as NaN and counts it; its gap is inf (never a score);
    a fit sees the barrier UNSTABLE_PENALTY_RAD instead of NaN."""
    stable, unstable = _models()
    run = _run(60)
    with Replayer(1, PENDULUM, 1e-3) as rep:
        th = rep.simulate([stable, unstable], [run])
        assert rep.unstable_replays == 1
    assert np.all(np.isfinite(th[0])) and np.all(np.isnan(th[1]))
    assert math.isfinite(gap([th[0] - run.theta])) and gap([th[1] - run.theta]) == math.inf
    prob = Problem(None, [], [], [run], None)
    assert np.all(prob.weighted([th[1] - run.theta]) == UNSTABLE_PENALTY_RAD * prob.weights[0])


# -- corrections ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def servo_spec():
    return mujoco.MjSpec.from_file(str(hidden.servo_truth.model_path()))


def test_correction_names(servo_spec):
    """auto: the default set on a user's device, none on the virtual Omni; only constants the
    nominal states (the servo pendulum has no offset: position_offset is a candidate effect);
    an explicit list is honoured; an unknown name is a user error."""
    omni = mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))
    assert correction_names("auto", omni, om.OMNI, own_device=False) == ()
    auto = correction_names("auto", servo_spec, PENDULUM, own_device=True)
    assert auto == ("armature", "viscous_damping", "coulomb_friction", "torque_gain")
    assert set(auto) < set(DEFAULT_CORRECTIONS)
    assert correction_names("default", servo_spec, PENDULUM, own_device=False) == auto
    assert correction_names("none", servo_spec, PENDULUM, own_device=True) == ()
    assert correction_names(("armature", "position_offset"), servo_spec, PENDULUM, True) == (
        "armature", "position_offset")
    with pytest.raises(UserError, match="unknown correction"):
        correction_names(("inertia",), servo_spec, PENDULUM, True)


def test_bound_flags():
    eff = fx.get("load_friction")
    assert _bound_flags(eff, [0.2, 9.0]) == {"mu_back": "upper"}
    assert _bound_flags(eff, [0.0, 0.5]) == {"mu_drive": "lower"}
    assert _bound_flags(eff, [0.2, 0.5]) == {}


def test_load_friction_bounds_admit_self_locking():
    """mu_back above 1 (a self-locking train in this law) is inside the bounds, up to a back-driven
    efficiency of 0.1; mu_drive below 1 (a drive that passes some torque)."""
    lo, hi = fx.get("load_friction").bounds()
    assert hi[1] == pytest.approx(1 / 0.1 - 1) and hi[1] > 1
    assert hi[0] == pytest.approx(1 - 0.1) and lo.tolist() == [0.0, 0.0, 0.0]
    assert hi[2] == 5.0  # b_emf: as current_limit's back-EMF damping


def test_cli_refuses_an_unknown_correction_before_work(tmp_path, capsys):
    assert main(["discrepancy", "--measured", str(tmp_path), "--model", str(hidden.servo_truth.model_path()),
                 "--joint", "pivot", "--actuator", "servo", "--corrections", "armature,inertia",
                 "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "inertia" in err[0]
    assert not (tmp_path / "out").exists()


# -- the bank's check of the corrections ----------------------------------------------------------
def _report(fitted: dict, half: float, named=("load_friction",)) -> dict:
    truth = dict(hidden.case("load_friction_nominal_off").effects)
    effects = [{"name": n, "confidence": "high",
                "parameters": {"mu_drive": truth[n][0], "mu_back": truth[n][1], "b_emf_nms_per_rad": truth[n][2]},
                "uncertainty": {"mu_drive": 0.05, "mu_back": 0.05, "b_emf_nms_per_rad": 0.05}} for n in named]
    corrections = [{"effect": hidden.CORRECTED_BY[a][0], "parameter": hidden.CORRECTED_BY[a][1],
                    "fitted": v, "half_width_95": half} for a, v in fitted.items()]
    return {"effects": effects or [{"name": "none"}], "corrections": corrections, "shrink_factor": 10.0}


def test_assess_checks_the_corrections_against_the_truth():
    """The truth of the nominal's wrong constants is read from the truth's own model file (2.5e-3
    kg*m^2, 0.03 N*m); a correction must cover it with its 95 % half-width."""
    case = hidden.case("load_friction_nominal_off")
    assert hidden.truth_joint(case) == {"armature": 2.5e-3, "frictionloss": 0.03}
    good = {"armature": 2.6e-3, "frictionloss": 0.031}
    assert hidden.assess(case, _report(good, 2e-3))[0]
    ok, why = hidden.assess(case, _report({"armature": 5.6e-3, "frictionloss": 0.031}, 1e-3))
    assert not ok and "armature" in why
    ok, why = hidden.assess(case, _report({"armature": 2.5e-3}, 1e-3))
    assert not ok and "frictionloss" in why
    null = hidden.case("nominal_off")
    assert hidden.assess(null, _report(good, 2e-3, named=()))[0]
    assert not hidden.assess(null, _report(good, 2e-3))[0]  # an effect named where none is hidden


def test_nominal_off_is_the_truth_with_the_stated_constants():
    """The model the workflow is given differs from the truth's file in the two stated joint
    attributes only."""
    case = hidden.case("load_friction_nominal_off")
    path, target = hidden.nominal(case)
    off = mujoco.MjModel.from_xml_path(str(path))
    truth = mujoco.MjModel.from_xml_path(str(hidden.servo_truth.model_path()))
    assert target == PENDULUM
    assert off.dof_armature.tolist() == [5.6e-3] and off.dof_frictionloss.tolist() == [0.018]
    for field in ("dof_damping", "body_mass", "actuator_gainprm", "actuator_biasprm", "opt.timestep"):
        a, b = (np.asarray(eval(f"m.{field}")) for m in (off, truth))
        assert np.array_equal(a, b), field


def test_docs_fold_figures_are_the_examples_record():
    """docs/method/discrepancy.md's figures on the two fold schemes are the Feetech example's record."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    rep = json.loads((root / "examples/real_servo/report/report.json").read_text())
    g = rep["gaps"]
    phrase = (f"{g['runs']['corrected'] / g['runs']['nominal']:.1f} times worse, {g['runs']['corrected']:.2e} "
              f"against the nominal's {g['runs']['nominal']:.2e} rad, where blocked folds find them "
              f"{100 * (1 - g['blocked']['corrected'] / g['blocked']['nominal']):.0f} %").replace("e-0", "e-")
    text = " ".join((root / "docs/method/discrepancy.md").read_text().split())
    assert phrase in text, phrase


def test_written_servo_runs_read_back(tmp_path):
    """The geared-servo bank's runs, written as a dataset, read back as ``omni discrepancy`` reads
    them: an "other" run's amplitude may be negative (a move to -1.0 rad)."""
    from identification.dataset import read_dataset, write_dataset

    runs = hidden.servo_truth.generate(experiments=[e for e in hidden.servo_truth.EXPERIMENTS
                                                    if e.name == "slow_up_am100"])
    assert runs[0].meta["amplitude_rad"] < 0
    write_dataset(runs, tmp_path / "d")
    back = read_dataset(tmp_path / "d", require_pose=False, uniform=False)
    assert back[0].meta["amplitude_rad"] == runs[0].meta["amplitude_rad"]


def test_performance_page_stage_figures_are_the_bench_record():
    """docs/reference/performance.md's physics steps per stage of the geared-servo figure are
    docs/reference/bench.json's."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    srv = json.loads((root / "docs/reference/bench.json").read_text())["discrepancy_servo"]
    per = srv["physics_steps_per_stage"]
    text = " ".join((root / "docs/reference/performance.md").read_text().split())
    for phrase in (f"{srv['physics_steps'] / 1e6:.1f} M physics steps, {per['naming'] / 1e6:.1f} M of them naming",
                   f"{per['uncertainty_and_evaluation'] / 1e6:.1f} M the uncertainty",
                   f"{per['other_fold_scheme'] / 1e6:.1f} M the other fold scheme, "
                   f"{per['corrections'] / 1e6:.1f} M the corrections"):
        assert phrase in text, phrase


def test_blend_paragraph_is_the_valley_record():
    """docs/method/discrepancy.md's figures on why the load law is blended and the prescreen starts
    twice are docs/studies/discrepancy/valley_scan.json's (scripts/valley_scan.py)."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    rec = json.loads((root / "docs/studies/discrepancy/valley_scan.json").read_text())
    text = " ".join((root / "docs/method/discrepancy.md").read_text().split())

    def e(x):  # 6.32e-04 -> 6.32e-4, as the page writes it
        return f"{x:.2e}".replace("e-0", "e-")

    sw, bl = rec["switch"], rec["blend"]
    names = bl["parameters"]
    scan = dict(zip(sw["mu_back_scan"]["mu_back"], sw["mu_back_scan"]["gap"]))
    smooth = dict(zip(bl["mu_back_scan"]["mu_back"], bl["mu_back_scan"]["gap"]))
    at = {k: dict(zip(names, f["x"])) for k, f in sw["fits"].items()}
    far = dict(zip(names, bl["fits"]["far"]["x"]))
    ps = bl["prescreen"]
    gc, go = ps["grid_gap"]["from_corrections"], ps["grid_gap"]["from_own_values"]
    px = dict(zip(names, ps["prescreen_x"]))
    phrases = [
        f"{e(scan[0.44])} rad at mu_back 0.44, {e(scan[0.45])} at the true 0.45, {e(scan[0.47])} at "
        f"0.47 and {e(scan[0.48])} at 0.48",
        "training gaps " + ", ".join(e(sw["fits"][k]["gap"]) for k in ("truth", "ci_point")) +
        f" and {e(sw['fits']['far']['gap'])} (mu_back " + ", ".join(f"{at[k]['mu_back']:.3f}" for k in
                                                                    ("truth", "ci_point", "far")) + ")",
        f"blends the coefficient over {rec['blend_rad_s']} rad/s",
        f"smooth ({e(smooth[0.44])}, {e(smooth[0.45])}, {e(smooth[0.47])}, {e(smooth[0.48])} at the same points)",
        f"training gap {e(bl['fits']['truth']['gap'])}: mu_drive {far['mu_drive']:.3f}, mu_back "
        f"{far['mu_back']:.3f}, armature {far['armature_kgm2']:.5f} kg m² from the far start",
        f"torque gain to {dict(zip(names, ps['corrections_x']))['gear_nm_per_v']:.3f} (truth 0.3)",
        f"than no load friction ({e(gc[0])} rad; the others {e(min(gc[1:]))} to {e(max(gc[1:]))})",
        f"worse at its best point ({e(min(go))})",
        f"here mu_drive {px['mu_drive']:.3f}, mu_back {px['mu_back']:.3f}, gap {e(ps['prescreen_gap'])}",
    ]
    # the three fits with the blend land within 0.5 % of each other in every parameter (the
    # page says so); with the switch mu_back alone spread over 20 %
    xs = np.array([f["x"] for f in bl["fits"].values()])
    assert np.all(np.ptp(xs, axis=0) <= 0.005 * np.abs(xs).max(axis=0))
    assert min(go) > gc[0] and min(gc[1:]) > gc[0]
    for ph in phrases:
        assert ph in text, ph


def test_load_friction_verdicts_on_the_pages():
    """The bench's and the bank's load_friction verdicts on docs/method/discrepancy.md and
    docs/reference/performance.md are their records'."""
    import json
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = " ".join((root / "docs/method/discrepancy.md").read_text().split())
    phrases = []
    def verdict(why):  # "mu_drive: 0.1777 vs truth 0.15 (± 0.02)" -> ("mu_drive", "0.1777", "0.02")
        m = re.fullmatch(r"(\w+): ([\d.]+) vs truth [\d.]+ \(± ([\d.e-]+)\)", why)
        return m.groups()

    srv = json.loads((root / "docs/reference/bench.json").read_text())["discrepancy_servo"]
    perf = " ".join((root / "docs/reference/performance.md").read_text().split())
    if srv["bank_verdict"] == "ok":
        assert 'meets the bank\'s criteria here (`bank_verdict` "ok")' in perf
        assert f"gap ×{srv['shrink_factor']:.1f}" in perf
    else:
        p, v, u = verdict(srv["bank_verdict"])
        assert f"{p} {float(v):.3f} ± {u} misses 0.15" in perf
    st = {k: v / 1e6 for k, v in srv["physics_steps_per_stage"].items()}
    assert (f"{srv['physics_steps'] / 1e6:.1f} M physics steps, {st['naming']:.1f} M of them naming" in perf)
    assert (f"{st['uncertainty_and_evaluation']:.1f} M the uncertainty, {st['other_fold_scheme']:.1f} M the "
            f"other fold scheme, {st['corrections']:.1f} M the corrections; {srv['unstable_replays']} replays "
            "went unstable") in perf
    # the bank's load_friction row (the table is the record's, test_discrepancy_bank) and the prose
    lf = json.loads((root / "docs/studies/discrepancy/bank.json").read_text())["cases"]["load_friction"]
    assert lf["why"] == "ok"
    row = next(line for line in text.split("| load_friction | load_friction (high) |")[1:2])
    fitted = re.findall(r"(mu_drive|mu_back) ([\d.]+ ± [\d.e-]+) \(", row.split("|")[0])
    assert [n for n, _ in fitted] == ["mu_drive", "mu_back"]
    phrases.append(f"(gap ×{lf['report']['shrink_factor']:.1f}), mu_drive {fitted[0][1]} and mu_back "
                   f"{fitted[1][1]} for 0.15 and 0.45")
    for ph in phrases:
        assert ph.replace("%", " %") in text or ph in text, ph


def test_performance_page_servo_time_is_the_bench_record():
    """docs/reference/performance.md's paragraphs on the geared-servo figure quote
    docs/reference/bench.json: its wall time, peak memory and CPU share, and from its ``measured``
    field the same machine's figures before it (every runner-up refitted; then the engine's
    small batches on the calling thread) and the record when the held-out folds landed;
    those before-figures are docs/studies/discrepancy/honest_folds.json's."""
    import json
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    srv = json.loads((root / "docs/reference/bench.json").read_text())["discrepancy_servo"]
    text = " ".join((root / "docs/reference/performance.md").read_text().split())
    m = srv["measured"]
    cpu, mb = re.search(r"(\d+) % of the 2 cores, (\d+) MB peak", m).groups()
    assert int(mb) == round(srv["peak_rss_mb"])
    every_s, every_steps, every_naming, every_mb = map(float, re.search(
        r"at 47ec9e1 \(every runner-up refitted, [^)]*\) ([\d.]+) s, ([\d.]+) M physics steps \(([\d.]+) M naming\), "
        r"(\d+) MB peak", m).groups())
    serial_s = float(re.search(r"at 190107f \([^)]*\) ([\d.]+) s", m)[1])
    landed_s, before_s = map(float, re.search(r"\(397d76b, an earlier machine\): ([\d.]+) s; the estimator before "
                                              r"them \(affc711, that machine\): ([\d.]+) s", m).groups())
    hf = json.loads((root / "docs/studies/discrepancy/honest_folds.json").read_text())["bench"]
    every, serial = hf["every_runner_up_confirmed"], hf["serial_small_batches"]
    assert (every["wall_s"], round(every["physics_steps"] / 1e6, 2), round(every["peak_rss_mb"]),
            round(every["physics_steps_per_stage"]["naming"] / 1e6, 2)) == (every_s, every_steps, every_mb, every_naming)
    assert serial["wall_s"] == serial_s and serial["physics_steps"] == every["physics_steps"]  # "the same steps"
    assert (f"with every runner-up refitted, {every_steps:.1f} M steps ({every_naming:.1f} M naming), "
            f"{every_s:.0f} s and {every_mb:.0f} MB peak; then with the engine's small batches on the calling "
            f"thread (the same steps, bit for bit), {serial_s:.0f} s") in text
    assert (f"Its time, {srv['wall_s']:.0f} s where the record when the held-out folds landed held {landed_s:.0f} s "
            f"on an earlier machine (the estimator before them {before_s:.0f} s there)") in text
    assert f"At {cpu} % of 2 cores" in text
    gate_s, gate_steps, gate_naming, gate_mb = map(float, re.search(
        r"at 86e7a53 \(the confirmation gate, [^)]*\) ([\d.]+) s, ([\d.]+) M physics steps \(([\d.]+) M naming\), "
        r"(\d+) MB peak", m).groups())
    gate = hf["confirmation_gate"]
    assert (gate["wall_s"], round(gate["physics_steps"] / 1e6, 2), round(gate["peak_rss_mb"]),
            round(gate["physics_steps_per_stage"]["naming"] / 1e6, 2)) == (gate_s, gate_steps, gate_mb, gate_naming)
    assert (f"without the Stribeck variant (the confirmation gate alone), {gate_steps:.1f} M steps "
            f"({gate_naming:.1f} M naming), {gate_s:.0f} s and {gate_mb:.0f} MB peak") in text
    variant = (srv["physics_steps_per_stage"]["naming"] - gate["physics_steps_per_stage"]["naming"]) / 1e6
    assert f"kept out by the nesting rule: {variant:.1f} M of the naming" in text
    assert f"{variant:.1f} M steps here where it cannot win" in text
