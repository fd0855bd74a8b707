"""``omni zwidth``: the command, its record (``zwidth.json``) and its figure.  The study -- which
walls (K, B) the virtual Omni's yaw renders passively, and how that is decided -- is
:mod:`omni_studies.zwidth`.  Also the records of ``scripts/zwidth_study.py`` (what moves the
boundary, :mod:`omni_studies.zwidth_study`) and ``scripts/zwidth_damping.py`` (the identified
damping's boundary, :mod:`omni_studies.zwidth_damping`)."""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from identification.errors import UserError
from omni_studies.zwidth import (DURATION_S, MEMORY_BUDGET_BYTES, PROBE_PERIODS, SETTLE_FRACTION,
                                  START_PENETRATION, TOL, MapRecord, MapSettings, beyond_boundary,
                                  colgate_limit, map_device, map_memory_bytes, map_record,
                                  passivity_map, probe_amplitude_counts, require_damping)
from omni_studies import zwidth_damping, zwidth_study


# --- the command --------------------------------------------------------------------------------
def _parse_range(text: str, what: str, max_count: int) -> list[float]:
    """``START:STOP:N`` (N evenly spaced values) or a comma-separated list; sorted, duplicates
    dropped; at most ``max_count`` values (checked before any array is made)."""
    try:
        if ":" in text:
            a, b, m = text.split(":")
            m = int(m)
            if m < 1:
                raise ValueError
            a, b = float(a), float(b)
        else:
            vals = [float(x) for x in text.split(",") if x.strip()]
            m = len(vals)
    except ValueError:
        raise UserError(f"--{what}: expected START:STOP:N or a comma-separated list of numbers, "
                        f"got {text!r}") from None
    if m > max_count:
        raise UserError(f"--{what}: {m} values; a map holds at most {max_count} along one axis "
                        f"(the {MEMORY_BUDGET_BYTES / 1e9:g} GB memory budget)")
    if ":" in text:
        vals = np.linspace(a, b, m).tolist()
    if not vals or not all(math.isfinite(v) for v in vals):
        raise UserError(f"--{what}: values must be finite numbers, got {text!r}")
    return sorted(set(vals))


def _check_out(out: str, force: bool) -> None:
    """Refuse an output folder :func:`atomic_output_dir` would refuse, before the work."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise UserError(f"{out}: output folder exists and is not empty (use --force to replace it)")
    if not out.resolve().parent.is_dir():
        raise UserError(f"{out}: parent folder {out.resolve().parent} does not exist")


def zwidth_command(args) -> int:
    if args.ideal and (args.model or args.friction):
        raise UserError("--ideal uses the built-in scene: not with --model or --friction")
    if args.model and args.friction:
        raise UserError("--model and --friction are exclusive")
    _check_out(args.out, args.force)
    dev, tlim = map_device(args.model, args.friction, ideal=args.ideal, substeps=args.substeps)
    b = require_damping(dev)
    T = dev.control_period_s
    # one axis may hold all the budget's cells (the other one value); checked before the values
    # are made
    n = int(round(DURATION_S / T))
    max_axis = int(MEMORY_BUDGET_BYTES // map_memory_bytes(dev, 1, len(PROBE_PERIODS), n))
    K = (_parse_range(args.stiffness, "stiffness", max_axis) if args.stiffness
         else np.linspace(0.0, 3.0 * b / T, 20).tolist())
    B = (_parse_range(args.damping, "damping", max_axis) if args.damping
         else np.linspace(0.0, 1.25 * b, 20).tolist())
    if len(K) < 2:
        raise UserError("--stiffness: give at least two different values")
    quantize = not args.ideal and not args.no_quantize
    t0 = time.perf_counter()
    res = passivity_map(dev, K, B, torque_limit=tlim, quantize=quantize, delay=args.delay,
                        probe_speed=args.probe_speed, nthread=args.jobs,
                        progress=sys.stderr.isatty())
    elapsed = time.perf_counter() - t0
    rec = _map_record(args, dev, K, B, res, quantize, tlim, elapsed)
    from identification.dataset import atomic_output_dir

    with atomic_output_dir(args.out, force=args.force) as tmp:
        (tmp / "zwidth.json").write_text(json.dumps(rec.to_json(), indent=1) + "\n")
        plot_map(rec, tmp / "zwidth.png")
    print(f"zwidth: {len(B)} x {len(K)} walls in {elapsed:.1f} s; b = {b:.4g} N*m*s/rad, "
          f"T = {T:g} s; wrote {Path(args.out) / 'zwidth.json'}, zwidth.png")
    for note in rec.notes:
        print(f"note: {note}")
    return 0


def _map_record(args, dev, K, B, res, quantize, tlim, elapsed) -> MapRecord:
    """The map's record (``zwidth.json``): the settings from the command's arguments."""
    from omni_sim.device import ENCODER_STEP_RAD
    from omni_sim.model import model_path

    family = "ideal" if args.ideal else dev.friction_family(
        None if args.model else model_path(None, args.friction))
    settings = MapSettings(
        model=str(args.model) if args.model else None, friction=family, ideal=bool(args.ideal),
        quantize=quantize, delay_periods=args.delay, physics_substeps=args.substeps,
        probe_speed=args.probe_speed, probe_periods=tuple(PROBE_PERIODS),
        start_penetration_rad=START_PENETRATION, duration_s=DURATION_S,
        settle_fraction=SETTLE_FRACTION, tolerance=TOL, torque_limit=tlim,
        encoder_step_rad=ENCODER_STEP_RAD, elapsed_s=round(elapsed, 2))
    return map_record(dev, K, B, res, settings)


def plot_map(rec: MapRecord, path: Path) -> None:
    """The map's figure: passive and active cells, the cells beyond the boundary (not a result),
    Colgate & Schenkel's line, the measured boundary, and the map's notes in short."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    K, B = np.array(rec.stiffness), np.array(rec.damping)
    P = np.array(rec.passive, dtype=bool)
    X = beyond_boundary(P)
    b, T = rec.physical_damping, rec.sample_period_s
    short = _figure_note(rec)
    fig, ax = plt.subplots(figsize=(6, 4.9 if short else 4.5))
    KK, BB = np.meshgrid(K, B)
    ax.scatter(KK[P & ~X], BB[P & ~X], s=18, c="tab:green", marker="o", label="passive")
    ax.scatter(KK[~P], BB[~P], s=18, c="tab:red", marker="x", label="not passive")
    if X.any():
        ax.scatter(KK[X], BB[X], s=40, facecolors="none", edgecolors="tab:orange", marker="o",
                   linewidths=1.5, label="passive beyond the boundary: not a result")
    bb = np.linspace(min(B.min(), 0), B.max(), 200)
    ax.plot(colgate_limit(b, bb, T), bb, "k-", label="Colgate & Schenkel: b = K T/2 + |B|")
    kb = np.array([np.nan if x is None else x for x in rec.boundary_stiffness], dtype=float)
    ax.plot(kb, B, "b--", drawstyle="default", label="measured boundary (largest passive K)")
    ax.set_xlabel("wall stiffness K [N m/rad]")
    ax.set_ylabel("wall damping B [N m s/rad]")
    s = rec.settings
    ax.set_title(f"Z-width, {s.friction}, T = {T * 1e3:g} ms, b = {b:.3g}, "
                 f"q={'on' if s.quantize else 'off'}, delay {s.delay_periods}", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    if short:
        fig.text(0.01, 0.01, short, fontsize=7, color="tab:orange", va="bottom", wrap=True)
        fig.tight_layout(rect=(0, 0.06, 1, 1))
    else:
        fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _figure_note(rec: MapRecord) -> str:
    """The figure's footnote: the notes that change how the map reads, in short (from the map's
    cells and settings, so that a record written before the notes plots the same way)."""
    s = rec.settings
    counts = max(probe_amplitude_counts(s.probe_speed, s.probe_periods, rec.sample_period_s).values())
    n_beyond = int(beyond_boundary(rec.passive).sum())
    parts = []
    if s.quantize and counts < 1:
        parts.append(f"every probe below one encoder count (at most {counts:.2f} counts): the "
                     f"boundary is the quantised loop's")
    if n_beyond:
        parts.append(f"{n_beyond} passive cell(s) beyond the boundary (orange) are not a result")
    if s.delay_periods:
        parts.append("loop delay: the map is optimistic")
    return "; ".join(parts)


# --- the study of what moves the boundary (scripts/zwidth_study.py) ---------------------------
def table_cell(v: dict) -> str:
    """A table entry: the boundary, "> 40" (passive to the grid's end), "none" (no cell of the
    row passive) or "none at K = 0" (K = 0 active, yet a cell further along the row passive)."""
    if v["none_passive"]:
        return "none"
    if v["whole_row_passive"]:
        return f"> {zwidth_study.STIFFNESS[-1]:g}"
    if v["boundary"] is None:
        return "none at K = 0"
    return f"{v['boundary']:.2f}"


def case_line(name: str, r: dict) -> str:
    """A case's line: its wall time, K_max at the table's damping rows, the non-monotone rows
    and cells."""
    tb = " / ".join(table_cell(v) for v in r["table"].values())
    return (f"{name:24s} {r['elapsed_s']:6.1f} s  K_max(B=0/0.004/0.008) = {tb}  "
            f"non-monotone rows {r['non_monotone_rows']}, cells {r['non_monotone_cells']}")


def write_study(doc: dict, out: Path) -> None:
    """The study's record at ``out`` (through a temporary file beside it)."""
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    tmp.replace(out)


# --- the identified damping's boundary (scripts/zwidth_damping.py) -----------------------------
def family_line(fam: str, info: dict) -> str:
    """A family's line: the actual pose, the yaw inertia, C_linear and the dampings."""
    return (f"{fam}: actual pose {info['gamma_actual_deg'][0]:.2f}/"
            f"{info['gamma_actual_deg'][1]:.2f} deg, I_yaw {info['I_yaw']:.5g}, C_linear "
            f"{info['C_linear']:.4g} 1/s -> b_id {info['b_linear']:.4g} "
            f"(nominal {info['b_nominal']:.4g})")


def damping_case_line(case: str, c: dict) -> str:
    """A case's line: the alpha at B = 0, its probe, the median |error| of every prediction."""
    rows, me = c["rows"], c["median_abs_error"]
    return (f"{case:24s} alpha(B=0) {rows[0]['alpha']:.4g} (probe m={rows[0]['binding_probe']})"
            f"  median |err| " + ", ".join(f"{k} {'-' if v is None else f'{v:.0%}'}"
                                           for k, v in me.items()))


def write_damping(doc: dict, damping: np.ndarray, out: Path) -> Path:
    """The record at ``out`` and its figure beside it (same stem, .png); the figure's path."""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1) + "\n")
    plot_damping(doc, damping, out.with_suffix(".png"))
    return out.with_suffix(".png")


def plot_damping(doc: dict, damping: np.ndarray, path: Path) -> None:
    """The measured boundary of every case beside the predicted 2(b_x - |B|)/T, one panel per
    case."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(zwidth_damping.CASES)
    fig, axes = plt.subplots(2, 4, figsize=(13, 6.4), sharey=True)
    style = {"nominal": ("k-", "nominal b"), "linear": ("b--", "b_id = C_linear I"),
             "alpha": ("r:", "C(alpha) I"), "coulomb_fc_over_v": ("g-.", "b + Fc/V")}
    kmax = 45.0
    for ax, case in zip(axes.ravel(), names):
        c = doc["cases"][case]
        rows = c["rows"]
        meas = np.array([np.nan if r["measured"] is None else r["measured"] for r in rows])
        capped = np.array([r["measured_capped_at_grid_end"] for r in rows])
        for k, (ls, lab) in style.items():
            if k not in rows[0]["predicted"]:
                continue
            pk = np.array([r["predicted"][k] for r in rows])
            ax.plot(np.minimum(pk, kmax), damping, ls, lw=1.4, label=lab)
            off = pk > kmax
            if off.any():
                ax.plot(np.full(off.sum(), kmax), damping[off], ls[0] + ">", ms=5)
        ax.plot(meas[~capped], damping[~capped], "ko", ms=5, mfc="none", label="measured")
        if capped.any():
            ax.plot(meas[capped], damping[capped], "k>", ms=6, mfc="none",
                    label="measured: passive to K = 40")
        fam, q, v = zwidth_damping.CASES[case]
        ax.set_title(f"{fam}, {'quantised' if q else 'exact'}, V = {v:g} rad/s", fontsize=9)
        ax.set_xlim(0, kmax + 1)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("K_max [N m/rad]")
    for ax in axes[:, 0]:
        ax.set_ylabel("wall damping B [N m s/rad]")
    h, lab = axes[1, 0].get_legend_handles_labels()
    seen = dict(zip(lab, h))
    for ax in axes.ravel():
        for hh, ll in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(ll, hh)
    fig.legend(seen.values(), seen.keys(), loc="lower center", ncol=6, fontsize=8)
    fig.suptitle("Z-width boundary: measured vs 2(b_x - |B|)/T (arrows: off the scale, > 45)",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(path, dpi=100)
    plt.close(fig)
