"""Coverage study of ``omni discrepancy``'s 95 % intervals on data with a known hidden truth
(``scripts/discrepancy_coverage.py`` is the command; :mod:`bank.writers.bank_report` draws its
figure and prints its summary).

For every effect asked for, ``n`` random magnitudes are drawn uniformly in the effect's
realistic range (:data:`bank.ranges.RANGES`, stated in the record); for each, the
independent truth model (:mod:`bank.omni_truths`, written without the effect
library) generates "measured" runs, with the encoder's quantisation and noise ("noisy") and/or
exactly ("exact": no noise, no quantisation), and the workflow fits them.  To keep the cost down
the workflow's candidates are restricted to the true effect: this measures the interval, not the
naming.  A parameter is covered when ``|fitted - truth| <= reported 95 % half-width``.

The record (``coverage.json``): the settings, every draw, per-effect and overall coverage with
Wilson 95 % intervals, the median width of the intervals relative to the truth.  A study resumes
from an earlier record with the same settings (draws already done are kept).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from identification.errors import UserError
from discrepancy import experiment_set

from bank import hidden, ranges

CONDITIONS = ("noisy", "exact")
#: Target coverage of the nominal 95 % intervals.
TARGET = 0.90


def experiments(kind: str):
    """The experiment set ``kind``: ``bank`` (the bank's runs) or ``small``."""
    if kind == "bank":
        return experiment_set.experiments()
    # a smaller set for quick checks: both poses, 2 frequencies, 1 step size, 1.2 s runs
    return experiment_set.experiments(frequencies_hz=(1.5, 3.5), step_amplitudes_rad=(0.2,), duration_s=1.2)


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion k/n."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (max(c - h, 0.0), min(c + h, 1.0))


def one_draw(effect: str, values: tuple, condition: str, seed: int, exps, jobs: int | None) -> dict:
    from discrepancy.workflow import run_discrepancy
    c = hidden.HiddenCase(f"{effect}_draw", ((effect, values),), expect=(effect,),
                          exact=condition == "exact")
    t0 = time.perf_counter()
    runs = hidden.generate(c, exps, seed=seed, jobs=jobs)
    rep = run_discrepancy(runs, None, candidates=(effect,), jobs=jobs).report
    out = {"effect": effect, "condition": condition, "seed": seed, "truth": list(values),
           "seconds": time.perf_counter() - t0, "gap_before": rep["gap_before"],
           "gap_after": rep["gap_after"], "named": [e["name"] for e in rep["effects"]]}
    e = rep["effects"][0]
    if e["name"] != effect:
        out["covered"] = None  # not named: no interval to check
        return out
    out["fitted"] = list(e["parameters"].values())
    out["half_width"] = [e["uncertainty"][p] for p in e["parameters"]]
    out["parameters"] = list(e["parameters"])
    out["terms"] = {k: list(e[k].values()) for k in e if k.startswith("standard_error")}
    out["measurement_bias"] = list(e.get("measurement_bias", {}).values())
    out["covered"] = [bool(abs(hidden.error(p, f, t)) <= h)
                      for p, f, t, h in zip(out["parameters"], out["fitted"], values, out["half_width"])]
    return out


def summarise(draws: list[dict]) -> dict:
    """Coverage per effect and condition, and overall per condition (over parameters)."""
    table: dict = {}
    for d in draws:
        key = (d["effect"], d["condition"])
        t = table.setdefault(key, {"covered": 0, "params": 0, "draws": 0, "not_named": 0,
                                   "rel_width": [], "err_over_half": []})
        t["draws"] += 1
        if d["covered"] is None:
            t["not_named"] += 1
            continue
        for p, cov, f, tr, h in zip(d["parameters"], d["covered"], d["fitted"], d["truth"], d["half_width"]):
            t["params"] += 1
            t["covered"] += int(cov)
            if tr != 0:
                t["rel_width"].append(h / abs(tr))
            t["err_over_half"].append(abs(hidden.error(p, f, tr)) / h if h > 0 else math.inf)
    per = []
    for (eff, cond), t in sorted(table.items()):
        lo, hi = wilson(t["covered"], t["params"])
        per.append({"effect": eff, "condition": cond, "draws": t["draws"], "not_named": t["not_named"],
                    "parameters_checked": t["params"], "covered": t["covered"],
                    "coverage": t["covered"] / t["params"] if t["params"] else math.nan,
                    "coverage_wilson95": [lo, hi],
                    "median_rel_half_width": float(np.median(t["rel_width"])) if t["rel_width"] else math.nan,
                    "max_err_over_half_width": float(np.max(t["err_over_half"])) if t["err_over_half"] else math.nan})
    overall = {}
    for cond in CONDITIONS:
        rows = [r for r in per if r["condition"] == cond]
        n = sum(r["parameters_checked"] for r in rows)
        k = sum(r["covered"] for r in rows)
        if n:
            rel = [w for (eff, c), t in table.items() if c == cond for w in t["rel_width"]]
            overall[cond] = {"coverage": k / n, "covered": k, "parameters_checked": n,
                             "coverage_wilson95": list(wilson(k, n)),
                             "median_rel_half_width": float(np.median(rel)) if rel else math.nan,
                             "not_named": sum(r["not_named"] for r in rows)}
    return {"per_effect": per, "overall": overall}


def effects_of(names: list[str] | None) -> list[str]:
    """The effects to study: ``names``, or every effect with a range (None or empty); a name
    without a range is a :class:`UserError`."""
    effects = names or list(ranges.RANGES)
    bad = [e for e in effects if e not in ranges.RANGES]
    if bad:
        raise UserError(f"--effects: no range for {', '.join(bad)} (known: {', '.join(ranges.RANGES)})")
    return effects


def study_settings(effects: list[str], n: int, seed: int, experiments: str) -> dict:
    """The record's settings: draws, seed, experiment set, the ranges of ``effects``."""
    return {"n": n, "seed": seed, "experiments": experiments,
            "ranges": {e: ranges.RANGES[e] for e in effects}, "range_centre": ranges.RANGE_CENTRE,
            "noise_rad": experiment_set.NOISE_RAD, "candidates": "the true effect only"}


def earlier_draws(jpath: Path, settings: dict, effects: list[str], *, seed: int, experiments: str,
                  summarise_only: bool) -> list[dict]:
    """The draws an existing ``coverage.json`` holds for ``effects`` (resumed or summarised);
    with ``summarise_only`` its seed and experiment set become ``settings``'."""
    if not jpath.exists():
        return []
    old = json.loads(jpath.read_text())
    had = old.get("settings", {})
    if summarise_only:  # summarise what is there, as it was made
        settings.update({k: had[k] for k in ("seed", "experiments") if k in had})
    elif (had.get("seed"), had.get("experiments")) != (seed, experiments):
        # its draws cannot be resumed with other settings, and are not silently dropped
        raise UserError(f"{jpath} holds draws made with --seed {had.get('seed')} --experiments "
                        f"{had.get('experiments')}; run with those, or with another --out")
    return [d for d in old.get("draws", []) if d["effect"] in effects]


def other_draws(path: str, settings: dict, draws: list[dict]) -> list[dict]:
    """The draws of another run's ``coverage.json`` (``--merge``) not already in ``draws``."""
    try:
        other = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise UserError(f"--merge {path}: {exc}") from None
    theirs = other.get("settings", {})
    if (theirs.get("seed"), theirs.get("experiments")) != (settings["seed"], settings["experiments"]):
        # draws made with another experiment set are not the same study: merged, they would be
        # labelled with this run's settings
        raise UserError(f"--merge {path} holds draws made with --seed {theirs.get('seed')} --experiments "
                        f"{theirs.get('experiments')}; this run has --seed {settings['seed']} --experiments "
                        f"{settings['experiments']}")
    have = {(d["effect"], d["condition"], d["seed"]) for d in draws}
    return [d for d in other.get("draws", []) if (d["effect"], d["condition"], d["seed"]) not in have]


def plan(effects: list[str], done: set, *, n: int, seed: int, conditions, summarise_only: bool) -> list[tuple]:
    """The draws still to make, ``(effect, values, condition, seed)``.

    Magnitudes: one generator per effect (the same draws whatever else is studied); the plan
    goes round the effects (draw 1 of every effect, then draw 2, ...), so a study stopped early
    still covers every effect."""
    values = {}
    for eff in effects:
        rng = np.random.default_rng([seed, sum(map(ord, eff))])
        values[eff] = [ranges.draw(eff, rng) for _ in range(n)]
    out = []
    for i in range(0 if summarise_only else n):
        for eff in effects:
            for cond in conditions:
                draw_seed = seed * 100_000 + i
                if (eff, cond, draw_seed) not in done:
                    out.append((eff, values[eff][i], cond, draw_seed))
    return out


def run_draws(plan: list[tuple], draws: list[dict], settings: dict, exps, jobs: int,
              save: Callable[[dict], None]) -> None:
    """Make the planned draws, appending to ``draws``; ``save`` gets the record after each (the
    caller writes it: a stopped study keeps what it did)."""
    try:
        from tqdm import tqdm
        bar = tqdm(total=len(plan), desc="coverage", unit="fit") if plan else None
    except ImportError:  # pragma: no cover
        bar = None
    for k, (eff, values, cond, seed) in enumerate(plan):
        d = one_draw(eff, values, cond, seed, exps, jobs)
        draws.append(d)
        save(dict(settings=settings, draws=draws, **summarise(draws)))
        if bar is not None:
            bar.set_postfix_str(f"{eff} {cond} {'/'.join('y' if c else 'n' for c in d['covered'] or [])}")
            bar.update()
        else:
            print(f"[{k + 1}/{len(plan)}] {eff} {cond} covered={d['covered']} {d['seconds']:.0f} s", flush=True)
    if bar is not None:
        bar.close()
