"""docs/usage/python.md runs as it stands: its ```python blocks are executed in order, in one
namespace, in an empty folder (pytest's tmp_path), and what they print is checked against the
facts they show (the Omni's metadata has a pose, the pendulum's none; the command limit bounds
the commands; the hidden friction is found).  The blocks up to the discrepancy section run in
the default suite; the whole page, the discrepancy workflow included (~15 s), is marked slow."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

import identification
import omni_sim

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "usage" / "python.md"
#: The heading of the section whose block runs the (slower) discrepancy workflow.
DISCREPANCY_SECTION = "## Find what your model misses (your own robot)"


def blocks(text: str) -> list[tuple[str, str]]:
    """The page's ```python blocks as ``(heading of their section, code)``, in order."""
    out, heading = [], ""
    for m in re.finditer(r"^(## [^\n]*)$|^```python\n(.*?)^```$", text, re.M | re.S):
        if m.group(1):
            heading = m.group(1)
        else:
            out.append((heading, m.group(2)))
    return out


def run_blocks(code_blocks, folder: Path, monkeypatch) -> str:
    """Execute the blocks in one namespace with ``folder`` as the current folder; their
    printed output."""
    monkeypatch.chdir(folder)
    namespace: dict = {"__name__": "python_page"}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        for i, code in enumerate(code_blocks):
            exec(compile(code, f"{PAGE.name}[block {i}]", "exec"), namespace)
    return out.getvalue()


def test_the_block_finder_reads_headings_and_blocks():
    text = "# t\n\n## A\n\n```python\nx = 1\n```\n\n```console\n$ no\n```\n## B\n```python\ny = 2\n```\n"
    assert blocks(text) == [("## A", "x = 1\n"), ("## B", "y = 2\n")]


def test_the_page_has_the_promised_sections():
    found = blocks(PAGE.read_text())
    headings = [h for h, _ in found]
    assert len(found) >= 6
    for h in ("## Load a device", "## Run experiments", "## Write and read a dataset",
              "## Identify and validate (Omni data)", DISCREPANCY_SECTION):
        assert h in headings, h
    assert headings[-1] == DISCREPANCY_SECTION  # the slow block comes last


def _check_fast_output(out: str, folder: Path) -> None:
    lines = out.splitlines()
    assert lines[0].startswith("Omni: ") and lines[1].endswith("arm: False"), lines[:2]
    # the Omni's runs have the arm's actual angles (sagged below the 45 deg set point)
    names, gamma1 = re.match(r"(\[.*\]) (\S+)$", lines[2]).groups()
    assert "sine_g45_090_f2p00" in names and 40 < float(gamma1) < 45
    assert lines[3] == "pivot servo 6.0 False"  # joint, actuator, command_limit, no pose claimed
    assert float(re.search(r"largest command (\S+) V", lines[4]).group(1)) <= 6.0
    assert lines[5] == "3 3"
    assert (folder / "omni_data" / "step_g45_090.json").is_file()
    assert (folder / "params.json").is_file()
    assert any("median |error| of the linear model" in ln for ln in lines)


def test_the_page_runs_up_to_the_discrepancy_section(tmp_path, monkeypatch):
    code = [c for h, c in blocks(PAGE.read_text()) if h != DISCREPANCY_SECTION]
    out = run_blocks(code, tmp_path, monkeypatch)
    _check_fast_output(out, tmp_path)
    # what the page says of the default purpose on the pendulum's runs
    with pytest.raises(identification.UserError, match=r"missing required key\(s\): gamma1_deg, gamma2_deg"):
        identification.read_dataset(tmp_path / "pendulum_data")


@pytest.mark.slow
def test_the_whole_page_runs(tmp_path, monkeypatch):
    """The discrepancy block finds the stand-in's tripled gear friction (0.09 N m)."""
    out = run_blocks([c for _, c in blocks(PAGE.read_text())], tmp_path, monkeypatch)
    _check_fast_output(out, tmp_path)
    m = re.search(r"^coulomb_friction \{'frictionloss_nm': (\S+)\} \{'frictionloss_nm': (\S+)\} (\w+)$", out, re.M)
    assert m and abs(float(m.group(1)) - 0.09) < 1e-3, out
    assert float(m.group(2)) > 0 and m.group(3) in ("high", "low"), out  # its 95 % half-width, confidence
    g = re.search(r"^gap (\S+) -> (\S+) rad$", out, re.M)
    assert g and float(g.group(2)) < float(g.group(1)) / 3, out
    assert (tmp_path / "pendulum_report" / "report.md").is_file()


def test_the_names_the_page_uses_are_exported():
    for name in ("Target", "Experiment", "Settings", "simulate", "campaign", "Device", "MODELS_DIR"):
        assert name in omni_sim.__all__ and hasattr(omni_sim, name), name
    for name in ("read_dataset", "write_dataset", "identify_runs", "validate_runs", "read_params", "UserError"):
        assert name in identification.__all__ and hasattr(identification, name), name
