"""omni reproduce's forked writers (omni_app.workers.Workers, reproduce._early_writer): work done in
children while the main process goes on, errors reported, the inline fallback, and nothing
left behind when a reproduction fails after the children started."""

import argparse

import pytest

from identification.errors import UserError
from omni_app import reproduce as rp
from omni_app.workers import Workers


def _in_one_thread(check, tmp_path):
    """Run ``check(tmp_path)`` in a process with one thread, as forking needs
    (:func:`omni_app.workers.fork_is_safe`): here if this process has one, else in a fresh
    interpreter (a pytest worker that ran other tests may keep their threads running: tqdm's
    monitor, dask's)."""
    import subprocess
    import sys
    import threading
    from pathlib import Path

    if threading.active_count() == 1:
        check(tmp_path)
        return
    code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
            f"from pathlib import Path; import test_reproduce_workers as t; "
            f"t.{check.__name__}(Path({str(tmp_path)!r}))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def _check_tasks_and_errors(tmp_path):
    w = Workers()
    w.start([lambda: (tmp_path / "a").write_text("a"), lambda: (tmp_path / "b").write_text("b")])
    w.start([lambda: (tmp_path / "c").write_text("c")])
    forked = all(job["proc"] is not None for job in w.jobs)
    w.wait()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "c"]
    w.start([lambda: 1 / 0])
    # a child's error is reported by wait(); inline, the error itself propagates
    with pytest.raises(RuntimeError if forked else ZeroDivisionError, match="ZeroDivisionError|division"):
        w.wait()
    return forked


@pytest.mark.parametrize("inline", [False, True])
def test_workers_run_tasks_and_report_errors(tmp_path, monkeypatch, inline):
    import sys

    if inline:
        monkeypatch.setenv("OMNI_FIGURES_INLINE", "1")
        assert not _check_tasks_and_errors(tmp_path)
    elif sys.platform.startswith("linux"):
        _in_one_thread(_check_tasks_and_errors_forked, tmp_path)
    else:  # no fork: the work is done in this process
        assert not _check_tasks_and_errors(tmp_path)


def _check_tasks_and_errors_forked(tmp_path):
    assert _check_tasks_and_errors(tmp_path), "not forked"


def _check_payloads(tmp_path):
    """A child started with ``then`` runs its tasks, then ``then(payload)`` once it is sent
    (through a temporary file, removed after)."""
    import glob
    import tempfile

    import numpy as np

    before = set(glob.glob(f"{tempfile.gettempdir()}/omni-figures-*"))
    w = Workers()
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


@pytest.mark.parametrize("inline", [False, True])
def test_work_waiting_for_a_payload(tmp_path, monkeypatch, inline):
    if inline:
        monkeypatch.setenv("OMNI_FIGURES_INLINE", "1")
        _check_payloads(tmp_path)
    else:
        _in_one_thread(_check_payloads, tmp_path)


def _check_hung_child(tmp_path):
    import os
    import time

    from omni_app import workers as wk

    wk.STALL_S = 1.0
    assert wk.FIGURES_TIMEOUT_S >= 60
    parent = os.getpid()

    def task():
        if os.getpid() != parent:
            time.sleep(60)                      # the child hangs
        (tmp_path / "done").write_text("here")

    w = Workers()
    w.start([task])
    w.start([], then=[lambda p: task() or (tmp_path / "late").write_text(p)])
    assert all(job["proc"] is not None for job in w.jobs), "not forked"
    w.send("payload")
    t0 = time.monotonic()
    w.wait()
    assert time.monotonic() - t0 < 10        # two stalls of ~1 s, not two minutes
    assert (tmp_path / "done").read_text() == "here"
    assert (tmp_path / "late").read_text() == "payload"


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="forks on Linux only")
def test_hung_child_is_killed_and_its_work_done_here(tmp_path):
    """A child that uses no CPU while waited for (hung on a lock) is found within ~STALL_S,
    not at FIGURES_TIMEOUT_S: killed, and its work done in the main process."""
    _in_one_thread(_check_hung_child, tmp_path)


def _check_busy_child(tmp_path):
    import os
    import time

    from omni_app import workers as wk

    wk.STALL_S = 0.5

    def spin(seconds):
        t0 = time.process_time()
        while time.process_time() - t0 < seconds:
            pass

    def task():
        inner = Workers()                        # the figure worker forks drawers of its own
        inner.start([lambda: spin(1.5)])
        inner.wait()
        (tmp_path / "who").write_text(str(os.getpid()))

    w = Workers()
    w.start([task])
    assert w.jobs[0]["proc"] is not None, "not forked"
    w.wait()
    assert int((tmp_path / "who").read_text()) != os.getpid()   # done by the child


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="forks on Linux only")
def test_busy_child_is_not_mistaken_for_a_hung_one(tmp_path):
    """A child (and a child of its own) computing for longer than STALL_S finishes its work."""
    _in_one_thread(_check_busy_child, tmp_path)


def test_no_fork_while_another_thread_runs(tmp_path):
    """With a second thread running, the work is done in this process (at wait)."""
    import os
    import threading

    from omni_app import workers as wk

    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    try:
        assert not wk.fork_is_safe()
        w = Workers()
        w.start([lambda: (tmp_path / "who").write_text(str(os.getpid()))])
        assert all(job["proc"] is None for job in w.jobs)
        w.wait()
    finally:
        stop.set()
        t.join()
    assert int((tmp_path / "who").read_text()) == os.getpid()


def test_failed_reproduction_leaves_nothing(tmp_path, monkeypatch):
    """Identification fails after the dataset writer started: the children are stopped, the
    output folder is not created and no temporary folder is left."""
    from omni_sim import experiments as ex

    step = ex.campaign("step")
    monkeypatch.setattr(ex, "campaign", lambda name: step)

    def fail(runs, **kwargs):
        raise UserError("identification failed (test)")

    monkeypatch.setattr(rp, "identify_runs", fail)
    out = tmp_path / "results"
    args = argparse.Namespace(out=str(out), model=None, friction=None, jobs=1, force=False)
    with pytest.raises(UserError, match="test"):
        rp.reproduce_command(args)
    assert list(tmp_path.iterdir()) == []
    import gc

    assert gc.get_freeze_count() == 0  # what the forks froze is given back by kill()


@pytest.mark.parametrize("extra, message", [
    (["--jobs", "0"], "must be >= 1"),
    (["--bogus"], "unrecognized arguments"),
    (["--model", "no/such/model.xml"], "no/such/model.xml"),
])
def test_rejected_reproduce_stops_the_early_worker(tmp_path, extra, message):
    """The command line forks the figure worker before parsing; arguments rejected then (by
    the parser or the command) end with the one-line error and exit 2, promptly, with no child
    left running (a child left waiting would keep the process from exiting)."""
    import subprocess
    import sys

    out = tmp_path / "results"
    proc = subprocess.run([sys.executable, "-m", "omni_app", "reproduce", "--out", str(out), *extra],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error:") and message in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not out.exists()


def test_worker_is_forked_before_the_heavy_imports(monkeypatch):
    """``omni reproduce`` starts its figure worker before the command line imports MuJoCo or
    scipy (that is the point of forking early); other commands and --help start none."""
    import sys

    from omni_app import cli, figure_worker

    seen = {}

    def fake_start():
        seen["mods"] = {m for m in ("mujoco", "scipy", "omni_sim") if m in sys.modules}
        return None

    monkeypatch.setattr(figure_worker, "start_reproduce_worker", fake_start)
    for m in ("mujoco", "scipy", "omni_sim"):
        monkeypatch.delitem(sys.modules, m, raising=False)
    cli._reproduce_worker(["reproduce", "--out", "x"])
    assert seen["mods"] == set()
    seen.clear()
    for argv in (["generate"], ["reproduce", "--help"], ["reproduce", "--friction", "all"],
                 ["reproduce", "--friction=all"]):
        cli._reproduce_worker(argv)
        assert not seen
