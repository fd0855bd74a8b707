"""What the long commands show while they work (on a terminal: tqdm on stderr)."""

from __future__ import annotations

import io
import sys
import time



def test_discrepancy_progress_shows_elapsed_time_between_lines():
    """On a terminal the discrepancy log has a status line with the elapsed time, redrawn
    between two log lines (the search can be silent for minutes); elsewhere plain lines."""
    from omni_app.discrepancy import Progress

    buf = io.StringIO()
    with Progress(enabled=True, file=buf, tick_s=0.02) as log:
        log("round 1: scoring 12 candidates")
        time.sleep(0.2)
    text = buf.getvalue()
    assert "round 1: scoring 12 candidates\n" in text
    assert text.count("elapsed]") >= 3  # redrawn by the ticker, not only at each line
    # the stage bar: the workflow's stage, its index and the physics steps so far
    buf = io.StringIO()
    with Progress(enabled=True, file=buf, tick_s=0.02) as log:
        log.stage(2, "naming", 3_500_000)
        time.sleep(0.05)
    text = buf.getvalue()
    assert "discrepancy: naming (3.5 M steps)" in text and "stage 2/5" in text
    plain = io.StringIO()
    with Progress(enabled=False, file=plain) as log:
        log("gap before 1e-3 rad")
        log.stage(1, "corrections", 10)  # no bar off a terminal: nothing written
    assert plain.getvalue() == "gap before 1e-3 rad\n"


def test_reproduce_all_names_the_family_it_runs(tmp_path, monkeypatch, capsys):
    """``omni reproduce --friction all`` on a terminal: a bar over the friction families, each
    named while its stages run (the stages themselves are stubbed here)."""
    from omni_app import reproduce as rp
    from omni_sim import model as om

    seen = []

    def stage(device, jobs, campaign, progress):
        seen.append((device.friction_family(), sys.stderr.getvalue()))
        return {}

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    monkeypatch.setattr(rp, "run_reproduce", stage)
    monkeypatch.setattr(rp, "write_reproduce", lambda *a: None)
    monkeypatch.setattr("omni_app.comparison.write_comparison", lambda tmp, results: {"families": {}})
    monkeypatch.setattr(rp, "_print_summary", lambda *a, **k: None)
    assert rp.reproduce_all(tmp_path / "out", campaign="step") == 0
    assert [fam for fam, _ in seen] == list(om.FRICTION_FAMILIES)
    for fam, (_, err) in zip(om.FRICTION_FAMILIES, seen):
        assert f"friction family {fam}" in err

