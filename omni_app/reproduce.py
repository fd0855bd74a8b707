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

def run_reproduce(model_path=None, jobs=None, progress=False) -> dict:
    """Run every stage in memory; returns everything the writers need."""
    from tqdm import tqdm

    model = om.load_model(model_path)
    t0 = time.perf_counter()
    bar = tqdm(total=5, disable=not progress, unit="stage", leave=False)
    bar.set_description("simulating the paper campaign")
    exps = ex.campaign("paper")
    runs = ex.simulate(exps, model_path, jobs=jobs, progress=False, model=model)
    bar.update(1)
    bar.set_description("identifying")
    ident = identify_runs(runs)
    if ident.inertia is None or ident.alpha_model is None:
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
    scores["summary"]["run"] = {"simulated_time_s": sim_time, "wall_s_before_writing": wall,
                                "model": str(model_path) if model_path else "built-in scene.xml",
                                "model_sha256": ex.model_digest(model_path)}
    return {"model": model, "runs": runs, "ident": ident, "params": params_dict, "scores": scores,
            "predictions": predictions, "linear_truth": lin, "bar": bar}


def reproduce_command(args) -> int:
    """``omni reproduce [--model PATH] [--out DIR] [--force] [--jobs N]``."""
    out = Path(args.out)
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise UserError(f"{out}: output folder exists and is not empty (use --force to replace it)")
    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs must be >= 1, got {args.jobs}")
    t0 = time.perf_counter()
    res = run_reproduce(args.model, args.jobs, progress=sys.stderr.isatty())
    bar = res["bar"]
    bar.set_description("writing report and figures")
    with atomic_output_dir(out, force=args.force) as tmp:
        (tmp / "dataset").mkdir()
        for run in res["runs"]:
            write_run(tmp / "dataset", run)
        write_predictions(tmp, res["runs"], res["predictions"])
        (tmp / "params.json").write_text(json.dumps(res["params"], indent=2) + "\n")
        (tmp / "identify").mkdir()
        write_identify_report(res["ident"], tmp / "identify", source="dataset/")
        from .figures import write_figures
        write_figures(tmp, res)
        summary = res["scores"]["summary"]
        summary["run"]["wall_s_total"] = time.perf_counter() - t0
        summary["run"]["real_time_factor"] = summary["run"]["simulated_time_s"] / summary["run"]["wall_s_total"]
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        (tmp / "scores.json").write_text(json.dumps(res["scores"], indent=2) + "\n")
        from .report import format_report
        (tmp / "report.md").write_text(format_report(res))
    bar.update(1)
    bar.close()
    s = res["scores"]["summary"]
    st, sn, inr = s["step"], s["sine"], s["inertia"]
    print(f"inertia model vs MuJoCo at {inr['n_poses']} Table 2 poses: max error "
          f"{100 * inr['max_rel_error']:.1f} %")
    print(f"step: alpha better at {st['alpha_better_poses']}/{st['n_poses']} poses; median |error| "
          f"linear {1e3 * st['median_abs_error_linear_rad']:.2f} mrad, alpha "
          f"{1e3 * st['median_abs_error_alpha_rad']:.2f} mrad (ratio {st['ratio_of_medians']:.2f})")
    print(f"sine: phase p90 linear {sn['phase_p90_linear_deg']:.1f} deg, alpha "
          f"{sn['phase_p90_alpha_deg']:.1f} deg; magnitude p90 linear {sn['magnitude_p90_linear']:.3f}, "
          f"alpha {sn['magnitude_p90_alpha']:.3f}")
    print(f"wrote {out}/report.md, summary.json, figures and predictions/ "
          f"(real-time factor {s['run']['real_time_factor']:.0f})")
    return 0
