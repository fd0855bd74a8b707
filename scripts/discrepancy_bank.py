"""Run the hidden-effect bank through ``omni discrepancy`` and write docs/discrepancy_bank.md.

For every case of :data:`omni_sim.discrepancy.bank.CASES` a truth model (the virtual Omni with
the effect written by bank.py with MuJoCo's own features, independently of the effect library)
generates quantised, noisy "measured" runs (exact ones for ``none_exact``); the workflow sees
only those runs and the nominal model.  The table lists the hidden and the named effects, the parameters (truth
vs fitted ± 95 % uncertainty), the held-out gap before/after, the runner-up and the margin.
A worked example with figures is written to docs/discrepancy_example/.

Usage: python scripts/discrepancy_bank.py [--cases NAME ...] [--no-example] [--jobs N]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from omni_app.discrepancy import demo  # noqa: E402
from omni_sim.discrepancy import bank  # noqa: E402
from omni_sim.discrepancy.workflow import run_discrepancy  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=None)
    ap.add_argument("--no-example", action="store_true")
    ap.add_argument("--jobs", type=int, default=None)
    ap.add_argument("--out", default=str(ROOT / "docs" / "discrepancy_bank.md"))
    args = ap.parse_args(argv)
    cases = [c for c in bank.CASES if args.cases is None or c.name in args.cases]
    rows, raw = [], {}
    t_all = time.perf_counter()
    for c in cases:
        t0 = time.perf_counter()
        runs = bank.generate(c, jobs=args.jobs)
        try:
            rep = run_discrepancy(runs, None, jobs=args.jobs).report
        except Exception as exc:  # a crash of the workflow is a result of the bank, not its end
            wall = time.perf_counter() - t0
            raw[c.name] = {"pass": False, "why": f"workflow crashed: {type(exc).__name__}: {exc}",
                           "seconds": wall}
            rows.append(f"| {c.name} | CRASH | | | | | | | | | FAIL ({raw[c.name]['why']}) | {wall:.0f} |")
            print(rows[-1], flush=True)
            continue
        wall = time.perf_counter() - t0
        ok, why = bank.assess(c, rep)
        raw[c.name] = {"hidden": [list(e) for e in c.effects], "outside": [list(e) for e in c.outside],
                       "exact": c.exact, "note": c.note, "gap_lives": c.gap_lives,
                       "report_effects": rep["effects"], "gap_before": rep["gap_before"],
                       "gap_after": rep["gap_after"], "unexplained": rep["unexplained"],
                       "noise_floor_rad": rep["noise_floor_rad"], "seconds": wall, "pass": ok, "why": why}
        truth = "; ".join(f"{n}: " + ", ".join(f"{v:g}" for v in vals)
                          for n, vals in c.effects + c.outside) or "-"
        if c.outside:
            truth += " (outside the library)"
        fitted = "; ".join(
            f"{e['name']}: " + ", ".join(f"{v:.4g} ± {e['uncertainty'][p]:.2g}" for p, v in e["parameters"].items())
            for e in rep["effects"] if e["name"] != "none") or "-"
        named = ", ".join(e["name"] for e in rep["effects"])
        ru = rep["effects"][0].get("runner_up") or "-"
        mg = rep["effects"][0].get("margin")
        conf = ", ".join(e.get("confidence", "-") for e in rep["effects"])
        rows.append(f"| {c.name} | {named} | {truth} | {fitted} | {rep['gap_before']:.2e} | "
                    f"{rep['gap_after']:.2e} | x{rep['shrink_factor']:.1f} | {ru} | "
                    f"{'-' if mg is None else f'{mg:.2f}'} | {conf} | {'PASS' if ok else 'FAIL'} ({why}) | {wall:.0f} |")
        print(rows[-1], flush=True)
    total = time.perf_counter() - t_all
    text = [
        "# Hidden-effect bank of `omni discrepancy`", "",
        "Each truth model is the virtual Omni (`models/scene.xml`) with effects written by "
        "`omni_sim/discrepancy/bank.py` with MuJoCo's own features, independently of the effect "
        "library the workflow searches (a test checks that bank.py does not use it), at realistic "
        "magnitudes (see each case's note in bank.py for the values and their provenance). It generates "
        f"{len(bank.bank_experiments())} runs of {bank.BANK_DURATION_S:g} s (sines at "
        f"{', '.join(map(str, bank.BANK_FREQUENCIES_HZ))} Hz x {', '.join(map(str, bank.BANK_AMPLITUDES_RAD))} rad "
        f"and square waves of {', '.join(map(str, bank.BANK_STEP_AMPLITUDES_RAD))} rad at poses "
        f"{', '.join(str(p) for p in bank.BANK_POSES)} deg) through `omni_sim.experiments.simulate`'s "
        f"reference loop, encoder quantised to 15000 counts/rev plus {bank.BANK_NOISE_RAD:g} rad white "
        "noise that the controller sees (`none_exact`: neither). The workflow sees only these runs and the "
        "nominal model.", "",
        "Gaps are held-out RMS replay errors [rad]; ± is the reported 95 % uncertainty: the Student-t "
        "factor of the k-fold jackknife times the root-sum-square of three standard errors (the "
        "jackknife over folds, the Jacobian estimate with the residual correlation time, and the "
        "measurement process -- quantised, noisy encoder in the device's loop and a measured start -- "
        "propagated through the closed loop by a parametric bootstrap), plus the bootstrap's mean "
        "shift. When no single candidate removes half of a gap far above the noise, every pair is "
        "also fitted jointly (effects that mask each other, like a delay and friction). Pass: the hidden effect is named, every parameter within ±, gap shrinks >= 3x; null case: "
        "`none`; outside-library cases: `none` or candidates with low confidence only (never a wrong "
        "name with high confidence).", "",
        "| hidden | named | truth | fitted ± 95 % | gap before | gap after | shrink | runner-up | margin | "
        "confidence | result | s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|", *rows, "",
        f"Total {total:.0f} s on this machine ({len(cases)} cases).", "",
    ]
    Path(args.out).write_text("\n".join(text))
    (Path(args.out).with_suffix(".json")).write_text(json.dumps(raw, indent=2, default=str) + "\n")
    if not args.no_example:
        ex_dir = ROOT / "docs" / "discrepancy_example"
        demo(ex_dir, force=True)
        shutil.rmtree(ex_dir / "measured", ignore_errors=True)  # keep the docs small
    print(f"wrote {args.out} ({total:.0f} s)")
    return 0 if all(v["pass"] for v in raw.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
