#!/usr/bin/env python
"""What moves the Z-width boundary: the table of docs/studies/haptics/haptics.md's "What moves the boundary".

Each case is one passivity map of the virtual Omni's yaw on the same 7 x 41 grid (B from 0 to
0.012 N*m*s/rad, K from 0 to 40 N*m/rad); the cases and what is recorded per case are
:mod:`omni_studies.zwidth_study`'s, the record's writing :mod:`omni_app.zwidth`'s.

    python scripts/zwidth_study.py                        # all cases -> docs/studies/haptics/study.json
    python scripts/zwidth_study.py --cases ideal,coulomb_exact_v1 --out /tmp/study.json

Runs one map at a time (each uses the machine's cores through the Engine's thread pool).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from omni_app.provenance import git_commit
from omni_app.zwidth import case_line, write_study
from omni_studies.zwidth_study import CASES, in_case_order, new_record, run_case

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="cases: " + ", ".join(CASES))
    p.add_argument("--out", default=str(ROOT / "docs/studies/haptics/study.json"),
                   help="output JSON (default docs/studies/haptics/study.json)")
    p.add_argument("--cases", default=",".join(CASES),
                   help="comma-separated subset of the cases (default: all)")
    p.add_argument("--merge", action="store_true",
                   help="keep the other cases already in --out (replace only those run)")
    p.add_argument("--jobs", type=int, default=None, help="Engine threads (default: all cores)")
    args = p.parse_args(argv)
    names = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in names if c not in CASES]
    if unknown or not names:
        p.error(f"unknown case(s) {unknown}; choose from {', '.join(CASES)}")
    out = Path(args.out)
    cases = {}
    if args.merge and out.exists():
        cases = json.loads(out.read_text()).get("cases", {})
    doc = new_record(cases, git_commit())
    out.parent.mkdir(parents=True, exist_ok=True)
    for name in names:
        r = run_case(name, args.jobs)
        doc["cases"][name] = r
        print(case_line(name, r), flush=True)
        doc["cases"] = in_case_order(doc["cases"])
        write_study(doc, out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
