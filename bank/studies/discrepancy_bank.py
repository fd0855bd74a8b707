"""The hidden-effect bank through ``omni discrepancy``'s workflow: each case's record entry, the
bank's settings, the gear_efficiency case's record (:mod:`bank.writers.bank_report` renders and
writes them; ``scripts/discrepancy_bank.py`` is the command).

For every case of :data:`bank.hidden.CASES` a truth model (the virtual Omni
with the effect written by :mod:`bank.omni_truths` with MuJoCo's own features,
independently of the effect library) generates quantised, noisy "measured" runs (exact ones for
``none_exact``); the workflow sees only those runs and the nominal model, and
:func:`bank.hidden.assess` gives the verdict.  A case with a truth of its own
(``truth="servo"``: the geared-servo pendulum of :mod:`bank.servo_truth`) is
given its own nominal model and target (:func:`bank.hidden.nominal`).

The gear_efficiency case's truth is written in another form than the library's law
(:func:`bank.servo_truth.generate_efficiency`: a gear efficiency law with a
smooth sign; judged by :func:`~bank.servo_truth.assess_efficiency`).
"""

from __future__ import annotations

import datetime as dt
import os
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from discrepancy import experiment_set
from identification.errors import UserError

from bank import hidden, servo_truth

#: The checkout this module runs from (a case's nominal model is named relative to it).
ROOT = Path(__file__).resolve().parents[2]
#: The settings the gear_efficiency record keeps of :func:`bank_meta`'s.
EFFICIENCY_META = ("commit", "started", "cpus", "load_start", "nice", "jobs", "command", "note")


def now() -> str:
    """The time of day in UTC, to the minute (the records' dates)."""
    return dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def select(names: Iterable[str] | None) -> list[hidden.HiddenCase]:
    """The bank's cases named in ``names`` (None: all), in the bank's order.  A name that is not
    one of them (a nominal-off case runs as a test only, ``pytest -m bank``) is refused."""
    known = {c.name for c in hidden.CASES}
    unknown = sorted(set(names or ()) - known)
    if unknown:
        raise UserError(f"not a case of the bank's record: {', '.join(unknown)} (its cases: {', '.join(sorted(known))}; "
                        "the nominal-off cases run as tests: pytest -m bank -k NAME)")
    return [c for c in hidden.CASES if names is None or c.name in names]


def bank_meta(*, commit: str, command: str, json_name: str, jobs: int | None, note: str) -> dict:
    """The bank run's settings: code, start, machine, and the experiment set every case runs."""
    return {"commit": commit, "started": now(), "cpus": os.cpu_count(),
            "load_start": os.getloadavg()[0], "nice": os.nice(0), "jobs": jobs,
            "command": command,
            "json": json_name,
            "runs": len(experiment_set.experiments()), "run_s": experiment_set.DURATION_S,
            "frequencies_hz": ", ".join(map(str, experiment_set.FREQUENCIES_HZ)),
            "amplitudes_rad": ", ".join(map(str, experiment_set.AMPLITUDES_RAD)),
            "step_amplitudes_rad": ", ".join(map(str, experiment_set.STEP_AMPLITUDES_RAD)),
            "poses_deg": ", ".join(str(p) for p in experiment_set.POSES), "noise_rad": experiment_set.NOISE_RAD,
            "note": note}


def case_entry(c: hidden.HiddenCase, *, jobs: int | None, merged: dict | None = None) -> dict:
    """Case ``c`` through the workflow: its record entry (the case, the verdict and the full
    report, or the crash; time and load).  ``merged``: the meta of a run merged into an existing
    record (``--merge``): the entry records its commit, start and command."""
    from discrepancy.workflow import run_discrepancy

    t0 = time.perf_counter()
    model, target = hidden.nominal(c)
    entry = {"hidden": [list(e) for e in c.effects], "outside": [list(e) for e in c.outside],
             "expect": list(c.expect), "exact": c.exact, "note": c.note, "gap_lives": c.gap_lives,
             "truth": c.truth}
    if model is not None:
        entry.update(model=str(Path(model).relative_to(ROOT)) if Path(model).is_relative_to(ROOT)
                     else str(model), target=[target.joint, target.actuator])
    if merged is not None:
        entry.update(commit=merged["commit"], started=now(), command=merged["command"])
    runs = hidden.generate(c, jobs=jobs)
    try:
        rep = run_discrepancy(runs, model, jobs=jobs, target=target).report
    except Exception as exc:  # a crash of the workflow is a result of the bank, not its end
        entry.update({"pass": False, "why": f"workflow crashed: {type(exc).__name__}: {exc}"})
    else:
        ok, why = hidden.assess(c, rep)
        entry.update({"pass": ok, "why": why, "report": rep})
    entry.update({"seconds": time.perf_counter() - t0, "finished": now(),
                  "load_after": os.getloadavg()[0]})
    return entry


def run_bank(cases: Iterable[hidden.HiddenCase], data: dict, meta: dict, *, jobs: int | None,
             merge: bool, on_case: Callable[[str, dict, dict], None]) -> dict:
    """Every case of ``cases`` into ``data["cases"]``, kept in the bank's order (a merged case in
    its place); ``on_case(name, entry, data)`` after each (the caller writes the record: a
    stopped run keeps what it did).  Without ``merge`` ``meta`` (``data["meta"]``) gets the
    end and the total time; a merge leaves the bank run's meta as it was."""
    t_all = time.perf_counter()
    order = [k.name for k in hidden.CASES]
    for c in cases:
        entry = case_entry(c, jobs=jobs, merged=meta if merge else None)
        data["cases"][c.name] = entry
        data["cases"] = dict(sorted(data["cases"].items(),
                                    key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order)))
        on_case(c.name, entry, data)
    if not merge:
        meta["finished"] = now()
        meta["total_s"] = time.perf_counter() - t_all
    return data


def efficiency_report(meta: dict, *, jobs: int | None, only_load_friction: bool = False) -> dict:
    """The workflow's report on the gear_efficiency case; ``meta`` gets the time, end and load.
    ``only_load_friction``: the workflow restricted to the library's ``load_friction`` (a
    diagnostic: what the engine's law makes of this truth when nothing else is scored)."""
    from discrepancy.workflow import run_discrepancy

    cands = ("load_friction",) if only_load_friction else None
    t0 = time.perf_counter()
    runs = servo_truth.generate_efficiency()
    rep = run_discrepancy(runs, servo_truth.model_path(), jobs=jobs, target=servo_truth.target(),
                          candidates=cands).report
    meta.update(seconds=time.perf_counter() - t0, finished=now(), load_after=os.getloadavg()[0])
    return rep


def efficiency_record(meta: dict, rep: dict, record: dict | None = None) -> tuple[dict, bool]:
    """The gear_efficiency record of report ``rep`` and whether it passes.  With ``record`` (the
    existing one) ``rep`` is the ``load_friction``-only diagnostic, stored in it under
    ``load_friction_only`` with its own meta; the verdict stays the record's."""
    if record is not None:
        record["load_friction_only"] = {"meta": meta, "candidates": ["load_friction"], "report": rep}
        return record, record["pass"]
    ok, why = servo_truth.assess_efficiency(rep)
    return {"meta": meta, "case": servo_truth.GEAR_EFFICIENCY_CASE, "pass": ok, "why": why, "report": rep}, ok
