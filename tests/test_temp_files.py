"""The suite's check that tests leave nothing in the system's temporary folder
(tests/conftest.py) fails when a test writes there, and a test writing through tempfile
writes under pytest's folder instead."""

from __future__ import annotations

from pathlib import Path

CONFTEST = Path(__file__).with_name("conftest.py")

INNER_TESTS = '''
import os, tempfile
from pathlib import Path

def test_through_tempfile():
    folder = Path(tempfile.mkdtemp(prefix="kept_"))  # never removed, as the bank's nominals
    (folder / "x.txt").write_text("x")
    assert os.environ["SYSTEM_TMP"] not in str(folder)

def test_written_to_the_system_folder():
    if os.environ.get("LEAK"):
        (Path(os.environ["SYSTEM_TMP"]) / "leaked.txt").write_text("x")
'''


def _run(pytester, monkeypatch, leak: bool):
    """The inner suite, with ``TMPDIR`` (its "system temporary folder") a folder of its own."""
    system = pytester.path / "system_tmp"
    system.mkdir(exist_ok=True)
    pytester.makeconftest(CONFTEST.read_text())
    pytester.makepyfile(test_inner=INNER_TESTS)
    monkeypatch.setenv("TMPDIR", str(system))
    monkeypatch.setenv("SYSTEM_TMP", str(system))
    monkeypatch.delenv("OMNI_TESTS_TMP_CHECK", raising=False)
    if leak:
        monkeypatch.setenv("LEAK", "1")
    else:
        monkeypatch.delenv("LEAK", raising=False)
    return pytester.runpytest_subprocess("-p", "no:cacheprovider", "-p", "no:xdist"), system


def test_leak_fails_the_run(pytester, monkeypatch):
    result, system = _run(pytester, monkeypatch, leak=True)
    assert result.ret != 0
    result.stdout.fnmatch_lines(["*left 1 new entry*leaked.txt*"])
    assert sorted(p.name for p in system.iterdir()) == ["leaked.txt"]  # tempfile's went elsewhere
    result.assert_outcomes(passed=2, errors=1)  # the check: an error after the last test

