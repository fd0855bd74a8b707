"""Every effect of the library has its facts, and a new one that lacks some is named with the
list of what it lacks.

An effect's facts live in two places:

* its own file (``discrepancy/effects/<family>.py``): its one-line description, its parameters
  (unit, bounds, typical scale), its read/write/grid functions; the registry
  (``discrepancy/effects/__init__.py``, :data:`~discrepancy.effects.LIBRARY`) lists it;
* the validation bank, written independently of the library: a single-effect case
  (``bank/hidden.py``, :data:`~bank.hidden.CASES`, with its note), a truth that
  hides it (a writer in :data:`bank.omni_truths.TRUTH`, or a truth simulation of its
  own, :data:`bank.servo_truth.SIMULATED`), and for a written truth a realistic range
  for the coverage study (:data:`bank.ranges.RANGES`);
* its line in the method's page (``docs/method/discrepancy.md``, the library's paragraph and
  table).

:func:`missing_facts` lists what an effect lacks; the first test asks it of the library (the
list must be empty), the second shows that it names each missing fact of an effect added
without them.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

from bank import hidden, omni_truths, ranges, servo_truth
from discrepancy import effects as fx

ROOT = Path(__file__).resolve().parent.parent
METHOD_PAGE = ROOT / "docs" / "method" / "discrepancy.md"


def library_section(page: str) -> str:
    """The library's paragraph and table of the method's page: from ``**The library**`` to the
    first blank line after the table."""
    start = page.index("**The library**")
    table = page.index("\n|", start)
    end = page.find("\n\n", table)
    return page[start:end if end >= 0 else len(page)]


def missing_facts(effects, *, cases=hidden.CASES, truths=omni_truths.TRUTH,
                  simulated=servo_truth.SIMULATED, ranges=ranges.RANGES,
                  doc: str | None = None) -> list[str]:
    """What each effect of ``effects`` lacks, one line per missing fact (``NAME: what, where``);
    empty when every effect has all its facts.

    Parameters
    ----------
    effects : sequence of Effect
    cases : sequence of HiddenCase
        The bank's cases; an effect needs a single-effect case (one effect, nothing outside the
        library) with a note.
    truths : dict
        Truth writers of the virtual Omni (name -> writer).
    simulated : collection of str
        Effects whose truth is a simulation of its own (they need no writer and no range).
    ranges : dict
        The coverage study's realistic ranges (name -> one ``(low, high, signed)`` per parameter).
    doc : str, optional
        The library's section of the method page (default: read from ``docs/method/discrepancy.md``).
    """
    doc = library_section(METHOD_PAGE.read_text()) if doc is None else doc
    singles = {c.effects[0][0]: c for c in cases if len(c.effects) == 1 and not c.outside}
    out = []
    for e in effects:
        n = e.name
        # the effect's own file
        if not e.description.strip() or "\n" in e.description.strip():
            out.append(f"{n}: no one-line description (Effect.description, discrepancy/effects/)")
        for p in e.params:
            if not (p.unit and math.isfinite(p.lower) and math.isfinite(p.upper)
                    and p.lower < p.upper and p.scale > 0):
                out.append(f"{n}: parameter {p.name} lacks a unit, finite bounds lower < upper "
                           f"or a positive scale (Param, discrepancy/effects/)")
        # the bank
        case = singles.get(n)
        if case is None:
            out.append(f"{n}: no single-effect bank case (HiddenCase in bank/hidden.py CASES)")
        else:
            if not case.note.strip():
                out.append(f"{n}: its bank case {case.name!r} has no note (provenance of the magnitude)")
            if len(case.effects[0][1]) != e.nparam:
                out.append(f"{n}: its bank case {case.name!r} gives {len(case.effects[0][1])} values, "
                           f"the effect has {e.nparam} parameters")
        if n not in simulated:
            if n not in truths:
                out.append(f"{n}: no truth writer (bank/omni_truths.py TRUTH) and no truth "
                           "simulation of its own (bank/servo_truth.py SIMULATED)")
            if n not in ranges:
                out.append(f"{n}: no coverage range (bank/ranges.py RANGES)")
            elif len(ranges[n]) != e.nparam:
                out.append(f"{n}: its coverage range has {len(ranges[n])} entries, the effect has "
                           f"{e.nparam} parameters")
        # the method's page
        if not re.search(rf"`{re.escape(n)}`", doc):
            out.append(f"{n}: no line in docs/method/discrepancy.md's library section")
    return out


def test_every_library_effect_has_its_facts():
    missing = missing_facts(fx.LIBRARY)
    assert not missing, "library effects lack facts:\n" + "\n".join(missing)


def test_the_method_page_section_is_the_library():
    """The section :func:`missing_facts` reads is the library's paragraph and its table (a
    section that swallowed the whole page would find every name)."""
    section = library_section(METHOD_PAGE.read_text())
    assert section.startswith("**The library**") and "| effect | MJCF change | parameters |" in section
    assert "`load_friction`" in section and "## " not in section
    assert len(section) < len(METHOD_PAGE.read_text()) / 5


def test_a_new_effect_without_its_facts_is_listed():
    """An effect added to the library (its own file and a registry line) without a bank case,
    a truth, a range or a doc line: each missing fact is named.  The fake is a copy of
    ``cogging`` (two parameters) under a new name; a second fake has no description and a
    parameter without bounds."""
    gremlin = dataclasses.replace(fx.get("cogging"), name="gremlin_torque")
    assert missing_facts([gremlin]) == [
        "gremlin_torque: no single-effect bank case (HiddenCase in bank/hidden.py CASES)",
        "gremlin_torque: no truth writer (bank/omni_truths.py TRUTH) and no truth "
        "simulation of its own (bank/servo_truth.py SIMULATED)",
        "gremlin_torque: no coverage range (bank/ranges.py RANGES)",
        "gremlin_torque: no line in docs/method/discrepancy.md's library section",
    ]
    # given a case, a writer, a range and a doc line of the right sizes, it lacks nothing
    case = hidden.HiddenCase("gremlin_torque", (("gremlin_torque", (0.003, 0.5)),),
                             expect=("gremlin_torque",), note="a stated magnitude")
    complete = dict(cases=hidden.CASES + (case,), truths={**omni_truths.TRUTH, "gremlin_torque": None},
                    ranges={**ranges.RANGES, "gremlin_torque": ((0.001, 0.005, False), (-1, 1, False))},
                    doc="| `gremlin_torque` | a torque | `amplitude_nm`, `phase_rad` |")
    assert missing_facts([gremlin], **complete) == []
    # sizes that do not match the effect's parameters, a case without a note
    short = dict(complete, cases=hidden.CASES + (dataclasses.replace(case, effects=(("gremlin_torque", (0.003,)),),
                                                                     note=""),),
                 ranges={**ranges.RANGES, "gremlin_torque": ((0.001, 0.005, False),)})
    assert missing_facts([gremlin], **short) == [
        "gremlin_torque: its bank case 'gremlin_torque' has no note (provenance of the magnitude)",
        "gremlin_torque: its bank case 'gremlin_torque' gives 1 values, the effect has 2 parameters",
        "gremlin_torque: its coverage range has 1 entries, the effect has 2 parameters",
    ]
    # the effect's own file: a description and parameters with units, bounds and a scale
    bad_param = dataclasses.replace(gremlin.params[0], lower=-math.inf)
    careless = dataclasses.replace(gremlin, description="", params=(bad_param, gremlin.params[1]))
    assert missing_facts([careless], **complete) == [
        "gremlin_torque: no one-line description (Effect.description, discrepancy/effects/)",
        f"gremlin_torque: parameter {bad_param.name} lacks a unit, finite bounds lower < upper or a "
        "positive scale (Param, discrepancy/effects/)",
    ]
    # a simulated truth needs no writer and no range
    assert missing_facts([gremlin], **dict(complete, truths={}, ranges={}, simulated={"gremlin_torque"})) == []
