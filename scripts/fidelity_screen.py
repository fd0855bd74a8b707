#!/usr/bin/env python
"""Fidelity screen: which single effect of the discrepancy library moves the virtual Omni's
linear-model step error towards the real Omni's, and at what cost on Table 3.

For each base scene (``lugre`` = models/omni/scene.xml, ``coulomb`` =
models/omni/scene_coulomb.xml) and each (effect, magnitude) of the screen's configurations, one
effect at a time is written into the base and the paper's campaign runs on it; the linear
model's step errors, Table 3 and the resonance are measured, the alpha model is not computed
(:mod:`omni_studies.fidelity_screen` says what and why).

Writes ``--out`` (default docs/studies/fidelity/screen.json) and, next to it, ``screen.md`` and
``screen.png`` (:mod:`omni_app.fidelity_screen_report`).

    python scripts/fidelity_screen.py --jobs 2
    python scripts/fidelity_screen.py --merge --only lugre/time_delay/2ms   # re-run one
    python scripts/fidelity_screen.py --list
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from omni_app.fidelity_screen_report import run_screen
from omni_studies.fidelity_screen import CONFIGURATIONS

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="configurations: see --list")
    p.add_argument("--out", default=str(ROOT / "docs/studies/fidelity/screen.json"),
                   help="output JSON; screen.md and screen.png go next to it "
                        "(default docs/studies/fidelity/screen.json)")
    p.add_argument("--jobs", type=int, default=None, help="simulation threads (default: all cores)")
    p.add_argument("--only", default=None,
                   help="comma-separated configuration ids (default: all; see --list)")
    p.add_argument("--merge", action="store_true",
                   help="keep the configurations already in --out and run only the missing ones "
                        "(with --only: re-run those)")
    p.add_argument("--list", action="store_true", help="print the configurations and exit")
    args = p.parse_args(argv)
    if args.list:
        for c in CONFIGURATIONS:
            print(f"{c['id']:40s} {c['values']}")
        return 0
    if args.jobs is not None and args.jobs < 1:
        p.error("--jobs must be >= 1")
    ids = [c["id"] for c in CONFIGURATIONS]
    chosen = ids if args.only is None else [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = [c for c in chosen if c not in ids]
    if unknown or not chosen:
        p.error(f"unknown configuration(s) {unknown}; see --list")
    out = Path(args.out)
    run_screen(out, chosen, args.jobs, merge=args.merge, rerun=args.only is not None)
    print(f"wrote {out} and {out.stem}.md, {out.stem}.png next to it")
    return 0


if __name__ == "__main__":
    sys.exit(main())
