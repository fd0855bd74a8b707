"""README.md's results tables and quoted figures against the JSON they summarise.

``scripts/readme_tables.py`` renders the README's results tables from docs/*.json,
docs/reproduce/summary.json, docs/friction/*.json, docs/sweep/results.csv and
models/calibration*.json, and the figures its prose quotes from them; these tests fail when
the README and those files drift apart (re-run the tool that writes the file, then
``python scripts/readme_tables.py --write`` and fix the prose it lists).
"""

from __future__ import annotations

import copy
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def rt():
    spec = importlib.util.spec_from_file_location("readme_tables", ROOT / "scripts" / "readme_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def src(rt):
    return rt.load_sources()


@pytest.fixture(scope="module")
def readme():
    return (ROOT / "README.md").read_text()


def test_readme_matches_its_sources(rt, src, readme):
    assert rt.check(readme, src) == []


def test_a_changed_source_figure_is_caught(rt, src, readme):
    """One figure moved in a source file: its table, or its quoted phrase, no longer matches."""
    bad = copy.deepcopy(src)
    bad["summary"]["step"]["windows"]["whole_record"]["ratio_of_means"] += 0.01
    assert any(p.startswith("table results_targets") for p in rt.check(readme, bad))
    bad = copy.deepcopy(src)
    bad["bench"]["vector_env"]["env_steps_per_s"] *= 1.1
    assert any("Omnis at" in p for p in rt.check(readme, bad))
    bad = copy.deepcopy(src)
    bad["comparison"]["families"]["coulomb"]["C_alpha_fall"] = 1.5
    problems = rt.check(readme, bad)
    assert any(p.startswith("table families_verdict") for p in problems), problems


def test_an_edited_readme_figure_is_caught(rt, src, readme):
    """A figure typed into the README by hand (a table cell, a quoted phrase) is caught."""
    table = rt.tables(src)["families_verdict"]
    row = next(line for line in table.splitlines() if line.startswith("| step: ratio of medians linear"))
    assert row in readme
    edited = readme.replace(row, row.replace("2.69", "2.60"))
    assert [p for p in rt.check(edited, src) if "families_verdict" in p]
    phrase = "of a raw `mujoco.rollout` of the same model"
    assert phrase in readme
    i = readme.index(phrase)
    start = readme.rindex("Omnis at", 0, i)
    edited = readme[:start] + readme[start:i].replace("k steps/s", "k step/s", 1) + readme[i:]
    assert any("Omnis at" in p for p in rt.check(edited, src))


def test_write_changes_only_the_generated_blocks(rt, src, readme):
    """--write replaces a stale table between its markers and nothing else."""
    name = "sweep"
    stale = rt._block(name).sub(lambda m: m.group(1) + "| stale |" + m.group(3), readme)
    assert stale != readme
    assert rt.write(stale, src) == rt.write(readme, src)
    assert rt.write(readme, src) == readme  # the README is up to date: no change
