"""Figures of ``omni reproduce``, numbered as the paper's (Figs. 4-14), written as PNG files.

The paper's figures did not survive its text extraction; ours show the same quantities for the
virtual Omni, with the paper's printed numbers overlaid where the paper gives them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from identification import paper as _paper
from omni_studies.comparison import DETAIL_POSE
from omni_studies.reproduce import ReproduceResult


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: Margins [in] of a figure laid out by matplotlib's ``tight_layout`` (measured on the built-in
#: reproduction's figures: left 0.54-1.02 with the y tick labels, right 0.15, bottom 0.59-0.61,
#: top 0.36 under a title); :func:`save_png` keeps the axes of this size.
TYPICAL_MARGINS_IN = {"left": 0.75, "right": 0.15, "bottom": 0.6, "top": 0.36}
#: The room [in] :func:`save_png` leaves around the axes before it crops: about twice the typical
#: margins (y tick labels of ~10 characters, a two-line title).
ROOM_IN = {"left": 1.4, "right": 0.4, "bottom": 0.9, "top": 0.65}
#: White border [in] kept around the ink of a cropped figure (tight_layout's pad is 0.15 in).
PAD_IN = 0.1


def save_png(fig, path: Path, dpi: int = 110, wspace_in: float = 0.95, hspace_in: float = 0.5) -> None:
    """Write ``fig`` as a PNG, laid out and drawn once, and close it.

    ``tight_layout`` measures every text of a figure to place its axes, then ``savefig`` lays
    them all out again to draw them (about a third of the figures' CPU time in
    ``omni reproduce``).  Here the axes keep the size they have with the typical margins
    (:data:`TYPICAL_MARGINS_IN`) and get :data:`ROOM_IN` around them, ``wspace_in`` /
    ``hspace_in`` inches between them; the figure is drawn once and the image cropped to
    what was drawn plus :data:`PAD_IN`.  If anything reaches the image's edge (a label longer
    than the room), or the axes are not a grid of subplots, the figure is laid out by
    ``tight_layout`` and saved uncropped instead: nothing is ever clipped.
    """
    import matplotlib.image as mimage
    import matplotlib.pyplot as plt

    try:
        w, h = fig.get_size_inches()
        spec = fig.axes[0].get_subplotspec() if fig.axes else None
        if spec is not None:
            nrows, ncols = spec.get_gridspec().get_geometry()
            T, R = TYPICAL_MARGINS_IN, ROOM_IN
            cw = w - T["left"] - T["right"] + R["left"] + R["right"]
            ch = h - T["bottom"] - T["top"] + R["bottom"] + R["top"]
            aw = (cw - R["left"] - R["right"] - (ncols - 1) * wspace_in) / ncols
            ah = (ch - R["bottom"] - R["top"] - (nrows - 1) * hspace_in) / nrows
            spec = None if min(aw, ah) <= 0.5 else spec
        for ax in fig.axes:
            # a title at the axes' top edge (no top tick labels here): matplotlib otherwise
            # places each title by measuring the x axis's ticks (~10 % of a figure's CPU)
            if ax.get_title() and ax.title.get_position()[1] == 1.0:
                ax.set_title(ax.get_title(), y=1.0)
        if spec is not None:
            fig.set_size_inches(cw, ch)
            fig.set_dpi(dpi)
            fig.subplots_adjust(left=R["left"] / cw, right=1 - R["right"] / cw,
                                bottom=R["bottom"] / ch, top=1 - R["top"] / ch,
                                wspace=wspace_in / aw, hspace=hspace_in / ah)
            fig.canvas.draw()
            buf = np.asarray(fig.canvas.buffer_rgba())
            ink = (buf != buf[0, 0]).any(axis=2)
            if not (ink[0].any() or ink[-1].any() or ink[:, 0].any() or ink[:, -1].any()):
                rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
                pad = int(round(PAD_IN * dpi))
                r0, r1 = max(rows[0] - pad, 0), min(rows[-1] + pad + 1, buf.shape[0])
                c0, c1 = max(cols[0] - pad, 0), min(cols[-1] + pad + 1, buf.shape[1])
                mimage.imsave(path, buf[r0:r1, c0:c1], format="png", dpi=dpi)
                return
            fig.set_size_inches(w, h)  # something reached the edge: matplotlib's layout
        fig.tight_layout()
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)


def _detail_pose(ident):
    for p in ident.poses:
        if (p.gamma1_set_deg, p.gamma2_set_deg) == DETAIL_POSE:
            return p
    return ident.poses[-1]


def fig_inertia(folder: Path, res: ReproduceResult) -> None:
    """Figs. 4-5: C_linear and beta_tilde_linear against the fitted inertia, with the paper's."""
    plt = _plt()
    ident = res.ident
    params = ident.inertia.params
    paper = _paper.table3()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    I = np.array([ident.pose_inertia(p) for p in ident.poses])
    grid = np.linspace(I.min() * 0.85, I.max() * 1.15, 100)
    axes[0].plot(I, [p.C_linear for p in ident.poses], "o", label="virtual Omni, identified")
    axes[0].plot(grid, 1 / (params.C0_bar * grid), "-", label=f"(8) C = 1/(C0 I), C0 = {params.C0_bar:.1f}")
    axes[1].plot(I, [p.beta_tilde_linear for p in ident.poses], "o", label="virtual Omni, identified")
    axes[1].plot(grid, 1 / grid, "-", label="(7) beta~ = 1/I")
    Ip = np.array([1 / r["beta_tilde_linear"] for r in paper])
    axes[0].plot(Ip, [r["C_linear"] for r in paper], "x", label="paper Table 3 (I = 1/beta~)")
    axes[1].plot(Ip, [r["beta_tilde_linear"] for r in paper], "x", label="paper Table 3")
    axes[0].set(xlabel="inertia I [V s^2/rad]", ylabel="C_linear [1/s]", title="Fig. 4: C against inertia")
    axes[1].set(xlabel="inertia I [V s^2/rad]", ylabel="beta~_linear [rad/(V s^2)]",
                title="Fig. 5: beta~_linear against inertia")
    for ax in axes:
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    save_png(fig, folder / "fig04_05_inertia_fits.png")


def fig_inertia_truth(folder: Path, res: ReproduceResult) -> None:
    """Identified inertia model x beta_bar against MuJoCo's mass matrix at the 25 poses."""
    plt = _plt()
    rows = res.summary.inertia.poses
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for fitted, marker, label in ((True, "o", "Table 1 pose (used in the fit)"),
                                  (False, "s", "Table 2 only (never fitted)")):
        sel = [r for r in rows if r.fitted_pose == fitted]
        ax.plot([1e3 * r.true_kg_m2 for r in sel], [1e3 * r.identified_kg_m2 for r in sel],
                marker, label=label)
    lo = min(min(r.true_kg_m2, r.identified_kg_m2) for r in rows) * 1e3 * 0.95
    hi = max(max(r.true_kg_m2, r.identified_kg_m2) for r in rows) * 1e3 * 1.05
    ax.plot([lo, hi], [lo, hi], "k-", lw=0.8, label="identity")
    ax.fill_between([lo, hi], [lo * 0.98, hi * 0.98], [lo * 1.02, hi * 1.02], color="g", alpha=0.15,
                    label="+-2 % target")
    ax.set(xlabel="MuJoCo yaw inertia [1e-3 kg m^2]", ylabel="identified (6) x beta_bar [1e-3 kg m^2]",
           title="Inertia model vs ground truth (25 Table 2 poses)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    save_png(fig, folder / "inertia_truth.png")


def fig_nonlinear_vs_inertia(folder: Path, res: ReproduceResult) -> None:
    """Figs. 6-7: C_k(I) and beta_k(I) of (40), (42) with the per-pose intermediate values."""
    plt = _plt()
    am = res.ident.alpha_model
    diag = am.diagnostics.get("poses", [])
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    I = np.array([d["I"] for d in diag])
    grid = np.linspace(I.min() * 0.85, I.max() * 1.15, 100)
    for k in range(4):
        line, = axes[0].plot(grid, am.C(np.full_like(grid, am.alpha_breaks[k]), grid), "-",
                             label=f"C_{k}(I), alpha_{k} = {am.alpha_breaks[k]:.3g}")
        if diag and "C_k" in diag[0]:
            axes[0].plot(I, [d["C_k"][k] for d in diag], "o", color=line.get_color())
    for k in range(2):
        line, = axes[1].plot(grid, am.beta_tilde(np.full_like(grid, am.alpha_bar[k]), grid), "-",
                             label=f"beta~_{k}(I), alpha = {am.alpha_bar[k]:.3g}")
        if diag and "beta_k" in diag[0]:
            axes[1].plot(I, [d["beta_k"][k] for d in diag], "o", color=line.get_color())
    lin = res.ident.inertia.params
    axes[0].plot(grid, 1 / (lin.C0_bar * grid), "k--", label="global linear (24)")
    axes[1].plot(grid, 1 / grid, "k--", label="global linear (25)")
    axes[0].set(xlabel="I [V s^2/rad]", ylabel="C [1/s]", title="Fig. 6: non-linear C model vs inertia")
    axes[1].set(xlabel="I [V s^2/rad]", ylabel="beta~ [rad/(V s^2)]",
                title="Fig. 7: non-linear beta~ model vs inertia")
    for ax in axes:
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    save_png(fig, folder / "fig06_07_nonlinear_vs_inertia.png")


def fig_alpha_vs_frequency(folder: Path, res: ReproduceResult) -> None:
    """Fig. 8: alpha (36) against frequency, every pose."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for p in res.ident.poses:
        ax.semilogy([q.frequency_hz for q in p.frequencies], [q.alpha for q in p.frequencies], "o-",
                    ms=3, label=f"({p.gamma1_set_deg:g}, {p.gamma2_set_deg:g})")
    ax.set(xlabel="frequency [Hz]", ylabel="alpha [V^2/s^2]", title="Fig. 8: alpha-invariant vs frequency")
    ax.legend(fontsize=7, ncol=3, title="set pose [deg]")
    ax.grid(alpha=0.3, which="both")
    save_png(fig, folder / "fig08_alpha_vs_frequency.png")


def fig_C_beta_vs_alpha(folder: Path, res: ReproduceResult) -> None:
    """Figs. 9-10: C_data and beta~_data against alpha at the detail pose, with both models."""
    plt = _plt()
    ident = res.ident
    am = ident.alpha_model
    p = _detail_pose(ident)
    I = ident.pose_inertia(p)
    a = np.array([q.alpha for q in p.frequencies])
    used = np.array([q.used for q in p.frequencies])
    grid = np.logspace(math.log10(max(a.min() * 0.5, 1e-3)), math.log10(a.max() * 2), 200)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, vals, model, lin, name in (
            (axes[0], [q.C_data for q in p.frequencies], am.C(grid, I), p.C_linear, "C [1/s]"),
            (axes[1], [q.beta_tilde_data for q in p.frequencies], am.beta_tilde(grid, I),
             p.beta_tilde_linear, "beta~ [rad/(V s^2)]")):
        vals = np.array(vals)
        ax.semilogx(a[used], vals[used], "o", label="data (19)-(20)")
        if (~used).any():
            ax.semilogx(a[~used], vals[~used], "o", mfc="none", label="excluded (non-physical)")
        for q in p.frequencies:
            ax.annotate(f"{q.frequency_hz:g}", (q.alpha, vals[p.frequencies.index(q)]), fontsize=6)
        ax.semilogx(grid, model, "-", label="alpha-invariant model")
        ax.axhline(lin, color="k", ls="--", label="global linear")
        ax.set(xlabel="alpha [V^2/s^2]", ylabel=name)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    axes[0].set_title(f"Fig. 9: C vs alpha at ({p.gamma1_set_deg:g}, {p.gamma2_set_deg:g}) deg")
    axes[1].set_title("Fig. 10: beta~ vs alpha (labels: f [Hz])")
    save_png(fig, folder / "fig09_10_C_beta_vs_alpha.png")


def _sine_row(res, pose):
    for row in res.sine_rows:
        if (row["gamma1_set_deg"], row["gamma2_set_deg"]) == pose:
            return row
    return res.sine_rows[-1]


def fig_bode(folder: Path, res: ReproduceResult) -> None:
    """Figs. 11-12: fundamental magnitude and phase at the detail pose."""
    plt = _plt()
    row = _sine_row(res, DETAIL_POSE)
    f = row["frequencies_hz"]
    fig, axes = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    for key, style, label in (("data", "ko", "virtual Omni (data)"), ("linear", "s--", "global linear"),
                              ("alpha", "^-", "alpha-invariant")):
        axes[0].plot(f, row[key]["magnitude"], style, label=label)
        axes[1].plot(f, row[key]["phase_deg"], style, label=label)
    axes[0].set(ylabel="|theta|/A_r [-]", title=f"Figs. 11-12 at ({DETAIL_POSE[0]}, {DETAIL_POSE[1]}) deg")
    axes[1].set(xlabel="frequency [Hz]", ylabel="phase [deg]")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    save_png(fig, folder / "fig11_12_bode.png", hspace_in=0.25)


#: The runs the time figures show (Figs. 13, 14): the only runs, and predictions, the figures
#: read (``omni reproduce`` sends its figure worker these, not the whole campaign).
TIME_FIGURE_RUNS = (f"sine_g{DETAIL_POSE[0]:02d}_{DETAIL_POSE[1]:03d}_f2p50",
                    f"step_g{DETAIL_POSE[0]:02d}_{DETAIL_POSE[1]:03d}")


def _run(res, name):
    return next(r for r in res.runs if r.name == name)


def _time_figure(folder: Path, res: ReproduceResult, name: str, keep, title: str, filename: str) -> None:
    """Measured and both models' yaw angle of one run over the samples ``keep(run)``."""
    plt = _plt()
    run = _run(res, name)
    pred = res.predictions[name]
    k = keep(run)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(run.t[k], run.r[k], ":", color="gray", label="reference r")
    ax.plot(run.t[k], run.theta[k], "k-", lw=2, label="virtual Omni")
    ax.plot(run.t[k], pred["theta_linear"][k], "--", label="global linear")
    ax.plot(run.t[k], pred["theta_alpha"][k], "-", label="alpha-invariant")
    ax.set(xlabel="t [s]", ylabel="yaw [rad]", title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save_png(fig, folder / filename)


def fig_time_sine(folder: Path, res: ReproduceResult) -> None:
    """Fig. 13: time response at 2.5 Hz at the detail pose (last two cycles)."""
    _time_figure(folder, res, TIME_FIGURE_RUNS[0],
                 lambda run: run.t >= run.t[-1] - 2 / 2.5,
                 f"Fig. 13: 2.5 Hz response at {DETAIL_POSE} deg", "fig13_time_2p5hz.png")


def fig_step(folder: Path, res: ReproduceResult) -> None:
    """Fig. 14: first second after the negative-to-positive edge at the detail pose."""
    _time_figure(folder, res, TIME_FIGURE_RUNS[1],
                 lambda run: run.t < 1.0, f"Fig. 14: step response at {DETAIL_POSE} deg",
                 "fig14_step.png")


#: Every figure of the reproduce report, in drawing order.
FIGURES = (fig_inertia, fig_inertia_truth, fig_nonlinear_vs_inertia, fig_alpha_vs_frequency,
           fig_C_beta_vs_alpha, fig_bode, fig_time_sine, fig_step)


def write_figures(folder: Path, res: ReproduceResult) -> list[str]:
    """Write every figure into ``folder``; returns the file names."""
    for fn in FIGURES:
        fn(folder, res)
    return sorted(p.name for p in folder.glob("*.png"))
