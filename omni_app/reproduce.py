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
from pathlib import Path


from identification.dataset import atomic_output_dir, check_output_dir, write_run
from identification.errors import UserError
from identification.identify import identify_runs
from identification.validation import Params, validate_runs, write_predictions
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim import truth
from omni_sim.device import Device

from . import figures as F
from .identify_report import write_identify_figures, write_identify_report


def _model_label(model_path) -> str:
    """``built-in scene_coulomb.xml`` for a built-in scene (where it is installed says
    nothing), else the path as given."""
    if model_path is None:
        return "built-in scene.xml"
    p = Path(model_path)
    if p.resolve().parent == om.OMNI_DIR.resolve():
        return f"built-in {p.name}"
    return str(model_path)


def run_reproduce(model_path=None, jobs=None, progress=False, model=None,
                  campaign="paper") -> dict:
    """Run every stage in memory (:func:`simulate_campaign`, then :func:`analyse`); returns
    everything the writers need.

    ``model``: an already compiled (possibly modified) model to run instead of the file
    ``model_path`` (e.g. the friction study's scaled models); ``campaign``: the campaign to
    generate (name or file, :func:`omni_sim.experiments.campaign`).

    Raises
    ------
    UserError
        The model or campaign is bad, or identification failed (no inertia or alpha model).
    """
    return analyse(simulate_campaign(model_path, jobs, progress, model, campaign))


def simulate_campaign(model_path=None, jobs=None, progress=False, model=None,
                      campaign="paper") -> dict:
    """The first stage: the campaign's runs on the model (arguments: :func:`run_reproduce`);
    returns the stages' shared state (``runs``, ``device``, the progress ``bar``, ...)."""
    from tqdm import tqdm

    from .accel import install
    install()  # the compiled α loop (loaded at its first use)
    in_memory = model is not None and model_path is None
    # built once: the campaign, the ground truth; from a file it knows the file's digest
    device = Device.load(model_path) if model is None else Device(model)
    t0 = time.perf_counter()
    bar = tqdm(total=5, disable=not progress, unit="stage", leave=False)
    bar.set_description("simulating the paper campaign")
    exps = ex.campaign(campaign)
    # a loaded device names its file itself; a compiled model is labelled by model_path (if any)
    runs = ex.simulate(exps, None if model is None else model_path, jobs=jobs, progress=False,
                       device=device)
    bar.update(1)
    run_meta = {"model": ("in-memory model" if in_memory else _model_label(model_path)),
                "model_sha256": "in-memory model" if in_memory else runs[0].meta["model_sha256"],
                "friction": runs[0].meta["friction"]}
    return {"model": device.model, "device": device, "runs": runs, "bar": bar, "t0": t0, "run_meta": run_meta}


def analyse(res: dict) -> dict:
    """The other stages on :func:`simulate_campaign`'s runs: identify, validate both models,
    compare with the ground truth; adds ``ident``, ``params``, ``scores``, ``predictions`` and
    ``linear_truth`` to ``res`` and returns it."""
    bar, runs, device = res["bar"], res["runs"], res["device"]
    bar.set_description("identifying")
    ident = identify_runs(runs)
    if ident.inertia is None or ident.alpha_model is None:
        bar.close()
        raise UserError("identification failed on the generated campaign: " + "; ".join(ident.warnings))
    params_dict = ident.to_params()
    bar.update(1)
    bar.set_description("validating")
    params = Params(ident.inertia.params, ident.alpha_model, params_dict["poses"])
    scores, predictions = validate_runs(runs, params)
    bar.update(1)
    bar.set_description("ground truth")
    scores["summary"]["inertia"] = truth.inertia_truth(device, ident.inertia.params)
    lin = truth.linear_truth(device, ident)
    bar.update(1)
    sim_time = sum(len(r.t) for r in runs) * ex.CONTROL_PERIOD_S
    scores["summary"]["run"] = {"simulated_time_s": sim_time,
                                "wall_s_before_writing": time.perf_counter() - res["t0"],
                                **res["run_meta"]}
    res.update(ident=ident, params=params_dict, scores=scores, predictions=predictions,
               linear_truth=lin)
    return res


def write_dataset(folder: Path, runs) -> None:
    """The campaign's runs into the (new) ``folder``."""
    folder.mkdir()
    for run in runs:
        write_run(folder, run)


def draw_figures(folder: Path, res: dict) -> None:
    """The reproduction's figures (the paper's and the identification's) into ``folder``."""
    F.write_figures(folder, res)
    write_identify_figures(res["ident"], folder / "identify")


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


def write_reproduce(folder: Path, res: dict, t0: float, pool=None, dataset=None) -> None:
    """Write one reproduction into the (new, empty) ``folder``: dataset/, predictions/,
    params.json, identify/, figures, summary.json, scores.json, report.md.  ``t0``: its start
    (perf_counter), for the real-time factor.  ``pool`` (:func:`worker_pool`): the figures are
    drawn there while this process writes the predictions (None: here); ``dataset``: the
    future of the dataset already being written there (:func:`write_dataset`; None: written
    here)."""
    (folder / "identify").mkdir()
    figures = None
    if pool is not None:
        shown = F.TIME_FIGURE_RUNS  # the only runs and predictions the figures draw
        figures = pool.submit(draw_figures, folder, {
            "ident": res["ident"], "scores": res["scores"],
            "runs": [r for r in res["runs"] if r.name in shown],
            "predictions": {n: p for n, p in res["predictions"].items() if n in shown}})
    if dataset is None:
        write_dataset(folder / "dataset", res["runs"])
    write_predictions(folder, res["runs"], res["predictions"])
    (folder / "params.json").write_text(json.dumps(res["params"], indent=2) + "\n")
    write_identify_report(res["ident"], folder / "identify", source="dataset/", figures=False)
    if figures is None:
        draw_figures(folder, res)
    for job in (dataset, figures):
        if job is not None:
            job.result()  # a worker's error, if any, is raised here
    summary = res["scores"]["summary"]
    summary["run"]["wall_s_total"] = time.perf_counter() - t0
    summary["run"]["real_time_factor"] = summary["run"]["simulated_time_s"] / summary["run"]["wall_s_total"]
    (folder / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    (folder / "scores.json").write_text(json.dumps(res["scores"], indent=2) + "\n")
    from .report import format_report
    (folder / "report.md").write_text(format_report(res))


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


def _print_summary(res: dict, label: str = "") -> None:
    s = res["scores"]["summary"]
    st, sn, inr = s["step"], s["sine"], s["inertia"]
    print(f"{label}inertia model vs MuJoCo at {inr['n_poses']} Table 2 poses: max error "
          f"{100 * inr['max_rel_error']:.1f} %")
    print(f"{label}step: alpha better at {st['alpha_better_poses']}/{st['n_poses']} poses; median |error| "
          f"linear {1e3 * st['median_abs_error_linear_rad']:.2f} mrad, alpha "
          f"{1e3 * st['median_abs_error_alpha_rad']:.2f} mrad (ratio {st['ratio_of_medians']:.2f})")
    print(f"{label}sine: phase p90 linear {sn['phase_p90_linear_deg']:.1f} deg, alpha "
          f"{sn['phase_p90_alpha_deg']:.1f} deg; magnitude p90 linear {sn['magnitude_p90_linear']:.3f}, "
          f"alpha {sn['magnitude_p90_alpha']:.3f}")


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
    model_path = None if (args.model is None and friction is None) else om.model_path(args.model, friction)
    check_output_dir(out, args.force, inputs=(model_path,))
    Device(om.load_model(model_path))  # a bad model file: refused before the workers start
    t0 = time.perf_counter()
    # the pool is left first: its jobs end before a failure removes the temporary folder
    with one_blas_thread(), atomic_output_dir(out, force=args.force) as tmp, worker_pool() as pool:
        res = simulate_campaign(model_path, args.jobs, progress=sys.stderr.isatty())
        dataset = pool.submit(write_dataset, tmp / "dataset", res["runs"])  # while it analyses
        res = analyse(res)
        bar = res["bar"]
        bar.set_description("writing report and figures")
        write_reproduce(tmp, res, t0, pool, dataset)
    bar.update(1)
    bar.close()
    _print_summary(res)
    print(f"wrote {out}/report.md, summary.json, figures and predictions/ "
          f"(real-time factor {res['scores']['summary']['run']['real_time_factor']:.0f})")
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
    for fam in families:  # each family's stages in a bar below this one
        families.set_description(f"friction family {fam}")
        starts[fam] = time.perf_counter()
        results[fam] = run_reproduce(om.scene_path(fam), jobs, progress=progress, campaign=campaign)
        results[fam]["bar"].close()
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
