"""Run the hidden-effect bank through ``omni discrepancy`` and write docs/studies/discrepancy/bank.md.

For every case of :data:`bank.hidden.CASES` a truth model (the virtual Omni
with the effect written by :mod:`bank.omni_truths` with MuJoCo's own features,
independently of the effect library)
generates quantised, noisy "measured" runs (exact ones for ``none_exact``); the workflow sees
only those runs and the nominal model.  The table lists the hidden and the named effects, the
parameters (truth vs fitted ± 95 % uncertainty), the held-out gap before/after, the runner-up,
the margin and the verdict of :func:`bank.hidden.assess`.  Beside the table, a
JSON (same name, ``.json``) holds the run's settings (commit, dates, machine load) and every
case's full workflow report; it is rewritten after each case, so a stopped run keeps what it
did.  A worked example with figures is written to docs/studies/discrepancy/example/ (``--no-example``:
not).

A case with a truth of its own (``truth="servo"``: the geared-servo pendulum of
:mod:`bank.servo_truth`) is given its own nominal model and target
(:func:`bank.hidden.nominal`: ``models/servo_pendulum/servo_pendulum.xml``, ``pivot``/``servo``).
``--merge`` runs the given cases and puts them into the existing JSON in the bank's order (the
other cases kept as they are); each merged entry records its own commit and dates.

``--table`` prints the bank table of docs/method/discrepancy.md made from the JSON
(``tests/test_discrepancy_bank.py`` checks that docs/method/discrepancy.md holds exactly that).

``--gear-efficiency`` runs the case whose truth is written in another form than the library's
law (:func:`bank.servo_truth.generate_efficiency`: a gear efficiency law with a
smooth sign; judged by :func:`~bank.servo_truth.assess_efficiency`), writes its
record to ``bank_gear_efficiency.json`` beside the table and the table's page with its section
(rendered from that record whenever the page is written).

Usage: python scripts/discrepancy_bank.py [--cases NAME ...] [--no-example] [--jobs N] [--out MD]
                                         [--commit TEXT] [--note TEXT] [--merge]
       python scripts/discrepancy_bank.py --table [--json JSON]      (docs/method/discrepancy.md's table)
       python scripts/discrepancy_bank.py --markdown [--json JSON] [--out MD]   (MD from JSON)
       python scripts/discrepancy_bank.py --gear-efficiency [--only-load-friction] [--jobs N] [--commit TEXT]
                                         [--note TEXT]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from bank.writers import bank_report as report
from bank.studies import discrepancy_bank as study
from identification.errors import UserError

DEFAULT_OUT = report.DEFAULT_OUT


def run_efficiency(args, meta: dict) -> int:
    """Run the gear_efficiency case, write its record beside ``args.out`` and the page.  With
    ``--only-load-friction``: the workflow restricted to the library's ``load_friction``, stored
    in the existing record under ``load_friction_only`` with its own meta."""
    out = Path(args.out)
    rep = study.efficiency_report(meta, jobs=args.jobs, only_load_friction=args.only_load_friction)
    old = json.loads(out.with_name(report.EFFICIENCY_JSON.name).read_text()) if args.only_load_friction else None
    rec, ok = study.efficiency_record(meta, rep, old)
    report.write_efficiency(out, Path(args.json), rec)
    print(f"gear_efficiency{' (load_friction only)' if args.only_load_friction else ''}: named "
          f"{[e['name'] for e in rep['effects']]}; gap {rep['gap_before']:.3g} -> {rep['gap_after']:.3g} rad")
    return 0 if ok else 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=None)
    ap.add_argument("--no-example", action="store_true")
    ap.add_argument("--jobs", type=int, default=None)
    ap.add_argument("--out", default=str(DEFAULT_OUT), help=f"table (default {DEFAULT_OUT.relative_to(report.ROOT)}; "
                    "the JSON beside it)")
    ap.add_argument("--commit", default=None, help="what the header names as the code's commit "
                    "(default: the checkout's, with its uncommitted code paths)")
    ap.add_argument("--note", default="", help="a sentence for the header (e.g. how the code was checked out)")
    ap.add_argument("--table", action="store_true", help="print docs/method/discrepancy.md's bank table made from --json")
    ap.add_argument("--markdown", action="store_true", help="rewrite --out's table from --json (no run)")
    ap.add_argument("--json", default=str(DEFAULT_OUT.with_suffix(".json")))
    ap.add_argument("--gear-efficiency", action="store_true", help="run the gear_efficiency case (a truth "
                    "of another form) into its own record beside --out and rewrite --out's page")
    ap.add_argument("--only-load-friction", action="store_true", help="with --gear-efficiency: the workflow "
                    "restricted to load_friction, added to the existing record (a diagnostic)")
    ap.add_argument("--merge", action="store_true", help="run --cases and put them into --out's "
                    "existing JSON (the other cases kept; each merged entry records its commit)")
    args = ap.parse_args(argv)
    if args.table:
        sys.stdout.write(report.readme_table(json.loads(Path(args.json).read_text())))
        return 0
    if args.markdown:
        Path(args.out).write_text(report.bank_page(json.loads(Path(args.json).read_text()), Path(args.out)))
        return 0
    try:
        cases = study.select(args.cases)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = study.bank_meta(commit=args.commit or report.checkout_commit(),
                           command="python scripts/discrepancy_bank.py " + " ".join(sys.argv[1:] if argv is None else argv),
                           json_name=out.with_suffix(".json").name, jobs=args.jobs, note=args.note)
    if args.gear_efficiency:
        return run_efficiency(args, {k: meta[k] for k in study.EFFICIENCY_META})
    data = {"meta": meta, "cases": {}}
    if args.merge:
        data = json.loads(out.with_suffix(".json").read_text())
    t_all = time.perf_counter()

    def written(name: str, entry: dict, data: dict) -> None:
        report.write_bank(out, data)
        print(report.bank_row(name, entry), flush=True)

    study.run_bank(cases, data, meta, jobs=args.jobs, merge=args.merge, on_case=written)
    report.write_bank(out, data)
    if not args.no_example:
        report.write_example()
    print(f"wrote {out} and {out.with_suffix('.json')} ({time.perf_counter() - t_all:.0f} s)")
    return 0 if all(v["pass"] for v in data["cases"].values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
