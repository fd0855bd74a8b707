"""The user's pendulum (the first test half's ``i_users_pendulum``, a spent case) fitted with
``load_friction``'s form (a level that sticks) and with the same law behind a smooth sign: where
each form's closed-loop optimum lies against the truth.

The study is :mod:`bank.studies.smooth_sign`; this is its command line.  It makes the first
test half's datasets (``python -m bank.test_half.make``, seed 41) in a temporary folder unless
``--data`` names them, and writes ``smooth_sign.json`` (``--out``, default
docs/studies/discrepancy).  Deterministic; about 10 min on 2 cores.

Usage: python scripts/smooth_sign.py [--data DIR] [--out docs/studies/discrepancy]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from bank.studies import smooth_sign as ss
from bank.test_half.plant import NOMINAL, NOMINAL_REL

CASE = "i_users_pendulum"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", help="the first test half's datasets (python -m bank.test_half.make --out DIR)")
    ap.add_argument("--out", default="docs/studies/discrepancy")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(args.data) if args.data else Path(tmp)
        if not args.data:
            subprocess.run([sys.executable, "-m", "bank.test_half.make", "--out", str(data)], check=True,
                           stdout=subprocess.DEVNULL)
        out = ss.record(data / CASE, data / "cases.json", NOMINAL)
    out["model"] = NOMINAL_REL
    dest = Path(args.out)
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "smooth_sign.json").write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {dest / 'smooth_sign.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
