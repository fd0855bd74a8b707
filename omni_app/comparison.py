"""``omni reproduce --friction all``: the friction families side by side.

:func:`family_figures` reads one family's in-memory reproduction (:func:`omni_app.reproduce.
run_reproduce`) and returns the comparison figures; :func:`write_comparison` writes
``comparison.json`` (``{"families": {family: figures}, "paper": {...}}``), ``comparison.md``
and three overlay figures:

* ``comparison_C_alpha.png``: C(alpha) of each family's identified alpha model at the 65/90 pose
  against the paper's Table 10 points and its Table 7 model (at Table 10's inertia);
* ``comparison_bode.png``: magnitude and phase of the fundamental against frequency at 65/90,
  each family's data with both models;
* ``comparison_step.png``: the step response at 65/90 (first second), each family's data with
  both models.

Nothing here changes a model: every number is measured on the family's scene as it is.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from identification import paper
from identification.nonlinear import paper_alpha_model

from .figures import DETAIL_POSE, _plt, _run, save_png

#: Files written next to the family folders.
FIGURES = ("comparison_C_alpha.png", "comparison_bode.png", "comparison_step.png")

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


def family_figures(res: dict) -> dict:
    """The comparison figures of one family's reproduction (see the module docstring)."""
    ident = res["ident"]
    s = res["scores"]["summary"]
    detail = pose_of(ident, DETAIL_POSE)
    am = ident.alpha_model
    I = ident.pose_inertia(detail)
    inr = s["inertia"]
    errs = [r["rel_error"] for r in inr["poses"]]
    win = s["step"]["windows"]
    return {
        "model": s["run"]["model"],
        "model_sha256": s["run"]["model_sha256"],
        "friction": s["run"].get("friction"),
        "table3": table3_errors(ident),
        "resonance_hz_65_90": resonance_hz(detail.beta_linear),
        "C_alpha_fall": am.C_fall(I),
        "alpha_breaks": [float(a) for a in am.alpha_breaks],
        "C_at_breaks_65_90": [float(c) for c in am.C(am.alpha_breaks, I)],
        "inertia_65_90": float(I),
        "inertia": {"max_rel_error": inr["max_rel_error"],
                    "worst_signed_rel_error": _worst(errs),
                    "min_rel_error": float(min(errs)), "max_signed_rel_error": float(max(errs)),
                    "n_poses": inr["n_poses"]},
        "step": {"ratio_of_medians_whole_record": win["whole_record"]["ratio_of_medians"],
                 "ratio_of_medians_after_edges": win["after_edges"]["ratio_of_medians"],
                 "ratio_of_means_whole_record": win["whole_record"]["ratio_of_means"],
                 "ratio_of_means_after_edges": win["after_edges"]["ratio_of_means"],
                 "p90_abs_error_linear_rad": win["whole_record"]["p90_abs_error_linear_rad"],
                 "p90_abs_error_alpha_rad": win["whole_record"]["p90_abs_error_alpha_rad"],
                 "alpha_better_poses": s["step"]["alpha_better_poses"],
                 "alpha_better_poses_p90": win["whole_record"]["alpha_better_poses_p90"],
                 "alpha_better_poses_after_edges": win["after_edges"]["alpha_better_poses"],
                 "n_poses": s["step"]["n_poses"]},
        "sine": {k: s["sine"][k] for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg",
                                           "magnitude_p90_linear", "magnitude_p90_alpha")},
        "step_linear_vs_table11": step_linear_vs_table11(res["scores"]["step"]),
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
                    "score had been seen, is in models/calibration*.json and "
                    "docs/friction-families.md. " + STEP_NOTE}


# -- figures ------------------------------------------------------------------------------------
def _colors(families):
    return {fam: f"C{i}" for i, fam in enumerate(families)}


def fig_C_alpha(folder: Path, results: dict) -> None:
    plt = _plt()
    colors = _colors(results)
    t7, t10 = paper.table7(), paper.table10()
    alphas = np.array([r["alpha"] for r in t7])
    fig, ax = plt.subplots(figsize=(7, 4.5))
    top = max(alphas.max(), *(res["ident"].alpha_model.alpha_breaks[-1] for res in results.values()))
    grid = np.concatenate([[0.0], np.logspace(-2, math.log10(top * 2), 300)])
    for fam, res in results.items():
        ident = res["ident"]
        p = pose_of(ident, DETAIL_POSE)
        am = ident.alpha_model
        I = ident.pose_inertia(p)
        ax.plot(grid, am.C(grid, I), "-", color=colors[fam], label=f"{fam}: identified alpha model")
        ax.plot(am.alpha_breaks, am.C(am.alpha_breaks, I), "o", mfc="none", color=colors[fam])
        used = [q for q in p.frequencies if q.used]
        ax.plot([q.alpha for q in used], [q.C_data for q in used], ".", color=colors[fam], alpha=0.6,
                label=f"{fam}: C_data (19)")
    ax.plot(grid, paper_alpha_model().C(grid, t10["I"]), "k--", lw=1,
            label="paper Table 7 model at Table 10's I")
    ax.plot(alphas, [t10[f"C{k}"] for k in range(4)], "ks", label="paper Table 10")
    ax.set_xscale("symlog", linthresh=0.1)
    ax.set(xlabel="alpha [V^2/s^2]", ylabel="C [1/s]",
           title=f"C(alpha) at ({DETAIL_POSE[0]}, {DETAIL_POSE[1]}) deg: friction families vs paper")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    save_png(fig, folder / "comparison_C_alpha.png")


def _sine_row(res):
    return next(r for r in res["scores"]["sine"]
                if (round(r["gamma1_set_deg"]), round(r["gamma2_set_deg"])) == DETAIL_POSE)


def fig_bode(folder: Path, results: dict) -> None:
    plt = _plt()
    colors = _colors(results)
    fig, axes = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    for fam, res in results.items():
        row = _sine_row(res)
        f = row["frequencies_hz"]
        for key, style, label in (("data", "o", "data"), ("linear", "--", "linear model"),
                                  ("alpha", "-", "alpha model")):
            kw = dict(color=colors[fam], label=f"{fam}: {label}")
            if key == "data":
                kw.update(mfc="none")
            axes[0].plot(f, row[key]["magnitude"], style, **kw)
            axes[1].plot(f, row[key]["phase_deg"], style, **kw)
    axes[0].set(ylabel="|theta|/A_r [-]",
                title=f"Fundamental at ({DETAIL_POSE[0]}, {DETAIL_POSE[1]}) deg: friction families")
    axes[1].set(xlabel="frequency [Hz]", ylabel="phase [deg]")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    save_png(fig, folder / "comparison_bode.png")


def fig_step(folder: Path, results: dict) -> None:
    plt = _plt()
    colors = _colors(results)
    name = f"step_g{DETAIL_POSE[0]:02d}_{DETAIL_POSE[1]:03d}"
    fig, axes = plt.subplots(1, len(results), figsize=(5.5 * len(results), 4), sharey=True,
                             squeeze=False)
    for ax, (fam, res) in zip(axes[0], results.items()):
        run = _run(res, name)
        pred = res["predictions"][name]
        k = run.t < 1.0
        ax.plot(run.t[k], run.r[k], ":", color="gray", label="reference r")
        ax.plot(run.t[k], run.theta[k], "-", color="k", lw=2, label=f"{fam} (data)")
        ax.plot(run.t[k], pred["theta_linear"][k], "--", color=colors[fam], label="linear model")
        ax.plot(run.t[k], pred["theta_alpha"][k], "-", color=colors[fam], alpha=0.7,
                label="alpha model")
        ax.set(xlabel="t [s]", title=f"{fam}: step at ({DETAIL_POSE[0]}, {DETAIL_POSE[1]}) deg")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0][0].set_ylabel("yaw [rad]")
    save_png(fig, folder / "comparison_step.png")


# -- markdown -----------------------------------------------------------------------------------
def format_markdown(comp: dict) -> str:
    fams = list(comp["families"])
    F = comp["families"]
    P = comp["paper"]
    PS = P["step"]

    def row(label, paper_value, fmt):
        return (f"| {label} | {paper_value} | "
                + " | ".join(fmt(F[f]) for f in fams) + " |")

    pct = lambda x: f"{100 * x:+.1f} %"  # noqa: E731
    lines = ["# Friction families compared (`omni reproduce --friction all`)", "",
             comp["note"], "",
             f"| figure | paper | {' | '.join(fams)} |", "|---|---|" + "---|" * len(fams),
             row("Table 3: worst C_linear error", "-", lambda d: pct(d["table3"]["C_linear_worst_rel_error"])),
             row("Table 3: worst beta~_linear error", "-",
                 lambda d: pct(d["table3"]["beta_tilde_linear_worst_rel_error"])),
             row("Table 3: worst actual-angle error [deg]", "-",
                 lambda d: f"{d['table3']['angle_worst_error_deg']:+.2f}"),
             row("resonance at 65/90 [Hz]", f"{P['resonance_hz_65_90']:.2f}",
                 lambda d: f"{d['resonance_hz_65_90']:.2f}"),
             row("C(alpha) fall, first/last breakpoint", f"{P['C_alpha_fall']:.2f}x",
                 lambda d: f"{d['C_alpha_fall']:.2f}x"),
             row("alpha breakpoints [V^2/s^2]", ", ".join(f"{r['alpha']:g}" for r in paper.table7()),
                 lambda d: ", ".join(f"{a:.3g}" for a in d["alpha_breaks"])),
             row("inertia (6) vs MuJoCo: max abs error (worst signed)", "-",
                 lambda d: f"{100 * d['inertia']['max_rel_error']:.1f} % ({pct(d['inertia']['worst_signed_rel_error'])})"),
             row("step ratio of medians linear/alpha, whole record", f"{PS['ratio_of_medians']:.2f}",
                 lambda d: f"{d['step']['ratio_of_medians_whole_record']:.2f}"),
             row("step ratio of means linear/alpha, whole record",
                 f"{PS['ratio_of_means']:.2f} (printed \"{P['step_ratio']}\")",
                 lambda d: f"{d['step']['ratio_of_means_whole_record']:.2f}"),
             row("step ratio of medians, first second after each edge", "-",
                 lambda d: f"{d['step']['ratio_of_medians_after_edges']:.2f}"),
             row("step p90 error linear / alpha, median over poses [mrad]",
                 f"{1e3 * PS['p90_abs_error_linear_rad']:.1f} / {1e3 * PS['p90_abs_error_alpha_rad']:.1f}",
                 lambda d: f"{1e3 * d['step']['p90_abs_error_linear_rad']:.1f} / "
                           f"{1e3 * d['step']['p90_abs_error_alpha_rad']:.1f}"),
             row("alpha better on steps (poses): by the median, by the p90, after edges",
                 f"{PS['alpha_better_poses']}/{PS['n_poses']}, {PS['alpha_better_poses_p90']}/{PS['n_poses']}, -",
                 lambda d: f"{d['step']['alpha_better_poses']}/{d['step']['n_poses']}, "
                           f"{d['step']['alpha_better_poses_p90']}/{d['step']['n_poses']}, "
                           f"{d['step']['alpha_better_poses_after_edges']}/{d['step']['n_poses']}"),
             row("sine phase p90 linear -> alpha [deg]",
                 f"{P['sine']['phase_p90_linear_deg']:.1f} -> {P['sine']['phase_p90_alpha_deg']:.1f}",
                 lambda d: f"{d['sine']['phase_p90_linear_deg']:.1f} -> {d['sine']['phase_p90_alpha_deg']:.1f}"),
             row("sine magnitude p90 linear -> alpha",
                 f"{P['sine']['magnitude_p90_linear']:.3f} -> {P['sine']['magnitude_p90_alpha']:.3f}",
                 lambda d: f"{d['sine']['magnitude_p90_linear']:.3f} -> {d['sine']['magnitude_p90_alpha']:.3f}"),
             row("linear model's step error, median over poses [mrad]",
                 f"{1e3 * F[fams[0]]['step_linear_vs_table11']['paper_median_over_poses_rad']:.1f}",
                 lambda d: f"{1e3 * d['step_linear_vs_table11']['median_over_poses_rad']:.2f}"),
             "", "Models: " + "; ".join(f"{f}: `{F[f]['model']}`" for f in fams)
             + f" (files' sha256 {', '.join(sorted({F[f]['model_sha256'] for f in fams}))}).", "",
             "## The linear model's step errors per pose (Table 11's linear column)", "",
             STEP_NOTE, "",
             "| set pose [deg] | paper median / p90 [mrad] | "
             + " | ".join(f"{f} median / p90" for f in fams) + " |",
             "|---|---|" + "---|" * len(fams)]
    per = {f: {tuple(r["set_deg"]): r for r in F[f]["step_linear_vs_table11"]["poses"]} for f in fams}
    for key in per[fams[0]]:
        r0 = per[fams[0]][key]
        pm = r0["paper_median_linear_rad"]
        ptxt = "-" if pm is None else f"{1e3 * pm:.1f} / {1e3 * r0['paper_p90_linear_rad']:.1f}"
        cells = []
        for f in fams:
            r = per[f].get(key)
            cells.append("-" if r is None else
                         f"{1e3 * r['median_linear_rad']:.2f} / {1e3 * r['p90_linear_rad']:.2f}")
        lines.append(f"| ({key[0]}, {key[1]}) | {ptxt} | " + " | ".join(cells) + " |")
    lines += ["", "## Figures", ""] + [f"![{n}]({n})" for n in FIGURES] + [""]
    return "\n".join(lines)


def json_safe(x):
    """JSON-safe: non-finite floats (an infinite C(alpha) fall) become null."""
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def write_comparison(folder: Path, results: dict) -> dict:
    """Write comparison.json, comparison.md and the overlay figures into ``folder``."""
    folder = Path(folder)
    comp = compare(results)
    (folder / "comparison.json").write_text(json.dumps(json_safe(comp), indent=2) + "\n")
    (folder / "comparison.md").write_text(format_markdown(comp))
    for fn in (fig_C_alpha, fig_bode, fig_step):
        fn(folder, results)
    return comp
