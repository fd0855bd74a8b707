#!/usr/bin/env python3
"""Time ``omni discrepancy`` on the whole paper campaign (README, Performance).

The truth model is the virtual Omni with the yaw viscous damping raised to 0.012 N m s/rad (the
bank's ``viscous_damping`` case); it generates the 106 runs of the paper campaign (quantised,
noisy encoder as in the bank), and the workflow sees only those runs and the nominal model.

Usage: python scripts/discrepancy_campaign.py [--jobs N]
"""

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from omni_sim import experiments as ex  # noqa: E402
from omni_sim.discrepancy import bank  # noqa: E402
from omni_sim.discrepancy.workflow import run_discrepancy  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=None)
    args = ap.parse_args(argv)
    hidden = bank.case("viscous_damping")
    runs = bank.generate(hidden, exps=ex.campaign("paper"), jobs=args.jobs)
    t0 = time.perf_counter()
    rep = run_discrepancy(runs, None, jobs=args.jobs).report
    wall = time.perf_counter() - t0
    n = sum(len(r.t) for r in runs)
    for e in rep["effects"]:
        (k, v), = e["parameters"].items()
        print(f"named {e['name']}: {k} = {v:.7g} +- {e['uncertainty'][k]:.2g} "
              f"(runner-up {e['runner_up']}, margin {e['margin']:.2f})")
    print(f"{len(runs)} runs, {n} samples: {wall:.0f} s; held-out gap {rep['gap_before']:.3g} -> "
          f"{rep['gap_after']:.3g} rad (x{rep['shrink_factor']:.0f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
