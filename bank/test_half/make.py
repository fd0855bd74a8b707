"""Write the test half's datasets: one folder of logged runs per truth, and ``cases.json``.

Each case (``truths.CASES``) runs the same campaign of 12 runs of 6 s on its truth
(:func:`campaign`): sines at 0.5, 1.5 and 2.5 Hz at 0.15 and 0.4 rad, square waves of +-0.2
and +-0.5 rad, a staircase, a slow triangle, a sine about an offset, and a lift-and-drop
(torque off from 3 s).  The servo closes its loop at 1 kHz (``control_period_s`` 0.001); the
host logs at about 200 Hz with jitter (intervals 3.5-6.5 ms, on a 0.1 ms grid) and sends the
goal at each log sample, which the servo holds until the next one.  Logged: ``t``, the goal
``r``, the encoder angle ``theta`` (4096 counts/rev), the command ``v`` [V] held at that time,
``enabled``.

Usage::

    python -m bank.test_half.make --out bank_data [--seed 41] [--only j_null] [--force]

Same seed -> same bytes (each case's plant perturbation and log jitter come from
``(seed, case index)``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from bank.test_half import truths as tr
from identification.dataset import Run, atomic_output_dir, check_output_dir, write_run

#: P gain [V/rad] (servo stiffness kp kt/R = 9 N m/rad against gravity's 1.18 N m/rad) and
#: the P law's clip: the 12 V supply.
KP = 30.0
COMMAND_LIMIT = 12.0
RUN_S = 6.0
#: Rest between two runs [s] (the thermal case cools over it).
REST_S = 5.0
#: Log intervals: 5 ms +- 1.5 ms, in 0.1 ms ticks.
LOG_TICKS = (35, 65)
DEFAULT_SEED = 41


def campaign(duration: float = RUN_S) -> list[dict]:
    """The runs: name, kind, reference function of time, metadata numbers, torque-off time."""
    runs = []
    for f in (0.5, 1.5, 2.5):
        for a in (0.15, 0.4):
            runs.append({"name": f"sine_f{f:.1f}_a{a:.2f}".replace(".", "p"), "kind": "sine",
                         "ref": (lambda t, f=f, a=a: a * np.sin(2 * np.pi * f * t)),
                         "frequency_hz": f, "amplitude_rad": a, "off_s": None})
    for a in (0.2, 0.5):
        runs.append({"name": f"square_a{a:.2f}".replace(".", "p"), "kind": "step",
                     "ref": (lambda t, a=a: np.where((t * 0.5) % 1.0 < 0.5, a, -a)),
                     "frequency_hz": 0.5, "amplitude_rad": a, "off_s": None})
    levels = np.array([0.0, 0.3, 0.6, 0.3, 0.0, -0.3, -0.6, -0.3, 0.0])
    runs.append({"name": "staircase", "kind": "other",
                 "ref": (lambda t: levels[np.minimum((t / (RUN_S / len(levels))).astype(int),
                                                     len(levels) - 1)]),
                 "frequency_hz": 0.0, "amplitude_rad": 0.6, "off_s": None})
    runs.append({"name": "triangle_slow", "kind": "other",
                 "ref": (lambda t: 0.8 * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * 0.25 * t))),
                 "frequency_hz": 0.25, "amplitude_rad": 0.8, "off_s": None})
    runs.append({"name": "offset_sine", "kind": "other",
                 "ref": (lambda t: 0.6 * np.minimum(t / 0.5, 1.0) + 0.2 * np.sin(2 * np.pi * t)),
                 "frequency_hz": 1.0, "amplitude_rad": 0.2, "off_s": None})
    runs.append({"name": "lift_and_drop", "kind": "other",
                 "ref": (lambda t: -1.0 * np.minimum(t / 1.5, 1.0)),
                 "frequency_hz": 0.0, "amplitude_rad": 1.0, "off_s": 0.5 * duration})
    return runs


def log_ticks(rng: np.random.Generator, duration: float) -> np.ndarray:
    """Log times in 0.1 ms ticks: 0, then intervals uniform in LOG_TICKS, up to ``duration``."""
    last = int(round(duration / tr.H))
    steps = rng.integers(LOG_TICKS[0], LOG_TICKS[1] + 1, size=int(last / LOG_TICKS[0]) + 2)
    ticks = np.concatenate([[0], np.cumsum(steps)])
    return ticks[ticks <= last]


def run_case(index: int, name: str, seed: int, quick: bool = False) -> tuple[tr.Truth, list[Run], dict]:
    """Simulate one case's campaign.  ``quick``: the first and last runs only, 1.5 s each
    (tests)."""
    plant, factors = tr.perturbed(tr.nominal_plant(), seed * 100 + index)
    truth = dict(tr.CASES)[name](plant)
    state = truth.initial_state()
    rng = np.random.default_rng([seed, index, 1])
    duration = 1.5 if quick else RUN_S
    plan = campaign(duration)
    if quick:
        plan = [plan[0], plan[-1]]
    runs = []
    n = int(round(duration / tr.CONTROL_PERIOD_S))
    for e in plan:
        ticks = log_ticks(rng, duration)
        t = ticks * tr.H
        r = np.asarray(e["ref"](t), dtype=float)
        en = np.ones(len(t)) if e["off_s"] is None else (t < e["off_s"]).astype(float)
        # the servo holds the last goal it received: period k starts at tick 10 k
        held = np.searchsorted(ticks, np.arange(n) * tr.SUBSTEPS, side="right") - 1
        theta, u = tr.simulate(truth, r[held], en[held], KP, COMMAND_LIMIT, float(r[0]), state)
        truth.rest(REST_S, state)
        y = np.round(theta[ticks] / tr.ENCODER_STEP_RAD) * tr.ENCODER_STEP_RAD
        v = u[np.minimum(ticks // tr.SUBSTEPS, n - 1)]
        meta = {"kind": e["kind"], "kp": KP, "command_limit": COMMAND_LIMIT,
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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, help="output folder (one sub-folder per case)")
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help=f"seed (default {DEFAULT_SEED})")
    p.add_argument("--only", help="comma-separated case names (default: all)")
    p.add_argument("--quick", action="store_true", help="two 1.5 s runs per case (tests)")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")
    args = p.parse_args(argv)
    names = [n for n, _ in tr.CASES]
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
            _, runs, record = run_case(index, name, args.seed, quick=args.quick)
            (tmp / name).mkdir()
            for run in runs:
                write_run(tmp / name, run)
            record.update({"measured": name, "model": tr.NOMINAL_REL, "joint": tr.JOINT,
                           "actuator": tr.ACTUATOR, "runs": len(runs), "quick": args.quick})
            cases.append(record)
            print(f"{name}: {len(runs)} runs", flush=True)
        doc = {"what": "the bank's test half (bank/README.md)", "seed": args.seed,
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
