"""Coverage study of ``omni discrepancy``'s 95 % intervals on data with a known hidden truth.

For every effect asked for, ``--n`` random magnitudes are drawn uniformly in the effect's
realistic range (:data:`omni_sim.discrepancy.bank.RANGES`, stated in the output); for each, the
independent truth model (:mod:`omni_sim.discrepancy.truth_models`, written without the effect
library) generates "measured" runs, with the encoder's quantisation and noise ("noisy") and/or
exactly ("exact": no noise, no quantisation), and the workflow fits them.  To keep the cost down
the workflow's candidates are restricted to the true effect: this measures the interval, not the
naming.  A parameter is covered when ``|fitted - truth| <= reported 95 % half-width``.

Writes ``coverage.json`` (every draw, per-effect and overall coverage with Wilson 95 % intervals,
the median width of the intervals relative to the truth) and ``coverage.png`` to ``--out``;
resumes from an existing ``coverage.json`` with the same settings (draws already done are kept).

Usage: python scripts/discrepancy_coverage.py [--effects NAME ...] [--n 20] [--seed 0]
       [--conditions noisy exact] [--out docs/studies/discrepancy] [--jobs 1] [--experiments bank|small]
       [--merge OTHER/coverage.json ...]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from identification.errors import UserError
from omni_sim.discrepancy import bank, experiment_set, hidden

ROOT = Path(__file__).resolve().parent.parent

CONDITIONS = ("noisy", "exact")
#: Target coverage of the nominal 95 % intervals.
TARGET = 0.90


def _experiments(kind: str):
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
    from omni_sim.discrepancy.workflow import run_discrepancy
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


def figure(summary: dict, draws: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    effects = sorted({r["effect"] for r in summary["per_effect"]})
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(max(7.0, 0.75 * len(effects) + 2), 7.5), sharex=True)
    w = 0.38
    for i, cond in enumerate(CONDITIONS):
        rows = {r["effect"]: r for r in summary["per_effect"] if r["condition"] == cond}
        xs = [j + (i - 0.5) * w for j, e in enumerate(effects) if e in rows]
        if not xs:
            continue
        cov = [rows[e]["coverage"] for e in effects if e in rows]
        lo = [max(rows[e]["coverage"] - rows[e]["coverage_wilson95"][0], 0.0) for e in effects if e in rows]
        hi = [max(rows[e]["coverage_wilson95"][1] - rows[e]["coverage"], 0.0) for e in effects if e in rows]
        a1.bar(xs, cov, w, yerr=[lo, hi], capsize=2, label=f"{cond} (overall "
               f"{summary['overall'].get(cond, {}).get('coverage', math.nan):.1%})",
               color=("C0", "C1")[i])
        for d in draws:
            if d["condition"] != cond or d["covered"] is None or d["effect"] not in effects:
                continue
            j = effects.index(d["effect"]) + (i - 0.5) * w
            for p, f, t, h in zip(d["parameters"], d["fitted"], d["truth"], d["half_width"]):
                r = abs(hidden.error(p, f, t)) / h if h > 0 else np.inf
                a2.plot(j + np.random.default_rng(hash((f, t)) % 2**32).uniform(-0.12, 0.12),
                        max(r, 1e-3), ".", color=("C0", "C1")[i], ms=4, alpha=0.7)
    a1.axhline(0.95, color="k", lw=0.8, ls=":", label="nominal 95 %")
    a1.axhline(TARGET, color="r", lw=0.8, ls="--", label=f"target {TARGET:.0%}")
    a1.set_ylim(0, 1.05)
    a1.set_ylabel("empirical coverage")
    a1.legend(fontsize=8, loc="lower left")
    a1.set_title("95 % intervals of omni discrepancy on random hidden magnitudes (bank truth)")
    a2.axhline(1.0, color="r", lw=0.8, ls="--")
    a2.set_yscale("log")
    a2.set_ylabel("|fitted - truth| / half-width")
    a2.set_xticks(range(len(effects)))
    a2.set_xticklabels(effects, rotation=35, ha="right", fontsize=8)
    a2.text(0.01, 0.97, "below the line: covered", transform=a2.transAxes, va="top", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 epilog="Ranges of the random magnitudes: omni_sim/discrepancy/bank.py RANGES.")
    ap.add_argument("--effects", nargs="*", default=None,
                    help="library effects to study (default: every effect with a range)")
    ap.add_argument("--n", type=int, default=20, help="random magnitudes per effect (default 20)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the magnitudes and of the noise")
    ap.add_argument("--conditions", nargs="*", default=list(CONDITIONS), choices=CONDITIONS,
                    help="noisy: quantised encoder + 1e-4 rad noise; exact: neither")
    ap.add_argument("--out", default=str(ROOT / "docs" / "studies" / "discrepancy"), help="output folder")
    ap.add_argument("--experiments", default="bank", choices=("bank", "small"),
                    help="bank: the bank's 16 runs of 2 s; small: 10 runs of 1.2 s")
    ap.add_argument("--jobs", type=int, default=1, help="rollout threads (default 1)")
    ap.add_argument("--summarise-only", action="store_true",
                    help="no new draws: summarise the draws in --out's coverage.json (and --merge)")
    ap.add_argument("--merge", nargs="*", default=[],
                    help="coverage.json files of other runs (e.g. one per condition run in "
                         "parallel) whose draws are added before the summary")
    return ap


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        effects = args.effects or list(bank.RANGES)
        bad = [e for e in effects if e not in bank.RANGES]
        if bad:
            raise UserError(f"--effects: no range for {', '.join(bad)} (known: {', '.join(bank.RANGES)})")
        if args.n < 1:
            raise UserError("--n must be at least 1")
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        jpath = out / "coverage.json"
        settings = {"n": args.n, "seed": args.seed, "experiments": args.experiments,
                    "ranges": {e: bank.RANGES[e] for e in effects}, "range_centre": bank.RANGE_CENTRE,
                    "noise_rad": experiment_set.NOISE_RAD, "candidates": "the true effect only"}
        draws = _earlier_draws(jpath, args, settings, effects)
        for f in args.merge:
            draws += _other_draws(f, settings, draws)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    t_all = time.perf_counter()
    done = {(d["effect"], d["condition"], d["seed"]) for d in draws}
    _run(_plan(args, effects, done), draws, settings, jpath, _experiments(args.experiments), args.jobs)
    summary = summarise(draws)
    res = dict(settings=settings, draws=draws, **summary)
    jpath.write_text(json.dumps(res, indent=1) + "\n")
    figure(summary, draws, out / "coverage.png")
    _print_summary(summary)
    print(f"wrote {jpath} and {out / 'coverage.png'} ({time.perf_counter() - t_all:.0f} s)")
    ok = all(o["coverage"] >= TARGET for o in summary["overall"].values())
    return 0 if ok else 1


def _earlier_draws(jpath: Path, args, settings: dict, effects: list[str]) -> list[dict]:
    """The draws an existing ``coverage.json`` holds for ``effects`` (resumed or summarised);
    with ``--summarise-only`` its seed and experiment set become ``settings``'."""
    if not jpath.exists():
        return []
    old = json.loads(jpath.read_text())
    had = old.get("settings", {})
    if args.summarise_only:  # summarise what is there, as it was made
        settings.update({k: had[k] for k in ("seed", "experiments") if k in had})
    elif (had.get("seed"), had.get("experiments")) != (args.seed, args.experiments):
        # its draws cannot be resumed with other settings, and are not silently dropped
        raise UserError(f"{jpath} holds draws made with --seed {had.get('seed')} --experiments "
                        f"{had.get('experiments')}; run with those, or with another --out")
    return [d for d in old.get("draws", []) if d["effect"] in effects]


def _other_draws(path: str, settings: dict, draws: list[dict]) -> list[dict]:
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


def _plan(args, effects: list[str], done: set) -> list[tuple]:
    """The draws still to make, ``(effect, values, condition, seed)``.

    Magnitudes: one generator per effect (the same draws whatever else is studied); the plan
    goes round the effects (draw 1 of every effect, then draw 2, ...), so a study stopped early
    still covers every effect."""
    values = {}
    for eff in effects:
        rng = np.random.default_rng([args.seed, sum(map(ord, eff))])
        values[eff] = [bank.draw(eff, rng) for _ in range(args.n)]
    plan = []
    for i in range(0 if args.summarise_only else args.n):
        for eff in effects:
            for cond in args.conditions:
                seed = args.seed * 100_000 + i
                if (eff, cond, seed) not in done:
                    plan.append((eff, values[eff][i], cond, seed))
    return plan


def _run(plan: list[tuple], draws: list[dict], settings: dict, jpath: Path, exps, jobs: int) -> None:
    """Make the planned draws, appending to ``draws``; ``jpath`` is rewritten after each (a
    stopped study keeps what it did)."""
    try:
        from tqdm import tqdm
        bar = tqdm(total=len(plan), desc="coverage", unit="fit") if plan else None
    except ImportError:  # pragma: no cover
        bar = None
    for k, (eff, values, cond, seed) in enumerate(plan):
        d = one_draw(eff, values, cond, seed, exps, jobs)
        draws.append(d)
        res = dict(settings=settings, draws=draws, **summarise(draws))
        tmp = jpath.with_suffix(".tmp")
        tmp.write_text(json.dumps(res, indent=1) + "\n")
        tmp.replace(jpath)
        if bar is not None:
            bar.set_postfix_str(f"{eff} {cond} {'/'.join('y' if c else 'n' for c in d['covered'] or [])}")
            bar.update()
        else:
            print(f"[{k + 1}/{len(plan)}] {eff} {cond} covered={d['covered']} {d['seconds']:.0f} s", flush=True)
    if bar is not None:
        bar.close()


def _print_summary(summary: dict) -> None:
    for r in summary["per_effect"]:
        print(f"{r['effect']:18s} {r['condition']:6s} coverage {r['coverage']:.0%} "
              f"({r['covered']}/{r['parameters_checked']}, not named {r['not_named']}) "
              f"median half-width/truth {r['median_rel_half_width']:.2e}")
    for cond, o in summary["overall"].items():
        print(f"overall {cond}: {o['coverage']:.1%} ({o['covered']}/{o['parameters_checked']}), "
              f"Wilson 95 % [{o['coverage_wilson95'][0]:.2f}, {o['coverage_wilson95'][1]:.2f}], "
              f"median half-width/truth {o['median_rel_half_width']:.2e}")


if __name__ == "__main__":
    raise SystemExit(main())
