#!/usr/bin/env python
"""Friction-strength study: how the alpha model's advantage and the inertia bias move with the
yaw's dry friction, per friction family.

For each family (``coulomb``, ``lugre``: the built-in scenes) and each scale factor, the yaw's
dry-friction levels (``frictionloss`` and the LuGre Fc, Fs; :func:`omni_sim.model.
scale_yaw_friction`, viscous damping unchanged) are set to factor x the calibrated ones and the
whole reproduction runs in memory (:func:`omni_studies.reproduce.run_reproduce`: generate the
campaign -> identify -> validate both models -> inertia (6) against MuJoCo).  Recorded per level:
the step ratio of medians linear/alpha (whole record and first second after each edge), the
sine phase and magnitude p90 of both models, the inertia (6) max |error| and its signed worst
bias.  A level whose identification or simulation fails is recorded with the reason
(``"ok": false``), never dropped.

Writes ``OUT/friction_study.json`` and ``OUT/friction_study.png`` (alpha-model advantage on
steps and sines, and the inertia bias, against the friction scale; one line per family).

    python scripts/friction_study.py --out docs/studies/friction
    python scripts/friction_study.py --out /tmp/study --levels 0,1,3 --families lugre
"""

from __future__ import annotations

import argparse
import copy
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from identification.dataset import atomic_write_text
from identification.errors import UserError

DEFAULT_LEVELS = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
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


def _worst(values) -> float:
    return float(max(values, key=abs))


def level_figures(res: dict) -> dict:
    """The study's figures of one in-memory reproduction."""
    s = res["scores"]["summary"]
    win = s["step"]["windows"]
    errs = [r["rel_error"] for r in s["inertia"]["poses"]]
    return {
        "step_ratio_of_medians_whole_record": win["whole_record"]["ratio_of_medians"],
        "step_ratio_of_medians_after_edges": win["after_edges"]["ratio_of_medians"],
        "step_alpha_better_poses": s["step"]["alpha_better_poses"],
        "step_n_poses": s["step"]["n_poses"],
        **{f"sine_{k}": s["sine"][k] for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg",
                                               "magnitude_p90_linear", "magnitude_p90_alpha")},
        "inertia_max_rel_error": s["inertia"]["max_rel_error"],
        "inertia_worst_signed_rel_error": _worst(errs),
        "alpha_breaks": [float(a) for a in res["ident"].alpha_model.alpha_breaks],
        "alpha_steps_not_converged": s["alpha_simulation"]["steps_not_converged"],
    }


def _short_reason(message: str) -> str:
    """A failed identification lists every warning; keep what failed and count the
    non-physical sine runs (the rest is in any reproduction's params.json)."""
    parts = message.split("; ")
    failed = [p for p in parts if "not fitted" in p]
    if not failed:
        return message
    n_bad = sum("non-physical local coefficients" in p for p in parts)
    return (f"{'; '.join(failed)} ({n_bad} sine run(s) with non-physical local coefficients, "
            "excluded from the alpha model)")


def run_level(base, factor: float, campaign: str, jobs: int | None) -> dict:
    """One level: the family's device ``base`` with its dry friction scaled by ``factor``."""
    from omni_sim.device import Device
    from omni_studies.reproduce import run_reproduce

    dev = Device(copy.deepcopy(base.model))
    dev.scale_friction(factor, base)
    row = {"scale": factor, "dry_friction": dev.friction()}
    t0 = time.perf_counter()
    try:
        res = run_reproduce(dev, jobs, campaign)
        row.update(ok=True, **level_figures(res))
    except (UserError, RuntimeError, ValueError, np.linalg.LinAlgError) as exc:
        row.update(ok=False, reason=_short_reason(f"{type(exc).__name__}: {exc}"))
    row["wall_s"] = time.perf_counter() - t0
    return row


def study(families, levels, campaign: str = "paper", jobs: int | None = None,
          progress: bool = True) -> dict:
    """Every family x level (see the module docstring); returns the JSON dict."""
    from tqdm import tqdm

    from omni_sim.device import Device

    bases = {fam: Device.load(friction=fam) for fam in families}
    out = {"description": __doc__.split("\n\n")[0],
           "campaign": str(campaign), "levels": list(levels),
           "scaled": "yaw dry friction: frictionloss and LuGre Fc, Fs (viscous damping unchanged)",
           "families": {}}
    with tqdm(total=len(families) * len(levels), unit="level", disable=not progress,
              file=sys.stderr) as bar:
        for fam in families:
            rows = []
            for f in levels:
                bar.set_description(f"{fam} x{f:g}")
                rows.append(run_level(bases[fam], f, campaign, jobs))
                bar.update(1)
            out["families"][fam] = {"calibrated_dry_friction": bases[fam].friction(),
                                    "levels": rows}
    return out


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


def build_parser() -> argparse.ArgumentParser:
    from omni_sim.model import FRICTION_FAMILIES

    class Parser(argparse.ArgumentParser):  # one line "error: ..." and status 2, as omni's
        def error(self, message: str) -> None:
            sys.stderr.write(f"error: {self.prog}: {message}\n")
            raise SystemExit(2)

    p = Parser(prog="friction_study.py", description=__doc__.split("\n\n")[0],
                                epilog="Each level is one in-memory `omni reproduce` (~10 s on 2 cores).")
    p.add_argument("--out", required=True, help="output folder (friction_study.json, friction_study.png)")
    p.add_argument("--levels", default=",".join(f"{x:g}" for x in DEFAULT_LEVELS),
                   help="comma-separated dry-friction factors >= 0 (default: %(default)s)")
    p.add_argument("--families", default=",".join(FRICTION_FAMILIES),
                   help="comma-separated friction families (default: %(default)s)")
    p.add_argument("--campaign", default="paper",
                   help="campaign name or file (default: paper; see docs/usage/campaigns.md)")
    p.add_argument("--jobs", type=int, default=None, help="threads (default: all cores)")
    p.add_argument("--force", action="store_true", help="replace existing friction_study.* files")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        from omni_sim import experiments as ex
        from omni_sim import model as om

        levels = parse_levels(args.levels)
        families = [f.strip() for f in args.families.split(",") if f.strip()]
        for fam in families:
            om.scene_path(fam)  # UserError for an unknown family
        if not families or len(set(families)) != len(families):
            raise UserError(f"--families: distinct families needed, got {args.families!r}")
        if args.jobs is not None and args.jobs < 1:
            raise UserError(f"--jobs must be >= 1, got {args.jobs}")
        ex.campaign(args.campaign)  # a bad campaign fails before any simulation
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise UserError(f"{out}: not a folder")
        existing = [f for f in FILES if (out / f).exists()]
        if existing and not args.force:
            raise UserError(f"{out}: {', '.join(existing)} exist(s) (use --force to replace)")
        result = study(families, levels, args.campaign, args.jobs)
        out.mkdir(parents=True, exist_ok=True)
        # figure first into a temporary file, then both renamed/written whole
        fd, tmp = tempfile.mkstemp(suffix=".png", dir=out)
        os.close(fd)
        try:
            write_figure(Path(tmp), result)
            import json

            from omni_app.comparison import json_safe

            atomic_write_text(out / FILES[0], json.dumps(json_safe(result), indent=2) + "\n")
            os.replace(tmp, out / FILES[1])
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except UserError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    for fam, d in result["families"].items():
        for r in d["levels"]:
            if r["ok"]:
                print(f"{fam} x{r['scale']:g}: steps {r['step_ratio_of_medians_whole_record']:.2f} "
                      f"(after edges {r['step_ratio_of_medians_after_edges']:.2f}); sine phase p90 "
                      f"{r['sine_phase_p90_linear_deg']:.1f} -> {r['sine_phase_p90_alpha_deg']:.1f} deg, "
                      f"magnitude {r['sine_magnitude_p90_linear']:.3f} -> {r['sine_magnitude_p90_alpha']:.3f}; "
                      f"inertia worst {100 * r['inertia_worst_signed_rel_error']:+.1f} %")
            else:
                print(f"{fam} x{r['scale']:g}: failed: {r['reason']}")
    print(f"wrote {out / FILES[0]} and {out / FILES[1]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
