"""Work done by forked children while the main process goes on (``omni reproduce``'s dataset
writer and figure drawers).

Import-light on purpose (the standard library only): the command line forks
:func:`omni_app.figure_worker.start_reproduce_worker`'s child before it imports scipy, MuJoCo
or matplotlib, so that the child loads matplotlib while the parent loads the rest (a core that
would otherwise wait).
"""

from __future__ import annotations

import gc
import time


#: Longest wait [s] for the forked children (together; they take ~3 s, 30x that on a loaded
#: machine): a child still running then is killed and its work done in the main process.
FIGURES_TIMEOUT_S = 120.0


class Workers:
    """Work done by forked children while the main process goes on.

    :meth:`start` forks a child for a list of tasks (callables), optionally followed by
    ``then``, callables of one argument run in turn with the payloads given by :meth:`send`
    (each passed through a temporary pickle file, so that the sender never blocks).  Where
    ``fork`` is missing, or ``OMNI_FIGURES_INLINE`` is set, the work is done at :meth:`wait`
    instead.  A forked child of a threaded process can in principle hang on a lock another
    thread held at the fork: a child not done within ``FIGURES_TIMEOUT_S`` is killed and its
    work done in the main process.  A child's error is raised by :meth:`wait`.
    """

    def __init__(self):
        import multiprocessing as mp
        import os

        self.fork = "fork" in mp.get_all_start_methods() and not os.environ.get("OMNI_FIGURES_INLINE")
        self.ctx = mp.get_context("fork") if self.fork else None
        self.jobs = []      # dicts: proc, queue, conn (or None), tasks, then, payloads, files

    def start(self, tasks, then=()) -> None:
        job = {"proc": None, "queue": None, "conn": None, "tasks": list(tasks),
               "then": list(then), "payloads": [], "files": []}
        self.jobs.append(job)
        if not self.fork:
            return
        import pickle

        queue = self.ctx.SimpleQueue()
        recv, send = self.ctx.Pipe(duplex=False) if job["then"] else (None, None)

        def child():
            import os
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
        proc = self.ctx.Process(target=child, daemon=False)
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
                import os
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
        import os

        for path in job["files"]:
            if os.path.exists(path):
                os.unlink(path)

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
            proc.join(max(0.0, deadline - time.monotonic()))
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

