"""The hidden-effect bank's report: docs/studies/discrepancy/bank.md (the table of every case,
then the gear_efficiency case's section), the bank table of docs/method/discrepancy.md and the
writing of the records.

The bank's records (:mod:`bank.studies.discrepancy_bank` makes them, ``scripts/discrepancy_bank.py``
is the command): ``bank.json`` beside the table holds the run's settings (commit, dates, machine
load) and every case's full workflow report; ``bank_gear_efficiency.json`` the gear_efficiency
case's (a truth written in another form than the library's law).  The page and the tables are
rendered from them alone (``--markdown``, ``--table``; ``tests/test_discrepancy_bank.py`` checks
that the committed pages are exactly that).

The coverage study's record ``coverage.json`` (:mod:`bank.studies.discrepancy_coverage` makes it,
``scripts/discrepancy_coverage.py`` is the command) is written by :func:`write_coverage`, its
figure drawn by :func:`coverage_figure`.  The writers import none of the bank's studies: the
scripts hand them the studies' results.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from discrepancy.effects.family import PARENT
from omni_app.provenance import git_commit, uncommitted
from bank import hidden

#: The checkout this module runs from.
ROOT = Path(__file__).resolve().parents[2]

#: Where the bank's table and its JSON live (docs/method/discrepancy.md links them).
DEFAULT_OUT = ROOT / "docs" / "studies" / "discrepancy" / "bank.md"
#: The record of the gear_efficiency case (a truth of another form), beside the table.
EFFICIENCY_JSON = DEFAULT_OUT.with_name("bank_gear_efficiency.json")
#: The worked example with figures the bank's run writes (``--no-example``: not).
EXAMPLE_DIR = ROOT / "docs" / "studies" / "discrepancy" / "example"


def checkout_commit() -> str:
    """The checkout's commit, with the code paths that differ from it (others' work in progress
    is part of what ran)."""
    head = git_commit(short=True)
    dirty = uncommitted(("omni_sim", "identification", "discrepancy", "omni_studies", "omni_app", "bank",
                         "models", "scripts/discrepancy_bank.py"))
    if head is None or dirty is None:
        return "unknown (not a git checkout)"
    return head + (f" with uncommitted changes in {', '.join(dirty)}" if dirty else "")


def _fmt_truth(c: dict) -> str:
    truth = "; ".join(f"{n}: " + ", ".join(f"{v:g}" for v in vals) for n, vals in c["hidden"] + c["outside"])
    return (truth or "-") + (" (outside the library)" if c["outside"] else "")


def _named(rep: dict) -> list[dict]:
    return [e for e in rep["effects"] if e["name"] != "none"]


def _verdict(c: dict) -> str:
    return f"{'PASS' if c['pass'] else 'FAIL'} ({c['why']})"


def bank_row(name: str, c: dict) -> str:
    """A row of bank.md from the JSON entry of case ``name``."""
    if "report" not in c:
        return f"| {name} | CRASH | {_fmt_truth(c)} | | | | | | | | {_verdict(c)} | {c['seconds']:.0f} |"
    rep = c["report"]
    fitted = "; ".join(
        f"{e['name']}: " + ", ".join(f"{v:.4g} ± {e['uncertainty'][p]:.2g}" for p, v in e["parameters"].items())
        for e in _named(rep)) or "-"
    first = rep["effects"][0]
    mg = first.get("margin")
    return (f"| {name} | {', '.join(e['name'] for e in rep['effects'])} | {_fmt_truth(c)} | {fitted} | "
            f"{rep['gap_before']:.2e} | {rep['gap_after']:.2e} | x{rep['shrink_factor']:.1f} | "
            f"{first.get('runner_up') or '-'} | {'-' if mg is None else f'{mg:.2f}'} | "
            f"{', '.join(e.get('confidence', '-') for e in rep['effects'])} | {_verdict(c)} | {c['seconds']:.0f} |")


def _merged(cases: dict) -> str:
    """The cases run apart from the bank's run (``--merge``): ``name (commit, date, time)`` each."""
    return ", ".join(f"{n} (commit {c['commit']}, {c['started'][:10]}, {c['seconds']:.0f} s)"
                     for n, c in cases.items() if c.get("commit"))


def _other_truths(cases: dict) -> str:
    """Sentences on the cases whose truth is not the virtual Omni, and on the merged cases."""
    text = ""
    servo = [n for n, c in cases.items() if c.get("truth", "omni") == "servo"]
    if servo:
        verb = "is" if len(servo) == 1 else "are"
        text += (f" Not the Omni: {', '.join(servo)} {verb} a pendulum on a geared servo (nominal model "
                 "`models/servo_pendulum/servo_pendulum.xml`, `--joint pivot --actuator servo`) whose truth "
                 "`bank/servo_truth.py` simulates the hidden drive law (a load-"
                 "dependent or direction-dependent friction, or a firmware current limit) step by step; 12 runs of 5 s logged as a host logs a servo (~200 Hz with "
                 "jitter, the goal held between writes, torque-off spans, 4096-count encoder, servo loop "
                 "1 kHz).")
    merged = _merged(cases)
    if merged:
        text += f" Run separately and merged into this table (`--merge`): {merged}."
    return text


def bank_markdown(data: dict) -> str:
    """docs/studies/discrepancy/bank.md from the JSON."""
    meta, cases = data["meta"], data["cases"]
    # the bank run's load and time: merged cases (their own "commit") ran at another time
    load = [c["load_after"] for c in cases.values() if "load_after" in c and not c.get("commit")]
    n_pass = sum(c["pass"] for c in cases.values())
    text = [
        "# Hidden-effect bank of `omni discrepancy`", "",
        f"Run at commit {meta['commit']}, {meta['started']} to {meta.get('finished', '(running)')}, "
        f"with `{meta['command']}` on {meta['cpus']} CPU cores shared with other jobs; load average "
        f"(1 min) {meta['load_start']:.2f} at the start"
        + (f", {min(load):.2f}-{max(load):.2f} at the end of each case (mean {sum(load) / len(load):.2f})"
           if load else "") + f" (nice {meta['nice']})."
        + (f" {meta['note']}" if meta.get("note") else "") + " Every case's full report is in "
        f"`{meta['json']}` beside this file (the bank table of docs/method/discrepancy.md is made from it: "
        "`python scripts/discrepancy_bank.py --table`).", "",
        "Each truth model is the virtual Omni (`models/omni/scene.xml`) with effects written by "
        "`bank/omni_truths.py` with MuJoCo's own features, independently of the "
        "effect library the workflow searches (a test checks that the truth models and the cases do "
        "not use it, directly or through another module), at realistic magnitudes (see each case's "
        "note in `bank/hidden.py` for the "
        f"values and their provenance). It generates {meta['runs']} runs of {meta['run_s']:g} s "
        f"(sines at {meta['frequencies_hz']} Hz x {meta['amplitudes_rad']} rad and square waves of "
        f"{meta['step_amplitudes_rad']} rad at poses {meta['poses_deg']} deg) through "
        "`omni_sim.experiments.simulate`'s reference loop, encoder quantised to 15000 counts/rev "
        f"plus {meta['noise_rad']:g} rad white noise that the controller sees (`none_exact`: "
        "neither). The workflow sees only these runs and the nominal model."
        + _other_truths(cases), "",
        "Gaps are held-out RMS replay errors [rad]; ± is the reported 95 % uncertainty (Student-t "
        "factor of the k-fold jackknife times the root-sum-square of the jackknife's, the "
        "Jacobian's and the measurement process's standard errors and the optimiser's and the "
        "replay's numerical terms, plus the bootstrap's mean shift). Pass (`hidden.assess`): library "
        "cases name exactly the hidden effects, each with high confidence, each parameter list as "
        "long as the truth's, every parameter within a finite ± of the truth, held-out gap shrunk "
        ">= 3x; null cases `none`; outside-library cases `none`, or only names of the case's "
        "`expect` list (its nearest library stand-ins) with low confidence.", "",
        "| hidden | named | truth | fitted ± 95 % | gap before | gap after | shrink | runner-up | margin | "
        "confidence | result | s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
        *(bank_row(n, c) for n, c in cases.items()), "",
        f"{n_pass} of {len(cases)} cases pass; total {sum(c['seconds'] for c in cases.values()):.0f} s "
        "of wall time.", "",
    ]
    return "\n".join(text)


def _fitted_cell(c: dict) -> str:
    truth = dict((n, v) for n, v in c["hidden"])
    parts = []
    named = _named(c["report"])
    for e in named:
        t = truth.get(e["name"])
        vals = []
        for i, (p, v) in enumerate(e["parameters"].items()):
            tv = f" ({t[i]:g})" if t is not None and i < len(t) else ""
            vals.append(f"{p} {v:.4g} ± {e['uncertainty'][p]:.2g}{tv}")
        parts.append((f"{e['name']}: " if len(named) > 1 or t is None else "") + ", ".join(vals))
    return "; ".join(parts) or "—"


def readme_table(data: dict) -> str:
    """The bank table of docs/method/discrepancy.md (section "The hidden-effect bank: what it proves"),
    from the JSON."""
    rows = ["| case | named (confidence) | fitted ± 95 % (truth) | held-out gap shrink | result | time |",
            "|---|---|---|---|---|---|"]
    for name, c in data["cases"].items():
        if "report" not in c:
            rows.append(f"| {name} | crashed | — | — | {_verdict(c)} | {c['seconds']:.0f} s |")
            continue
        rep = c["report"]
        named = ", ".join(e["name"] + (f" ({e['confidence']})" if "confidence" in e else "")
                          for e in rep["effects"])
        if rep["effects"][0]["name"] == "none" and rep.get("unexplained"):
            named += ", gap flagged unexplained"
        label = name + (" (outside the library)" if c["outside"] else "")
        rows.append(f"| {label} | {named} | {_fitted_cell(c)} | ×{rep['shrink_factor']:.3g} | "
                    f"{_verdict(c)} | {c['seconds']:.0f} s |")
    meta, cases = data["meta"], data["cases"]
    load = [c["load_after"] for c in cases.values() if "load_after" in c and not c.get("commit")]
    merged = _merged(cases)
    rows += ["", f"{sum(c['pass'] for c in cases.values())} of {len(cases)} cases pass. One run at commit "
             f"{meta['commit']}, {meta['started'][:10]}: "
             f"{sum(c['seconds'] for c in cases.values() if not c.get('commit')):.0f} s "
             f"of wall time in all, one process (`--jobs {meta['jobs']}`, nice {meta['nice']}) on "
             f"{meta['cpus']} cores shared with other jobs"
             + (f" (load average {min(load):.1f}-{max(load):.1f})" if load else "") + "."
             + (f" Run separately and merged (`--merge`): {merged}." if merged else "")]
    return "\n".join(rows) + "\n"


def _fmt_fit(e: dict) -> str:
    return ", ".join(f"{p} {v:.4g} ± {e['uncertainty'][p]:.2g}" for p, v in e["parameters"].items())


def _efficiency_rounds(rep: dict) -> list[str]:
    """The search on the gear_efficiency case in words: each round's best and runner-up, the
    pair search, and where load_friction stood in the first round's prescreen."""
    lines = []
    for r in rep["rounds"]:
        line = (f"- round {r['round']}: best `{r['best']}` (share {r['share']:.3f} of the round's held-out gap "
                f"{r['gap_start_rad']:.3g} rad), runner-up `{r.get('runner_up') or '—'}`"
                + (f" ({r['runner_up_share']:.3f})" if r.get("runner_up_share") is not None else "")
                + f"; {'accepted' if r['accepted'] else 'not accepted'}")
        ps = r.get("pair_search")
        if ps:
            line += (f"; pair search: best `{ps['best']}` (share {ps['share']:.3f}, "
                     f"{'accepted' if ps['accepted'] else 'not accepted'})")
        lines.append(line)
    first = [c for c in rep["candidates"][0] if "prescreen_gap_rad" in c]
    scored = [c for c in first if c["method"] in ("one-step", "refit")]
    screen = sorted((c for c in first if not c["name"].startswith("(") and c["method"] != "equation-error"),
                    key=lambda c: c["prescreen_gap_rad"])
    shares = ("- round 1's held-out shares (of the round's gap): "
              + ", ".join(f"`{c['name']}` {c['share']:.3f}" for c in scored))
    variants = rep["rounds"][0].get("variants") or {}
    if variants:  # the friction family's variants, each confirmed; the chosen one stands in the candidates
        lines.append("- round 1's friction family (held-out gaps): "
                     + ", ".join(f"`{n}` {v['heldout_gap_rad']:.3g} rad" for n, v in variants.items() if n != "chosen")
                     + f"; kept `{variants['chosen']}` (`discrepancy.nesting.choose_variant`), which stands in "
                     "the family's place among the candidates")
    if not any(c["name"] == "load_friction" for c in screen):
        lines.append(shares + ("" if "load_friction" in variants else
                               "; `load_friction` was not among the best by equation error, so it was not replayed"))
        return lines
    rank = next(i for i, c in enumerate(screen) if c["name"] == "load_friction") + 1
    lf = screen[rank - 1]
    nth = {1: "1st", 2: "2nd", 3: "3rd"}.get(rank, f"{rank}th")
    lines.append(shares
                 + f"; `load_friction` was {nth} of {len(screen)} candidates on the prescreen (first second of each "
                 f"run: gap {lf['prescreen_gap_rad']:.3g} rad at mu_drive {lf['parameters']['mu_drive']:.3g}, "
                 f"mu_back {lf['parameters']['mu_back']:.3g}), "
                 + ("so it was fitted on all runs" if lf["method"] != "prescreen" else
                    f"below the {len(scored)} fitted on all runs"))
    return lines


def _fmt_corrections(rep: dict) -> str:
    """The nominal's corrections of a report (nominal -> fitted ± 95 %), or '' if none."""
    cs = rep.get("corrections") or []
    return "; ".join(f"{c['parameter']} {c['nominal']:.4g} -> {c['fitted']:.4g} ± {c['half_width_95']:.2g}"
                     + ("" if c.get("plausible", True) else " (implausible)") for c in cs)


def _efficiency_restricted(rec: dict) -> list[str]:
    """The diagnostic run restricted to load_friction, if the record holds it."""
    diag = rec.get("load_friction_only")
    if not diag:
        return []
    rep, meta = diag["report"], diag["meta"]
    named = ", ".join(e["name"] + (f" ({e['confidence']})" if "confidence" in e else "") for e in rep["effects"])
    fitted = "; ".join(_fmt_fit(e) for e in _named(rep))
    lf = [c for c in rep["candidates"][0] if c["name"] == "load_friction"]
    if lf:
        p = lf[0]["parameters"]
        fitted += ("; " if fitted else "") + (
            f"load_friction's held-out share {lf[0]['share']:.3f} of the gap the corrections leave, "
            f"at mu_drive {p['mu_drive']:.3g}, mu_back {p['mu_back']:.3g}")
    return ["", "**Diagnostic: `load_friction` alone** (the workflow with `load_friction` its only "
            f"candidate, `--only-load-friction`; commit {meta['commit']}, {meta['started']}, "
            f"{meta['seconds']:.0f} s): named {named}; {fitted}; held-out gap {rep['gap_before']:.3g} -> "
            f"{rep['gap_after']:.3g} rad (×{rep['shrink_factor']:.3g})"
            + ("; gap flagged unexplained" if rep.get("unexplained") else "")
            + (f"; the nominal's corrections: {_fmt_corrections(rep)}" if _fmt_corrections(rep) else "") + "."]


def _efficiency_variant_reading(rep: dict, eq: dict) -> list[str]:
    """When the first named law is a variant nested in ``load_friction`` (the case's expectation,
    set before the variants existed, asks for ``load_friction`` itself and is kept as written):
    whether each of its load coefficients' intervals holds the truth's equivalent."""
    first = rep["effects"][0]
    if PARENT.get(first["name"]) != "load_friction":
        return []
    held = [f"{k} {first['parameters'][k]:.3g} ± {first['uncertainty'][k]:.2g} "
            + ("holds" if abs(first["parameters"][k] - eq[k]) <= first["uncertainty"][k] else "misses")
            + f" {eq[k]:g}" for k in ("mu_drive", "mu_back")]
    return [f"The first named law, `{first['name']}`, is a variant nested in `load_friction` "
            "(`discrepancy/effects/family.py`); the expectation above names `load_friction` itself and "
            "is kept as written, so the verdict is a fail by its letter. Its load coefficients against "
            "the truth's equivalents: " + "; ".join(held) + ".", ""]


def efficiency_section(rec: dict) -> str:
    """The bank page's section on the gear_efficiency case, from its record (the JSON
    ``--gear-efficiency`` writes)."""
    case, rep, meta = rec["case"], rec["report"], rec["meta"]
    tr, eq = case["truth"], case["equivalent"]
    named = ", ".join(e["name"] + (f" ({e['confidence']})" if "confidence" in e else "") for e in rep["effects"])
    if rep.get("unexplained"):
        named += ", gap flagged unexplained"
    fitted = "; ".join(f"{e['name']}: {_fmt_fit(e)}" for e in _named(rep)) or "—"
    first = rep["effects"][0]
    mg = first.get("margin")
    runner = f"{first.get('runner_up') or '—'}" + ("" if mg is None else f" (margin {mg:.2f})")
    if first["name"] == "none" and first.get("best_candidate"):
        runner = (f"best candidate {first['best_candidate']} (share {first['best_share']:.3f}), "
                  f"runner-up {runner}")
    text = [
        "## A truth of another form: the gear's efficiency law (`gear_efficiency`)", "",
        "The geared-servo cases above hide the device engine's own law (a Coulomb level "
        "`Fc + mu |tau|` of the transmitted torque `tau = g u`, set into MuJoCo's `frictionloss`: "
        "a hard stick). This case's truth (`bank/servo_truth.py`, "
        "`simulate_efficiency`) writes the same servo's gearbox losses in another form, in plain "
        "code of its own: the mesh torque `tau_m = g u - c_e w - J_r a` (the winding's torque less "
        "its back-EMF `c_e = kt g` and its rotor's inertia `J_r`, the model's armature, times the "
        "previous step's acceleration), a loss `(1 - eta_drive) |tau_m|` while the motor drives "
        "the load and `(1/eta_back - 1) |tau_m|` while the load back-drives the motor, acting "
        "against the motion through a smooth sign `tanh(w / w_s)` (no stick: the loss vanishes at "
        "rest; applied linearly implicitly at each 1 ms step). "
        f"Truth: eta_drive {tr['eta_drive']:.4g}, eta_back {tr['eta_back']:.4g} (the load_friction "
        f"case's efficiencies: mu_drive {eq['mu_drive']:g}, mu_back {eq['mu_back']:g} in the "
        f"engine's form), w_s {tr['smooth_speed_rad_s']:g} rad/s (an estimate), kt "
        f"{tr['kt_nm_per_a']:g} N*m/A; provenance of each in servo_truth.py. The nominal model "
        "`models/servo_pendulum/servo_pendulum.xml`; the load_friction case's 12 runs of 5 s, log and encoder. "
        "`tests/test_servo_truth.py` checks the truth against steady speeds in closed form "
        "(driving and back-driven) and the law step by step.", "",
        "Where the two forms differ (by construction, whatever the workflow does): the truth does not "
        "stick (its loss vanishes at rest, where the engine's law holds the joint up to `Fc + mu |tau|`); "
        "its mesh carries the back-EMF's torque, so the torque-off falls (0 V, the winding shorted) "
        "lose `(1/eta_back - 1) c_e |w|` in the mesh, which the engine's law (`tau = g u = 0` there) "
        "cannot give, and a part of every loss is proportional to the speed, as a viscous damping is; "
        "the rotor's inertia torque passes the mesh too.", "",
        f"What a correct workflow should do (stated before the run): {case['expect']}.", "",
        "| named (confidence) | fitted ± 95 % | gap before | gap after | shrink | noise floor | "
        "candidates | result | time |",
        "|---|---|---|---|---|---|---|---|---|",
        f"| {named} | {fitted} | {rep['gap_before']:.3g} rad | {rep['gap_after']:.3g} rad | "
        f"×{rep['shrink_factor']:.3g} | {rep['noise_floor_rad']:.3g} rad | {runner} | "
        f"{'PASS' if rec['pass'] else 'FAIL'} ({rec['why']}) | {meta['seconds']:.0f} s |", "",
        *([f"The nominal's corrections (refitted with the named effects, reported apart): "
           f"{_fmt_corrections(rep)}.", ""] if _fmt_corrections(rep) else []),
        *_efficiency_variant_reading(rep, eq),
        "The search, round by round (from the report):", "", *_efficiency_rounds(rep),
        *_efficiency_restricted(rec), "",
        *([] if rec["pass"] else ["`tests/test_discrepancy_bank.py` runs the case as a strict expected "
                                  "failure (`test_bank_gear_efficiency`) with these figures in its reason.", ""]),
        f"Run at commit {meta['commit']}, {meta['started']} to {meta['finished']}, with "
        f"`{meta['command'].split(' --note')[0]}` on {meta['cpus']} CPU cores shared with other jobs (load average "
        f"{meta['load_start']:.2f} at the start, {meta['load_after']:.2f} at the end; nice "
        f"{meta['nice']})." + (f" {meta['note']}" if meta.get("note") else "")
        + f" The full report is in `{EFFICIENCY_JSON.name}` beside this file.",
    ]
    return "\n".join(text) + "\n"


def bank_page(data: dict, out: Path) -> str:
    """The bank's page: the table of the bank's JSON, then the gear_efficiency section if its
    record lies beside ``out``."""
    page = bank_markdown(data)
    rec = out.with_name(EFFICIENCY_JSON.name)
    if rec.is_file():
        page += "\n" + efficiency_section(json.loads(rec.read_text()))
    return page



def write_bank(out: Path, data: dict) -> None:
    """The bank's JSON beside ``out`` (replaced whole: a stopped run keeps what it did), then
    the page ``out``."""
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, default=str) + "\n")
    tmp.replace(out.with_suffix(".json"))
    out.write_text(bank_page(data, out))


def write_efficiency(out: Path, bank_json: Path, rec: dict) -> None:
    """The gear_efficiency case's record beside ``out``, then the page ``out`` from the bank's
    JSON ``bank_json`` and that record."""
    out.with_name(EFFICIENCY_JSON.name).write_text(json.dumps(rec, indent=1, default=str) + "\n")
    out.write_text(bank_page(json.loads(Path(bank_json).read_text()), out))


def write_example(ex_dir: Path = EXAMPLE_DIR) -> None:
    """The worked example of ``omni discrepancy`` with figures and the measured runs its report
    names (``measured/``: what ``omni discrepancy --demo --out`` writes)."""
    from omni_app.discrepancy import demo

    demo(ex_dir, force=True)


def write_coverage(jpath: Path, res: dict) -> None:
    """The coverage study's record ``jpath`` (replaced whole: a stopped study keeps what it did)."""
    tmp = jpath.with_suffix(".tmp")
    tmp.write_text(json.dumps(res, indent=1) + "\n")
    tmp.replace(jpath)


def coverage_figure(summary: dict, draws: list[dict], path: Path, conditions: tuple[str, ...],
                    target: float) -> None:
    """The coverage study's figure: coverage per effect and condition with its Wilson interval
    (``conditions`` in their order, ``target`` the line to reach), and every parameter's
    |fitted - truth| / half-width."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    effects = sorted({r["effect"] for r in summary["per_effect"]})
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(max(7.0, 0.75 * len(effects) + 2), 7.5), sharex=True)
    w = 0.38
    for i, cond in enumerate(conditions):
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
    a1.axhline(target, color="r", lw=0.8, ls="--", label=f"target {target:.0%}")
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


def print_coverage_summary(summary: dict) -> None:
    """The coverage study's summary on stdout: a line per effect and condition, then per condition."""
    for r in summary["per_effect"]:
        print(f"{r['effect']:18s} {r['condition']:6s} coverage {r['coverage']:.0%} "
              f"({r['covered']}/{r['parameters_checked']}, not named {r['not_named']}) "
              f"median half-width/truth {r['median_rel_half_width']:.2e}")
    for cond, o in summary["overall"].items():
        print(f"overall {cond}: {o['coverage']:.1%} ({o['covered']}/{o['parameters_checked']}), "
              f"Wilson 95 % [{o['coverage_wilson95'][0]:.2f}, {o['coverage_wilson95'][1]:.2f}], "
              f"median half-width/truth {o['median_rel_half_width']:.2e}")
