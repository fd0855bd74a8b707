"""Write the second test half's datasets: one folder of logged runs per truth, and ``cases.json``.

The campaign, the P law, the log's jitter and the metadata are the first half's
(``bank.test_half.make``: :func:`~bank.test_half.make.campaign`,
:func:`~bank.test_half.make.log_ticks`, ``KP``, ``COMMAND_LIMIT``, ``RUN_S``, ``REST_S``):
12 runs of 6 s per case, the servo's loop at 1 kHz, the host's log at about 200 Hz.  Only the
truths (``bank.test_half_2.truths``) and their loop (:func:`bank.test_half_2.truths.simulate`)
are this half's.

Usage::

    python -m bank.test_half_2.make --out bank_data_2 [--seed 43] [--only j_null] [--force]

Same seed -> same bytes (each case's plant perturbation comes from ``seed * 100 + index``, its
log jitter from ``(seed, index, 2)``).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from bank.test_half import make as make1
from bank.test_half import truths as tr
from bank.test_half_2 import truths as tr2
from identification.dataset import Run, atomic_output_dir, check_output_dir, write_run

DEFAULT_SEED = 43
#: The third entry of the log jitter's seed (the first half's is 1).
JITTER_SALT = 2


@dataclass(frozen=True)
class Half:
    """What tells one test half's datasets apart: its truths module (``CASES`` and a
    ``simulate`` with the first half's signature), its default seed, its log jitter's salt and
    the ``what`` line of its ``cases.json``."""

    truths: ModuleType
    seed: int
    salt: int
    what: str


def run_case(index: int, name: str, seed: int, quick: bool = False) -> tuple[tr.Truth, list[Run], dict]:
    """Simulate one case's campaign (the first half's ``run_case`` with this half's truths).
    ``quick``: the first and last runs only, 1.5 s each (tests)."""
    return run_half_case(HALF, index, name, seed, quick)


def run_half_case(half: Half, index: int, name: str, seed: int,
                  quick: bool = False) -> tuple[tr.Truth, list[Run], dict]:
    """:func:`run_case` of the test half ``half`` (the second half's and the later ones')."""
    plant, factors = tr.perturbed(tr.nominal_plant(), seed * 100 + index)
    truth = dict(half.truths.CASES)[name](plant)
    state = truth.initial_state()
    rng = np.random.default_rng([seed, index, half.salt])
    duration = 1.5 if quick else make1.RUN_S
    plan = make1.campaign(duration)
    if quick:
        plan = [plan[0], plan[-1]]
    runs = []
    n = int(round(duration / tr.CONTROL_PERIOD_S))
    for e in plan:
        ticks = make1.log_ticks(rng, duration)
        t = ticks * tr.H
        r = np.asarray(e["ref"](t), dtype=float)
        en = np.ones(len(t)) if e["off_s"] is None else (t < e["off_s"]).astype(float)
        # the servo holds the last goal it received: period k starts at tick 10 k
        held = np.searchsorted(ticks, np.arange(n) * tr.SUBSTEPS, side="right") - 1
        theta, u = half.truths.simulate(truth, r[held], en[held], make1.KP, make1.COMMAND_LIMIT,
                                        float(r[0]), state)
        truth.rest(make1.REST_S, state)
        y = np.round(theta[ticks] / tr.ENCODER_STEP_RAD) * tr.ENCODER_STEP_RAD
        v = u[np.minimum(ticks // tr.SUBSTEPS, n - 1)]
        meta = {"kind": e["kind"], "kp": make1.KP, "command_limit": make1.COMMAND_LIMIT,
                "frequency_hz": e["frequency_hz"], "amplitude_rad": e["amplitude_rad"],
                "control_period_s": tr.CONTROL_PERIOD_S,
                "encoder_step_rad": tr.ENCODER_STEP_RAD,
                "units": {"r": "rad", "theta": "rad", "v": "V (motor voltage command)",
                          "kp": "V/rad", "command_limit": "V"},
                "device": "geared servo pendulum (bank test half)"}
        runs.append(Run(e["name"], t, r, y, v, meta, extra={"enabled": en}))
    record = {"name": name, "index": index, "seed": seed, "plant_factors": factors,
              **truth.describe()}
    return truth, runs, record


#: This half.
HALF = Half(tr2, DEFAULT_SEED, JITTER_SALT, "the bank's second test half (bank/README.md)")


def main(argv: list[str] | None = None) -> int:
    return half_main(HALF, argv, __doc__.split("\n\n")[0])


def half_main(half: Half, argv: list[str] | None, description: str) -> int:
    """The command line of a test half's ``make`` (:func:`main`'s, for ``half``)."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--out", required=True, help="output folder (one sub-folder per case)")
    p.add_argument("--seed", type=int, default=half.seed, help=f"seed (default {half.seed})")
    p.add_argument("--only", help="comma-separated case names (default: all)")
    p.add_argument("--quick", action="store_true", help="two 1.5 s runs per case (tests)")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")
    args = p.parse_args(argv)
    names = [n for n, _ in half.truths.CASES]
    chosen = names if not args.only else args.only.split(",")
    unknown = [n for n in chosen if n not in names]
    if unknown:
        print(f"error: unknown case {unknown[0]!r}; choose from {', '.join(names)}", file=sys.stderr)
        return 2
    try:
        check_output_dir(Path(args.out), force=args.force)
    except Exception as exc:  # the contract's one-line refusal
        print(f"error: {exc}", file=sys.stderr)
        return 2
    cases = []
    with atomic_output_dir(Path(args.out), force=args.force) as tmp:
        for name in chosen:
            index = names.index(name)
            _, runs, record = run_half_case(half, index, name, args.seed, quick=args.quick)
            (tmp / name).mkdir()
            for run in runs:
                write_run(tmp / name, run)
            record.update({"measured": name, "model": tr.NOMINAL_REL, "joint": tr.JOINT,
                           "actuator": tr.ACTUATOR, "runs": len(runs), "quick": args.quick})
            cases.append(record)
            print(f"{name}: {len(runs)} runs", flush=True)
        doc = {"what": half.what, "seed": args.seed,
               "command": ("omni discrepancy --measured OUT/<case> --model <model> "
                           "--joint pivot --actuator servo --out REPORTS/<case>"),
               "cases": cases}
        with open(tmp / "cases.json", "w", newline="\n") as fh:
            json.dump(doc, fh, indent=2, sort_keys=True, allow_nan=False)
            fh.write("\n")
    print(f"{len(cases)} cases in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
