"""The calibration's figures: the paper's numbers overlaid on the calibrated virtual Omni's
(:func:`omni_studies.calibration.calibrate` computes the record)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from identification import paper as paper_tables
from omni_studies.calibration import TABLE10_ALPHA, TABLE10_C, alphas_text


def plot_record(record: dict, folder: Path, prefix: str = "calibration") -> list[Path]:
    """Figures overlaying the paper's numbers on the calibrated virtual Omni's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    poses = record["poses"]
    labels = [f"{int(p['set'][0])}/{int(p['set'][1])}" for p in poses]
    x = np.arange(len(poses))
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for ax, key, paper, name in ((axes[0], "C_linear", "C_paper", "C_linear [1/s]"),
                                 (axes[1], "beta_tilde_linear", "beta_tilde_paper", "beta~_linear [rad/(V s^2)]")):
        ax.bar(x - 0.2, [p[paper] for p in poses], 0.4, label="paper Table 3 (real Omni)")
        ax.bar(x + 0.2, [p[key] for p in poses], 0.4, label="virtual Omni, same method")
        ax.set_xticks(x, labels, rotation=45)
        ax.set(ylabel=name, xlabel="set pose gamma1/gamma2 [deg]")
        ax.legend(fontsize=8)
    for k, (key, paper) in enumerate((("gamma1_deg", "gamma1_paper"), ("gamma2_deg", "gamma2_paper"))):
        axes[2].plot(x, [p[key] - p[paper] for p in poses], "o-", label=f"gamma{k + 1}: virtual - paper")
    axes[2].axhspan(-1.5, 1.5, color="g", alpha=0.15, label="+-1.5 deg target")
    axes[2].set_xticks(x, labels, rotation=45)
    axes[2].set(ylabel="actual angle difference [deg]", xlabel="set pose")
    axes[2].legend(fontsize=8)
    fig.tight_layout()
    p1 = folder / f"{prefix}_table3.png"
    fig.savefig(p1, dpi=100)
    plt.close(fig)

    d = next(p for p in poses if tuple(p["set"]) == paper_tables.TABLE9_10_SET_POSE)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    axes[0].semilogx(d["alpha"], d["C_data"], "o-", label="virtual Omni C_data (19)")
    for f, a, c in zip(d["frequency_hz"], d["alpha"], d["C_data"]):
        axes[0].annotate(f"{f:g} Hz", (a, c), fontsize=7)
    axes[0].semilogx(TABLE10_ALPHA, TABLE10_C, "ks", label=f"paper Table 10 (alpha {alphas_text(TABLE10_ALPHA)})")
    axes[0].set(xlabel="alpha [V^2/s^2]", ylabel="C [1/s]", title="damping vs alpha at 65/90")
    axes[1].plot(d["frequency_hz"], d["alpha"], "o-")
    axes[1].set(xlabel="frequency [Hz]", ylabel="alpha [V^2/s^2]", yscale="log",
                title="alpha vs frequency at 65/90\n(paper Fig. 8: rises to resonance, then falls)")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    p2 = folder / f"{prefix}_alpha.png"
    fig.savefig(p2, dpi=100)
    plt.close(fig)
    return [p1, p2]
