"""The friction-strength study's record and figure: ``friction_study.json`` and
``friction_study.png`` (alpha-model advantage on steps and sines, and the inertia bias, against
the friction scale; one line per family), the ``--levels`` text, and the lines printed per
level.  The study is :mod:`omni_studies.friction_study`; ``scripts/friction_study.py`` is the
command."""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

from identification.dataset import atomic_write_text
from identification.errors import UserError
from omni_app.comparison import json_safe

FILES = ("friction_study.json", "friction_study.png")


def parse_levels(text: str) -> list[float]:
    """``"0,0.5,1"`` -> [0.0, 0.5, 1.0]: finite factors >= 0, distinct, at least one."""
    try:
        levels = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UserError(f"--levels: comma-separated numbers expected, got {text!r}") from None
    if not levels:
        raise UserError("--levels: at least one level needed")
    bad = [x for x in levels if not (math.isfinite(x) and x >= 0)]
    if bad:
        raise UserError(f"--levels: factors must be finite and >= 0, got {bad[0]:g}")
    if len(set(levels)) != len(levels):
        raise UserError(f"--levels: repeated factor in {text!r}")
    return sorted(levels)



def write_figure(path: Path, result: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.3))
    for i, (fam, d) in enumerate(result["families"].items()):
        c = f"C{i}"
        ok = [r for r in d["levels"] if r["ok"]]
        bad = [r["scale"] for r in d["levels"] if not r["ok"]]
        x = [r["scale"] for r in ok]
        axes[0].plot(x, [r["step_ratio_of_medians_whole_record"] for r in ok], "o-", color=c,
                     label=f"{fam}: whole record")
        axes[0].plot(x, [r["step_ratio_of_medians_after_edges"] for r in ok], "s--", color=c,
                     label=f"{fam}: first second after edges")
        axes[1].plot(x, [r["sine_phase_p90_linear_deg"] / r["sine_phase_p90_alpha_deg"] for r in ok],
                     "o-", color=c, label=f"{fam}: phase p90")
        axes[1].plot(x, [r["sine_magnitude_p90_linear"] / r["sine_magnitude_p90_alpha"] for r in ok],
                     "s--", color=c, label=f"{fam}: magnitude p90")
        axes[2].plot(x, [100 * r["inertia_worst_signed_rel_error"] for r in ok], "o-", color=c,
                     label=f"{fam}")
        if bad:  # failed levels: a cross on the bottom edge (no value), the reason in the JSON
            for ax in axes:
                ax.plot(bad, [0.03 + 0.04 * i] * len(bad), "x", color=c, ms=9,
                        transform=ax.get_xaxis_transform(), clip_on=False,
                        label=f"{fam}: failed, no alpha model (JSON)")
    for ax in axes[:2]:
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_yscale("log")
    axes[0].set(xlabel="dry friction / calibrated", ylabel="median error linear / alpha",
                title="steps: alpha-model advantage (> 1: alpha better)")
    axes[1].set(xlabel="dry friction / calibrated", ylabel="p90 error linear / alpha",
                title="sines: alpha-model advantage (> 1: alpha better)")
    axes[2].axhline(0.0, color="k", lw=0.8)
    axes[2].axhspan(-2, 2, color="g", alpha=0.15, label="+-2 % target")
    axes[2].set(xlabel="dry friction / calibrated", ylabel="worst signed error [%]",
                title="inertia (6) x beta_bar vs MuJoCo (25 poses)")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)



def write_outputs(out: Path, result: dict) -> None:
    """``out/friction_study.json`` and ``out/friction_study.png``: the figure first into a
    temporary file, then both renamed/written whole."""
    out.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=out)
    os.close(fd)
    try:
        write_figure(Path(tmp), result)
        atomic_write_text(out / FILES[0], json.dumps(json_safe(result), indent=2) + "\n")
        os.replace(tmp, out / FILES[1])
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def level_lines(result: dict) -> list[str]:
    """One line per family x level: the alpha model's advantage and the inertia bias, or why the
    level failed."""
    out = []
    for fam, d in result["families"].items():
        for r in d["levels"]:
            if r["ok"]:
                out.append(f"{fam} x{r['scale']:g}: steps {r['step_ratio_of_medians_whole_record']:.2f} "
                           f"(after edges {r['step_ratio_of_medians_after_edges']:.2f}); sine phase p90 "
                           f"{r['sine_phase_p90_linear_deg']:.1f} -> {r['sine_phase_p90_alpha_deg']:.1f} deg, "
                           f"magnitude {r['sine_magnitude_p90_linear']:.3f} -> {r['sine_magnitude_p90_alpha']:.3f}; "
                           f"inertia worst {100 * r['inertia_worst_signed_rel_error']:+.1f} %")
            else:
                out.append(f"{fam} x{r['scale']:g}: failed: {r['reason']}")
    return out
