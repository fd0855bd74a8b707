"""The results tables and quoted figures of docs/**/*.md against the files they summarise.

``scripts/docs_tables.py`` renders the pages' results tables from docs/reference/bench.json,
docs/studies/reproduce/summary.json, docs/studies/friction/*.json, docs/studies/sweep/results.csv,
docs/studies/calibration/calibration_*_run.json and models/omni/calibration*.json, and the figures their prose quotes
from them and from docs/studies/haptics/zwidth_ideal.json and examples/real_servo/report/report.json;
these tests fail when a page and those files drift apart (re-run the tool that writes the
file, then ``python scripts/docs_tables.py --write`` and fix the prose it lists), and when a
figure of the README's haptics section or real-servo paragraph is checked against no record.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def dt():
    from tools import docs_tables
    return docs_tables


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
    assert any("docs/studies/calibration/calibration.md" in p for p in dt.check(pages, bad))


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


# -- the README's haptics and real-servo passages -----------------------------------------------
def _bump(figure: str) -> str:
    """The figure with its last digit changed (a count in words: the next one)."""
    words = ["two", "three", "four", "five", "six", "seven", "eight", "nine", "ten", "eleven", "twelve"]
    if figure.lower() in words:
        return words[(words.index(figure.lower()) + 1) % len(words)]
    return figure[:-1] + str((int(figure[-1]) + 1) % 10)


def test_every_figure_of_the_record_passages_is_checked(dt, src, pages):
    """Each figure of the README's haptics section and real-servo paragraph, edited by hand
    (its last digit changed), makes the check report a problem it did not report before."""
    before = set(dt.check(pages, src))
    text = pages["readme"]
    n = 0
    for key in dt.RECORD_PASSAGES["readme"]:
        i, j = dt.passage_span(text, key)
        for m in dt.FIGURE.finditer(dt.mask(text[i:j])):
            a, b = i + m.start(), i + m.end()
            edited = dict(pages, readme=text[:a] + _bump(m.group()) + text[b:])
            assert set(dt.check(edited, src)) - before, f"an edited {m.group()!r} at {text[a - 40:b + 20]!r}"
            n += 1
    assert n >= 6  # at least the servo rate, the Z-width bound, the servo's gap, ratio and runs


def test_a_figure_typed_into_a_record_passage_is_caught(dt, src, pages):
    """A new figure without a record in the real-servo paragraph is reported as unchecked."""
    text = pages["readme"]
    i, j = dt.passage_span(text, "(examples/real_servo/README.md)")
    para = text[i:j]
    edited = dict(pages, readme=text[:i] + para.replace("noise floor)", "noise floor, in 12 s)") + text[j:])
    assert any("figure '12'" in p for p in dt.check(edited, src))


def test_a_changed_servo_or_zwidth_record_is_caught(dt, src, pages):
    before = set(dt.check(pages, src))
    bad = copy.deepcopy(src)
    bad["real_servo"]["noise_floor_rad"] *= 1.05
    new = set(dt.check(pages, bad)) - before
    assert any("README.md" in p for p in new) and any("examples/real_servo/README.md" in p for p in new), new
    bad = copy.deepcopy(src)
    bad["real_servo"]["timings"]["total_s"] += 10
    assert any("timings.total_s" in p for p in set(dt.check(pages, bad)) - before)
    bad = copy.deepcopy(src)
    k = bad["zwidth_ideal"]["boundary_stiffness"]
    last = max(i for i, x in enumerate(k) if x is not None)
    k[last] *= 1.5  # the last row's error grows by half its bound
    assert any("Z-width" in p for p in set(dt.check(pages, bad)) - before)


def test_the_zwidth_rule_reads_the_record(dt, src):
    """The Z-width sentence is checked whatever its wording: a percentage "up to x b" is the
    worst error of those rows, "at x b" that row's; the others, smallest first, the worst
    errors over all rows but the last m - 1, ..., all rows."""
    rec = src["zwidth_ideal"]
    errs = dt.zwidth_row_errors(rec)
    assert len(errs) > 2 and f"{errs[0]:.1f}" != f"{max(errs[:-1]):.1f}"

    def problems(within, last, near="near 0"):
        text = (f"the map follows Colgate & Schenkel's bound within {within} % ({last} % on the last "
                f"row below b, where the bound is {near}); more text.")
        return dt.zwidth_bound(text, rec)[0]

    good = (f"{max(errs[:-1]):.1f}", f"{errs[-1]:.1f}")
    assert problems(*good) == []
    assert problems(f"{errs[0]:.1f}", good[1])  # the B = 0 row's error is no bound for the rest
    assert problems(good[0], f"{errs[-1] + 1:.1f}")
    assert dt.zwidth_bound(f"Colgate's bound within {good[1]} %.", rec)[0] == []  # one bound for all
    assert dt.zwidth_bound(f"Colgate's bound within {good[0]} %.", rec)[0]
    rows = [B / rec["physical_damping"] for B, k, c in zip(rec["damping"], rec["boundary_stiffness"],
                                                           rec["colgate_stiffness"]) if k is not None and c > 0]
    upto, last = f"{rows[-2]:.2f}", f"{rows[-1]:.2f}"
    assert dt.zwidth_bound(f"Colgate's bound within {good[0]} % up to {upto} b ({good[1]} % at {last} b).",
                           rec)[0] == []
    early = f"{max(errs[:3]):.1f}"  # the worst of the first three rows: no bound up to the last but one
    assert early != good[0] and dt.zwidth_bound(f"Colgate's bound within {early} % up to {upto} b.", rec)[0]
    assert dt.zwidth_bound(f"Colgate's bound within {good[1]} % at {rows[-1] + 0.5:.2f} b.", rec)[0]
    far = copy.deepcopy(rec)
    c = far["colgate_stiffness"]
    last = max(i for i, (k, x) in enumerate(zip(far["boundary_stiffness"], c)) if k is not None and x > 0)
    c[last] = 0.9 * c[last - 1]  # the last bound no longer near 0
    assert any("not near 0" in p for p in dt.zwidth_bound("Colgate's bound, near 0.", far)[0])


def test_derived_figures_follow_their_records(dt, src):
    """The README's "N× better than the real Omni's" and the Coulomb all-free run's starting cost
    are rendered from their records (they were typed-in literals)."""
    bad = copy.deepcopy(src)
    t11 = bad["comparison"]["families"]["lugre"]["step_linear_vs_table11"]
    t11["median_over_poses_rad"] /= 2
    ratio = t11["paper_median_over_poses_rad"] / t11["median_over_poses_rad"]
    assert any(c.startswith(f"{ratio:.1f}× better than the real Omni's") for c in dt.claims(bad)["readme"])
    bad = copy.deepcopy(src)
    bad["cal_coulomb_all_free"]["cost_before"] += 5
    cost = bad["cal_coulomb_all_free"]["cost_before"]
    assert any(c.startswith(f"{cost:.1f} → ") for c in dt.claims(bad)["friction"])


def test_the_servo_example_describes_its_model(dt, src, pages):
    """The example's model table and actuator paragraph follow its model.xml: the back-EMF
    described as joint damping, or moved back there in the model, is caught."""
    before = set(dt.check(pages, src))
    row = "| back-EMF (the actuator's velocity bias, `biasprm`) |"
    assert row in pages["real_servo"]
    old = dict(pages, real_servo=pages["real_servo"].replace(row, "| back-EMF (in the joint's `damping`) |"))
    assert any("back-EMF" in p for p in set(dt.check(old, src)) - before)
    bad = copy.deepcopy(src)
    bad["real_servo_model"]["joint"]["damping"] = "0.6576"  # back-EMF + gearbox as joint damping
    bad["real_servo_model"]["actuator"]["biasprm"] = "0 0 0"
    new = set(dt.check(pages, bad)) - before
    assert any("biasprm" in p for p in new) and any("damping" in p for p in new), new
