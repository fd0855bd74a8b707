"""``omni sweep``: the command and the figures of the sweep engine (:mod:`omni_studies.sweep`:
the study file, the pipelines, the Dask run and the resumable output folder).
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

from identification.errors import UserError
from omni_studies.sweep import (EXAMPLE, FIGURES, Study, VariantResult, cell_text, load_study,
                                parse_study, read_table, run_sweep)


# -- figures ---------------------------------------------------------------------------------
def plot(out: str | os.PathLike) -> list[Path]:
    """Each numeric figure of ``out/results.csv`` against each varied parameter:
    ``out/sweep_<param>.png`` (one panel per figure; other parameters' combinations as lines)."""
    out = Path(out)
    if not (out / "results.csv").is_file() or not (out / "spec.toml").is_file():
        raise UserError(f"{out}: no study results (results.csv, spec.toml); run omni sweep first")
    study = parse_study((out / "spec.toml").read_text(), str(out / "spec.toml"), out)
    variants = read_table((out / "results.csv").read_text(), study)
    return [plot_param(study, variants, p, out) for p in study.params]


def _num(x) -> float | None:
    """``x`` as a number (None: not one, e.g. a failed variant's figure or a list of effects)."""
    try:
        return float(x)
    except (TypeError, ValueError):
        return None


def _figure(v: VariantResult, k: str):
    """The figure ``k`` of a variant (None: it failed)."""
    return None if v.figures is None else getattr(v.figures, k)


def plot_param(study: Study, variants, p: str, out: Path) -> Path:
    """The numeric figures of ``variants`` (:class:`VariantResult`) against the parameter ``p``:
    ``out/sweep_<p>.png``, one panel per figure, the other parameters' combinations as lines,
    failed variants as red crosses."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = [k for k in FIGURES[study.pipeline["name"]]
            if any(_num(_figure(v, k)) is not None for v in variants)]
    others = [q for q in study.params if q != p]
    n = len(figs)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow), squeeze=False)
    groups: dict = {}
    for v in variants:  # keyed by the other parameters' values as results.csv writes them
        groups.setdefault(tuple(cell_text(v.params[q]) for q in others), []).append(v)
    for ax, k in zip(axes.flat, figs):
        for key, grp in groups.items():
            ok = sorted((v.params[p], _num(_figure(v, k))) for v in grp
                        if v.status == "ok" and _num(_figure(v, k)) is not None)
            label = ", ".join(f"{q}={x}" for q, x in zip(others, key)) or None
            if ok:
                ax.plot([a for a, _ in ok], [b for _, b in ok], "o-", label=label)
            bad = [v.params[p] for v in grp if v.status != "ok"]
            if bad:
                ax.plot(bad, [0.0] * len(bad), "x", color="red",
                        label="failed" if key == next(iter(groups)) else None, transform=ax.get_xaxis_transform())
        ax.set_xlabel(p)
        ax.set_title(k, fontsize=9)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if labels:
        fig.legend(handles, labels, loc="lower center", ncol=min(4, len(labels)), fontsize=8)
    fig.suptitle(f"{study.source}: {study.pipeline['name']} vs {p}", fontsize=10)
    fig.tight_layout(rect=(0, 0.08 if labels else 0, 1, 0.96))
    safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in p)
    path = out / f"sweep_{safe}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# -- benchmark and command -------------------------------------------------------------------
def sweep_command(args) -> int:
    """``omni sweep SPEC.toml --out DIR [--workers N] [--scheduler ADDRESS]``, ``--example``,
    ``--plot DIR``."""
    if args.example:
        sys.stdout.write(EXAMPLE)
        return 0
    if args.plot:
        for p in plot(args.plot):
            print(p)
        return 0
    if args.spec is None:
        raise UserError("sweep: give a study file SPEC.toml (or --example, --plot DIR)")
    if args.out is None:
        raise UserError("sweep: --out DIR is required")
    if args.workers is not None and args.scheduler:
        raise UserError("sweep: --workers sizes the local cluster; not with --scheduler")
    study = load_study(args.spec)
    res = run_sweep(study, args.out, workers=args.workers, scheduler=args.scheduler)
    print(f"{res.n} variants ({res.skipped} already done, {res.ran} run, {res.failed} failed) "
          f"in {res.wall_s:.1f} s: {Path(args.out) / 'results.csv'}")
    return 0
