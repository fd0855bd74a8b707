#!/usr/bin/env python
"""Friction-strength study: how the alpha model's advantage and the inertia bias move with the
yaw's dry friction, per friction family.

For each family and each scale factor the yaw's dry friction is set to factor x the calibrated
one and the whole reproduction runs in memory (:mod:`omni_studies.friction_study`); a level that
fails is recorded with the reason, never dropped.

Writes ``OUT/friction_study.json`` and ``OUT/friction_study.png`` (alpha-model advantage on
steps and sines, and the inertia bias, against the friction scale; one line per family;
:mod:`omni_app.friction_study_report`).

    python scripts/friction_study.py --out docs/studies/friction
    python scripts/friction_study.py --out /tmp/study --levels 0,1,3 --families lugre
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from identification.errors import UserError
from omni_app.friction_study_report import FILES, level_lines, parse_levels, write_outputs
from omni_studies.friction_study import DEFAULT_LEVELS, study


def build_parser() -> argparse.ArgumentParser:
    from omni_sim.model import FRICTION_FAMILIES

    class Parser(argparse.ArgumentParser):  # one line "error: ..." and status 2, as omni's
        def error(self, message: str) -> None:
            sys.stderr.write(f"error: {self.prog}: {message}\n")
            raise SystemExit(2)

    p = Parser(prog="friction_study.py", description=__doc__.split("\n\n")[0],
                                epilog="Each level is one in-memory `omni reproduce` (~10 s on 2 cores).")
    p.add_argument("--out", required=True, help="output folder (friction_study.json, friction_study.png)")
    p.add_argument("--levels", default=",".join(f"{x:g}" for x in DEFAULT_LEVELS),
                   help="comma-separated dry-friction factors >= 0 (default: %(default)s)")
    p.add_argument("--families", default=",".join(FRICTION_FAMILIES),
                   help="comma-separated friction families (default: %(default)s)")
    p.add_argument("--campaign", default="paper",
                   help="campaign name or file (default: paper; see docs/usage/campaigns.md)")
    p.add_argument("--jobs", type=int, default=None, help="threads (default: all cores)")
    p.add_argument("--force", action="store_true", help="replace existing friction_study.* files")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        from omni_sim import experiments as ex
        from omni_sim import model as om

        levels = parse_levels(args.levels)
        families = [f.strip() for f in args.families.split(",") if f.strip()]
        for fam in families:
            om.scene_path(fam)  # UserError for an unknown family
        if not families or len(set(families)) != len(families):
            raise UserError(f"--families: distinct families needed, got {args.families!r}")
        if args.jobs is not None and args.jobs < 1:
            raise UserError(f"--jobs must be >= 1, got {args.jobs}")
        ex.campaign(args.campaign)  # a bad campaign fails before any simulation
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise UserError(f"{out}: not a folder")
        existing = [f for f in FILES if (out / f).exists()]
        if existing and not args.force:
            raise UserError(f"{out}: {', '.join(existing)} exist(s) (use --force to replace)")
        result = study(families, levels, args.campaign, args.jobs)
        write_outputs(out, result)
    except UserError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    for line in level_lines(result):
        print(line)
    print(f"wrote {out / FILES[0]} and {out / FILES[1]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
