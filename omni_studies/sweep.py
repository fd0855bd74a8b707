"""The sweep engine: studies of many model variants on Dask (``dask.distributed``); the command
``omni sweep`` and its figures are :mod:`omni_app.sweep`.

A study file (TOML, ``omni sweep --example``) names a base model, the pipeline every variant
runs and the parameters to vary (a grid, a list of rows, or seeded random samples).  Each variant
is one Dask task (``client.submit(..., retries=2)``) on a ``LocalCluster`` of one-thread worker
processes listening on 127.0.0.1 (default) or on an existing cluster (``--scheduler``); its
rollouts run on one thread.  The client writes each finished variant atomically into
``DIR/variants/<id>/`` (``result.json`` plus the pipeline's own files), so a killed study resumes
where it stopped; ``DIR/results.csv`` is rebuilt from the variants' ``result.json`` in id order.
Results are frozen objects: a variant's :class:`VariantResult` (``result.json``, its figures a
typed record per pipeline), :func:`run_sweep`'s :class:`SweepSummary`; the writers take them.

Pipelines:

* ``reproduce``: the reproduce job's stages in memory (generate the campaign, identify, validate
  both models, inertia against MuJoCo's mass matrix) with the variant's run settings; the
  summary figures.
* ``discrepancy``: "measured" data of the variant with a hidden effect of the validation
  bank's cases, ``bank.hidden`` (installed from the source checkout: :mod:`.bank_link`; the
  compact experiment set of :mod:`discrepancy.experiment_set`, quantised, noisy encoder), the
  discrepancy workflow with the variant as the nominal model; the effects it names, whether the
  bank's criteria (``bank.hidden.assess``) pass, the gap's shrink factor.
* ``simulate``: the campaign only; tracking errors (cheap: for checking a study file).

This module runs a study (:func:`run_sweep`: the Dask cluster and the output folder); the study
file is :mod:`omni_studies.sweep_study`, the pipelines :mod:`omni_studies.sweep_pipelines`, the
results and ``results.csv``'s text :mod:`omni_studies.sweep_results`.  Their public names are
importable from here as well.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import time
import uuid
from pathlib import Path

from identification.errors import UserError

from .sweep_pipelines import run_variant
from .sweep_results import (FIGURE_TYPES, FIGURES, TIMING_COLUMNS, DiscrepancyFigures, Figures,
                            ReproduceFigures, SimulateFigures, SweepSummary, VariantOutput,
                            VariantResult, cell_text, read_table, table_text)
from .sweep_study import EXAMPLE, PIPELINES, Study, load_study, parse_study, variant_seed

__all__ = ["CONNECT_TIMEOUT_S", "DiscrepancyFigures", "EXAMPLE", "FIGURES", "FIGURE_TYPES", "Figures",
           "PIPELINES", "ReproduceFigures", "SimulateFigures", "Study", "SweepSummary",
           "TIMING_COLUMNS", "VariantOutput", "VariantResult", "cell_text", "check_out", "finished",
           "load_study", "parse_study", "read_table", "read_variants", "run_sweep", "run_variant",
           "table_text", "variant_seed", "write_table"]

#: Seconds to wait for an existing scheduler (--scheduler).
CONNECT_TIMEOUT_S = 20


# -- the output folder ---------------------------------------------------------------------
def _write_variant(out: Path, res: VariantOutput) -> None:
    """``out/variants/<id>/`` atomically: a temporary folder renamed into place."""
    vdir = out / "variants"
    final = vdir / res.result.id
    tmp = vdir / f".{res.result.id}.{uuid.uuid4().hex}.tmp"
    tmp.mkdir(parents=True)
    for name, text in res.files.items():
        (tmp / name).write_text(text)
    (tmp / "result.json").write_text(json.dumps(res.result.to_json(), indent=2, default=float) + "\n")
    if final.exists():
        shutil.rmtree(final)
    os.rename(tmp, final)


def finished(out: Path) -> set[str]:
    """Ids of the variants with a complete output folder."""
    vdir = out / "variants"
    if not vdir.is_dir():
        return set()
    return {d.name for d in vdir.iterdir() if not d.name.startswith(".") and (d / "result.json").is_file()}


def read_variants(out: Path, study: Study) -> tuple[VariantResult, ...]:
    """The finished variants' results (``out/variants/<id>/result.json``), in id order."""
    files = [Path(out) / "variants" / vid / "result.json" for vid, _ in study.variants]
    return tuple(VariantResult.from_json(json.loads(f.read_text())) for f in files if f.is_file())


def write_table(out: Path, study: Study, variants=None) -> Path:
    """``out/results.csv`` (:func:`table_text`) of ``variants`` (default: :func:`read_variants`),
    written atomically."""
    out = Path(out)
    variants = read_variants(out, study) if variants is None else variants
    tmp = out / ".results.csv.tmp"
    tmp.write_text(table_text(study, variants))
    os.replace(tmp, out / "results.csv")
    return out / "results.csv"


def check_out(out: Path, study: Study) -> None:
    """Check the output folder before any work, writing nothing: not a file, its parent a
    writable folder; a new or empty folder, or one holding this study (a resume).

    Raises
    ------
    UserError
        Any of those is not so."""
    from identification.dataset import check_output_dir

    check_output_dir(out, force=True)  # a file, a missing or read-only parent (a resume: not empty)
    copy = out / "spec.toml"
    if copy.is_file():
        if copy.read_text() != study.text:
            raise UserError(f"{out}: holds a study with a different spec ({copy}); "
                            "use a new --out folder")
    elif out.is_dir() and any(p.name != "variants" for p in out.iterdir()):
        raise UserError(f"{out}: output folder exists, is not empty and holds no study (spec.toml)")


def _prepare_out(out: Path, study: Study) -> None:
    """The output folder (:func:`check_out`): ``spec.toml`` and ``variants/``; leftovers of a
    killed run removed."""
    check_out(out, study)
    copy = out / "spec.toml"
    (out / "variants").mkdir(parents=True, exist_ok=True)
    if not copy.is_file():
        (out / ".spec.toml.tmp").write_text(study.text)
        os.replace(out / ".spec.toml.tmp", copy)
    for d in (out / "variants").iterdir():  # leftovers of a killed run
        if d.name.startswith(".") and d.name.endswith(".tmp"):
            shutil.rmtree(d, ignore_errors=True)


def _client(workers: int | None, scheduler: str | None):
    """A Dask client: on ``scheduler``, or on a new LocalCluster (everything on 127.0.0.1, the
    dashboard on a free loopback port)."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s"), None
        except (OSError, TimeoutError) as exc:
            raise UserError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


def run_sweep(study: Study, out: str | os.PathLike, workers: int | None = None,
              scheduler: str | None = None, progress: bool | None = None) -> SweepSummary:
    """Run every unfinished variant of ``study`` into ``out``; returns a frozen
    :class:`SweepSummary` (every variant's result, what ran, what was skipped, the wall time)."""
    from distributed import as_completed
    from tqdm import tqdm

    out = Path(out)
    check_out(out, study)  # before the cluster starts; written only once it runs
    done = finished(out)
    todo = [j for j in study.jobs() if j["id"] not in done]
    t0 = time.perf_counter()
    if not todo:
        _prepare_out(out, study)
    else:
        client, cluster = _client(workers, scheduler)
        try:
            _prepare_out(out, study)
            tag = hashlib.sha256(study.text.encode()).hexdigest()[:10]
            futures = [client.submit(run_variant, j, retries=2, pure=False,
                                     key=f"omni-sweep-{tag}-{j['id']}-{uuid.uuid4().hex[:6]}")
                       for j in todo]
            bar = tqdm(total=len(study.variants), initial=len(done), unit="variant",
                       desc="sweep", disable=progress is False or (progress is None and not sys.stderr.isatty()))
            for fut in as_completed(futures):
                _write_variant(out, fut.result())
                bar.update(1)
            bar.close()
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    variants = read_variants(out, study)
    write_table(out, study, variants)
    return SweepSummary(variants, ran=len(todo), skipped=len(done), wall_s=time.perf_counter() - t0)
