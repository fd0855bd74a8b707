#!/usr/bin/env python
"""Does the identified damping predict the Z-width boundary better than the nominal b?

For each friction family (lugre, coulomb) the paper's identification runs on the virtual Omni
(``omni reproduce --friction F``, or a given params.json); at the wall maps' pose the nominal,
the linear model's and the alpha model's dampings are turned into Colgate & Schenkel's
boundary 2(b_x - |B|)/T and compared with the measured boundary of
docs/studies/haptics/study.json (``scripts/zwidth_study.py``); :mod:`omni_studies.zwidth_damping`
says how.

Writes ``--out`` (JSON, default docs/studies/haptics/damping_prediction.json) and the figure beside it
(same stem, .png).

    python scripts/zwidth_damping.py
    python scripts/zwidth_damping.py --params lugre=docs/studies/friction/lugre/params.json,coulomb=...
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from identification.nonlinear import AlphaModel
from omni_app.zwidth import damping_case_line, family_line, write_damping
from omni_studies.zwidth_damping import CASES, FAMILIES, case_prediction, family_dampings

ROOT = Path(__file__).resolve().parents[1]


def identify(family: str, workdir: Path) -> Path:
    """Run ``omni reproduce --friction family`` into workdir/family; returns its params.json."""
    out = workdir / family
    workdir.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "omni_app", "reproduce", "--friction", family, "--out", str(out), "--force"]
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    print(f"identified {family} in {time.perf_counter() - t0:.1f} s ({' '.join(cmd[1:])})",
          flush=True)
    return out / "params.json"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--study", default=str(ROOT / "docs/studies/haptics/study.json"),
                   help="the study's JSON with the measured boundaries (scripts/zwidth_study.py)")
    p.add_argument("--out", default=str(ROOT / "docs/studies/haptics/damping_prediction.json"),
                   help="output JSON; the figure is written beside it (.png)")
    p.add_argument("--params", default=None,
                   help="FAMILY=params.json[,FAMILY=...]: use these identifications instead of "
                        "running omni reproduce")
    p.add_argument("--keep", default=None,
                   help="folder to keep the omni reproduce outputs in (default: a temporary one)")
    args = p.parse_args(argv)

    study = json.loads(Path(args.study).read_text())
    damping = np.array(study["grid"]["damping"])
    missing = [c for c in CASES if c not in study["cases"]]
    if missing:
        p.error(f"{args.study} lacks the case(s) {missing}: run scripts/zwidth_study.py")
    given = {}
    if args.params:
        for item in args.params.split(","):
            fam, _, path = item.partition("=")
            given[fam.strip()] = Path(path.strip())
    tmp = tempfile.TemporaryDirectory() if args.keep is None else None
    workdir = Path(args.keep) if args.keep else Path(tmp.name)
    doc = {"study": str(Path(args.study).resolve().relative_to(ROOT))
           if Path(args.study).resolve().is_relative_to(ROOT) else args.study,
           "families": {}, "cases": {}}
    models = {}
    try:
        for fam in FAMILIES:
            src = given.get(fam) or identify(fam, workdir)
            params = json.loads(Path(src).read_text())
            info = family_dampings(fam, params, str(src) if fam in given
                                   else f"omni reproduce --friction {fam} (run by this script)")
            doc["families"][fam] = info
            print(family_line(fam, info), flush=True)
            models[fam] = AlphaModel.from_dict(params["alpha_model"])
    finally:
        if tmp is not None:
            tmp.cleanup()

    for case, (fam, _, _) in CASES.items():
        doc["cases"][case] = case_prediction(case, study, damping, doc["families"][fam], models[fam])
        print(damping_case_line(case, doc["cases"][case]), flush=True)
    out = Path(args.out)
    png = write_damping(doc, damping, out)
    print(f"wrote {out}, {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
