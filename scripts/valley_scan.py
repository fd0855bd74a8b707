"""Why ``load_friction``'s coefficient is blended, and why the prescreen also starts from the
model's own values: the objective of the joint fit (the nominal's corrections +
``load_friction``) on the ``load_friction_nominal_off`` case's runs, with the law as the
library holds it (``blend``: the coefficient passes from mu_back to mu_drive over
``omni_sim.device.LOAD_FRICTION_BLEND_RAD_S``) and as a switch (``switch``: on the sign
of tau*w, mu_back at rest: the blend speed set to 0, in the engine and in the case's truth
alike, so the truth's runs change with it).

The study is :mod:`bank.studies.valley_scan` (what the record holds, per law); this is its
command line.  Writes ``valley_scan.json`` (``--out``, default docs/studies/discrepancy).
Deterministic (the case's seed); a few minutes on 2 cores.

Usage: python scripts/valley_scan.py [--out docs/studies/discrepancy]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from bank.studies import valley_scan as vs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs/studies/discrepancy")
    args = ap.parse_args(argv)
    out = vs.record()
    dest = Path(args.out)
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "valley_scan.json").write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {dest / 'valley_scan.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
