"""Score ``omni discrepancy`` reports on the test half against its expectations.

Usage::

    python -m bank.test_half.score DATA/cases.json REPORTS --commit SHA [--out score.json]
        [--families names.json]

``REPORTS/<case>/report.json`` is each case's report.  The library's effect names are put
into physics families by keywords (:data:`FAMILY_KEYWORDS`, written from the candidate names
the one null-case run printed; ``--families`` maps further names), and each case gets four
points (bank/README.md, "Make, run once, score"): family, no spurious second effect,
direction, unexplained.  A point that cannot be read from the report is ``None``
(unchecked), never passed.

The report keys read: ``effects[].name``/``parameters`` (``"none"`` when nothing is named),
``unexplained``, ``effects[].reason`` (its text), ``where`` (the maps of where the gap
lives), ``corrections[]`` (``effect``, ``ratio_to_nominal``), ``settings.candidates``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

#: Keyword (in a library effect's name) -> physics family; the first match wins.
FAMILY_KEYWORDS = (
    ("load", "friction: load-dependent"), ("efficien", "friction: load-dependent"),
    ("stribeck", "friction: stribeck"), ("presliding", "friction: dynamic"),
    ("lugre", "friction: dynamic"), ("asym", "friction: asymmetric"),
    ("thermal", "friction: drifting"), ("temperat", "friction: drifting"),
    ("drift", "friction: drifting"), ("coulomb", "friction: coulomb"),
    ("viscous", "friction: viscous"), ("backlash", "backlash"), ("stop", "end_stop"),
    ("wall", "end_stop"), ("joint_limit", "end_stop"), ("compliance", "drive compliance"),
    ("saturation", "torque saturation"), ("current_limit", "torque saturation"),
    ("torque_gain", "torque gain"), ("delay", "time delay"), ("lag", "time delay"),
    ("armature", "inertia"), ("bias", "torque bias"),
)


def family_of(name: str, extra: dict | None = None, keywords: tuple = FAMILY_KEYWORDS) -> str:
    """The physics family of a library effect name (``"other"`` when no keyword matches):
    ``extra``'s, else the first of ``keywords`` (pairs ``(keyword, family)``, this half's table
    by default; a later half passes its own) found in the name."""
    if extra and name in extra:
        return extra[name]
    low = name.lower()
    for key, fam in keywords:
        if key in low:
            return fam
    return "other"


def _param(params: dict, *keys: str, avoid: tuple = ()) -> float | None:
    """The first parameter whose name contains one of ``keys`` (and none of ``avoid``)."""
    for name, val in params.items():
        low = name.lower()
        if any(k in low for k in keys) and not any(a in low for a in avoid):
            return float(val)
    return None


def check_signs(signs: dict, params: dict, corrections: list) -> dict:
    """Each direction claim: True, False, or None (not readable from the report)."""
    out = {}
    for claim, want in signs.items():
        ok = None
        if claim == "driving_vs_back_driven":
            d, b = _param(params, "drive"), _param(params, "back")
            if d is not None and b is not None:
                ok = {"driving larger": d > b, "back-driven larger": b > d,
                      "equal": b > 0 and d > 0 and 2 / 3 <= d / b <= 3 / 2}[want]
        elif claim == "static_above_kinetic":
            s, k = _param(params, "fs"), _param(params, "fc")
            if s is not None and k is not None:
                ok = (s > k) == want
        elif claim == "coulomb_vs_nominal":
            ratio = [c["ratio_to_nominal"] for c in corrections
                     if "coulomb" in str(c.get("effect", "")) and c.get("ratio_to_nominal") is not None]
            if ratio:
                ok = (ratio[0] > 1) == (want == "higher")
        elif claim == "direction_larger":
            p, n = _param(params, "pos", "plus"), _param(params, "neg", "minus")
            if p is not None and n is not None:
                ok = (p > n) == (want == "positive")
        elif claim == "side":
            a = _param(params, "angle", "stop", "limit")
            if a is not None:
                ok = (a > 0) == (want == "positive")
        elif claim == "angle_rad":
            a = _param(params, "angle", "stop", "limit")
            if a is not None:
                ok = abs(a - want) <= 0.1
        elif claim == "gap_rad":
            g = _param(params, "gap", "width", "play", "backlash")
            if g is not None:   # total play or half of it, within a factor 2
                ok = want / 4 <= g <= 2 * want
        elif claim == "torque_bound_nm":
            t = _param(params, "limit", "max", "sat", "bound")
            if t is not None:   # in N m, or in the command's volts (torque / (kt/R) = i_max R)
                ok = abs(t - want) <= 0.3 * want or abs(t - want / 0.30) <= 0.3 * want / 0.30
        elif claim == "bound_vs_stall":
            t = _param(params, "limit", "max", "sat", "bound")
            if t is not None:
                ok = t < 3.6 or (3.6 < t < 12.0 and want == "below")
        out[claim] = ok
    return out


def score_case(case: dict, report: dict, extra: dict | None = None) -> dict:
    """The four points of one case (True, False, or None = unchecked)."""
    exp = case["expected"]
    named = [e for e in report.get("effects", []) if e.get("name") not in (None, "none")]
    fams = [family_of(e["name"], extra) for e in named]
    library = list(report.get("settings", {}).get("candidates", [])) + \
        [c.get("effect", "") for c in report.get("corrections", [])]
    expressible = any(family_of(n, extra) in exp["accept"] for n in library)
    flag = bool(report.get("unexplained"))
    text = " ".join(str(e.get("reason", "")) for e in report.get("effects", []))
    text_flag = "UNEXPLAINED" in text
    maps = bool(report.get("where"))
    want_unexplained = exp["family"] == "unexplained" or (exp["family"] != "none" and not expressible)

    if exp["family"] == "none":
        family_ok = not named
    elif not expressible:          # the library has no law of this family: flag it
        family_ok = (not named and flag) or any(f in exp["accept"] for f in fams)
    else:
        family_ok = bool(fams) and fams[0] in exp["accept"]
    partial = bool(fams) and fams[0] in exp["partial"]
    spurious_ok = len([f for f in fams[1:] if f not in exp["accept"]]) == 0
    params = named[0].get("parameters", {}) if named else {}
    signs = check_signs(exp["signs"], params, report.get("corrections", [])) if named or \
        "coulomb_vs_nominal" in exp["signs"] else {k: None for k in exp["signs"]}
    readable = [v for v in signs.values() if v is not None]
    direction_ok = (all(readable) if readable else None) if exp["signs"] else True
    if want_unexplained:
        unexplained_ok = flag and maps
    else:
        unexplained_ok = (not flag) or exp["unexplained_ok"]
    return {"case": case["name"], "expected_family": exp["family"], "named": [e["name"] for e in named],
            "named_families": fams, "library_can_express": expressible,
            "unexplained_flag": flag, "reason_text_says_unexplained": text_flag,
            "flag_and_text_disagree": flag != text_flag, "maps": maps,
            "points": {"family": family_ok, "no_spurious": spurious_ok, "direction": direction_ok,
                       "unexplained": unexplained_ok},
            "partial_family": partial, "signs": signs}


def record_table(record: Path) -> str:
    """The table of a test half's one run (bank/README.md) made from its record folder: its
    ``score.json`` and each case's ``report.json``, a row a case and the totals."""
    sc = json.loads((record / "score.json").read_text())
    mark = {True: "yes", False: "**no**", None: "unchecked"}
    rows = ["| case | expected | named (confidence) | held-out gap [rad] | family | no spurious | direction | unexplained |",
            "|---|---|---|---|---|---|---|---|"]
    for c in sc["cases"]:
        rep = json.loads((record / c["case"] / "report.json").read_text())
        named = ", ".join(f"`{e['name']}` ({e.get('confidence')})" for e in rep["effects"] if e["name"] != "none")
        named = (named or "none") + ("; flagged unexplained" if c["unexplained_flag"] else "")
        p = c["points"]
        rows.append(f"| `{c['case']}` | {c['expected_family']} | {named} | {rep['gap_before']:.2e} → "
                    f"{rep['gap_after']:.2e} | {mark[p['family']]} | {mark[p['no_spurious']]} | "
                    f"{mark[p['direction']]} | {mark[p['unexplained']]} |")
    t = sc["totals"]
    rows += ["", (f"Totals ({sc['n_cases']} cases): family {t['family']}, no spurious second effect "
                  f"{t['no_spurious']}, direction {t['direction']} (the others unchecked or wrong), "
                  f"unexplained {t['unexplained']}.")]
    return "\n".join(rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    return cli(argv, score_case, "bank.test_half.make", __doc__.split("\n\n")[0])


def cli(argv: list[str] | None, scorer, maker: str, description: str) -> int:
    """The command line of a test half's ``score`` (:func:`main`'s): ``scorer(case, report,
    extra)`` scores one case, ``maker`` names the module that wrote the cases."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("cases", help=f"cases.json written by {maker}")
    p.add_argument("reports", help="folder with one sub-folder per case holding report.json")
    p.add_argument("--commit", required=True, help="the commit the reports were made at")
    p.add_argument("--families", help="JSON object: library effect name -> physics family")
    p.add_argument("--out", help="write the scores here (default: stdout)")
    args = p.parse_args(argv)
    try:
        cases = json.loads(Path(args.cases).read_text())["cases"]
        extra = json.loads(Path(args.families).read_text()) if args.families else None
    except (OSError, ValueError, KeyError) as exc:
        print(f"error: {args.cases}: cannot read the cases ({exc}); give the cases.json make.py wrote",
              file=sys.stderr)
        return 2
    missing = [c["name"] for c in cases if not (Path(args.reports) / c["name"] / "report.json").is_file()]
    if missing:
        print(f"error: {args.reports}/{missing[0]}/report.json missing; run omni discrepancy on "
              f"every case first ({len(missing)} missing)", file=sys.stderr)
        return 2
    rows = [scorer(c, json.loads((Path(args.reports) / c["name"] / "report.json").read_text()), extra)
            for c in cases]
    totals = {k: sum(1 for r in rows if r["points"][k] is True) for k in rows[0]["points"]}
    doc = {"commit": args.commit, "cases": rows, "totals": totals, "n_cases": len(rows)}
    text = json.dumps(doc, indent=2, sort_keys=True) + "\n"
    if args.out:
        Path(args.out).write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
