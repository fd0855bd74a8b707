"""``report.md`` and figures for ``omni identify`` (matplotlib, Agg backend, files only).

Figures written:

* ``inertia_fit.png``: C_linear and β̃_linear of each pose against its fitted inertia (6), with
  the model curves (8) ``C = 1/(C̄0 I)`` and (7) ``β̃ = 1/I`` (as the paper's Figs 4–5);
  only when the inertia model was fitted.
* ``local_linear.png``: local C_data (19) and β_data (20) against frequency [Hz] and against
  the α-invariant (36) [V²/s²], one line per pose; excluded frequencies as open markers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import save_png


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _inertia_figure(ident, path: Path) -> None:
    plt = _plt()
    fit = ident.inertia
    p = fit.params
    poses = [q for q in ident.poses if q.physical]
    inert = np.array([p.inertia(q.gamma1_deg, q.gamma2_deg) for q in poses])
    grid = np.linspace(inert.min() * 0.9, inert.max() * 1.1, 200)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].plot(inert, [q.C_linear for q in poses], "o", label="C_linear (22)")
    ax[0].plot(grid, 1 / (p.C0_bar * grid), "-", label=f"1/(C0_bar I), C0_bar={p.C0_bar:.3f}")
    ax[0].set_xlabel("modelled inertia I (6) [beta_bar = 1 units]")
    ax[0].set_ylabel("C_linear [1/s]")
    ax[1].plot(inert, [q.beta_tilde_linear for q in poses], "o", label="beta_tilde_linear (22)")
    ax[1].plot(grid, 1 / grid, "-", label="1/I (7)")
    ax[1].set_xlabel("modelled inertia I (6) [beta_bar = 1 units]")
    ax[1].set_ylabel("beta_tilde_linear [rad/(V s^2)]")
    for a in ax:
        a.legend()
        a.grid(True, alpha=0.3)
    save_png(fig, path, dpi=100)


def _local_figure(ident, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(2, 2, figsize=(10, 7))
    for q in ident.poses:
        f = np.array([x.frequency_hz for x in q.frequencies])
        c = np.array([x.C_data for x in q.frequencies])
        b = np.array([x.beta_data for x in q.frequencies])
        a = np.array([x.alpha for x in q.frequencies])
        used = np.array([x.used for x in q.frequencies])
        line = None
        for col, xv in ((0, f), (1, a)):
            o = np.argsort(xv)
            xv, c, b, used = xv[o], c[o], b[o], used[o]
            line, = ax[0, col].plot(xv[used], c[used], "o-", label=q.label if col == 0 else None,
                                    color=None if line is None else line.get_color())
            ax[0, col].plot(xv[~used], c[~used], "o", mfc="none", color=line.get_color())
            ax[1, col].plot(xv[used], b[used], "o-", color=line.get_color())
            ax[1, col].plot(xv[~used], b[~used], "o", mfc="none", color=line.get_color())
    ax[0, 0].set_ylabel("C_data (19) [1/s]")
    ax[1, 0].set_ylabel("beta_data (20) [1/s^2]")
    ax[1, 0].set_xlabel("frequency [Hz]")
    ax[1, 1].set_xlabel("alpha (36) [V^2/s^2]")
    for a in ax[:, 1]:
        a.set_xscale("log")
    for a in ax.ravel():
        a.grid(True, alpha=0.3)
    ax[0, 0].legend(fontsize=7)
    save_png(fig, path, dpi=100)


#: The legend of every report that shows the paper's equation numbers.
EQUATIONS_LEGEND = ("Numbers in parentheses, such as (6) or (22), are the equation numbers of the paper this "
                    "project implements, \"The α-invariant: an energy-based nonlinear minimal damping model "
                    "for robotic joints with friction\" (Phantom Omni yaw axis); its tables and figures are "
                    "named as there.")


def format_report(ident, source: str = "") -> str:
    """The ``report.md`` text."""
    out = ["# Identification report", "", EQUATIONS_LEGEND, ""]
    if source:
        out += [f"Dataset: `{source}`", ""]
    out += ["## Global linear model per pose (22)", "",
            "| pose | gamma1 [deg] | gamma2 [deg] | kp [V/rad] | freqs (used) | C_linear [1/s] "
            "| beta_linear [1/s^2] | beta_tilde_linear |",
            "|---|---|---|---|---|---|---|---|"]
    for q in ident.poses:
        n_used = sum(x.used for x in q.frequencies)
        out.append(f"| {q.label} | {q.gamma1_deg:.2f} | {q.gamma2_deg:.2f} | {q.kp:g} | "
                   f"{len(q.frequencies)} ({n_used}) | {q.C_linear:.4g} | {q.beta_linear:.4g} | "
                   f"{q.beta_tilde_linear:.4g} |")
    out += ["", "## Local linear model (19)-(20) and the alpha-invariant (36)", "",
            "| pose | f [Hz] | A1 [rad] | A2 [rad] | C_data [1/s] | beta_data [1/s^2] | alpha [V^2/s^2] "
            "| used | fit explained | 3rd harm. |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for q in ident.poses:
        for x in q.frequencies:
            out.append(f"| {q.label} | {x.frequency_hz:g} | {x.A1:.5g} | {x.A2:.5g} | {x.C_data:.4g} | "
                       f"{x.beta_data:.4g} | {x.alpha:.4g} | {'yes' if x.used else 'no'} | "
                       f"{x.explained_fraction:.4f} | {x.harmonic3_ratio:.3g} |")
    out += ["", "## Inertia and damping model (6)-(8)", ""]
    if ident.inertia is None:
        out.append("Not fitted (see warnings): per-pose results above are complete.")
    else:
        fit = ident.inertia
        out += [f"Fitted to {fit.n_poses} poses by the non-linear regression (27)-(29) with relative residuals "
                f"({fit.dof} degrees of freedom). Intervals are linearised 95% intervals.", "",
                "| parameter | value | 95% interval | note |", "|---|---|---|---|"]
        for k in ("I_base", "I1", "I2", "I3", "gamma_offs_deg", "C0_bar"):
            lo, hi = fit.ci95[k]
            note = "poorly determined" if k in fit.poorly_determined else ""
            if k in fit.at_bound:
                note += " (at bound 0)"
            out.append(f"| {k} | {getattr(fit.params, k):.5g} | [{lo:.4g}, {hi:.4g}] | {note} |")
        out += ["", f"- C0_bar by simple regression (through origin): {fit.C0_bar_regression:.4f}",
                f"- rms relative residual: beta_tilde {fit.rms_rel_beta:.4f}, C {fit.rms_rel_C:.4f}",
                f"- scaled Jacobian condition number: {fit.condition_number:.3g}"]
    out += ["", "## Warnings", ""]
    out += [f"- {w}" for w in ident.warnings] or ["- none"]
    if ident.ignored_runs:
        out += ["", f"Ignored (not sine) runs: {', '.join(ident.ignored_runs)}"]
    return "\n".join(out) + "\n"


def write_identify_report(ident, folder, source: str = "", figures: bool = True) -> None:
    """Write ``report.md`` and (unless ``figures`` is False) the PNG figures into ``folder``."""
    folder = Path(folder)
    (folder / "report.md").write_text(format_report(ident, source))
    if figures:
        write_identify_figures(ident, folder)


def write_identify_figures(ident, folder, which=("local", "inertia")) -> None:
    """The PNG figures of :func:`write_identify_report`: ``local_linear.png`` (the per-pose
    stage's: ``"local"``) and, if the inertia model was fitted, ``inertia_fit.png``
    (``"inertia"``)."""
    folder = Path(folder)
    if "local" in which:
        _local_figure(ident, folder / "local_linear.png")
    if "inertia" in which and ident.inertia is not None:
        _inertia_figure(ident, folder / "inertia_fit.png")
