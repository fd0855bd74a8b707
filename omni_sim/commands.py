"""Implementations of the ``omni`` subcommands that need the simulator."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from identification.dataset import atomic_output_dir, write_run
from identification.errors import UserError

from . import experiments as ex


def _settings(args: argparse.Namespace) -> ex.Settings:
    noise = float(getattr(args, "noise", 0.0) or 0.0)
    if not (noise >= 0 and math.isfinite(noise)):
        raise UserError(f"--noise must be a finite standard deviation >= 0, got {noise}")
    return ex.Settings(quantize=bool(getattr(args, "quantize", False)), noise_rad=noise,
                       seed=int(getattr(args, "seed", 0) or 0))


def _check_jobs(jobs: int | None) -> int | None:
    if jobs is not None and jobs < 1:
        raise UserError(f"--jobs must be >= 1, got {jobs}")
    return jobs


def write_dataset(runs, out, force: bool) -> None:
    """Write runs into ``out`` atomically (temporary folder, then rename)."""
    with atomic_output_dir(out, force=force) as tmp:
        for run in runs:
            write_run(tmp, run)


def generate(args: argparse.Namespace) -> int:
    """``omni generate``: run a campaign (or one user reference) and write a dataset."""
    jobs = _check_jobs(args.jobs)
    settings = _settings(args)
    out = Path(args.out)
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise UserError(f"{out}: output folder exists and is not empty (use --force to replace it)")
    if args.reference is not None:
        exps = [ex.reference_experiment(args.reference, args.gamma1, args.gamma2)]
    else:
        exps = ex.campaign(args.campaign)
    runs = ex.simulate(exps, args.model, settings, jobs=jobs, progress=sys.stderr.isatty())
    write_dataset(runs, out, args.force)
    n_sine = sum(r.kind == "sine" for r in runs)
    n_step = sum(r.kind == "step" for r in runs)
    print(f"wrote {len(runs)} runs ({n_sine} sine, {n_step} step, "
          f"{len(runs) - n_sine - n_step} other) to {out}")
    return 0


def bench(args: argparse.Namespace) -> int:
    """``omni bench``: print (and write) the performance figures."""
    from .bench import run_bench

    jobs = _check_jobs(args.jobs)
    figures = run_bench(jobs=jobs)
    text = json.dumps(figures, indent=2, sort_keys=True)
    print(text)
    if args.out:
        from identification.dataset import atomic_write_text
        atomic_write_text(args.out, text + "\n")
    return 0


def reproduce(args: argparse.Namespace) -> int:
    from .reproduce import reproduce_command
    return reproduce_command(args)


def discrepancy(args: argparse.Namespace) -> int:
    from .discrepancy import discrepancy_command
    return discrepancy_command(args)
