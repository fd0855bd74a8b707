"""Suite-wide settings: the validation bank is installed; the tests write temporary files only
under pytest's own folder.

The suite needs the bank (``bank/``, the distribution ``omni-alpha-bank``) installed, as the
README's test command does (``pip install -e ".[test]" -e ./bank``): its scripts and studies
run in processes of their own, where the checkout's root is not on the path.  Without it the
run stops at once with one line that names the fix.

A fixture of the whole run points ``TMPDIR`` (and :mod:`tempfile`'s cached folder) at a folder
of ``tmp_path_factory``, in the test processes and every process they start;
code that writes to :func:`tempfile.gettempdir` (e.g. the bank's nominal models,
``bank.hidden``: ``omni_bank_nominals/``; Dask's scratch space) writes there.
At the end it compares the system's temporary folder with its listing at the start and fails
the run (an error after its last test), naming them, if anything new is there besides pytest's own folder (a path written
without :mod:`tempfile`, or a process started with ``TMPDIR`` removed).  Another program writing
to the same folder meanwhile also shows there; ``OMNI_TESTS_TMP_CHECK=0`` skips the comparison
(the redirection stays).

Under pytest-xdist each worker's simulations use the worker's share of the cores
(``OMNI_THREADS``, :func:`omni_sim.device.default_threads`; unless set already): with two
workers on two cores, each batch stepped on both cores made four threads contend for two, and
a bank case run beside another took 15 % longer on two threads than on one (the ``armature``
case, two at once: 81-83 s against 68-72 s).

Under pytest-xdist, a run of slow tests only (``.ci/run``'s slow stage, ``--dist worksteal``)
is ordered for the scheduler:
pytest-xdist hands each worker a contiguous share of the collection and an idle worker steals
from the end of the other's queue, never its last tests, so a long test near the end ran alone
while the other worker idled.  Each worker's share is made of the tests a longest-first
assignment gives it (by the durations of one run, ``tests/slow_durations.json``; a test not
there counts as short), longest first.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]  # tests/test_temp_files.py runs a small suite with this conftest


#: The validation bank's distribution (bank/pyproject.toml).
BANK_DISTRIBUTION = "omni-alpha-bank"


def pytest_configure(config):
    from importlib import metadata

    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT")
    if workers and workers.isdigit() and "OMNI_THREADS" not in os.environ:
        os.environ["OMNI_THREADS"] = str(max(1, (os.cpu_count() or 1) // int(workers)))

    try:
        metadata.version(BANK_DISTRIBUTION)
    except metadata.PackageNotFoundError:
        raise pytest.UsageError(f"the validation bank ({BANK_DISTRIBUTION}) is not installed: "
                                'pip install -e ./bank (the README\'s test command, pip install -e ".[test]" '
                                "-e ./bank, installs it with the project)") from None


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    workers = getattr(config, "workerinput", {}).get("workercount", 0)  # in a pytest-xdist worker
    if workers < 2 or not items or not all(it.get_closest_marker("slow") for it in items):
        return
    import json

    seconds = json.loads((Path(__file__).parent / "slow_durations.json").read_text())["seconds"]
    items[:] = worksteal_order(items, lambda it: seconds.get(it.nodeid, 0.0), workers)


def worksteal_order(items: list, seconds, workers: int) -> list:
    """``items`` in the order that gives each of ``workers`` workers, in the contiguous share
    pytest-xdist's work stealing hands it at the start (``WorkStealingScheduling.check_schedule``:
    ``len // w`` to the first of ``w`` workers left), the items a longest-first assignment to the
    least loaded worker gives it, longest first (``seconds(item)``: its expected duration)."""
    order = sorted(items, key=lambda it: -seconds(it))  # stable: ties keep their order
    left, sizes = len(items), []
    for w in range(workers, 0, -1):
        sizes.append(left // w)
        left -= sizes[-1]
    shares, load = [[] for _ in sizes], [0.0] * len(sizes)
    for it in order:
        w = min((w for w in range(len(sizes)) if len(shares[w]) < sizes[w]), key=lambda w: load[w])
        shares[w].append(it)
        load[w] += seconds(it)
    return [it for share in shares for it in share]


def _listing(folder: Path) -> set[str]:
    return set(os.listdir(folder))


@pytest.fixture(scope="session", autouse=True)
def _temporary_files_under_pytest(tmp_path_factory):
    """``TMPDIR`` -> a folder of ``tmp_path_factory`` for the whole run; afterwards, nothing new
    in the system's temporary folder but pytest's own (else an error)."""
    system = Path(tempfile.gettempdir())
    base = tmp_path_factory.getbasetemp().resolve()
    ours = {base.relative_to(system.resolve()).parts[0]} if base.is_relative_to(system.resolve()) else set()
    before = _listing(system)
    scratch = tmp_path_factory.mktemp("tempdir")
    old_env, old_tempdir = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"] = str(scratch)
    tempfile.tempdir = str(scratch)
    try:
        yield scratch
    finally:
        tempfile.tempdir = old_tempdir
        if old_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = old_env
    new = sorted(_listing(system) - before - ours)
    if new and os.environ.get("OMNI_TESTS_TMP_CHECK", "1") != "0":
        pytest.fail(f"the tests left {len(new)} new entr{'y' if len(new) == 1 else 'ies'} in the "
                    f"system's temporary folder {system}: {', '.join(new)} (write under pytest's "
                    "tmp_path, or through tempfile, which the suite points at pytest's folder; "
                    "OMNI_TESTS_TMP_CHECK=0 skips this check where other programs write there)",
                    pytrace=False)
