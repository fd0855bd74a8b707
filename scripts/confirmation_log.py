"""The confirmation gate's evidence: every confirmation of the bank's searches with every
runner-up refitted, and the gate read on it (:mod:`bank.studies.confirmation_log`).

Runs every case of the bank (or ``--cases``), one process per case with one thread each,
``--jobs`` at a time (about 40 minutes on 2 cores), and writes the record (``--out``, default
docs/studies/discrepancy/confirmation_log.json).

Usage: python scripts/confirmation_log.py [--cases NAME ...] [--jobs 2] [--commit SHA] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from bank import hidden
from bank.studies import confirmation_log as cl


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=[c.name for c in hidden.CASES])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--commit", default="", help="the commit the record names")
    ap.add_argument("--out", default="docs/studies/discrepancy/confirmation_log.json")
    args = ap.parse_args(argv)
    unknown = [c for c in args.cases if c not in {k.name for k in hidden.CASES}]
    if unknown or args.jobs < 1:
        ap.error(f"unknown case(s) {', '.join(unknown)}" if unknown else "--jobs must be at least 1")
    os.environ["OMNI_THREADS"] = "1"  # one thread per case, --jobs cases at a time
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        cases = list(pool.map(cl.case_log, args.cases))
    s = cl.summary(cases)
    rec = {"about": "Every confirmation of the bank's searches with every runner-up refitted (the "
                    "confirmation gate off): scripts/confirmation_log.py (bank.studies.confirmation_log).",
           "commit": args.commit, "summary": {k: v for k, v in s.items() if k != "events"},
           "events": s["events"], "cases": cases}
    Path(args.out).write_text(json.dumps(rec, indent=1) + "\n")
    print(f"{s['confirmations_of_two']} confirmations of two; {s['far']} runner-ups screened at "
          f">= {cl.sel.CONFIRM_WITHIN:g}x the best; {s['violations']} of them within "
          f"{cl.LOW_CONFIDENCE_RATIO:.2f}x after their refits; written {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
