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


from identification.dataset import atomic_output_dir, write_run
from identification.errors import UserError
from identification.identify import identify_runs
from identification.validation import Params, validate_runs, write_predictions
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim import truth

from .identify_report import write_identify_report

def _model_label(model_path) -> str:
    """``built-in scene_coulomb.xml`` for a built-in scene (where it is installed says
    nothing), else the path as given."""
    if model_path is None:
        return "built-in scene.xml"
    p = Path(model_path)
    if p.resolve().parent == om.MODELS_DIR.resolve():
        return f"built-in {p.name}"
    return str(model_path)


def run_reproduce(model_path=None, jobs=None, progress=False, model=None,
                  campaign="paper") -> dict:
    """Run every stage in memory; returns everything the writers need.

    ``model``: an already compiled (possibly modified) model to run instead of the file
    ``model_path`` (e.g. the friction study's scaled models); ``campaign``: the campaign to
    generate (name or file, :func:`omni_sim.experiments.campaign`).

    Raises
    ------
    UserError
        The model or campaign is bad, or identification failed (no inertia or alpha model).
    """
    from tqdm import tqdm

    from .accel import install
    install()  # compiled kernels: α simulation, CSV writing (loaded at their first use)
    in_memory = model is not None and model_path is None
    if model is None:
        model = om.load_model(model_path)
    t0 = time.perf_counter()
    bar = tqdm(total=5, disable=not progress, unit="stage", leave=False)
    bar.set_description("simulating the paper campaign")
    exps = ex.campaign(campaign)
    runs = ex.simulate(exps, model_path, jobs=jobs, progress=False, model=model)
    bar.update(1)
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
    scores["summary"]["inertia"] = truth.inertia_truth(model, ident.inertia.params)
    lin = truth.linear_truth(model, ident)
    bar.update(1)
    sim_time = sum(len(r.t) for r in runs) * ex.CONTROL_PERIOD_S
    wall = time.perf_counter() - t0
    scores["summary"]["run"] = {
        "simulated_time_s": sim_time, "wall_s_before_writing": wall,
        "model": ("in-memory model" if in_memory else _model_label(model_path)),
        "model_sha256": "in-memory model" if in_memory else ex.model_digest(model_path),
        "friction": runs[0].meta["friction"]}
    return {"model": model, "runs": runs, "ident": ident, "params": params_dict, "scores": scores,
            "predictions": predictions, "linear_truth": lin, "bar": bar}


def write_reproduce(folder: Path, res: dict, t0: float) -> None:
    """Write one reproduction into the (new, empty) ``folder``: dataset/, predictions/,
    params.json, identify/, figures, summary.json, scores.json, report.md.  ``t0``: its start
    (perf_counter), for the real-time factor."""
    (folder / "identify").mkdir()
    figures = _start_figures(folder, res)  # drawn in child processes meanwhile (POSIX)
    (folder / "dataset").mkdir()
    for run in res["runs"]:
        write_run(folder / "dataset", run)
    write_predictions(folder, res["runs"], res["predictions"])
    (folder / "params.json").write_text(json.dumps(res["params"], indent=2) + "\n")
    write_identify_report(res["ident"], folder / "identify", source="dataset/", figures=False)
    figures()
    summary = res["scores"]["summary"]
    summary["run"]["wall_s_total"] = time.perf_counter() - t0
    summary["run"]["real_time_factor"] = summary["run"]["simulated_time_s"] / summary["run"]["wall_s_total"]
    (folder / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    (folder / "scores.json").write_text(json.dumps(res["scores"], indent=2) + "\n")
    from .report import format_report
    (folder / "report.md").write_text(format_report(res))


#: Longest wait [s] for a forked figure child (it takes ~2 s; 30x that on a loaded machine).
FIGURES_TIMEOUT_S = 120.0
#: Forked children drawing the figures (the main process writes the CSVs meanwhile).
FIGURE_CHILDREN = 2


def _figure_tasks(folder: Path, res: dict) -> list[list]:
    """The figures of one reproduction (``folder``: the report's; ``folder/identify``: the
    identify report's) as ``FIGURE_CHILDREN`` lists of callables of similar drawing time."""
    from . import figures as F
    from . import identify_report as IR

    ident, ident_dir = res["ident"], folder / "identify"
    a = [F.fig_C_beta_vs_alpha, F.fig_alpha_vs_frequency, F.fig_inertia, F.fig_time_sine]
    b = [F.fig_nonlinear_vs_inertia, F.fig_bode, F.fig_inertia_truth, F.fig_step]
    tasks = [[lambda fn=fn: fn(folder, res) for fn in a],
             [lambda: IR.write_identify_figures(ident, ident_dir)]
             + [lambda fn=fn: fn(folder, res) for fn in b]]
    assert sorted(fn.__name__ for fn in a + b) == sorted(fn.__name__ for fn in F.FIGURES)
    if FIGURE_CHILDREN == 1:
        return [tasks[0] + tasks[1]]
    return tasks


def _start_figures(folder: Path, res: dict):
    """Start drawing the figures of ``res`` into ``folder`` (and ``folder/identify``, which
    must exist); returns a function that waits for them (and raises if drawing failed).  Where
    ``fork`` exists the figures are drawn in forked children (matplotlib is imported there
    only), in parallel with the writing of the dataset and predictions; elsewhere they are drawn
    at the wait."""
    import multiprocessing as mp
    import os

    groups = _figure_tasks(folder, res)

    def draw(tasks):
        for task in tasks:
            task()

    if "fork" not in mp.get_all_start_methods() or os.environ.get("OMNI_FIGURES_INLINE"):
        def draw_all():
            for tasks in groups:
                draw(tasks)
        return draw_all
    ctx = mp.get_context("fork")
    children = []
    for tasks in groups:
        queue = ctx.SimpleQueue()

        def child(tasks=tasks, queue=queue):
            try:
                draw(tasks)
                queue.put(None)
            except BaseException as exc:  # reported to the parent
                queue.put(f"{type(exc).__name__}: {exc}")

        proc = ctx.Process(target=child, daemon=True)
        proc.start()
        children.append((proc, queue, tasks))

    def wait():
        # the message is a few bytes: a child never blocks on the pipe.  A forked child of a
        # threaded process can in principle hang on a lock another thread held at the fork:
        # after FIGURES_TIMEOUT_S it is killed and its figures are drawn here instead.
        errors = []
        deadline = time.monotonic() + FIGURES_TIMEOUT_S
        for proc, queue, tasks in children:
            proc.join(max(0.0, deadline - time.monotonic()))
            if proc.is_alive():
                proc.kill()
                proc.join()
                draw(tasks)
                continue
            error = queue.get() if not queue.empty() else f"exit code {proc.exitcode}"
            if error is not None:
                errors.append(error)
        if errors:
            raise RuntimeError(f"drawing the figures failed ({'; '.join(errors)})")

    return wait


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


def _check_out(out: Path, force: bool) -> None:
    if out.is_dir() and any(out.iterdir()) and not force:
        raise UserError(f"{out}: output folder exists and is not empty (use --force to replace it)")


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
    _check_out(out, args.force)
    t0 = time.perf_counter()
    res = run_reproduce(model_path, args.jobs, progress=sys.stderr.isatty())
    bar = res["bar"]
    bar.set_description("writing report and figures")
    with atomic_output_dir(out, force=args.force) as tmp:
        write_reproduce(tmp, res, t0)
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
    from .comparison import write_comparison

    _check_out(out, force)
    results, starts = {}, {}
    for fam in om.FRICTION_FAMILIES:
        starts[fam] = time.perf_counter()
        results[fam] = run_reproduce(om.scene_path(fam), jobs, progress=sys.stderr.isatty(),
                                     campaign=campaign)
        results[fam]["bar"].close()
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
