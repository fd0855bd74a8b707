"""The documentation a newcomer reads: a README of a screen or two that lists every command of
``omni --help`` and links the docs/ pages; pages whose links and code paths exist; and text
that describes the code, not how it came to be (no "sess"+"ion" or "issue N" in the README,
docs/, the packages, the tests, the scripts, the examples or the model and data notes)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from omni_app.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: One or two screens.
MAX_README_LINES = 200
#: The pages the README's documentation table links (docs/READER/*.md, one folder per reader:
#: usage, method, studies, reference) and the changelog.
PAGES = ("studies/reproduce/results", "reference/model", "studies/calibration/calibration",
         "method/friction-families", "method/discrepancy", "usage/sweeps", "reference/performance",
         "method/paper-errata", "usage/gymnasium", "studies/haptics/haptics", "usage/campaigns",
         "usage/python", "reference/architecture")
#: The folders of docs/, one per reader; docs/README.md indexes them.
READERS = ("usage", "method", "studies", "reference")
#: Words that tell how the code came to be instead of what it is (split so that this file
#: does not match itself).
HISTORY = re.compile("sess" + r"ion|issue\s+\d", re.IGNORECASE)
#: ``subprocess.Popen``'s ``start_new_`` + ``...=True`` argument names a POSIX process group;
#: a pytest fixture's scope of the whole run (tests/conftest.py) is named so too.
ALLOWED = re.compile("start_new_" + "sess" + "ion=True|scope=\"" + "sess" + "ion\"")
#: Where the history words are looked for: (folder or file, glob).
SCANNED = (("README.md", None), ("docs", "**/*"), ("omni_sim", "**/*.py"), ("omni_sim", "**/*.toml"),
           ("omni_app", "**/*.py"), ("omni_studies", "**/*.py"), ("identification", "**/*.py"), ("identification/data", "*.md"),
           ("tests", "**/*.py"), ("scripts", "*.py"), ("examples", "**/*"), ("models", "**/README.md"),
           ("discrepancy", "**/*.py"), ("bank", "**/*.py"), ("bank", "**/*.md"))
#: Repository paths named in backticks in the README and docs/**/*.md (checked to exist): a file
#: (with a suffix) or a folder (ending in ``/``) under one of the project's top-level folders.
CODE_PATH = re.compile(r"`((?:omni_sim|omni_app|identification|discrepancy|bank|scripts|tests|models|docs|examples)"
                       r"/[A-Za-z0-9_/-]*(?:\.[A-Za-z0-9_.]+|/))`")


def _subcommands() -> set[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return set(sub.choices)


def _readme_commands(text: str) -> set[str]:
    """The commands of the README's table under "## Commands" (first cell ``omni NAME ...``)."""
    section = text[text.index("\n## Commands"):]
    section = section[:section.index("\n## ", 1)]
    return {m.group(1) for m in re.finditer(r"^\| `omni ([a-z-]+)", section, re.M)}


def _scanned_files():
    for where, pattern in SCANNED:
        path = ROOT / where
        files = [path] if pattern is None else sorted(path.glob(pattern))
        for f in files:
            if f.is_file() and f.suffix not in (".png", ".pyc") and "__pycache__" not in f.parts:
                yield f


def test_readme_fits_two_screens():
    n = len(README.read_text().splitlines())
    assert n <= MAX_README_LINES, f"README.md has {n} lines (at most {MAX_README_LINES})"


def test_readme_lists_every_command():
    """The README's commands table lists exactly the subcommands ``omni --help`` lists."""
    assert _readme_commands(README.read_text()) == _subcommands()


def test_the_command_finder_reads_the_table():
    text = "# x\n\n## Commands\n\n| command | does |\n|---|---|\n| `omni a --x` | . |\n| `omni b-c` | . |\n\n## Next\n"
    assert _readme_commands(text) == {"a", "b-c"}
    assert _readme_commands(text.replace("| `omni b-c` | . |\n", "")) == {"a"}


def test_readme_keeps_the_two_setup_commands():
    """.ci/run runs the second verbatim, a line of its own (the project and the validation bank,
    bank/, in one install)."""
    text = README.read_text()
    test_command = 'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" -e ./bank && pytest -q'
    for cmd in ("python3 -m venv .venv && . .venv/bin/activate && pip install -e . && omni reproduce --out results",
                test_command):
        assert f"```bash\n{cmd}\n```" in text, cmd
    assert test_command in (ROOT / ".ci" / "run").read_text().splitlines()


def test_pages_exist_and_the_readme_links_them():
    text = README.read_text()
    for page in PAGES:
        assert (ROOT / "docs" / f"{page}.md").is_file(), page
        assert f"(docs/{page}.md)" in text, page
    assert (ROOT / "CHANGELOG.md").is_file() and "(CHANGELOG.md)" in text


#: Every Markdown page of the README and docs/, the generated reports included.
MARKDOWN = ["README.md"] + sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("**/*.md"))


def _broken_links(path: Path) -> list[str]:
    """The relative links of a Markdown page (``[text](target)``, images too) whose file or
    folder does not exist; web and mail addresses and in-page anchors are skipped."""
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", path.read_text()):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        if not (path.parent / target.split("#")[0]).exists():
            broken.append(target)
    return broken


@pytest.mark.parametrize("page", MARKDOWN)
def test_every_relative_link_resolves(page):
    """Every relative link of the README and of every page under docs/ (the reader folders,
    the studies' generated reports) names a file or folder that exists."""
    assert _broken_links(ROOT / page) == [], page


def test_the_link_check_sees_every_folder_and_a_broken_link(tmp_path):
    assert {"usage", "method", "studies", "reference"} <= {Path(p).parts[1] for p in MARKDOWN[1:]}
    assert "docs/README.md" in MARKDOWN and len(MARKDOWN) > 20
    (tmp_path / "there.md").write_text("x")
    page = tmp_path / "page.md"
    page.write_text("[a](there.md) [b](there.md#top) [c](missing.md) ![d](gone/fig.png) "
                    "[e](https://example.org/x.md) [f](#anchor)")
    assert _broken_links(page) == ["missing.md", "gone/fig.png"]


def test_docs_index_lists_every_page_by_reader():
    """docs/ holds only the index and the four reader folders, and the index links every page
    under them (the studies' generated reports too)."""
    docs = ROOT / "docs"
    # docs/rollout/: scripts/render_rollout.py's frames, ignored by git
    assert sorted(p.name for p in docs.iterdir() if p.name != "rollout") == sorted(["README.md", *READERS])
    index = (docs / "README.md").read_text()
    assert _broken_links(docs / "README.md") == []
    for reader in READERS:
        pages = sorted((docs / reader).glob("**/*.md"))
        assert pages, reader
        for p in pages:
            assert f"]({p.relative_to(docs)})" in index, p


@pytest.mark.parametrize("page", ["README.md", "docs/README.md"] + [f"docs/{p}.md" for p in PAGES])
def test_links_and_code_paths_exist(page):
    """Every relative link of a page resolves, and every repository path it names in backticks
    exists (a renamed module shows up here)."""
    path = ROOT / page
    text = path.read_text()
    assert _broken_links(path) == [], page
    for name in CODE_PATH.findall(text):
        if "*" in name or "<" in name:
            continue
        assert (ROOT / name).exists(), f"{page}: `{name}` does not exist"


def test_no_history_words():
    hits = []
    for f in _scanned_files():
        text = f.read_bytes().decode("utf-8", errors="replace")
        for i, line in enumerate(text.splitlines(), 1):
            if HISTORY.search(ALLOWED.sub("", line)):
                hits.append(f"{f.relative_to(ROOT)}:{i}: {line.strip()[:100]}")
    assert hits == []


def test_the_history_search_finds_them():
    assert HISTORY.search("as in the first " + "sess" + "ion")
    assert HISTORY.search("Issue" + " 14: faster")
    assert not HISTORY.search(ALLOWED.sub("", "Popen(cmd, start_new_" + "sess" + "ion=True)"))
    assert not HISTORY.search("the issue targets")
    assert len(list(_scanned_files())) > 100


def test_the_readme_says_what_torque_off_does():
    """The dataset's ``enabled`` = 0 (torque off): the replay zeroes the actuator's gain and
    bias (``Device.off_model``), not its command, which on a ``dcmotor`` or a back-EMF bias is
    a shorted winding that brakes (docs/method/servo-actuators.md); the README says so."""
    import mujoco

    from omni_sim.device import Device
    from omni_sim.model import Target

    m = mujoco.MjModel.from_xml_path(str(ROOT / "examples" / "real_servo" / "model.xml"))
    dev = Device(m, target=Target("servo_axis", "servo"))
    a = dev.ix.yaw_act
    assert m.actuator_gainprm[a].any() and m.actuator_biasprm[a].any()  # a gain and a back-EMF bias
    off = dev.off_model()
    assert not off.actuator_gainprm[a].any() and not off.actuator_biasprm[a].any()
    bullet = re.search(r"optional `enabled`(.*?); more columns", " ".join(README.read_text().split())).group(1)
    assert "zeroes the actuator's gain and bias" in bullet and "shorted winding" in bullet, bullet
    assert "command is zero" not in bullet
