"""Test-session settings: how ``--dist loadfile`` (pyproject addopts) shares the tests out.

xdist's ``loadfile`` sends each test module to one worker, so a module-scoped fixture (e.g.
test_reproduce's whole reproduce run) is computed once.  Two changes to it, for the 2-core CI:

* the few tests that each take a large share of the suite's CPU time and share no expensive
  fixture with their module are work units of their own (``OWN_UNIT``), so that they can run
  on the other worker while the rest of their module runs;
* the units known to be long (``LONG_FIRST``) are handed out first, the short ones fill in
  at the end (longest-first packing; the default orders units by their number of tests).

Only the order and the grouping of the tests change: every test still runs once.
"""

from __future__ import annotations

#: Node ids run as work units of their own (long, and no module fixture worth sharing).
OWN_UNIT = (
    "tests/test_discrepancy.py::test_fast_hidden_cases[coulomb_friction]",
    "tests/test_discrepancy.py::test_fast_hidden_cases[none]",
    "tests/test_discrepancy.py::test_fast_masking_pair",
)
#: Work units handed out first, longest first (a unit missing from the run is skipped).
LONG_FIRST = (
    "tests/test_reproduce.py",
    "tests/test_friction_families.py",
    "tests/test_discrepancy.py::test_fast_hidden_cases[coulomb_friction]",
    "tests/test_truth.py",
    "tests/test_experiments.py",
    "tests/test_discrepancy.py::test_fast_hidden_cases[none]",
    "tests/test_identify_cli.py",
    "tests/test_discrepancy.py::test_fast_masking_pair",
    "tests/test_discrepancy.py",
)


def _scheduler_class():
    from xdist.scheduler import LoadFileScheduling

    class LongFirstFileScheduling(LoadFileScheduling):
        """``loadfile`` with ``OWN_UNIT`` split off and ``LONG_FIRST`` units handed out first."""

        _ordered = False

        def _split_scope(self, nodeid: str) -> str:
            for own in OWN_UNIT:
                if nodeid.endswith(own):
                    return nodeid
            return super()._split_scope(nodeid)

        def _assign_work_unit(self, node) -> None:
            if not self._ordered:  # the work queue is complete at the first assignment
                self._ordered = True
                scopes = list(self.workqueue)
                first = [s for name in LONG_FIRST for s in scopes if s.endswith(name)]
                for s in reversed(list(dict.fromkeys(first))):
                    self.workqueue.move_to_end(s, last=False)
            super()._assign_work_unit(node)

    return LongFirstFileScheduling


try:
    import xdist  # noqa: F401
except ImportError:  # without pytest-xdist there is nothing to schedule (and no such hook)
    pass
else:
    def pytest_xdist_make_scheduler(config, log):
        if config.getvalue("dist") != "loadfile":
            return None  # another --dist given on the command line: xdist's own
        return _scheduler_class()(config, log)
