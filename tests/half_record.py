"""A test half's one run against its record (bank/README.md's section of it): the shared check of
tests/test_bank_test_half_2.py and tests/test_bank_test_half_3.py."""

from __future__ import annotations

import json
from pathlib import Path

from bank.test_half import score as base_score

ROOT = Path(__file__).resolve().parents[1]


def check_readme_run(record: Path, table: str, score_case) -> str:
    """bank/README.md's table ``<!-- TABLE table: ... -->`` ... ``<!-- end of TABLE table -->`` is
    made from ``record`` (the score as run and each case's report), the commit it names is the
    score's, the record's scores are what ``score_case`` says of its reports, and the wall times
    and physics steps it quotes are the reports' own.  Returns the page's text, whitespace
    flattened, for a half's own further checks."""
    text = (ROOT / "bank" / "README.md").read_text()
    a = text.index(f"<!-- {table} table:")
    made = text[text.index("\n", a) + 1:text.index(f"<!-- end of {table} table -->")]
    assert made == base_score.record_table(record)
    sc = json.loads((record / "score.json").read_text())
    assert f"at commit {sc['commit'][:7]}" in text and f"score.py --commit {sc['commit'][:7]}" in text
    cases = json.loads((record / "cases.json").read_text())["cases"]
    walls, steps = [], []
    for case, row in zip(cases, sc["cases"], strict=True):
        rep = json.loads((record / case["name"] / "report.json").read_text())
        assert score_case(case, rep)["points"] == row["points"], case["name"]
        walls.append(rep["timings"]["total_s"] / 60)
        steps.append(rep["timings"]["physics_steps"] / 1e6)
    flat = " ".join(text.split())
    assert f"{min(walls):.1f} to {max(walls):.1f} min a case" in flat
    assert (f"{min(steps):.1f} to {max(steps):.1f} M physics steps a case ({sum(steps):.0f} M for the "
            "ten") in flat
    return flat
