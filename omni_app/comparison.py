"""``omni reproduce --friction all``: the friction families side by side.

The figures are :mod:`omni_studies.comparison`'s (:func:`~omni_studies.comparison.family_figures`
of one family's in-memory reproduction); :func:`write_comparison` writes
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
from omni_studies.comparison import DETAIL_POSE, STEP_NOTE, compare, pose_of

from .figures import _plt, _run, save_png

#: Files written next to the family folders.
FIGURES = ("comparison_C_alpha.png", "comparison_bode.png", "comparison_step.png")

# -- figures ------------------------------------------------------------------------------------
def _colors(families):
    return {fam: f"C{i}" for i, fam in enumerate(families)}


def fig_C_alpha(folder: Path, results: dict) -> None:
    plt = _plt()
    colors = _colors(results)
    t7, t10 = paper.table7(), paper.table10()
    alphas = np.array([r["alpha"] for r in t7])
    fig, ax = plt.subplots(figsize=(7, 4.5))
    top = max(alphas.max(), *(res.ident.alpha_model.alpha_breaks[-1] for res in results.values()))
    grid = np.concatenate([[0.0], np.logspace(-2, math.log10(top * 2), 300)])
    for fam, res in results.items():
        ident = res.ident
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
    return next(r for r in res.sine_rows
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
        pred = res.predictions[name]
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
