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
import csv
import json
import math
import re
from pathlib import Path

from identification import paper

ROOT = Path(__file__).resolve().parents[1]

#: The pages that hold generated tables or quoted figures, by short name (paths from the root).
PAGES = {"results": "docs/studies/reproduce/results.md", "model": "docs/reference/model.md",
         "calibration": "docs/studies/calibration/calibration.md",
         "friction": "docs/method/friction-families.md", "errata": "docs/method/paper-errata.md",
         "performance": "docs/reference/performance.md", "gymnasium": "docs/usage/gymnasium.md",
         "sweeps": "docs/usage/sweeps.md", "readme": "README.md",
         "real_servo": "examples/real_servo/README.md"}
#: The targets the tables state (the report's: omni_app/report.py).
TARGET_INERTIA_REL = 0.02
TARGET_STEP_RATIO = 3.0
TARGET_RTF = 50.0
TARGET_C_REL = 0.10             # calibration: C_linear, beta~_linear within 10 % of Table 3
TARGET_ANGLE_DEG = 1.5
TARGET_RESONANCE_HZ = (3.4, 0.3)
TARGET_FALL = 3.0
TARGET_GENERATE_RTF = 100.0     # omni bench (omni_studies/bench.py)
TARGET_ROLLOUT_RATIO = 0.8
TARGET_ALPHA_LSIM = 3.0
TARGET_REPRODUCE_RATIO = 6.0
TARGET_VECTOR_RATIO = 0.3
TARGET_SWEEP_SPEEDUP = 1.7
TARGET_COLD_RATIO = 1.3         # omni reproduce's first run after an install / a later one (bench.py)
#: docs/studies/calibration/calibration.md's "close" candidates of the table-level search: a step error (Table 11's
#: linear column, median over poses) within this share of the real Omni's.
CLOSE_STEP_REL = 0.25
MINUS = "\u2212"


# -- sources ------------------------------------------------------------------------------------
def _json(rel):
    return json.loads((ROOT / rel).read_text())


def _servo_model(rel) -> dict:
    """The real-servo example's nominal model: its hinge's and its actuator's attributes."""
    import xml.etree.ElementTree as ET

    root = ET.parse(ROOT / rel).getroot()
    return {"joint": root.find(".//joint[@name='servo_axis']").attrib,
            "actuator": root.find("./actuator/*[@name='servo']").attrib}


def load_sources() -> dict:
    """Every file the pages' results quote, parsed."""
    with open(ROOT / "docs" / "studies" / "sweep" / "results.csv") as fh:
        sweep = list(csv.DictReader(fh))
    return {"summary": _json("docs/studies/reproduce/summary.json"),
            "comparison": _json("docs/studies/friction/comparison.json"),
            "lugre_params": _json("docs/studies/friction/lugre/params.json"),
            "study": _json("docs/studies/friction/friction_study.json"),
            "cal": _json("models/omni/calibration.json"),
            "cal_coulomb": _json("models/omni/calibration_coulomb.json"),
            "cal_hard_stick": _json("docs/studies/calibration/calibration_coulomb_run.json"),
            "cal_coulomb_all_free": _json("docs/studies/fidelity/coulomb_all_free.json"),
            "cal_weighted": _json("docs/studies/calibration/calibration_weighted_run.json"),
            "cal_matched": _json("models/omni/calibration_matched.json"),
            "matched_summary": _json("docs/studies/friction/matched/summary.json"),
            "search": _json("docs/studies/fidelity/search.json"),
            "bench": _json("docs/reference/bench.json"),
            "zwidth_ideal": _json("docs/studies/haptics/zwidth_ideal.json"),
            "real_servo": _json("examples/real_servo/report/report.json"),
            "real_servo_model": _servo_model("examples/real_servo/model.xml"),
            "sweep": sweep}


# -- formatting ---------------------------------------------------------------------------------
def _s(x: float, nd: int = 1) -> str:
    """Signed, with a true minus sign: +2.2, −7.3."""
    return f"{x:+.{nd}f}".replace("-", MINUS)


def _m(x: float, nd: int = 1) -> str:
    """A number with a true minus sign."""
    return f"{x:.{nd}f}".replace("-", MINUS)


def _sci(x: float, nd: int = 1) -> str:
    """6.8e-4 (no zero-padded exponent)."""
    mant, exp = f"{x:.{nd}e}".split("e")
    return f"{mant}e{int(exp)}"


def _int(n: int) -> str:
    """686 000 (a space between thousands)."""
    return f"{n:,}".replace(",", " ")


def _met(ok: bool) -> str:
    return "met" if ok else "**not met**"


def _pose(p) -> str:
    return f"{round(p[0])}/{round(p[1])}"


def _mrad(x: float, nd: int = 1) -> str:
    return f"{1e3 * x:.{nd}f}"


# -- the α model of the reproduction at 65/90 ------------------------------------------------------
def _beta_tilde_65_90(params: dict) -> dict:
    """beta~(alpha) of the reproduction's alpha model at 65/90 (inertia model (6)) at alpha = 0,
    the highest alpha fitted there (frequencies up to resonance), alpha at resonance and the
    right edge of Fig. 10 (twice the highest alpha of the pose's data)."""
    import numpy as np

    from identification.inertia import InertiaParameters
    from identification.nonlinear import AlphaModel, pose_resonance_hz

    pose = next(p for p in params["poses"] if (round(p["gamma1_set_deg"]), round(p["gamma2_set_deg"]))
                == paper.TABLE9_10_SET_POSE)
    am = AlphaModel.from_dict(params["alpha_model"])
    I = float(InertiaParameters.from_dict(params["inertia_model"]).inertia(pose["gamma1_deg"],
                                                                          pose["gamma2_deg"]))
    f_res = pose_resonance_hz({"beta_linear": pose["beta_linear"]})
    freqs = pose["frequencies"]
    fitted = [q["alpha"] for q in freqs if q["used"] and q["frequency_hz"] <= f_res]
    at_res = max(q["alpha"] for q in freqs)
    edge = 2 * max(q["alpha"] for q in freqs)
    bt = lambda a: float(am.beta_tilde(np.array([a]), I)[0])  # noqa: E731
    return {"alpha_fitted": max(fitted), "alpha_resonance": at_res, "alpha_edge": edge,
            "at_0": bt(0.0), "at_fitted": bt(max(fitted)), "at_resonance": bt(at_res),
            "at_edge": bt(edge)}


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


def _cal_detail(rec: dict) -> dict:
    return next(p for p in rec["poses"] if tuple(round(x) for x in p["set"]) == paper.TABLE9_10_SET_POSE)


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


# -- figures quoted in the prose and in the hand-written tables ----------------------------------
# One function per page (two for docs/method/friction-families.md): each returns the page's
# phrases, a flat list, one entry per quoted figure, read beside the page it checks.
def _values(rec: dict) -> dict:
    """A calibration record's parameter values by name."""
    return {k: p["value"] for k, p in rec["parameters"].items()}


def _lugre_values(cal: dict) -> tuple[dict, float, float]:
    """A calibration record's parameter values by name, and its LuGre Fc and Fs (N m)."""
    v = _values(cal)
    return v, v["lugre_friction"], v["lugre_friction"] * v["stribeck_ratio"]


def _resonance_by_frequency(cal: dict) -> tuple[dict, dict]:
    """The calibration's resonance detail, and frequency (Hz) -> (α, C_data, β̃_data)."""
    d = _cal_detail(cal)
    return d, dict(zip(d["frequency_hz"], zip(d["alpha"], d["C_data"], d["beta_tilde_data"])))


def _matched_figures(src: dict) -> dict:
    """The matched calibration's step figures against the real Omni's (Table 11's linear column),
    and the spread of Table 3's worst coefficient over the search's close lugre candidates."""
    from omni_studies.calibration import STEP_BAND_REL

    lug = src["comparison"]["families"]["lugre"]
    mst = src["matched_summary"]["step"]
    cm = src["cal_matched"]["achieved"]
    paper_med = lug["step_linear_vs_table11"]["paper_median_over_poses_rad"]
    close = [max(abs(r["figures"]["table3_C_worst_rel"]), abs(r["figures"]["table3_beta_tilde_worst_rel"]))
             for r in src["search"]["candidates"] if r.get("ok") and r["family"] == "lugre"
             and abs(r["figures"]["step_median_rad"] / paper_med - 1) <= CLOSE_STEP_REL]
    return {"paper_step_rad": paper_med, "step_mrad": 1e3 * cm["step_median_rad"],
            "step_p90_rad": cm["step_p90_median_rad"], "poses": cm["poses_within_40pct"],
            "C": 100 * cm["table3_C_worst_rel"], "beta": 100 * cm["table3_beta_tilde_worst_rel"],
            "angle": cm["angle_worst_deg"], "n_close": len(close), "close_lo": 100 * min(close),
            "close_hi": 100 * max(close), "n_poses": mst["n_poses"], "band": 100 * STEP_BAND_REL,
            "ratio": paper_med / lug["step_linear_vs_table11"]["median_over_poses_rad"]}


def results_claims(src: dict) -> list[str]:
    """docs/studies/reproduce/results.md's quoted figures (``omni reproduce``)."""
    s, comp = src["summary"], src["comparison"]
    st = s["step"]
    whole, after = st["windows"]["whole_record"], st["windows"]["after_edges"]
    p11 = st["paper_table11"]
    errs = [r["rel_error"] for r in s["inertia"]["poses"]]
    lug, cou = comp["families"]["lugre"], comp["families"]["coulomb"]
    _, fd = _resonance_by_frequency(src["cal"])
    bt = _beta_tilde_65_90(src["lugre_params"])
    return [
        f"the same fit is off by {_m(100 * min(errs))} to {_s(100 * max(errs))} %",
        f"(the coulomb family's worst error is {_s(100 * cou['inertia']['worst_signed_rel_error'])} %)",
        f"ratio of means {whole['ratio_of_means']:.2f} (the paper's {p11['ratio_of_means']:.2f}, its "
        f"\"{paper.PAPER_STEP_RATIO}×\"), ratio of medians {whole['ratio_of_medians']:.2f} (the "
        f"paper's {p11['ratio_of_medians']:.2f})",
        f"α's whole-record p90 error is twice the linear model's ({_mrad(whole['p90_abs_error_alpha_rad'])} "
        f"vs {_mrad(whole['p90_abs_error_linear_rad'])} mrad, median over runs; α better by the p90 at "
        f"{whole['alpha_better_poses_p90']} of {whole['n_poses']} poses), where the paper's α halved "
        f"it ({_mrad(p11['p90_abs_error_alpha_rad'])} vs {_mrad(p11['p90_abs_error_linear_rad'])} mrad)",
        f"the linear model is better ({after['ratio_of_medians']:.2f}; α better at "
        f"{after['alpha_better_poses']} of {after['n_poses']} poses)",
        f"(Fig. 10: {bt['at_0']:.0f} at α = 0, {bt['at_fitted']:.0f} at α = {bt['alpha_fitted']:.0f}, "
        f"the highest α fitted at 65/90, ~{bt['at_edge']:.0f} at the figure's edge, α = "
        f"{bt['alpha_edge']:.0f}; paper {paper.table10()['beta_tilde_0']:.0f} → "
        f"{paper.table10()['beta_tilde_1']:.0f} from α = 0 to 250)",
        f"(C_data = {fd[2.0][1]:.0f} 1/s, β̃_data = {fd[2.0][2]:.0f} at 2 Hz, 65/90)",
        f"breakpoints ({', '.join(f'{a:.3g}' for a in lug['alpha_breaks'])} V²/s²)",
        f"cycles or creeps on {100 * s['alpha_simulation']['steps_solved_by_bisection'] / s['alpha_simulation']['steps']:.1f} % of the steps",
    ]


def readme_claims(src: dict) -> list[str]:
    """README.md's quoted figures (the calibrated virtual Omni against the paper)."""
    comp = src["comparison"]
    lug, mat = comp["families"]["lugre"], comp["families"]["matched"]
    mt = _matched_figures(src)
    return [
        f"{mt['ratio']:.1f}× better than the real Omni's (Table 11's linear column: "
        f"{_mrad(lug['step_linear_vs_table11']['median_over_poses_rad'], 2)} against "
        f"{_mrad(mt['paper_step_rad'])} mrad)",
        f"calibrated {len(src['search']['candidates'])} candidate effects",
        f"linear column met ({mt['step_mrad']:.1f} mrad, {mt['poses']} of {mt['n_poses']} poses within "
        f"{mt['band']:.0f} %) with "
        f"Table 3's C_linear {abs(mt['C']):.1f} % off",
        f"(ratio of medians linear/α {mat['step']['ratio_of_medians_whole_record']:.2f}, the paper's "
        f"{comp['paper']['step']['ratio_of_medians']:.2f})",
    ]


def calibration_claims(src: dict) -> list[str]:
    """docs/studies/calibration/calibration.md's quoted figures (``scripts/calibrate.py``)."""
    comp, cal = src["comparison"], src["cal"]
    lug, mat = comp["families"]["lugre"], comp["families"]["matched"]
    mst = src["matched_summary"]["step"]
    hs, wt = src["cal_hard_stick"]["achieved"], src["cal_weighted"]["achieved"]
    v, fc, fs = _lugre_values(cal)
    d, fd = _resonance_by_frequency(cal)
    mt = _matched_figures(src)
    return [
        f"each of the {mt['n_close']} lugre-footed candidates whose step error comes within "
        f"{100 * CLOSE_STEP_REL:.0f} % of the "
        f"real Omni's misses Table 3, its worst coefficient {mt['close_lo']:.1f}–{mt['close_hi']:.1f} % off",
        f"(median {mt['step_mrad']:.1f} mrad against {_mrad(mt['paper_step_rad'])}, p90 "
        f"{_mrad(mt['step_p90_rad'])} against {_mrad(comp['paper']['step']['p90_abs_error_linear_rad'])} mrad, "
        f"{mt['poses']}/{mt['n_poses']} poses within {mt['band']:.0f} %) with Table 3's C_linear at "
        f"{_m(mt['C'])} % at its worst pose "
        f"(β̃ {_m(mt['beta'])} %, angles {mt['angle']:.2f}°)",
        f"{_mrad(mst['median_abs_error_linear_rad'], 2)} → {_mrad(mst['median_abs_error_alpha_rad'], 2)} mrad",
        f"ratio of medians {mat['step']['ratio_of_medians_whole_record']:.2f} against "
        f"{comp['paper']['step']['ratio_of_medians']:.2f}, of means {mat['step']['ratio_of_means_whole_record']:.2f} "
        f"against {comp['paper']['step']['ratio_of_means']:.2f}",
        f"p90 {_mrad(mat['step']['p90_abs_error_linear_rad'])} → {_mrad(mat['step']['p90_abs_error_alpha_rad'])} mrad",
        f"phase p90 {mat['sine']['phase_p90_linear_deg']:.1f}° → {mat['sine']['phase_p90_alpha_deg']:.1f}°",
        f"magnitude p90 {mat['sine']['magnitude_p90_linear']:.3f} → {mat['sine']['magnitude_p90_alpha']:.3f}",
        f"errs by up to {_s(100 * mat['inertia']['worst_signed_rel_error'])} % against",
        f"Calibrated values: link masses {1e3 * v['m_upper_arm']:.0f} g, {1e3 * v['m_forearm']:.0f} g, "
        f"stylus {1e3 * v['m_stylus']:.0f} g",
        f"turret {_sci(v['I_turret'])} kg m², yaw viscous damping {_sci(v['yaw_damping'])} N m s/rad, "
        f"LuGre Fc {1e3 * fc:.1f} mN m, Fs {1e3 * fs:.1f} mN m, vs {v['stribeck_speed']:.2f} rad/s, "
        f"σ0 {v['lugre_stiffness']:.2f} N m/rad, arm servo gains {v['shoulder_kp']:.2f} and "
        f"{v['elbow_kp']:.2f} N m/rad, A_r = {v['sine_amplitude_rad']:.3f} rad",
        f"(Fs/σ0 ≈ {1e3 * fs / v['lugre_stiffness']:.0f} mrad)",
        f"fall ({cal['achieved']['C_alpha_fall_65_90']:.1f}×, the calibration's identification; "
        f"{lug['C_alpha_fall']:.2f}× in the reproduction's) overshoots the paper's "
        f"{comp['paper']['C_alpha_fall']:.1f}×",
        f"coefficients at 65/90 are large ({fd[1.5][1]:.0f}–{fd[2.0][1]:.0f} 1/s)",
        f"the model's α at resonance stays at {max(d['alpha']):.0f}",
        f"meets Table 3 (C_linear within {100 * hs['max_rel_error_C_linear']:.1f} %, β̃_linear within "
        f"{100 * hs['max_rel_error_beta_tilde_linear']:.1f} %) but leaves the C(α) fall at "
        f"{hs['C_alpha_fall_65_90']:.1f}×",
        f"reaches only a fall of {wt['C_alpha_fall_65_90']:.2f}× and loses Table 3 (C_linear "
        f"{100 * wt['max_rel_error_C_linear']:.0f} %, β̃_linear {100 * wt['max_rel_error_beta_tilde_linear']:.0f} % off",
    ]


def model_claims(src: dict) -> list[str]:
    """docs/reference/model.md's quoted figures (the calibrated model's parameters)."""
    v, fc, fs = _lugre_values(src["cal"])
    return [
        f"Fc {1e3 * fc:.1f} mN m, Fs {1e3 * fs:.1f} mN m, vs {v['stribeck_speed']:.2f} rad/s, σ0 "
        f"{v['lugre_stiffness']:.2f} N m/rad",
        f"| yaw viscous damping | {_sci(v['yaw_damping'])} N m s/rad |",
        f"elastic up to Fs/σ0 ≈ {1e3 * fs / v['lugre_stiffness']:.0f} mrad",
    ]


def errata_claims(src: dict) -> list[str]:
    """docs/method/paper-errata.md's quoted figures (the paper's Table 11)."""
    p11 = src["summary"]["step"]["paper_table11"]
    return [
        f"the paper's \"{paper.PAPER_STEP_RATIO}×\" is a ratio of means ({p11['ratio_of_means']:.2f}); its "
        f"ratio of medians is {p11['ratio_of_medians']:.2f}",
    ]


def friction_calibration_claims(src: dict) -> list[str]:
    """docs/method/friction-families.md's quoted figures of the calibrated families (the first
    part of the page's phrases; :func:`friction_study_claims` the rest)."""
    comp = src["comparison"]
    lug, cou = comp["families"]["lugre"], comp["families"]["coulomb"]
    mat = comp["families"]["matched"]
    mst = src["matched_summary"]["step"]
    paper_med = lug["step_linear_vs_table11"]["paper_median_over_poses_rad"]
    v, fc, fs = _lugre_values(src["cal"])
    vc = _values(src["cal_coulomb"])
    hs = src["cal_hard_stick"]["achieved"]
    af = src["cal_coulomb_all_free"]
    afa, afv = af["achieved"], _values(af)
    beta_bar = src["cal"]["fixed"]["beta_bar_N_m_per_V"]
    kp = paper.kp()
    return [
        f"({_mrad(mat['step_linear_vs_table11']['median_over_poses_rad'], 2)} mrad against {_mrad(paper_med)})",
        f"steps linear → α {_mrad(mst['median_abs_error_linear_rad'], 2)} → "
        f"{_mrad(mst['median_abs_error_alpha_rad'], 2)} mrad by the medians (ratio "
        f"{mat['step']['ratio_of_medians_whole_record']:.2f} against the paper's "
        f"{comp['paper']['step']['ratio_of_medians']:.2f}; of means {mat['step']['ratio_of_means_whole_record']:.2f} "
        f"against {comp['paper']['step']['ratio_of_means']:.2f})",
        f"Fc {1e3 * fc:.1f} mN m, Fs {1e3 * fs:.1f} mN m, vs {v['stribeck_speed']:.2f} rad/s, σ0 "
        f"{v['lugre_stiffness']:.2f} N m/rad, σ1 0; viscous {_sci(v['yaw_damping'])} N m s/rad",
        f"joint `frictionloss` {1e3 * vc['yaw_frictionloss']:.2f} mN m; viscous "
        f"{_sci(vc['yaw_damping'], 2)} N m s/rad",
        f"drove the Coulomb level down to {1e3 * vc['yaw_frictionloss']:.2f} mN m",
        f"{af['cost_before']:.1f} → {af['cost_after']:.1f} (lugre's calibration: {src['cal']['cost_after']:.1f}), Table 3 at "
        f"{100 * afa['max_rel_error_C_linear']:.1f} %/{100 * afa['max_rel_error_beta_tilde_linear']:.1f} %, "
        f"angles {afa['max_angle_error_deg']:.2f}°, resonance {afa['resonance_65_90_hz']:.2f} Hz, frictionloss "
        f"{1e3 * afv['yaw_frictionloss']:.1f} mN m, damping {_sci(afv['yaw_damping'])} N m s/rad, A_r = "
        f"{afv['sine_amplitude_rad']:.3f} rad",
        f"a fall of C(α) of only {afa['C_alpha_fall_65_90']:.2f}×",
        f"{100 * hs['max_rel_error_C_linear']:.1f} %/{100 * hs['max_rel_error_beta_tilde_linear']:.1f} %, "
        f"fall {hs['C_alpha_fall_65_90']:.1f}×",
        f"±Fc/(kp β̄) = ±{1e3 * vc['yaw_frictionloss'] / (kp * beta_bar):.1f} mrad",
        f"the family's fall is {cou['C_alpha_fall']:.1f}×",
        f"(ratio of medians {cou['step']['ratio_of_medians_whole_record']:.2f}; p90 "
        f"{_mrad(cou['step']['p90_abs_error_alpha_rad'])} vs {_mrad(cou['step']['p90_abs_error_linear_rad'])} "
        f"mrad, α lower at {cou['step']['alpha_better_poses_p90']}/{cou['step']['n_poses']} poses)",
        ("but loses them by the p90 and in the first second after each edge, at every pose"
         if lug["step"]["alpha_better_poses_p90"] == 0 and lug["step"]["alpha_better_poses_after_edges"] == 0
         else f"α better by the p90 at {lug['step']['alpha_better_poses_p90']}/{lug['step']['n_poses']} "
              f"poses and after the edges at {lug['step']['alpha_better_poses_after_edges']}"),
        f"(ratio of means {lug['step']['ratio_of_means_whole_record']:.2f} against the paper's "
        f"{comp['paper']['step']['ratio_of_means']:.2f}, ratio of medians "
        f"{lug['step']['ratio_of_medians_whole_record']:.2f} against its "
        f"{comp['paper']['step']['ratio_of_medians']:.2f})",
    ]


def friction_study_claims(src: dict) -> list[str]:
    """docs/method/friction-families.md's quoted figures of the friction study's levels
    (``scripts/friction_study.py``)."""
    study = src["study"]["families"]
    sl = {L["scale"]: L for L in study["lugre"]["levels"]}
    sc = {L["scale"]: L for L in study["coulomb"]["levels"]}
    c_ok = [L for L in sc.values() if L["ok"]]
    l_fail = [L for L in sl.values() if not L["ok"]]
    n_nonphys = [int(re.search(r"\((\d+) sine run", L["reason"]).group(1)) for L in l_fail]
    return [
        f"tie (step ratio {sc[0.0]['step_ratio_of_medians_whole_record']:.2f} and "
        f"{sl[0.0]['step_ratio_of_medians_whole_record']:.2f}) and the inertia model is within "
        f"{math.ceil(100 * max(sc[0.0]['inertia_max_rel_error'], sl[0.0]['inertia_max_rel_error'])):.0f} % of MuJoCo",
        f"Coulomb (0 … {1e3 * sc[3.0]['dry_friction']['frictionloss']:.1f} mN m): the α model never "
        f"helps the steps by more than {max(L['step_ratio_of_medians_whole_record'] for L in c_ok):.2f}×",
        f"(magnitude p90 ratio {sc[0.0]['sine_magnitude_p90_linear'] / sc[0.0]['sine_magnitude_p90_alpha']:.1f} → "
        f"{sc[3.0]['sine_magnitude_p90_linear'] / sc[3.0]['sine_magnitude_p90_alpha']:.2f}); the inertia "
        f"bias grows linearly, {_s(100 * sc[0.0]['inertia_worst_signed_rel_error'])} % → "
        f"{_s(100 * sc[3.0]['inertia_worst_signed_rel_error'])} %",
        f"LuGre (0 … {1e3 * sl[1.0]['dry_friction']['lugre_Fc']:.1f} mN m sliding level, the calibrated one)",
        f"({sl[0.0]['step_ratio_of_medians_whole_record']:.2f} → {sl[0.5]['step_ratio_of_medians_whole_record']:.2f} → "
        f"{sl[1.0]['step_ratio_of_medians_whole_record']:.2f} at 0, 0.5, 1×)",
        f"the inertia bias goes {_m(100 * sl[0.5]['inertia_worst_signed_rel_error'])} %, "
        f"{_m(100 * sl[1.0]['inertia_worst_signed_rel_error'])} %",
        f"({min(n_nonphys)} to {max(n_nonphys)} of 81)",
    ]


def performance_claims(src: dict) -> list[str]:
    """docs/reference/performance.md's quoted figures (``omni bench``)."""
    bench = src["bench"]
    srv = bench["discrepancy_servo"]
    stages = srv["physics_steps_per_stage"]
    return [
        f"{bench['reproduce']['ratio_to_raw_rollout']:.1f} ({bench['reproduce']['wall_s']:.2f} s vs "
        f"{bench['reproduce']['raw_rollout_s']:.2f} s, the run in `docs/reference/bench.json`)",
        f"The geared servo with its nominal off: {srv['physics_steps'] / 1e6:.1f} M physics steps, "
        f"{stages['naming'] / 1e6:.1f} M of them naming",
        f"{stages['uncertainty_and_evaluation'] / 1e6:.1f} M the uncertainty, {stages['other_fold_scheme'] / 1e6:.1f} M "
        f"the other fold scheme, {stages['corrections'] / 1e6:.1f} M the corrections; {srv['unstable_replays']} "
        "replays went unstable",
        f"Its time, {srv['wall_s']:.0f} s where",
    ]


def gymnasium_claims(src: dict) -> list[str]:
    """docs/usage/gymnasium.md's quoted figures (``omni bench``'s vector environment)."""
    bench = src["bench"]
    b_vec = bench["vector_env"]
    return [
        f"{b_vec['num_envs']} Omnis at {b_vec['env_steps_per_s'] / 1e3:.0f} k steps/s against "
        f"{b_vec['rollout_ceiling_steps_per_s'] / 1e3:.0f} k steps/s of a raw `mujoco.rollout` of the "
        f"same model on {bench['cores']} threads ({b_vec['ratio_to_raw_rollout']:.2f}×; `omni bench`, "
        f"`docs/reference/bench.json`)",
    ]


#: The functions that render each page's phrases, by page (a key of :data:`PAGES`), in order.
CLAIMS = {"results": (results_claims,), "readme": (readme_claims,),
          "calibration": (calibration_claims,), "model": (model_claims,),
          "errata": (errata_claims,), "friction": (friction_calibration_claims, friction_study_claims),
          "performance": (performance_claims,), "gymnasium": (gymnasium_claims,)}


def claims(src: dict | None = None) -> dict[str, list[str]]:
    """Phrases of the pages that carry a figure from the sources, rendered from them: page
    (a key of :data:`PAGES`) -> its phrases (:data:`CLAIMS`, then :func:`record_claims`)."""
    src = src or load_sources()
    out = {page: [phrase for fn in fns for phrase in fn(src)] for page, fns in CLAIMS.items()}
    for page, found in record_claims(src).items():
        out[page] = out.get(page, []) + found
    return out


# -- the README's record passages: every figure in them checked ------------------------------------
#: The passages of a page whose every figure must be checked against a record (by a phrase of
#: :func:`claims` or by :func:`zwidth_bound`): page -> passages, each the section under a
#: heading (a key that starts with ``#``) or the paragraph that holds the key.
RECORD_PASSAGES = {"readme": ("## Haptic walls", "(examples/real_servo/README.md)")}
#: A figure: a number that is not the tail of a name (``STS3250``, ``OmniWall-v0``) or a count
#: in words.
FIGURE = re.compile(r"(?<![\w.\-−/])[\-−]?\d+(?:\.\d+)?(?:e[\-−]?\d+)?|"
                    r"\b(?:two|three|four|five|six|seven|eight|nine|ten|eleven|twelve)\b", re.I)
_WORDS = {2: "two", 3: "three", 4: "four", 5: "five", 6: "six", 7: "seven", 8: "eight", 9: "nine",
          10: "ten", 11: "eleven", 12: "twelve"}


def _count(n: int) -> str:
    """A count as the prose writes it: in words up to twelve."""
    return _WORDS.get(n, str(n))


def zwidth_row_errors(rec: dict) -> list[float]:
    """|boundary / Colgate's bound - 1| [%] of each damping row of a ``zwidth.json`` that has a
    passive cell and a positive bound, the row B = 0 first."""
    return [100 * abs(k / c - 1) for k, c in zip(rec["boundary_stiffness"], rec["colgate_stiffness"])
            if k is not None and c > 0]


def _digits(x: float, like: str) -> str:
    """``x`` with as many decimals as the figure ``like``."""
    return f"{x:.{len(like.partition('.')[2])}f}"


def zwidth_bound(text: str, rec: dict) -> tuple[list[str], list[tuple[int, int]]]:
    """The sentence of ``text`` that compares the ideal Z-width map with Colgate & Schenkel's
    bound, checked against the map's record (``docs/studies/haptics/zwidth_ideal.json``) whatever its
    wording.  A percentage followed by "up to x b" must be the worst error of the boundary
    against the bound (:func:`zwidth_row_errors`, to the digits printed) over the rows with
    B <= x b, one followed by "at x b" that row's error.  The m others, smallest first, must be
    the worst error over all rows but the last m - 1, ..., all rows but the last, all rows: a
    bound, then its exceptions, which are the rows nearest b.  Any other "x b" must be a row's
    B/b, and a bound "near 0" the last row's, closer to 0 than to the row before's.  Returns
    the problems and the spans of the figures checked (none if no sentence names Colgate)."""
    at = text.find("Colgate")
    if at < 0:
        return [], []
    ends = [m.end() for m in re.finditer(r"[.!?]\s", text[:at])]
    start = ends[-1] if ends else 0
    stop = re.compile(r"[.!?](?:\s|$)").search(text, at)
    sentence = text[start:stop.start() if stop else len(text)]
    errs = zwidth_row_errors(rec)
    rows = [B / rec["physical_damping"] for B, k, c in zip(rec["damping"], rec["boundary_stiffness"],
                                                           rec["colgate_stiffness"]) if k is not None and c > 0]
    problems, spans, free = [], [], []
    for m in re.finditer(r"(\d+(?:\.\d+)?) ?%(?:,? (up to|at) (\d+(?:\.\d+)?) ?b\b)?", sentence):
        if m.group(2) is None:
            free.append(m)
            continue
        x = m.group(3)
        near = [float(_digits(r, x)) for r in rows]  # B/b to the digits printed
        sel = [e for e, r in zip(errs, near) if (r == float(x) if m.group(2) == "at" else r <= float(x))]
        want = _digits(max(sel), m.group(1)) if sel else f"(no row {m.group(2)} {x} b)"
        if m.group(1) != want:
            problems.append(f"Z-width sentence {sentence.strip()!r}: {m.group(1)} % {m.group(2)} {x} b should be "
                            f"{want} % (docs/studies/haptics/zwidth_ideal.json)")
        spans += [(start + m.start(1), start + m.end(1)), (start + m.start(3), start + m.end(3))]
    free.sort(key=lambda m: float(m.group(1)))
    for i, m in enumerate(free):
        n = len(errs) - (len(free) - 1 - i)
        want = _digits(max(errs[:n]), m.group(1)) if n > 0 else "(no such rows)"
        if m.group(1) != want:
            problems.append(f"Z-width sentence {sentence.strip()!r}: {m.group(1)} % should be {want} % "
                            f"(the worst of the first {n} rows of docs/studies/haptics/zwidth_ideal.json)")
        spans.append((start + m.start(1), start + m.end(1)))
    for m in re.finditer(r"(\d+(?:\.\d+)?) ?b\b", sentence):
        if any(a <= start + m.start(1) < b for a, b in spans):
            continue  # an "up to x b" or "at x b" of a percentage, checked above
        if m.group(1) not in {_digits(x, m.group(1)) for x in rows}:
            problems.append(f"Z-width sentence {sentence.strip()!r}: {m.group(1)} b is no row of the map "
                            f"(B/b = {', '.join(f'{x:.2f}' for x in rows)})")
        spans.append((start + m.start(1), start + m.end(1)))
    near = re.search(r"near (0|zero)\b", sentence)
    if near:
        c = [c for k, c in zip(rec["boundary_stiffness"], rec["colgate_stiffness"]) if k is not None and c > 0]
        if not (len(c) > 1 and c[-1] < c[-2] - c[-1]):
            problems.append(f"Z-width sentence {sentence.strip()!r}: the last row's bound is not near 0 "
                            f"(rows' bounds {', '.join(f'{x:.3g}' for x in c[-2:])} N·m/rad)")
        spans.append((start + near.start(1), start + near.end(1)))
    return problems, spans


#: The passages of :data:`RECORD_PASSAGES` that a rule checks besides the phrases:
#: key -> rule(passage text, sources) -> (problems, spans of the figures checked).
PASSAGE_RULES = {"## Haptic walls": lambda text, src: zwidth_bound(text, src["zwidth_ideal"])}


def passage_span(text: str, key: str) -> tuple[int, int] | None:
    """Where in ``text`` the passage that ``key`` names (:data:`RECORD_PASSAGES`) is; None if
    the page has none."""
    if key.startswith("#"):
        i = text.find("\n" + key)
        j = text.find("\n" + key.split()[0] + " ", i + 1)
        return None if i < 0 else (i, j if j >= 0 else len(text))
    starts = [0] + [m.end() for m in re.finditer(r"\n\s*\n", text)]
    ends = [m.start() for m in re.finditer(r"\n\s*\n", text)] + [len(text)]
    return next(((i, j) for i, j in zip(starts, ends) if key in text[i:j]), None)


def _passage(text: str, key: str) -> str | None:
    """The passage of ``text`` that ``key`` names, white space collapsed; None if none."""
    span = passage_span(text, key)
    return None if span is None else _norm(text[span[0]:span[1]])


def mask(text: str) -> str:
    """``text`` with code spans, link targets and comments blanked (the same length)."""
    return re.sub(r"`[^`]*`|\]\([^)]*\)|<!--.*?-->", lambda m: " " * len(m.group()), text)


def unchecked_figures(pages: dict[str, str], src: dict, phrases: dict[str, list[str]]) -> list[str]:
    """Every figure of the :data:`RECORD_PASSAGES` that no phrase of its page and no rule
    checks against a record: one problem per figure (and per passage not found)."""
    problems = []
    for page, keys in RECORD_PASSAGES.items():
        for key in keys:
            text = _passage(pages[page], key)
            if text is None:
                problems.append(f"{PAGES[page]}: no passage {key!r} (scripts/docs_tables.py RECORD_PASSAGES)")
                continue
            bad, spans = PASSAGE_RULES[key](text, src) if key in PASSAGE_RULES else ([], [])
            problems += bad
            for c in map(_norm, phrases.get(page, [])):
                spans += [(m.start(), m.end()) for m in re.finditer(re.escape(c), text)]
            for m in FIGURE.finditer(mask(text)):
                if not any(a <= m.start() and m.end() <= b for a, b in spans):
                    where = text[max(0, m.start() - 40):m.end() + 20]
                    problems.append(f"{PAGES[page]}: figure {m.group()!r} in {where!r} is checked against "
                                    "no record (scripts/docs_tables.py claims)")
    return problems


def record_claims(src: dict) -> dict[str, list[str]]:
    """The phrases of the README's haptics and real-servo passages and of the real-servo
    example's page, rendered from their records (``docs/studies/haptics/zwidth_ideal.json``,
    ``examples/real_servo/report/report.json``, the example's ``model.xml``)."""
    zw, rs = src["zwidth_ideal"], src["real_servo"]
    gap, noise = rs["gap_after"], rs["noise_floor_rad"]
    runs = [r["run"] for r in rs["sampling"]]
    named = [e["name"] for e in rs["effects"] if e["name"] != "none"]
    verdict = (f"names {', '.join(f'`{n}`' for n in named)}" if named else "names nothing") + (
        " and flags the gap unexplained" if rs["unexplained"] else "")
    cands = {c["name"]: c for c in rs["candidates"][0]}
    corr = {c["parameter"]: c for c in rs["corrections"]}
    blocked = rs["gaps"]["blocked"]
    where = {w["where"]: w["ratio"] for w in rs["where"]}
    joint, act = src["real_servo_model"]["joint"], src["real_servo_model"]["actuator"]
    bias = [float(x) for x in act["biasprm"].split()]
    removed = 100 * (1 - blocked["corrected"] / blocked["nominal"])
    best = min((c for n, c in cands.items() if n != "(no new effect)" and c["method"] == "refit"),
               key=lambda c: c["heldout_gap_rad"])
    lf = cands["load_friction"]

    def row(param: str, label: str, digits: int) -> str:
        c = corr[param]
        flag = " (flagged: more than 2x)" if c.get("warning") else ""
        return (f"| {label} | {c['nominal']:.{digits}g} | {c['fitted']:.2g} ± {c['half_width_95']:.2g} | "
                f"{c['ratio_to_nominal']:.2g}{flag} |")

    return {"readme": [
        f"at the {1e-3 / zw['sample_period_s']:g} kHz servo rate",
        f"the nominal's corrections remove {removed:.0f} % of the held-out gap ({_sci(blocked['nominal'], 2)} to "
        f"{_sci(blocked['corrected'], 2)} rad, blocked folds)",
        f"the workflow {verdict} ({gap / noise:.1f} x the noise floor)",
    ], "real_servo": [
        f"| torque per volt (the actuator's gain, `gainprm`) | {float(act['gainprm']):.4f} N·m/V = kt/R |",
        f"| back-EMF (the actuator's velocity bias, `biasprm`) | {-bias[2]:.4f} N·m·s/rad = kt²/R |",
        f"| reflected rotor inertia (`armature`) | {float(joint['armature']):.4f} kg·m² |",
        f"| gearbox viscous friction (in `damping`) | {float(joint['damping']):.4f} N·m·s/rad |",
        f"| dry friction (`frictionloss`) | {float(joint['frictionloss']):.3f} N·m |",
        f"(`gainprm=\"{act['gainprm']}\"`) and its affine velocity bias is the back-EMF "
        f"(`biasprm=\"{act['biasprm']}\"`)",
        f"the joint keeps only the gearbox's {float(joint['damping']):.4f} N·m·s/rad",
        f"on the {_count(len(runs))} converted runs ({sum(r['samples'] for r in rs['sampling'])} logged samples)",
        f"took {rs['timings']['total_s']:.0f} s (`timings.total_s` of `report.json`), "
        f"{rs['timings']['physics_steps'] / 1e6:.1f} M physics steps",
        f"falls from {_sci(blocked['nominal'], 2)} to {_sci(blocked['corrected'], 2)} rad ({removed:.0f} %) under "
        f"blocked folds",
        f"{gap / noise:.1f} x the noise floor ({_sci(noise, 2)} rad) is left",
        row("armature_kgm2", "armature [kg·m²]", 3), row("damping_nms_per_rad", "damping [N·m·s/rad]", 3),
        row("frictionloss_nm", "frictionloss [N·m]", 3), row("gear_nm_per_v", "torque per volt (gear) [-]", 3),
        f"the best, `{best['name']}`, leaves {_sci(best['heldout_gap_rad'], 2)} rad "
        f"({abs(100 * best['share']):.0f} % {'better' if best['share'] > 0 else 'worse'} than the corrected "
        f"nominal's {_sci(blocked['corrected'], 2)})",
        f"ends at `mu_drive` {lf['parameters']['mu_drive']:.2f} and `mu_back` {lf['parameters']['mu_back']:.2f} "
        f"and replays the held-out blocks far worse ({_sci(lf['heldout_gap_rad'], 2)} rad)",
        f"make the held-out gap {rs['gaps']['runs']['corrected'] / blocked['nominal']:.1f}x worse "
        f"({_sci(rs['gaps']['runs']['corrected'], 2)} rad)",
        f"{where['small amplitudes']:.1f} x larger at the smallest amplitude, {where['high speed']:.1f} x at "
        f"high speed and {where['command near its limit']:.1f} x where the command is near its limit",
        f"The gap left is {gap / noise:.1f}x the noise floor",
    ]}


# -- check and write ----------------------------------------------------------------------------
def load_pages() -> dict[str, str]:
    """The text of every page of :data:`PAGES`, by short name."""
    return {name: (ROOT / rel).read_text() for name, rel in PAGES.items()}


def _block(name: str) -> re.Pattern:
    return re.compile(rf"(<!-- docs_tables: {name} -->\n)(.*?)(\n<!-- /docs_tables: {name} -->)", re.S)


def _norm(text: str) -> str:
    return re.sub(r"\s+", " ", text)


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
