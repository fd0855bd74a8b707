"""Work done by forked children while the main process goes on (``omni reproduce``'s dataset
writer and figure drawers).

Import-light on purpose (the standard library only): the command line forks
:func:`omni_app.figure_worker.start_reproduce_worker`'s child before it imports scipy, MuJoCo
or matplotlib, so that the child loads matplotlib while the parent loads the rest (a core that
would otherwise wait).
"""

from __future__ import annotations

import gc
import os
import sys
import threading
import time


#: Longest wait [s] for the forked children (together; they take ~3 s, 30x that on a loaded
#: machine): a child still running then is killed and its work done in the main process.  A
#: child that has hung is found much sooner, by STALL_S.
FIGURES_TIMEOUT_S = 120.0
#: A child whose processes (it and its own children) have used no CPU time for this long [s]
#: while the main process waits for it has hung (a lock held at the fork: it waits for ever,
#: without CPU); it is killed and its work done in the main process.  A working child, even on
#: a loaded machine, uses CPU every second.
STALL_S = 3.0


def fork_is_safe() -> bool:
    """Whether forking now is safe: on Linux (Python's documentation calls ``fork`` unsafe on
    macOS, and Windows has none), with no thread but this one running (a forked child gets
    only the forking thread; a lock another thread held stays held in the child for ever),
    and not switched off by ``OMNI_FIGURES_INLINE``."""
    return (sys.platform.startswith("linux") and hasattr(os, "fork")
            and threading.active_count() == 1 and not os.environ.get("OMNI_FIGURES_INLINE"))


def _tree_cpu_ticks(pid: int) -> int | None:
    """CPU clock ticks used so far by process ``pid`` and its descendants (Linux ``/proc``:
    user + system time of each live process, plus what its waited-for children used); None if
    ``/proc`` cannot be read."""
    parent, ticks = {}, {}
    try:
        entries = [e for e in os.listdir("/proc") if e.isdigit()]
    except OSError:
        return None
    for entry in entries:
        try:
            with open(f"/proc/{entry}/stat") as fh:
                text = fh.read()
        except OSError:  # ended meanwhile
            continue
        fields = text[text.rindex(")") + 2:].split()  # from field 3 (state) on
        parent[int(entry)] = int(fields[1])
        ticks[int(entry)] = sum(int(x) for x in fields[11:15])  # utime stime cutime cstime
    if pid not in ticks:
        return None
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        total += ticks.get(p, 0)
        todo += [c for c, pp in parent.items() if pp == p]
    return total


class Workers:
    """Work done by forked children while the main process goes on.

    :meth:`start` forks a child for a list of tasks (callables), optionally followed by
    ``then``, callables of one argument run in turn with the payloads given by :meth:`send`
    (each passed through a temporary pickle file, so that the sender never blocks).  A child is
    forked only where that is safe (:func:`fork_is_safe`: Linux, no other thread running);
    elsewhere the work is done at :meth:`wait` instead.  A child that hangs anyway (uses no CPU
    for ``STALL_S`` while waited for), or is not done within ``FIGURES_TIMEOUT_S``, is killed
    and its work done in the main process.  A child's error is raised by :meth:`wait`.
    """

    def __init__(self):
        self.fork = fork_is_safe()  # whether this platform forks at all (checked again per start)
        self.jobs = []      # dicts: proc, queue, conn (or None), tasks, then, payloads, files

    def start(self, tasks, then=()) -> None:
        job = {"proc": None, "queue": None, "conn": None, "tasks": list(tasks),
               "then": list(then), "payloads": [], "files": []}
        self.jobs.append(job)
        if not (self.fork and fork_is_safe()):
            return
        import multiprocessing as mp
        import pickle

        ctx = mp.get_context("fork")
        queue = ctx.SimpleQueue()
        recv, send = ctx.Pipe(duplex=False) if job["then"] else (None, None)

        def child():
            try:
                for task in job["tasks"]:
                    task()
                for stage in job["then"]:
                    path = recv.recv()
                    with open(path, "rb") as fh:
                        payload = pickle.load(fh)
                    os.unlink(path)
                    stage(payload)
                queue.put(None)
            except BaseException as exc:  # reported to the parent
                queue.put(f"{type(exc).__name__}: {exc}")

        # not a daemon: a child may start children of its own (every child is waited for or
        # killed by this object)
        proc = ctx.Process(target=child, daemon=False)
        # the objects alive now are moved out of the collector's reach (gc.freeze, as Python's
        # documentation advises before a fork): neither side's collections then touch the pages
        # both share (each touch copies a page), and full collections skip them (~0.5 s of CPU
        # in omni reproduce); wait() and kill() give them back
        gc.freeze()
        proc.start()
        job.update(proc=proc, queue=queue, conn=send)

    def send(self, payload) -> None:
        """Give ``payload`` to the next ``then`` stage waiting for one (none: nothing to do)."""
        for job in self.jobs:
            if len(job["payloads"]) == len(job["then"]):
                continue
            job["payloads"].append(payload)
            if job["conn"] is not None:
                import pickle
                import tempfile

                fd, path = tempfile.mkstemp(prefix="omni-figures-", suffix=".pkl")
                with os.fdopen(fd, "wb") as fh:
                    pickle.dump(payload, fh, protocol=pickle.HIGHEST_PROTOCOL)
                job["files"].append(path)
                try:
                    job["conn"].send(path)   # a few bytes: never blocks
                except OSError:              # the child has failed: wait() reports it
                    pass
            return

    @staticmethod
    def _run(job) -> None:
        for task in job["tasks"]:
            task()
        for stage, payload in zip(job["then"], job["payloads"]):
            stage(payload)

    @staticmethod
    def _clean(job) -> None:

        for path in job["files"]:
            if os.path.exists(path):
                os.unlink(path)

    @staticmethod
    def _join(proc, deadline: float) -> None:
        """Wait for ``proc`` until it ends, ``deadline`` passes, or it has used no CPU (with
        its children) for ``STALL_S``."""
        last, since = None, time.monotonic()
        while time.monotonic() < deadline:
            proc.join(min(0.25, max(0.0, deadline - time.monotonic())))
            if not proc.is_alive():
                return
            ticks = _tree_cpu_ticks(proc.pid)
            now = time.monotonic()
            if ticks is None or ticks != last:
                last, since = ticks, now
            elif now - since >= STALL_S:
                return  # hung: the caller kills it

    def wait(self) -> None:
        errors = []
        deadline = time.monotonic() + FIGURES_TIMEOUT_S
        jobs, self.jobs = self.jobs, []
        for job in jobs:
            proc = job["proc"]
            if proc is None:
                self._run(job)
                continue
            # the message is a few bytes: a child never blocks on the pipe
            self._join(proc, deadline)
            if proc.is_alive():
                proc.kill()
                proc.join()
                self._clean(job)
                self._run(job)
            else:
                queue = job["queue"]
                error = queue.get() if not queue.empty() else f"exit code {proc.exitcode}"
                if error is not None:
                    errors.append(error)
            self._clean(job)
        gc.unfreeze()  # what start() froze is the collector's again
        if errors:
            raise RuntimeError(f"writing the dataset or drawing the figures failed ({'; '.join(errors)})")

    def kill(self) -> None:
        """Stop every child (the output is being abandoned)."""
        for job in self.jobs:
            proc = job["proc"]
            if proc is not None and proc.is_alive():
                proc.kill()
                proc.join()
            self._clean(job)
        self.jobs = []
        gc.unfreeze()

