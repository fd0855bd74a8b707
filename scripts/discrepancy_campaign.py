#!/usr/bin/env python3
"""Time ``omni discrepancy`` on the whole paper campaign with the whole library
(docs/reference/performance.md; the same measurement as ``omni bench --discrepancy-campaign``).

The truth model is the bank's ``viscous_damping`` case (the virtual Omni with the yaw viscous
damping raised to 0.012 N m s/rad, written independently of the effect library); it generates
the 106 runs of the paper campaign (quantised, noisy encoder as in the bank), and the workflow
sees only those runs and the nominal model.

Usage: python scripts/discrepancy_campaign.py [--jobs N] [--case NAME]
"""

import argparse
import json
import sys

from omni_studies.bench import CAMPAIGN_CASE, bench_discrepancy_campaign


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=None, help="rollout threads (default: all cores)")
    ap.add_argument("--case", default=CAMPAIGN_CASE, help="bank case hidden in the truth model")
    args = ap.parse_args(argv)
    out = bench_discrepancy_campaign(args.case, jobs=args.jobs,
                                     log=lambda s: print(s, file=sys.stderr, flush=True))
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
