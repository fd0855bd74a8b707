#!/usr/bin/env python
"""The alpha model's verdict on every candidate of the table-level search within Table 11's band.

Reads ``docs/studies/fidelity/search.json``, selects the candidates whose linear model errs on the steps
as much as the real Omni's (:func:`omni_studies.fidelity_alpha.in_band`, from the record's
linear figures only), rebuilds each one's device and runs ``omni reproduce``'s stages on it, and
writes ``docs/studies/fidelity/alpha_verdict.json`` (with the code commit), ``alpha_verdict.md`` and
``alpha_verdict.png`` (rendered from the JSON).  The verdict is reported, never used to choose.

    nice -n 10 python scripts/fidelity_alpha.py          # every in-band candidate (a few minutes)
    python scripts/fidelity_alpha.py --list              # which candidates, and exit
    python scripts/fidelity_alpha.py --report-only       # rewrite the md/png from the JSON
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

from omni_app import fidelity_alpha as fav
from omni_app.provenance import git_commit
from omni_app.report import TARGET_STEP_RATIO
from omni_app.reproduce import one_blas_thread
from omni_studies import fidelity_alpha as study

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--search", type=Path, default=study.SEARCH, help="the search record")
    ap.add_argument("--out", type=Path, default=fav.OUT, help="the verdict record (JSON)")
    ap.add_argument("--jobs", type=int, default=None, help="threads of each campaign (default: all cores)")
    ap.add_argument("--list", action="store_true", help="list the in-band candidates and exit")
    ap.add_argument("--report-only", action="store_true", help="rewrite the md/png from --out")
    args = ap.parse_args(argv)
    if args.report_only:
        rec = json.loads(args.out.read_text())
    else:
        doc = json.loads(args.search.read_text())
        if args.list:
            for r in study.in_band(doc):
                print(r["id"])
            return 0
        with one_blas_thread():
            rec = study.run(doc, TARGET_STEP_RATIO, args.jobs,
                            progress=lambda row: print(fav.row_line(row), flush=True))
        rec.update(code_commit=git_commit(), versions=_versions())
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(rec, indent=1) + "\n")
        print("wrote", args.out)
    for path in fav.write_report(rec, args.out.parent):
        print("wrote", path)
    return 0



def _versions() -> dict:
    import mujoco
    import numpy
    import scipy

    return {"python": platform.python_version(), "mujoco": mujoco.__version__,
            "numpy": numpy.__version__, "scipy": scipy.__version__}


if __name__ == "__main__":
    raise SystemExit(main())
