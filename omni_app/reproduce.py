"""``omni reproduce``: the paper, end to end, on the virtual Omni, checked against ground truth.

Stages: generate the paper campaign (Table 1 sines, Table 2 squares) -> identify (2.1-2.3.5)
-> validate both models (Tables 8, 11) -> compare the identified inertia model with MuJoCo's
mass matrix at the 25 Table 2 poses -> write ``summary.json``, ``predictions/``, ``params.json``,
``report.md`` and the figures (``fig04``-``fig14`` as the paper's, plus ``inertia_truth.png``).
The dataset itself is written to ``dataset/`` so every number can be re-derived with
``omni identify`` / ``omni validate``.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace
from pathlib import Path


from identification.dataset import atomic_output_dir, check_output_dir, write_run
from identification.errors import UserError
from identification.validation import write_predictions
from omni_sim import model as om
from omni_sim.device import Device
from omni_studies.reproduce import STAGES, ReproduceResult, analyse, run_reproduce, simulate_campaign

from . import figures as F
from .identify_report import write_identify_figures, write_identify_report


def stage_bar(progress: bool):
    """A tqdm bar over the study's stages and the writing (:data:`STAGES` + 1), and the
    callback that moves it on (pass it as the study's ``progress``)."""
    from tqdm import tqdm

    bar = tqdm(total=len(STAGES) + 1, disable=not progress, unit="stage", leave=False)
    started = []

    def advance(stage: str) -> None:
        if started:
            bar.update(1)
        started.append(stage)
        bar.set_description(stage)

    return bar, advance


def write_dataset(folder: Path, runs) -> None:
    """The campaign's runs into the (new) ``folder``."""
    folder.mkdir()
    for run in runs:
        write_run(folder, run)


def draw_figures(folder: Path, res: ReproduceResult) -> None:
    """The reproduction's figures (the paper's and the identification's) into ``folder``
    (``res.device`` is not read)."""
    F.write_figures(folder, res)
    write_identify_figures(res.ident, folder / "identify")


def worker_pool():
    """Two worker processes that draw the figures and write the dataset while this process
    goes on (:func:`reproduce_command`), started now (one imports matplotlib while the command
    simulates): a ``concurrent.futures`` pool with the ``spawn`` start method (safe with
    threads, the same on every platform).  A spawned worker imports the caller's main script,
    so only ``omni reproduce`` (a guarded main) uses it.  Measured on an idle 2-core machine
    (A/B, 5-6 pairs of whole commands): drawing in a worker while this process writes the CSV
    files took the command from 5.2-5.3 s to 4.0 s; with the other core busy it gains
    nothing."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(max_workers=2, mp_context=mp.get_context("spawn"))
    pool.submit(F._plt)  # start a worker and import matplotlib there
    return pool


def write_reproduce(folder: Path, res: ReproduceResult, t0: float, pool=None, dataset=None) -> float:
    """Write one reproduction into the (new, empty) ``folder``: dataset/, predictions/,
    params.json, identify/, figures, summary.json, scores.json, report.md.  ``t0``: its start
    (perf_counter), for the real-time factor.  ``pool`` (:func:`worker_pool`): the figures are
    drawn there while this process writes the predictions (None: here); ``dataset``: the
    future of the dataset already being written there (:func:`write_dataset`; None: written
    here).  Returns the whole wall time [s] (``summary.json``'s ``run.wall_s_total``; ``res``
    is not changed)."""
    (folder / "identify").mkdir()
    figures = None
    if pool is not None:
        shown = F.TIME_FIGURE_RUNS  # the only runs and predictions the figures draw
        # nor do they read the device: a MuJoCo model, whose unpickling imports MuJoCo there
        figures = pool.submit(draw_figures, folder, replace(
            res, device=None, runs=tuple(r for r in res.runs if r.name in shown),
            predictions={n: p for n, p in res.predictions.items() if n in shown}))
    if dataset is None:
        write_dataset(folder / "dataset", res.runs)
    write_predictions(folder, list(res.runs), res.predictions)
    (folder / "params.json").write_text(json.dumps(res.params, indent=2) + "\n")
    write_identify_report(res.ident, folder / "identify", source="dataset/", figures=False)
    if figures is None:
        draw_figures(folder, res)
    for job in (dataset, figures):
        if job is not None:
            job.result()  # a worker's error, if any, is raised here
    wall_s_total = time.perf_counter() - t0
    (folder / "summary.json").write_text(json.dumps(res.summary.to_json(wall_s_total), indent=2) + "\n")
    (folder / "scores.json").write_text(json.dumps(res.to_json(wall_s_total), indent=2) + "\n")
    from .report import format_report
    (folder / "report.md").write_text(format_report(res))
    return wall_s_total


def one_blas_thread():
    """A context limiting BLAS (numpy's and scipy's OpenBLAS) to one thread.  The method's
    least-squares problems are small (thousands of samples by at most 7 columns): a second
    BLAS thread gains nothing.  The numbers do not depend on it (the same files, byte for
    byte)."""
    import contextlib

    try:
        from threadpoolctl import threadpool_limits
        return threadpool_limits(limits=1, user_api="blas")
    except Exception:  # noqa: BLE001  (threadpoolctl missing or failing: BLAS as configured)
        return contextlib.nullcontext()


def _print_summary(res: ReproduceResult, label: str = "") -> None:
    """Every target of the report's table, met or not, with its measured figure (the same
    rows: :func:`omni_app.report.summary_lines`)."""
    from .report import summary_lines

    for line in summary_lines(res, label):
        print(line)


def reproduce_command(args) -> int:
    """``omni reproduce [--model PATH | --friction {coulomb,lugre,all}] [--out DIR] [--force]
    [--jobs N]``."""
    out = Path(args.out)
    friction = getattr(args, "friction", None)
    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs must be >= 1, got {args.jobs}")
    if friction == "all":
        if args.model is not None:
            om.model_path(args.model, friction)  # raises: a model file and a family
        return reproduce_all(out, force=args.force, jobs=args.jobs)
    check_output_dir(out, args.force, inputs=(om.model_path(args.model, friction),))
    device = Device.load(args.model, friction=friction)  # a bad model file: refused before the workers start
    t0 = time.perf_counter()
    bar, advance = stage_bar(sys.stderr.isatty())
    # the pool is left first: its jobs end before a failure removes the temporary folder
    with one_blas_thread(), atomic_output_dir(out, force=args.force) as tmp, worker_pool() as pool:
        try:
            sim = simulate_campaign(device, args.jobs, progress=advance)
            dataset = pool.submit(write_dataset, tmp / "dataset", sim.runs)  # while it analyses
            res = analyse(sim, advance)
            advance("writing report and figures")
            wall_s_total = write_reproduce(tmp, res, t0, pool, dataset)
        finally:
            bar.close()
    _print_summary(res)
    print(f"wrote {out}/report.md, summary.json, figures and predictions/ "
          f"(real-time factor {res.summary.run.real_time_factor(wall_s_total):.0f})")
    return 0


def reproduce_all(out: Path, force: bool = False, jobs: int | None = None,
                  campaign: str = "paper") -> int:
    """``omni reproduce --friction all``: the reproduction of every friction family into
    ``out/<family>/`` and their comparison (``out/comparison.json``, ``comparison.md``,
    overlay figures; :mod:`omni_app.comparison`).  ``campaign``: the paper's (the command's),
    or a smaller one (tests)."""
    check_output_dir(out, force)
    with one_blas_thread():
        return _reproduce_all(out, force, jobs, campaign)


def _reproduce_all(out: Path, force: bool, jobs: int | None, campaign: str) -> int:
    from tqdm import tqdm

    from .comparison import write_comparison

    results, starts = {}, {}
    progress = sys.stderr.isatty()
    families = tqdm(om.FRICTION_FAMILIES, unit="family", disable=not progress, leave=False)
    for fam in families:
        families.set_description(f"friction family {fam}")
        starts[fam] = time.perf_counter()
        bar, advance = stage_bar(progress)  # each family's stages in a bar below this one
        try:
            results[fam] = run_reproduce(Device.load(friction=fam), jobs, campaign, advance)
        finally:
            bar.close()
    families.close()
    with atomic_output_dir(out, force=force) as tmp:
        for fam, res in results.items():
            (tmp / fam).mkdir()
            write_reproduce(tmp / fam, res, starts[fam])
        comparison = write_comparison(tmp, results)
    for fam, res in results.items():
        _print_summary(res, label=f"{fam}: ")
    for fam, c in comparison["families"].items():
        print(f"{fam}: Table 3 worst error C {100 * c['table3']['C_linear_worst_rel_error']:+.1f} %, "
              f"beta~ {100 * c['table3']['beta_tilde_linear_worst_rel_error']:+.1f} %; resonance "
              f"{c['resonance_hz_65_90']:.2f} Hz; C(alpha) fall {c['C_alpha_fall']:.2f}x")
    print(f"wrote {out}/<family>/ for {', '.join(results)} and {out}/comparison.json, comparison.md")
    return 0
