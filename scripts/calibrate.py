#!/usr/bin/env python3
"""Calibrate the virtual Omni to the paper's measurements (see omni_studies/calibration.py).

Usage: python scripts/calibrate.py [--friction {lugre,coulomb}] [--free {friction,all}]
                                  [--max-nfev N] [--dry-run] [--record FILE]

Runs the paper's sine campaign on the model, identifies it with the project's own pipeline,
compares with the paper's Tables 3 and 10, and adjusts the physical parameters by bounded least
squares. Writes the result as data: models/omni/omni.xml (numbers only), the sine amplitude into
the campaign file omni_sim/campaigns/paper.toml, and the record (targets, achieved values, date) into
models/omni/calibration.json. --dry-run only prints and writes the record to --record.
"""

import argparse
import json
from pathlib import Path

from omni_app.calibration_report import plot_record
from omni_studies import calibration as cal


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--friction", choices=("lugre", "coulomb"), default="lugre",
                    help="friction family to calibrate (its scene models/omni/scene_<family>.xml)")
    ap.add_argument("--free", choices=cal.FREE_CHOICES, default="friction",
                    help="fit the family's friction only (the shared robot and A_r fixed; default) "
                         "or everything (writes the shared robot and the campaign's A_r too)")
    ap.add_argument("--max-nfev", type=int, default=60, help="simulation budget of the optimiser")
    ap.add_argument("--dry-run", action="store_true", help="do not modify the model files")
    ap.add_argument("--record", default=None, help="where --dry-run writes the record (a real run "
                    "writes models/omni/calibration.json for lugre, models/omni/calibration_coulomb.json for coulomb)")
    ap.add_argument("--jobs", type=int, default=None)
    ap.add_argument("--start", default=None, help="JSON object of starting values (default: the model's)")
    args = ap.parse_args()
    record = cal.calibrate(max_nfev=args.max_nfev, jobs=args.jobs, family=args.friction, free=args.free,
                           start=json.loads(args.start) if args.start else None)
    print(json.dumps(record["achieved"], indent=2))
    if not args.dry_run:
        record = cal.finalize(record)
        figs = plot_record(record, Path(__file__).resolve().parent.parent / "docs" / "studies" / "calibration",
                           prefix=cal.figure_prefix(args.friction))
        print(f"wrote the model files, {cal.RECORDS[args.friction].name} and",
              ", ".join(str(f) for f in figs))
    else:
        cal.write_record(record, Path(args.record or f"calibration_{args.friction}_dry_run.json"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
