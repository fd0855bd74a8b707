"""The results tables and quoted figures of docs/**/*.md, generated from the files they summarise.

The documentation's results pages copy figures from files the tools write:

* ``docs/studies/reproduce/summary.json`` (``omni reproduce``), ``docs/studies/friction/comparison.json``,
  ``docs/studies/friction/lugre/params.json`` and ``docs/studies/friction/friction_study.json``
  (``omni reproduce --friction all``, ``scripts/friction_study.py``);
* ``models/omni/calibration.json``, ``models/omni/calibration_coulomb.json``, and the records of two
  calibrations not adopted, ``docs/studies/calibration/calibration_coulomb_run.json`` (a hard stick, every robot
  parameter free) and ``docs/studies/calibration/calibration_weighted_run.json`` (``scripts/calibrate.py``);
* ``docs/reference/bench.json`` (``omni bench``), ``docs/studies/sweep/results.csv`` (``omni sweep``);
* ``docs/studies/haptics/zwidth_ideal.json`` (``omni zwidth --ideal``) and
  ``examples/real_servo/report/report.json`` (``omni discrepancy`` on the real-servo example);
* the paper's tables (``identification/paper.py``).

:func:`tables` renders each results table from them; the page named in :data:`TABLES` holds it
between ``<!-- docs_tables: NAME -->`` and ``<!-- /docs_tables: NAME -->``.  :func:`claims`
renders the figures the pages quote in their prose, as the phrases that must appear in the page
named with them (compared with runs of white space, line breaks included, collapsed to one
space).  In the passages of :data:`RECORD_PASSAGES` (the README's haptics section and its
real-servo paragraph) every figure must lie inside such a phrase or be checked by a rule of
:data:`PASSAGE_RULES` (the Z-width sentence, whatever its wording): a figure typed in there
without a record is reported too (:func:`unchecked_figures`).

    python scripts/docs_tables.py            # check: list what drifted, exit status 1 if any
    python scripts/docs_tables.py --write    # rewrite the generated tables in docs/**/*.md

(``scripts/docs_tables.py`` runs this file, which calls :func:`main`.)  It reads the checkout's
files: it runs from one, and is not installed (``tools/`` is no package of the install).

``--write`` replaces only the text between the markers; the quoted figures are checked, never
written (the prose around them is the author's).  ``tests/test_docs_claims.py`` runs the check.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

if __package__ in (None, ""):  # run as a file (scripts/docs_tables.py): its siblings from the checkout's root
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identification import paper

from tools.docs_claims import (FIGURE, RECORD_PASSAGES, claims, mask, passage_span, unchecked_figures,  # noqa: F401
                               zwidth_bound, zwidth_row_errors)
from tools.docs_sources import (ROOT, PAGES, TARGET_INERTIA_REL, TARGET_STEP_RATIO, TARGET_RTF, TARGET_C_REL,
                                TARGET_ANGLE_DEG, TARGET_RESONANCE_HZ, TARGET_FALL, TARGET_GENERATE_RTF,
                                TARGET_ROLLOUT_RATIO, TARGET_ALPHA_LSIM, TARGET_REPRODUCE_RATIO,
                                TARGET_VECTOR_RATIO, TARGET_SWEEP_SPEEDUP, TARGET_COLD_RATIO, load_sources, _s,
                                _int, _met, _pose, _mrad, _beta_tilde_65_90, _cal_detail, _norm)


# -- tables -------------------------------------------------------------------------------------
def results_targets(src: dict) -> str:
    """docs/studies/reproduce/results.md: the project's targets, measured (docs/studies/reproduce, docs/reference/bench.json)."""
    s, b = src["summary"], src["bench"]["reproduce"]
    inr, st, sn, asim = s["inertia"], s["step"], s["sine"], s["alpha_simulation"]
    whole, after = st["windows"]["whole_record"], st["windows"]["after_edges"]
    p11, t8 = st["paper_table11"], paper.table8_average()
    errs = [r["rel_error"] for r in inr["poses"]]
    n = st["n_poses"]
    inertia_ok = inr["max_rel_error"] <= TARGET_INERTIA_REL
    all_better = st["alpha_better_poses"] == n
    only_median = all_better and (whole["alpha_better_poses_p90"] < n or after["alpha_better_poses"] < n)
    ratio_ok = whole["ratio_of_medians"] >= TARGET_STEP_RATIO and after["ratio_of_medians"] >= TARGET_STEP_RATIO
    nbis, nsteps, nbad = asim["steps_solved_by_bisection"], asim["steps"], asim["steps_not_converged"]
    rows = [
        "| target | measured | |", "|---|---|---|",
        f"| identified inertia (6) × β̄ within {100 * TARGET_INERTIA_REL:.0f} % of MuJoCo's mass matrix "
        f"at all {inr['n_poses']} Table 2 poses | max {100 * inr['max_rel_error']:.1f} % "
        f"({_s(100 * min(errs))} … {_s(100 * max(errs))} %) | {_met(inertia_ok)}"
        f"{'' if inertia_ok else ' (friction, see below)'} |",
        f"| α model beats the linear model on the step response at every pose | "
        f"{st['alpha_better_poses']} / {n} poses by each run's median error; "
        f"{whole['alpha_better_poses_p90']} / {n} by its 90th percentile (whole-record p90, median "
        f"over runs: α {_mrad(whole['p90_abs_error_alpha_rad'])} mrad, linear "
        f"{_mrad(whole['p90_abs_error_linear_rad'])} mrad) and {after['alpha_better_poses']} / {n} "
        f"over the first second after each edge | {_met(all_better)}"
        f"{' by the median only' if only_median else ''} (the paper's α: {p11['alpha_better_poses']} / "
        f"{p11['n_poses']} by the median, {p11['alpha_better_poses_p90']} / {p11['n_poses']} by the p90) |",
        f"| ratio of median step errors linear/α ≥ {TARGET_STEP_RATIO:g} | {whole['ratio_of_medians']:.2f} "
        f"(whole record; the paper's Table 11: {p11['ratio_of_medians']:.2f}), "
        f"{after['ratio_of_medians']:.2f} (first second after each edge). Ratio of means, the "
        f"statistic of the paper's \"{paper.PAPER_STEP_RATIO}×\": {whole['ratio_of_means']:.2f} "
        f"(paper {p11['ratio_of_means']:.2f}) | {_met(ratio_ok)} |",
        f"| α model halves the linear model's sine phase p90 error (paper "
        f"{t8['phase_p90_linear_deg']:.1f}° → {t8['phase_p90_alpha_deg']:.1f}°) | "
        f"{sn['phase_p90_linear_deg']:.1f}° → {sn['phase_p90_alpha_deg']:.1f}° (magnitude p90 "
        f"{sn['magnitude_p90_linear']:.3f} → {sn['magnitude_p90_alpha']:.3f}) | "
        f"{_met(sn['phase_p90_alpha_deg'] <= 0.5 * sn['phase_p90_linear_deg'])} |",
        f"| quasilinear iteration (46) converges | "
        f"{'every step solved' if nbad == 0 else f'{_int(nbad)} steps not solved'}: {_int(nbis)} of "
        f"{_int(nsteps)} ({100 * nbis / nsteps:.1f} %) do not meet (46) within 50 iterations (they "
        f"cycle or creep where C(α) is steep) and are solved by a bracketed bisection of the same "
        f"equation | {_met(nbad == 0)} (with the fallback) |",
        f"| `omni reproduce` real-time factor ≥ {TARGET_RTF:.0f} | {b['real_time_factor']:.0f} "
        f"(`omni bench`, `docs/reference/bench.json`: {b['simulated_time_s']:.0f} s simulated in "
        f"{b['wall_s']:.2f} s, the fastest of {len(b['wall_s_runs'])} runs of the whole command in a "
        f"child process, start-up and imports included). The report's own figure, "
        f"`run.real_time_factor` of `docs/studies/reproduce/summary.json`, is "
        f"{s['run']['real_time_factor']:.0f}: timed inside the command, from after its imports to "
        f"the last file written, in the one run that wrote `docs/studies/reproduce` (on a shared machine) | "
        f"{_met(b['real_time_factor'] >= TARGET_RTF)} |",
    ]
    return "\n".join(rows)



def calibration_targets(src: dict) -> str:
    """docs/studies/calibration/calibration.md: the LuGre calibration (models/omni/calibration.json) against the paper."""
    from omni_studies.calibration import TABLE10_ALPHA, TABLE10_C, TABLE10_FALL, c_at_alpha

    rec = src["cal"]
    a = rec["achieved"]
    P = rec["poses"]
    t3 = paper.table3()
    cerr = {tuple(p["set"]): abs(p["C_linear"] / p["C_paper"] - 1) for p in P}
    worst = max(cerr, key=cerr.get)
    others = max(v for k, v in cerr.items() if k != worst)
    over_aim = [k for k, v in cerr.items() if v > 0.05]
    sag = [r[f"gamma{j}_set_deg"] - r[f"gamma{j}_deg"] for r in t3 for j in (1, 2)]
    d = _cal_detail(rec)
    c_at = c_at_alpha(d, TABLE10_ALPHA)
    below = [x for x, f in zip(d["alpha"], d["frequency_hz"]) if f <= d["resonance_hz"]]
    bt = _beta_tilde_65_90(src["lugre_params"])
    fd = dict(zip(d["frequency_hz"], zip(d["alpha"], d["C_data"], d["beta_tilde_data"])))
    i_res = max(range(len(d["alpha"])), key=lambda i: d["alpha"][i])
    f_res_data = d["frequency_hz"][i_res]
    nonphys = [tuple(p["set"]) for p in P if p["non_physical"]]
    nonphys_f = sorted({f for p in P for f in p["non_physical"]})
    t9_res = TARGET_RESONANCE_HZ[0]
    rows = [
        "| target (paper) | paper | virtual Omni | error | |", "|---|---|---|---|---|",
        f"| C_linear at {len(P)} poses (Table 3) | {min(r['C_linear'] for r in t3):.3f}–"
        f"{max(r['C_linear'] for r in t3):.3f} 1/s | {min(p['C_linear'] for p in P):.2f}–"
        f"{max(p['C_linear'] for p in P):.2f} | max {100 * a['max_rel_error_C_linear']:.1f} % "
        f"({_pose(worst)}; others ≤ {100 * others:.1f} %) | "
        f"{_met(a['max_rel_error_C_linear'] < TARGET_C_REL)} (< {100 * TARGET_C_REL:.0f} %"
        + (f"; 5 % aim not met at {', '.join(_pose(k) for k in over_aim)}" if over_aim else "") + ") |",
        f"| β̃_linear at {len(P)} poses (Table 3) | {min(r['beta_tilde_linear'] for r in t3):.0f}–"
        f"{max(r['beta_tilde_linear'] for r in t3):.0f} | {min(p['beta_tilde_linear'] for p in P):.0f}–"
        f"{max(p['beta_tilde_linear'] for p in P):.0f} | max "
        f"{100 * a['max_rel_error_beta_tilde_linear']:.1f} % | "
        f"{_met(a['max_rel_error_beta_tilde_linear'] < TARGET_C_REL)} (< {100 * TARGET_C_REL:.0f} %) |",
        f"| actual arm angles (Table 3) | sag {min(sag):.1f}–{max(sag):.1f}° | | max "
        f"{a['max_angle_error_deg']:.2f}° | {_met(a['max_angle_error_deg'] < TARGET_ANGLE_DEG)} "
        f"(< {TARGET_ANGLE_DEG:g}°) |",
        f"| linear resonance at 65/90 (Table 9) | {t9_res:g} Hz | {a['resonance_65_90_hz']:.2f} Hz | "
        f"{_s(a['resonance_65_90_hz'] - t9_res, 2)} Hz | "
        f"{_met(abs(a['resonance_65_90_hz'] - t9_res) <= TARGET_RESONANCE_HZ[1])} |",
        f"| C(α) fall, lowest to highest breakpoint, 65/90 (Tables 7, 10) | {TABLE10_FALL:.1f}× | "
        f"{a['C_alpha_fall_65_90']:.1f}× (the calibration's identification, each pose at I = "
        f"1/β̃_linear; the reproduction's, with the inertia model (6): "
        f"{src['comparison']['families']['lugre']['C_alpha_fall']:.2f}×) | | "
        f"{_met(a['C_alpha_fall_65_90'] >= TARGET_FALL)} (≥ {TARGET_FALL:g}×)"
        f"{', steeper than the paper' if a['C_alpha_fall_65_90'] > TABLE10_FALL else ''} |",
        f"| C_data at α = {', '.join(f'{x:g}' for x in TABLE10_ALPHA)} (Table 10) | "
        f"{TABLE10_C[0]:.1f}, {TABLE10_C[1]:.2f}, {TABLE10_C[2]:.2f} | "
        f"{', '.join(f'{c:.3g}' for c in c_at)} (the last held at the highest α below resonance, "
        f"{max(below):.0f}) | {', '.join(_s(100 * (c / t - 1), 0) for c, t in zip(c_at, TABLE10_C))} % | |",
        f"| β̃ falls with α (Table 10: {paper.table10()['beta_tilde_0']:.0f} → "
        f"{paper.table10()['beta_tilde_1']:.0f}) | yes | yes: the α model at 65/90 falls "
        f"{bt['at_0']:.0f} → {bt['at_fitted']:.0f} over the α it fitted there (0 → "
        f"{bt['alpha_fitted']:.0f}), to {bt['at_resonance']:.0f} at resonance (α = "
        f"{bt['alpha_resonance']:.0f}) and {bt['at_edge']:.0f} at α = {bt['alpha_edge']:.0f} (Fig. 10's "
        f"edge); β̃_data {fd[2.0][2]:.0f} at 2 Hz → {fd[f_res_data][2]:.0f} at resonance, but "
        f"{fd[1.5][2]:.0f} at 1.5 Hz | | met |",
        f"| a low frequency with non-physical local coefficients (section 2.3) | yes | "
        f"{', '.join(f'{f:g}' for f in nonphys_f)} Hz at {' and '.join(_pose(k) for k in nonphys)} | | "
        f"{_met(bool(nonphys))} |",
        f"| α rises to resonance, falls after (Fig. 8) | yes | yes ({fd[f_res_data][0]:.0f} at "
        f"{f_res_data:g} Hz → {fd[6.0][0]:.0f} at 6 Hz) | | met |",
    ]
    return "\n".join(rows)


def families_calibration(src: dict) -> str:
    """docs/method/friction-families.md: both calibration records side by side."""
    from omni_studies.calibration import TABLE10_FALL

    recs = {"coulomb": src["cal_coulomb"], "lugre": src["cal"]}
    A = {f: r["achieved"] for f, r in recs.items()}

    def both(ok: dict, what: str) -> str:
        good = [f for f in recs if ok[f]]
        text = {2: "both", 1: f"{good[0]} only" if good else "", 0: "neither"}[len(good)]
        return text + (f" ({what})" if what else "")

    def nonphys(a, rec):
        if not a["poses_with_non_physical_frequencies"]:
            return f"none (smallest margin {_s(a['min_physical_margin'], 2)})"
        fs = sorted({f for p in rec["poses"] for f in p["non_physical"]})
        return (f"{', '.join(f'{f:g}' for f in fs)} Hz at "
                + ", ".join(_pose(k) for k in a["poses_with_non_physical_frequencies"]))

    row = lambda label, pap, fmt, met="": (  # noqa: E731
        f"| {label} | {pap} | {fmt(A['coulomb'], recs['coulomb'])} | {fmt(A['lugre'], recs['lugre'])} | {met} |")
    res = TARGET_RESONANCE_HZ
    rows = [
        "| target | paper | coulomb | lugre | met |", "|---|---|---|---|---|",
        row("C_linear at 9 poses (Table 3), worst", "—", lambda a, r: f"{100 * a['max_rel_error_C_linear']:.1f} %",
            both({f: A[f]["max_rel_error_C_linear"] < TARGET_C_REL for f in recs}, "< 10 %")),
        row("β̃_linear at 9 poses (Table 3), worst", "—",
            lambda a, r: f"{100 * a['max_rel_error_beta_tilde_linear']:.1f} %",
            both({f: A[f]["max_rel_error_beta_tilde_linear"] < TARGET_C_REL for f in recs}, "< 10 %")),
        row("actual arm angles (Table 3), worst", "—", lambda a, r: f"{a['max_angle_error_deg']:.2f}°",
            both({f: A[f]["max_angle_error_deg"] < TARGET_ANGLE_DEG for f in recs}, "< 1.5°")),
        row("linear resonance at 65/90 (Table 9)", f"{res[0]:g} Hz", lambda a, r: f"{a['resonance_65_90_hz']:.2f} Hz",
            both({f: abs(A[f]["resonance_65_90_hz"] - res[0]) <= res[1] for f in recs}, f"± {res[1]:g} Hz")),
        row("C(α) fall, 65/90 (Tables 7, 10; the calibration's identification)", f"{TABLE10_FALL:.1f}×",
            lambda a, r: f"{a['C_alpha_fall_65_90']:.{1 if a['C_alpha_fall_65_90'] >= 10 else 2}f}×",
            both({f: A[f]["C_alpha_fall_65_90"] >= TARGET_FALL for f in recs}, "≥ 3×")),
        row("a low frequency with non-physical local coefficients (section 2.3)", "yes", nonphys,
            both({f: bool(A[f]["poses_with_non_physical_frequencies"]) for f in recs}, "")),
        row("calibration cost (same residuals, same scales)", "", lambda a, r: f"{r['cost_after']:.1f}"),
    ]
    return "\n".join(rows)


def families_verdict(src: dict) -> str:
    """docs/method/friction-families.md: the alpha model's verdict per family (comparison.json)."""
    comp = src["comparison"]
    F, P = comp["families"], comp["paper"]
    ps = P["step"]
    fams = tuple(F)  # every family the comparison ran (omni_sim.model.FRICTION_FAMILIES)

    def row(label, pap, fmt):
        return f"| {label} | {pap} | " + " | ".join(fmt(F[f]) for f in fams) + " |"

    t7 = paper.table7()
    t11 = F["lugre"]["step_linear_vs_table11"]
    rows = [
        "| figure | paper | " + " | ".join(fams) + " |", "|---|---|" + "---|" * len(fams),
        row("step: ratio of medians linear/α, whole record", f"{ps['ratio_of_medians']:.2f}",
            lambda d: f"{d['step']['ratio_of_medians_whole_record']:.2f}"),
        row(f"step: ratio of means linear/α, whole record (the paper's \"{P['step_ratio']}\")",
            f"{ps['ratio_of_means']:.2f}", lambda d: f"{d['step']['ratio_of_means_whole_record']:.2f}"),
        row("step: ratio of medians over the first second after each edge", "—",
            lambda d: f"{d['step']['ratio_of_medians_after_edges']:.2f}"),
        row("step: α better, by each run's median error", f"{ps['alpha_better_poses']}/{ps['n_poses']} poses",
            lambda d: f"{d['step']['alpha_better_poses']}/{d['step']['n_poses']} poses"),
        row("step: α better, by each run's p90 error", f"{ps['alpha_better_poses_p90']}/{ps['n_poses']} poses",
            lambda d: f"{d['step']['alpha_better_poses_p90']}/{d['step']['n_poses']} poses"),
        row("step: α better over the first second after each edge (median)", "—",
            lambda d: f"{d['step']['alpha_better_poses_after_edges']}/{d['step']['n_poses']} poses"),
        row("step: p90 error linear → α, median over poses",
            f"{_mrad(ps['p90_abs_error_linear_rad'])} → {_mrad(ps['p90_abs_error_alpha_rad'])} mrad",
            lambda d: f"{_mrad(d['step']['p90_abs_error_linear_rad'])} → "
                      f"{_mrad(d['step']['p90_abs_error_alpha_rad'])} mrad"),
        row("sine phase p90, linear → α",
            f"{P['sine']['phase_p90_linear_deg']:.1f}° → {P['sine']['phase_p90_alpha_deg']:.1f}°",
            lambda d: f"{d['sine']['phase_p90_linear_deg']:.1f}° → {d['sine']['phase_p90_alpha_deg']:.1f}°"),
        row("sine magnitude p90, linear → α",
            f"{P['sine']['magnitude_p90_linear']:.3f} → {P['sine']['magnitude_p90_alpha']:.3f}",
            lambda d: f"{d['sine']['magnitude_p90_linear']:.3f} → {d['sine']['magnitude_p90_alpha']:.3f}"),
        row("identified α breakpoints [V²/s²]", ", ".join(f"{r['alpha']:g}" for r in t7),
            lambda d: ", ".join(f"{a:.3g}" for a in d["alpha_breaks"])),
        row("C(α) fall, first to last breakpoint (this identification, inertia model (6))",
            f"{P['C_alpha_fall']:.2f}×", lambda d: f"{d['C_alpha_fall']:.2f}×"),
        row("inertia (6) × β̄ vs MuJoCo, worst signed", "—",
            lambda d: f"{_s(100 * d['inertia']['worst_signed_rel_error'])} %"),
        row("linear model's step error, median over poses", f"{_mrad(t11['paper_median_over_poses_rad'])} mrad",
            lambda d: f"{_mrad(d['step_linear_vs_table11']['median_over_poses_rad'], 2)} mrad"),
    ]
    return "\n".join(rows)


def sweep_table(src: dict) -> str:
    """docs/usage/sweeps.md: docs/studies/sweep/results.csv, one row per variant."""
    rows = ["| friction scale | inertia max error | step ratio whole / after edges | "
            "sine phase p90 lin → α [deg] | magnitude p90 lin → α |", "|---|---|---|---|---|"]
    for r in src["sweep"]:
        if r["status"] != "ok":
            why = ("the α model cannot be fitted (fitted torque constant zero)"
                   if "torque constant is zero" in r["error"] else r["error"])
            rows.append(f"| {r['friction_scale']} | failed: {why} | | | |")
            continue
        f = {k: float(v) for k, v in r.items() if k not in ("id", "status", "error")}
        rows.append(f"| {r['friction_scale']} | {100 * f['inertia_max_rel_error']:.1f} % | "
                    f"{f['step_ratio_of_medians_whole_record']:.2f} / {f['step_ratio_of_medians_after_edges']:.2f} | "
                    f"{f['sine_phase_p90_linear_deg']:.1f} → {f['sine_phase_p90_alpha_deg']:.1f} | "
                    f"{f['sine_magnitude_p90_linear']:.2f} → {f['sine_magnitude_p90_alpha']:.2f} |")
    return "\n".join(rows)


def performance_table(src: dict) -> str:
    """docs/reference/performance.md: ``omni bench``'s figures (docs/reference/bench.json) against their targets."""
    b = src["bench"]
    ps, asim, rep = b["paper_campaign"], b["alpha_simulation"], b["reproduce"]
    vec, sw, dis = b["vector_env"], b["sweep"], b["discrepancy"]

    def met(ok: bool) -> str:
        return "met" if ok else "**not met**"

    rows = [
        "| figure | target | measured | |", "|---|---|---|---|",
        f"| paper campaign ({ps['runs']} runs, {ps['simulated_time_s']:.0f} s simulated): real-time factor of "
        f"`omni generate` (simulation + writing the dataset) | ≥ {TARGET_GENERATE_RTF:.0f} | "
        f"{ps['generate_rtf']:.0f} (simulation alone {ps['simulate_rtf']:.0f}) | "
        f"{met(ps['generate_rtf'] >= TARGET_GENERATE_RTF)} |",
        f"| campaign physics steps/s ÷ raw `mujoco.rollout` steps/s, same model, steps and "
        f"{b['jobs']} threads | ≥ {TARGET_ROLLOUT_RATIO:g} | {ps['rollout_ratio']:.2f} "
        f"({ps['steps_per_s'] / 1e3:.0f} k vs {ps['rollout_ceiling_steps_per_s'] / 1e3:.0f} k steps/s) | "
        f"{met(ps['rollout_ratio'] >= TARGET_ROLLOUT_RATIO)} |",
        f"| α-model quasilinear simulation of {asim['n_runs']} step runs ÷ `scipy.signal.lsim` of the "
        f"linear model | ≤ {TARGET_ALPHA_LSIM:g} | {asim['ratio_alpha_to_lsim']:.3f} | "
        f"{met(asim['ratio_alpha_to_lsim'] <= TARGET_ALPHA_LSIM)} |",
        f"| `omni reproduce` as a user runs it (a child process: imports, simulation, identification, "
        f"validation, writing, figures; the fastest of {len(rep['wall_s_runs'])} runs, as the raw rollout "
        f"is the fastest of its {len(rep['wall_s_runs'])}) ÷ the raw rollout time of its "
        f"{ps['physics_steps'] / 1e3:.0f} k physics steps | ≤ {TARGET_REPRODUCE_RATIO:g} | "
        f"{rep['ratio_to_raw_rollout']:.1f} ({rep['wall_s']:.2f} s vs {rep['raw_rollout_s']:.2f} s; the "
        f"runs {', '.join(f'{w:.2f}' for w in rep['wall_s_runs'])} s; real-time factor "
        f"{rep['real_time_factor']:.0f}; peak memory {rep['peak_rss_mb']:.0f} MB) | "
        f"{met(rep['ratio_to_raw_rollout'] <= TARGET_REPRODUCE_RATIO)} |",
    ]
    cold = rep.get("cold")
    if cold:
        rows.append(
            f"| `omni reproduce` as the first run after an install (the same child process from a fresh "
            f"copy of the packages without `__pycache__`, empty numba cache and matplotlib cache folders; "
            f"the fastest of {len(cold['wall_s_runs'])}) ÷ the same command with all cached "
            f"{'(measured on its own, see its `measured`) ' if cold.get('measured') else ''}"
            f"| ≤ {TARGET_COLD_RATIO:g} | {cold['ratio_to_warm']:.2f} ({cold['wall_s']:.2f} s vs "
            f"{cold['warm_wall_s']:.2f} s; the cold runs {', '.join(f'{w:.2f}' for w in cold['wall_s_runs'])} s) | "
            f"{met(cold['ratio_to_warm'] <= TARGET_COLD_RATIO)} |")
    rows += [
        f"| native vector environment, {vec['num_envs']} Omnis, steps/s ÷ raw rollout steps/s | "
        f"≥ {TARGET_VECTOR_RATIO:g} | {vec['ratio_to_raw_rollout']:.2f} ({vec['env_steps_per_s'] / 1e3:.0f} k "
        f"vs {vec['rollout_ceiling_steps_per_s'] / 1e3:.0f} k) | "
        f"{met(vec['ratio_to_raw_rollout'] >= TARGET_VECTOR_RATIO)} |",
        f"| `omni sweep --example` (6 variants), 2 Dask workers ÷ 1 worker, cluster start-up included | "
        f"≥ {TARGET_SWEEP_SPEEDUP:g} | {sw['speedup_2_workers']:.2f} ({sw['variants_per_s_2_workers']:.3f} vs "
        f"{sw['variants_per_s_1_worker']:.3f} variants/s) | "
        f"{met(sw['speedup_2_workers'] >= TARGET_SWEEP_SPEEDUP)} |",
        f"| `omni discrepancy` on the demo case (16 runs, {dis['discrepancy_samples'] / 1e3:.0f} k samples, "
        f"16 candidates, k-fold) | minutes | {dis['discrepancy_s']:.0f} s (named "
        f"`{'`, `'.join(dis['discrepancy_named'])}`) | "
        f"{met(dis['discrepancy_correct'] and dis['discrepancy_s'] < 600)} |",
    ]
    srv = b.get("discrepancy_servo")
    if srv:
        rows.append(
            f"| `omni discrepancy` as a user runs it on {srv['runs']} geared-servo runs of 6 s with the "
            f"nominal off (`{srv['case']}`: {srv['control_periods'] / 1e3:.0f} k control periods, "
            f"{srv['log_samples'] / 1e3:.0f} k logged samples at 200 Hz; measured on its own, see its `measured`) | "
            f"≤ 180 s, ≤ 1 GB; ≤ 30 M physics steps aimed at | {srv['wall_s']:.0f} s, {srv['peak_rss_mb']:.0f} MB, "
            f"{srv['physics_steps'] / 1e6:.1f} M steps (named `{'`, `'.join(srv['named'])}`, gap "
            f"×{srv['shrink_factor']:.1f}, bank criteria "
            f"{'met' if srv['passes_bank_criteria'] else 'not met: ' + srv.get('bank_verdict', '?')}) | "
            f"{met(srv['wall_s'] <= 180 and srv['peak_rss_mb'] <= 1024)} (time "
            f"{'met' if srv['wall_s'] <= 180 else 'not met'}, memory "
            f"{'met' if srv['peak_rss_mb'] <= 1024 else 'not met'}; steps "
            f"{'met' if srv['physics_steps'] <= 30e6 else 'not met'}; the answer "
            f"{'right' if srv['passes_bank_criteria'] else '**wrong**'} by the bank's criteria) |")
    return "\n".join(rows)


#: Every generated table: name -> (the page that holds it, the function that renders it).
TABLES = {"results_targets": ("results", results_targets),
          "calibration_targets": ("calibration", calibration_targets),
          "families_calibration": ("friction", families_calibration),
          "families_verdict": ("friction", families_verdict),
          "sweep": ("sweeps", sweep_table),
          "performance": ("performance", performance_table)}


def tables(src: dict | None = None) -> dict[str, str]:
    """Every generated table, by name."""
    src = src or load_sources()
    return {name: fn(src) for name, (_, fn) in TABLES.items()}


# -- check and write ----------------------------------------------------------------------------
def load_pages() -> dict[str, str]:
    """The text of every page of :data:`PAGES`, by short name."""
    return {name: (ROOT / rel).read_text() for name, rel in PAGES.items()}


def _block(name: str) -> re.Pattern:
    return re.compile(rf"(<!-- docs_tables: {name} -->\n)(.*?)(\n<!-- /docs_tables: {name} -->)", re.S)




def check(pages: dict[str, str] | None = None, src: dict | None = None) -> list[str]:
    """What in ``pages`` (short name -> text, default :func:`load_pages`) differs from the
    sources: one line per drifted table or figure, naming its page."""
    pages = pages if pages is not None else load_pages()
    src = src or load_sources()
    problems = []
    for name, table in tables(src).items():
        page = TABLES[name][0]
        m = _block(name).search(pages[page])
        if m is None:
            problems.append(f"table {name}: no '<!-- docs_tables: {name} -->' block in {PAGES[page]}")
        elif m.group(2).strip() != table:
            problems.append(f"table {name} ({PAGES[page]}): differs from its sources "
                            "(run scripts/docs_tables.py --write)")
    phrases = claims(src)
    for page, found in phrases.items():
        text = _norm(pages[page])
        problems += [f"figure not in {PAGES[page]}: {c!r}" for c in found if _norm(c) not in text]
    return problems + unchecked_figures(pages, src, phrases)


def write(pages: dict[str, str], src: dict | None = None) -> dict[str, str]:
    """``pages`` with every generated table replaced by its current rendering."""
    pages = dict(pages)
    for name, table in tables(src or load_sources()).items():
        page = TABLES[name][0]
        pat = _block(name)
        if pat.search(pages[page]) is None:
            raise SystemExit(f"error: {PAGES[page]}: no '<!-- docs_tables: {name} -->' block")
        pages[page] = pat.sub(lambda m: m.group(1) + table + m.group(3), pages[page])
    return pages


def main(argv=None) -> int:
    """The command line of ``scripts/docs_tables.py`` (check; ``--write``)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite the generated tables in docs/**/*.md")
    args = ap.parse_args(argv)
    pages = load_pages()
    if args.write:
        for name, text in write(pages).items():
            if text != pages[name]:
                (ROOT / PAGES[name]).write_text(text)
                print(f"wrote {PAGES[name]}")
    problems = check()
    for p in problems:
        print(p)
    return 1 if problems else 0



if __name__ == "__main__":
    raise SystemExit(main())
