"""The results tables and quoted figures of docs/*.md against the files they summarise.

``scripts/docs_tables.py`` renders the pages' results tables from docs/bench.json,
docs/reproduce/summary.json, docs/friction/*.json, docs/sweep/results.csv,
docs/calibration_*_run.json and models/calibration*.json, and the figures their prose quotes
from them; these tests fail when a page and those files drift apart (re-run the tool that
writes the file, then ``python scripts/docs_tables.py --write`` and fix the prose it lists).
"""

from __future__ import annotations

import copy
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def dt():
    spec = importlib.util.spec_from_file_location("docs_tables", ROOT / "scripts" / "docs_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def src(dt):
    return dt.load_sources()


@pytest.fixture(scope="module")
def pages(dt):
    return dt.load_pages()


def test_pages_match_their_sources(dt, src, pages):
    assert dt.check(pages, src) == []


def test_every_table_and_phrase_has_its_page(dt, src):
    """Each generated table and each group of phrases names a page that exists."""
    assert {page for page, _ in dt.TABLES.values()} <= set(dt.PAGES)
    assert set(dt.claims(src)) <= set(dt.PAGES)
    for rel in dt.PAGES.values():
        assert (ROOT / rel).is_file(), rel


def test_a_changed_source_figure_is_caught(dt, src, pages):
    """One figure moved in a source file: its table, or its quoted phrase, no longer matches."""
    bad = copy.deepcopy(src)
    bad["summary"]["step"]["windows"]["whole_record"]["ratio_of_means"] += 0.01
    assert any(p.startswith("table results_targets") for p in dt.check(pages, bad))
    bad = copy.deepcopy(src)
    bad["bench"]["vector_env"]["env_steps_per_s"] *= 1.1
    problems = dt.check(pages, bad)
    assert any("Omnis at" in p for p in problems), problems
    assert any(p.startswith("table performance") for p in problems), problems
    bad = copy.deepcopy(src)
    bad["comparison"]["families"]["coulomb"]["C_alpha_fall"] = 1.5
    problems = dt.check(pages, bad)
    assert any(p.startswith("table families_verdict") for p in problems), problems
    bad = copy.deepcopy(src)
    bad["cal_weighted"]["achieved"]["C_alpha_fall_65_90"] = 3.0
    assert any("docs/calibration.md" in p for p in dt.check(pages, bad))


def test_an_edited_page_figure_is_caught(dt, src, pages):
    """A figure typed into a page by hand (a table cell, a quoted phrase) is caught."""
    table = dt.tables(src)["families_verdict"]
    row = next(line for line in table.splitlines() if line.startswith("| step: ratio of medians linear"))
    assert row in pages["friction"]
    edited = dict(pages, friction=pages["friction"].replace(row, row.replace("2.69", "2.60")))
    assert [p for p in dt.check(edited, src) if "families_verdict" in p]
    phrase = "of a raw `mujoco.rollout` of the same model"
    text = pages["gymnasium"]
    assert phrase in text
    i = text.index(phrase)
    start = text.rindex("Omnis at", 0, i)
    edited = dict(pages, gymnasium=text[:start] + text[start:i].replace("k steps/s", "k step/s", 1) + text[i:])
    assert any("Omnis at" in p for p in dt.check(edited, src))


def test_write_changes_only_the_generated_blocks(dt, src, pages):
    """--write replaces a stale table between its markers and nothing else."""
    name = "sweep"
    page = dt.TABLES[name][0]
    stale = dict(pages)
    stale[page] = dt._block(name).sub(lambda m: m.group(1) + "| stale |" + m.group(3), pages[page])
    assert stale[page] != pages[page]
    assert dt.write(stale, src) == dt.write(pages, src)
    assert dt.write(pages, src) == pages  # the pages are up to date: no change
