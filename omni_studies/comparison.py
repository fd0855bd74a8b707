"""The friction families beside the paper: the comparison's figures (a study: it computes them;
``omni reproduce --friction all`` writes them through :mod:`omni_app.comparison`).

:func:`family_figures` reads one family's in-memory reproduction (``omni_studies.reproduce.
run_reproduce``'s result) and returns its figures; :func:`paper_figures` the paper's values of
the same figures; :func:`compare` both, as ``comparison.json`` holds them.  Nothing here changes
a model: every number is measured on the family's scene as it is.
"""

from __future__ import annotations

import math

import numpy as np

from identification import paper

#: The pose of the paper's detailed figures (Table 9, Figs. 9-14) and of Table 10, set points
#: [deg] (65/90).
DETAIL_POSE = paper.TABLE9_10_SET_POSE

STEP_NOTE = ("The linear model's step errors are a property of the device (how far a linear "
             "model can follow its friction), shown beside the paper's Table 11 for scale; they "
             "are not a calibration target.")


def _worst(values) -> float:
    """The value of largest magnitude, with its sign."""
    values = list(values)
    return float(max(values, key=abs)) if values else math.nan


def pose_of(ident, set_pose):
    for p in ident.poses:
        if (round(p.gamma1_set_deg), round(p.gamma2_set_deg)) == tuple(set_pose):
            return p
    return None


def table3_errors(ident) -> dict:
    """Identified C_linear, beta~_linear and actual angles against Table 3, matched by set point."""
    t3 = paper.by_set_pose(paper.table3())
    rows = []
    for p in ident.poses:
        t = t3.get((round(p.gamma1_set_deg), round(p.gamma2_set_deg)))
        if t is None:
            continue
        rows.append({
            "set_deg": [p.gamma1_set_deg, p.gamma2_set_deg],
            "C_linear": p.C_linear, "C_linear_paper": t["C_linear"],
            "C_linear_rel_error": p.C_linear / t["C_linear"] - 1,
            "beta_tilde_linear": p.beta_tilde_linear, "beta_tilde_linear_paper": t["beta_tilde_linear"],
            "beta_tilde_linear_rel_error": p.beta_tilde_linear / t["beta_tilde_linear"] - 1,
            "gamma1_deg": p.gamma1_deg, "gamma1_paper_deg": t["gamma1_deg"],
            "gamma2_deg": p.gamma2_deg, "gamma2_paper_deg": t["gamma2_deg"],
            "angle_error_deg": _worst([p.gamma1_deg - t["gamma1_deg"], p.gamma2_deg - t["gamma2_deg"]]),
        })
    return {"n_poses": len(rows),
            "C_linear_worst_rel_error": _worst(r["C_linear_rel_error"] for r in rows),
            "beta_tilde_linear_worst_rel_error": _worst(r["beta_tilde_linear_rel_error"] for r in rows),
            "angle_worst_error_deg": _worst(r["angle_error_deg"] for r in rows),
            "poses": rows}


def resonance_hz(beta_linear: float) -> float:
    return math.sqrt(max(beta_linear, 0.0)) / (2 * math.pi)


def step_linear_vs_table11(step_rows) -> dict:
    """The linear model's per-pose step errors (whole record) beside Table 11's linear column."""
    t11 = paper.by_set_pose(paper.table11())
    rows = []
    for r in step_rows:
        key = (round(r["gamma1_set_deg"]), round(r["gamma2_set_deg"]))
        t = t11.get(key, {})
        lin = r["whole_record"]["linear"]
        rows.append({"set_deg": list(key), "median_linear_rad": lin["median_abs_error_rad"],
                     "p90_linear_rad": lin["p90_abs_error_rad"],
                     "paper_median_linear_rad": t.get("median_linear_rad"),
                     "paper_p90_linear_rad": t.get("p90_linear_rad")})
    ours = [r["median_linear_rad"] for r in rows]
    theirs = [r["paper_median_linear_rad"] for r in rows if r["paper_median_linear_rad"] is not None]
    return {"note": STEP_NOTE,
            "median_over_poses_rad": float(np.median(ours)) if ours else None,
            "paper_median_over_poses_rad": float(np.median(theirs)) if theirs else None,
            "poses": rows}


def family_figures(res) -> dict:
    """The comparison figures of one family's reproduction (a
    :class:`omni_studies.reproduce.ReproduceResult`; see the module docstring)."""
    ident = res.ident
    s = res.summary
    detail = pose_of(ident, DETAIL_POSE)
    am = ident.alpha_model
    I = ident.pose_inertia(detail)
    inr = s.inertia
    errs = [r.rel_error for r in inr.poses]
    win = s.step.windows
    return {
        "model": s.run.model,
        "model_sha256": s.run.model_sha256,
        "friction": s.run.friction,
        "table3": table3_errors(ident),
        "resonance_hz_65_90": resonance_hz(detail.beta_linear),
        "C_alpha_fall": am.C_fall(I),
        "alpha_breaks": [float(a) for a in am.alpha_breaks],
        "C_at_breaks_65_90": [float(c) for c in am.C(am.alpha_breaks, I)],
        "inertia_65_90": float(I),
        "inertia": {"max_rel_error": inr.max_rel_error,
                    "worst_signed_rel_error": _worst(errs),
                    "min_rel_error": float(min(errs)), "max_signed_rel_error": float(max(errs)),
                    "n_poses": inr.n_poses},
        "step": {"ratio_of_medians_whole_record": win.whole_record.ratio_of_medians,
                 "ratio_of_medians_after_edges": win.after_edges.ratio_of_medians,
                 "ratio_of_means_whole_record": win.whole_record.ratio_of_means,
                 "ratio_of_means_after_edges": win.after_edges.ratio_of_means,
                 "p90_abs_error_linear_rad": win.whole_record.p90_abs_error_linear_rad,
                 "p90_abs_error_alpha_rad": win.whole_record.p90_abs_error_alpha_rad,
                 "alpha_better_poses": s.step.alpha_better_poses,
                 "alpha_better_poses_p90": win.whole_record.alpha_better_poses_p90,
                 "alpha_better_poses_after_edges": win.after_edges.alpha_better_poses,
                 "n_poses": s.step.n_poses},
        "sine": {k: getattr(s.sine, k) for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg",
                                           "magnitude_p90_linear", "magnitude_p90_alpha")},
        "step_linear_vs_table11": step_linear_vs_table11(res.step_rows),
    }


def paper_figures() -> dict:
    """The paper's values of the same figures."""
    t10 = paper.table10()
    t8 = paper.table8_average()
    return {"resonance_hz_65_90": resonance_hz(paper.table9()["beta_linear"]["fitted"]),
            "C_alpha_fall": t10["C0"] / t10["C3"],
            "step_ratio": paper.PAPER_STEP_RATIO,
            # Table 11 reduced with the statistics of the families' step figures (like for like)
            "step": paper.table11_summary(),
            "sine": {k: t8[k] for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg",
                                        "magnitude_p90_linear", "magnitude_p90_alpha")}}


def compare(results: dict) -> dict:
    """``{"families": {family: figures}, "paper": {...}}`` from ``{family: reproduction}``."""
    return {"families": {fam: family_figures(res) for fam, res in results.items()},
            "paper": paper_figures(),
            "note": "Each family runs its own scene file as it is; how each was calibrated, "
                    "and which calibration and method choices were made after an alpha-model "
                    "score had been seen, is in models/omni/calibration*.json and "
                    "docs/method/friction-families.md. " + STEP_NOTE}
