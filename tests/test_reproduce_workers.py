"""omni reproduce's forked writers (omni_app.reproduce._Workers, _early_writer): work done in
children while the main process goes on, errors reported, the inline fallback, and nothing
left behind when a reproduction fails after the children started."""

import argparse

import pytest

from identification.errors import UserError
from omni_app import reproduce as rp


@pytest.mark.parametrize("inline", [False, True])
def test_workers_run_tasks_and_report_errors(tmp_path, monkeypatch, inline):
    if inline:
        monkeypatch.setenv("OMNI_FIGURES_INLINE", "1")
    w = rp._Workers()
    assert not (inline and w.fork)
    w.start([lambda: (tmp_path / "a").write_text("a"), lambda: (tmp_path / "b").write_text("b")])
    w.start([lambda: (tmp_path / "c").write_text("c")])
    w.wait()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "c"]
    w.start([lambda: 1 / 0])
    # a child's error is reported by wait(); inline, the error itself propagates
    with pytest.raises(ZeroDivisionError if inline else RuntimeError, match="ZeroDivisionError|division"):
        w.wait()


@pytest.mark.parametrize("inline", [False, True])
def test_work_waiting_for_a_payload(tmp_path, monkeypatch, inline):
    """A child started with ``then`` runs its tasks, then ``then(payload)`` once it is sent
    (through a temporary file, removed after)."""
    import glob
    import tempfile

    import numpy as np

    if inline:
        monkeypatch.setenv("OMNI_FIGURES_INLINE", "1")
    before = set(glob.glob(f"{tempfile.gettempdir()}/omni-figures-*"))
    w = rp._Workers()
    w.start([lambda: (tmp_path / "first").write_text("1")],
            then=[lambda p: (tmp_path / "mid").write_text(p),
                  lambda p: np.save(tmp_path / "late.npy", p["x"])])
    w.start([lambda: (tmp_path / "other").write_text("2")])
    w.send("stage 1")
    w.send({"x": np.arange(100000.0)})
    w.wait()
    np.testing.assert_array_equal(np.load(tmp_path / "late.npy"), np.arange(100000.0))
    assert (tmp_path / "mid").read_text() == "stage 1"
    assert (tmp_path / "first").exists() and (tmp_path / "other").exists()
    assert set(glob.glob(f"{tempfile.gettempdir()}/omni-figures-*")) == before


def test_hung_child_is_killed_and_its_work_done_here(tmp_path, monkeypatch):
    import os
    import time

    monkeypatch.setattr(rp, "FIGURES_TIMEOUT_S", 1.0)
    parent = os.getpid()

    def task():
        if os.getpid() != parent:
            time.sleep(60)                      # the child hangs
        (tmp_path / "done").write_text("here")

    w = rp._Workers()
    if not w.fork:
        pytest.skip("no fork")
    w.start([task])
    w.start([], then=[lambda p: task() or (tmp_path / "late").write_text(p)])
    w.send("payload")
    w.wait()
    assert (tmp_path / "done").read_text() == "here"
    assert (tmp_path / "late").read_text() == "payload"


def test_failed_reproduction_leaves_nothing(tmp_path, monkeypatch):
    """Identification fails after the dataset writer started: the children are stopped, the
    output folder is not created and no temporary folder is left."""
    from omni_sim import experiments as ex

    step = ex.campaign("step")
    monkeypatch.setattr(ex, "campaign", lambda name: step)

    def fail(runs):
        raise UserError("identification failed (test)")

    monkeypatch.setattr(rp, "identify_runs", fail)
    out = tmp_path / "results"
    args = argparse.Namespace(out=str(out), model=None, friction=None, jobs=1, force=False)
    with pytest.raises(UserError, match="test"):
        rp.reproduce_command(args)
    assert list(tmp_path.iterdir()) == []
