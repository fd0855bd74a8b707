"""omni reproduce's failures: a reproduction that fails part-way leaves nothing behind, and
rejected arguments end with the contract's one-line error."""

import argparse

import pytest

from identification.errors import UserError
from omni_app import reproduce as rp


def test_failed_reproduction_leaves_nothing(tmp_path, monkeypatch):
    """Identification fails after the campaign was simulated: the output folder is not
    created and no temporary folder is left."""
    from omni_sim import experiments as ex

    step = ex.campaign("step")[:1]  # one run: the failure comes after it was simulated
    monkeypatch.setattr(ex, "campaign", lambda name: step)

    def fail(runs, **kwargs):
        raise UserError("identification failed (test)")

    from omni_studies import reproduce as study
    monkeypatch.setattr(study, "identify_runs", fail)
    # the workers as threads: the same jobs (the dataset written while identification runs),
    # without two processes started and matplotlib imported in them (~2 s)
    from concurrent.futures import ThreadPoolExecutor
    monkeypatch.setattr(rp, "worker_pool", lambda: ThreadPoolExecutor(max_workers=2))
    out = tmp_path / "results"
    args = argparse.Namespace(out=str(out), model=None, friction=None, jobs=1, force=False)
    with pytest.raises(UserError, match="test"):
        rp.reproduce_command(args)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("extra, message", [
    (["--jobs", "0"], "must be >= 1"),
    (["--bogus"], "unrecognized arguments"),
    (["--model", "no/such/model.xml"], "no/such/model.xml"),
])
def test_rejected_reproduce_is_one_line(tmp_path, extra, message):
    """Arguments rejected by the parser or the command: the one-line error, exit 2, no
    traceback, no output folder."""
    import subprocess
    import sys

    out = tmp_path / "results"
    proc = subprocess.run([sys.executable, "-m", "omni_app", "reproduce", "--out", str(out), *extra],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error:") and message in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not out.exists()
