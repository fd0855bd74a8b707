"""Coverage study of ``omni discrepancy``'s 95 % intervals on data with a known hidden truth.

``--n`` random magnitudes per effect in its realistic range, each fitted by the workflow on
runs of the independent truth model; a parameter is covered when the truth lies inside the
reported 95 % interval (the method: :mod:`bank.studies.discrepancy_coverage`).

Writes ``coverage.json`` (every draw, per-effect and overall coverage with Wilson 95 % intervals,
the median width of the intervals relative to the truth) and ``coverage.png`` to ``--out``;
resumes from an existing ``coverage.json`` with the same settings (draws already done are kept).

Usage: python scripts/discrepancy_coverage.py [--effects NAME ...] [--n 20] [--seed 0]
       [--conditions noisy exact] [--out docs/studies/discrepancy] [--jobs 1] [--experiments bank|small]
       [--merge OTHER/coverage.json ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from identification.errors import UserError
from bank.writers import bank_report as report
from bank.studies import discrepancy_coverage as cov

ROOT = Path(__file__).resolve().parent.parent
CONDITIONS = cov.CONDITIONS


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 epilog="Ranges of the random magnitudes: bank/ranges.py RANGES.")
    ap.add_argument("--effects", nargs="*", default=None,
                    help="library effects to study (default: every effect with a range)")
    ap.add_argument("--n", type=int, default=20, help="random magnitudes per effect (default 20)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the magnitudes and of the noise")
    ap.add_argument("--conditions", nargs="*", default=list(CONDITIONS), choices=CONDITIONS,
                    help="noisy: quantised encoder + 1e-4 rad noise; exact: neither")
    ap.add_argument("--out", default=str(ROOT / "docs" / "studies" / "discrepancy"), help="output folder")
    ap.add_argument("--experiments", default="bank", choices=("bank", "small"),
                    help="bank: the bank's 16 runs of 2 s; small: 10 runs of 1.2 s")
    ap.add_argument("--jobs", type=int, default=1, help="rollout threads (default 1)")
    ap.add_argument("--summarise-only", action="store_true",
                    help="no new draws: summarise the draws in --out's coverage.json (and --merge)")
    ap.add_argument("--merge", nargs="*", default=[],
                    help="coverage.json files of other runs (e.g. one per condition run in "
                         "parallel) whose draws are added before the summary")
    return ap


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        effects = cov.effects_of(args.effects)
        if args.n < 1:
            raise UserError("--n must be at least 1")
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        jpath = out / "coverage.json"
        settings = cov.study_settings(effects, args.n, args.seed, args.experiments)
        draws = cov.earlier_draws(jpath, settings, effects, seed=args.seed, experiments=args.experiments,
                                  summarise_only=args.summarise_only)
        for f in args.merge:
            draws += cov.other_draws(f, settings, draws)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    t_all = time.perf_counter()
    done = {(d["effect"], d["condition"], d["seed"]) for d in draws}
    plan = cov.plan(effects, done, n=args.n, seed=args.seed, conditions=args.conditions,
                    summarise_only=args.summarise_only)
    cov.run_draws(plan, draws, settings, cov.experiments(args.experiments), args.jobs,
                  save=lambda res: report.write_coverage(jpath, res))
    summary = cov.summarise(draws)
    report.write_coverage(jpath, dict(settings=settings, draws=draws, **summary))
    report.coverage_figure(summary, draws, out / "coverage.png", CONDITIONS, cov.TARGET)
    report.print_coverage_summary(summary)
    print(f"wrote {jpath} and {out / 'coverage.png'} ({time.perf_counter() - t_all:.0f} s)")
    ok = all(o["coverage"] >= cov.TARGET for o in summary["overall"].values())
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
