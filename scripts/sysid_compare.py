"""MuJoCo's own identification (``mujoco.sysid``) beside ``omni discrepancy``'s fit, on the same
parameters of the same data: estimates, 95 % intervals, wall time, physics steps.

A study tool: ``mujoco.sysid`` is not a dependency of the project.  It ships with MuJoCo >= 3.5,
its optional requirements with the extra::

    pip install "mujoco[sysid]==4.0.0"      # the installed MuJoCo's version

The study (cases, methods) is :mod:`bank.studies.sysid_compare`, the page
:mod:`bank.writers.sysid_report`; this is its command line.  Writes ``sysid_compare.json`` and
``sysid.md`` (rendered from the JSON) to ``--out``.

Usage: python scripts/sysid_compare.py [--out docs/studies/discrepancy] [--cases ...] [--jobs 1]
       [--feetech-data DIR] | --report-only
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from omni_app.provenance import git_commit, uncommitted
from bank.writers.sysid_report import JSON_NAME, MD_NAME, render
from bank.studies import sysid_compare as sc

OUT = sc.ROOT / "docs" / "studies" / "discrepancy"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--cases", nargs="+", choices=sc.CASES, default=list(sc.CASES))
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--feetech-data", type=Path, default=None,
                    help="converted examples/real_servo runs (default: convert into a temporary folder)")
    ap.add_argument("--report-only", action="store_true", help="re-render the md from the JSON")
    args = ap.parse_args(argv)
    jpath, mpath = args.out / JSON_NAME, args.out / MD_NAME
    if args.report_only:
        mpath.write_text(render(json.loads(jpath.read_text())))
        return 0
    sysid = sc.load_sysid()
    if sysid is None:
        print('error: mujoco.sysid needs its extra: pip install "mujoco[sysid]"', file=sys.stderr)
        return 2
    record = json.loads(jpath.read_text()) if jpath.exists() else {}
    # the code this process imports, as it stands at its start (later commits do not change it)
    commit = git_commit()
    record.update(sc.record_header(commit, uncommitted(sc.CODE_PATHS), args.jobs))
    cases = {c["id"]: c for c in record.get("cases", [])}
    for cid in args.cases:
        cases[cid] = sc.run_case(sysid, cid, args.jobs, args.feetech_data, lambda s: print(s, flush=True), commit)
        record["cases"] = [cases[c] for c in sc.CASES if c in cases]
        jpath.write_text(json.dumps(record, indent=1) + "\n")
    mpath.write_text(render(record))
    return 0


if __name__ == "__main__":
    sys.exit(main())
