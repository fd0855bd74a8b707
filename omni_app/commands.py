"""The ``omni`` subcommands: argparse namespaces in, files and printed summaries out.

Presentation layer: each handler calls the method (:mod:`identification`) or the simulator
(:mod:`omni_sim`) and writes what they return."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from identification.dataset import (atomic_output_dir, atomic_write_text, check_output_dir,
                                    check_output_file, read_dataset, read_table, write_dataset)
from identification.errors import UserError
from identification.identify import check_closed_loop_runs, check_pose_runs, fit_inertia_table, identify_runs
from identification.inertia import InertiaFit
from identification.validation import ValidationSummary, read_params, validate_runs, write_predictions
from .inputs import check_run_poses, omni_pose_check
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device


def _settings(args: argparse.Namespace) -> ex.Settings:
    noise = float(getattr(args, "noise", 0.0) or 0.0)
    if not (noise >= 0 and math.isfinite(noise)):
        raise UserError(f"--noise must be a finite standard deviation >= 0, got {noise}")
    kp = getattr(args, "kp", None)
    if kp is not None and not (kp > 0 and math.isfinite(kp)):
        raise UserError(f"--kp must be a finite P gain > 0, got {kp}")
    limit = getattr(args, "command_limit", None)
    if limit is not None and not limit > 0:
        raise UserError(f"--command-limit must be > 0 (the P law's saturation, in the actuator's "
                        f"control units), got {limit}")
    return ex.Settings(quantize=bool(getattr(args, "quantize", False)), noise_rad=noise,
                       seed=int(getattr(args, "seed", 0) or 0),
                       kp=ex.KP_DEFAULT if kp is None else kp, command_limit=limit)


def _check_jobs(jobs: int | None) -> int | None:
    if jobs is not None and jobs < 1:
        raise UserError(f"--jobs must be >= 1, got {jobs}")
    return jobs


def model_arg(args: argparse.Namespace):
    """The model file of ``--model`` / ``--friction`` (both: a user error), or None for the
    built-in default scene."""
    model = getattr(args, "model", None)
    friction = getattr(args, "friction", None)
    if model is None and friction is None:
        return None
    return str(om.model_path(model, friction))


def _generate_target(args: argparse.Namespace) -> om.Target | None:
    """``--joint``/``--actuator`` of ``omni generate`` (both or neither; None: the Omni's)."""
    joint, actuator = getattr(args, "joint", None), getattr(args, "actuator", None)
    if joint is None and actuator is None:
        return None
    if joint is None or actuator is None:
        raise UserError("generate: give --joint and --actuator together (your model's controlled "
                        "hinge and the actuator that drives it)")
    return om.Target(joint, actuator)


def generate(args: argparse.Namespace) -> int:
    """``omni generate``: run a campaign (or one user reference) and write a dataset.

    On a single-joint device (``--joint``/``--actuator``, a model without the Omni's arm) the
    runs have no arm pose: ``--gamma1``/``--gamma2`` and campaign groups with ``poses_deg``
    (the built-in campaigns) are refused."""
    jobs = _check_jobs(args.jobs)
    model = model_arg(args)
    settings = _settings(args)
    target = _generate_target(args)
    out = Path(args.out)
    campaign = args.campaign or "paper"
    campaign_file = None if args.reference is not None or campaign in ex.CAMPAIGNS else campaign
    check_output_dir(out, args.force, inputs=(args.reference, campaign_file, model))
    if args.reference is not None and Path(args.reference).is_file():
        read_table(args.reference, ("t", "r"))  # one clear line for an empty or malformed file
    device = Device.load(model, target=target)  # the model file: refused here if bad
    arm = device.ix.has_arm
    gammas = (args.gamma1, args.gamma2)
    if not arm:
        what = f"this device (joint {target.joint!r})" if target is not None else "this model"
        if gammas != (None, None):
            raise UserError(f"generate: --gamma1/--gamma2 set the Omni's arm; {what} has no arm: "
                            "leave them out")
        if args.reference is None and campaign in ex.CAMPAIGNS:
            raise UserError(f"generate: --campaign {campaign} is the Omni's (every group sets arm "
                            f"poses); {what} has no arm: give a campaign file whose groups have no "
                            "poses_deg (docs/usage/campaigns.md), or --reference CSV")
    if args.reference is not None:
        if arm:
            gammas = (65.0 if gammas[0] is None else gammas[0], 90.0 if gammas[1] is None else gammas[1])
        exps = [ex.reference_experiment(args.reference, *gammas)]
        source = "--gamma1/--gamma2"
    else:
        exps = ex.load_campaign(campaign).experiments(arm=arm)
        source = str(campaign)
    for e in exps:
        try:
            ex.check_experiment(device, e)
        except UserError as exc:
            raise UserError(f"{source}: {exc}") from None
    runs = ex.simulate(device, exps, settings, jobs=jobs, progress=sys.stderr.isatty())
    write_dataset(runs, out, args.force)
    n_sine = sum(r.kind == "sine" for r in runs)
    n_step = sum(r.kind == "step" for r in runs)
    print(f"wrote {len(runs)} runs ({n_sine} sine, {n_step} step, "
          f"{len(runs) - n_sine - n_step} other) to {out}")
    return 0


def bench(args: argparse.Namespace) -> int:
    """``omni bench``: print (and write) the performance figures."""
    from omni_studies.bench import run_bench

    jobs = _check_jobs(args.jobs)
    if args.out:
        check_output_file(args.out)
    figures = run_bench(jobs=jobs, friction=getattr(args, "friction", None),
                        discrepancy_campaign=getattr(args, "discrepancy_campaign", False),
                        only=getattr(args, "only", None))
    text = json.dumps(figures, indent=2, sort_keys=True)
    print(text)
    if args.out:
        atomic_write_text(args.out, text + "\n")
    return 0


def reproduce(args: argparse.Namespace) -> int:
    from .reproduce import reproduce_command
    return reproduce_command(args)


def discrepancy(args: argparse.Namespace) -> int:
    from .discrepancy import discrepancy_command
    return discrepancy_command(args)


def read_omni_runs(data, command: str) -> list:
    """The runs of dataset ``data`` for the paper's method (``command``: identify, validate).

    A run without an arm pose (neither ``gamma1_deg`` nor ``gamma2_deg``: a single-joint
    device of your own) is refused in one line that says what to run instead: the paper's
    method is for the Omni's gravity-free (vertical) yaw axis, and nothing here can tell a
    made-up pose from a real one, so it is not asked for one."""
    runs = read_dataset(data, require_pose=False)
    check_pose_runs(runs, command, data)
    return runs


def identify(args: argparse.Namespace) -> int:
    """``omni identify DATA --out DIR [--force]``: writes params.json, report.md, figures."""
    check_output_dir(args.out, getattr(args, "force", False), inputs=(args.data,))
    runs = read_omni_runs(args.data, "identify")
    check_run_poses(runs, args.data)
    check_closed_loop_runs([r for r in runs if r.kind == "sine"], "identify", args.data)
    ident = identify_runs(runs)
    params = ident.to_params()
    with atomic_output_dir(args.out, force=getattr(args, "force", False)) as tmp:
        (tmp / "params.json").write_text(json.dumps(params, indent=2) + "\n")
        from .identify_report import write_identify_report
        write_identify_report(ident, tmp, source=str(args.data))
    print(f"identified {len(ident.poses)} pose(s) from {len(runs)} run(s); wrote {args.out}/params.json")
    for w in ident.warnings:
        print(f"warning: {w}")
    return 0


def format_inertia_fit(fit: InertiaFit) -> str:
    """Readable multi-line summary of an inertia fit."""
    p = fit.params
    lines = [f"inertia model (6)-(8) fitted to {fit.n_poses} poses ({fit.dof} degrees of freedom)",
             f"{'parameter':<16}{'value':>12}   95% interval (approx.)"]
    for k in ("I_base", "I1", "I2", "I3", "gamma_offs_deg", "C0_bar"):
        lo, hi = fit.ci95[k]
        flag = "  poorly determined" if k in fit.poorly_determined else ""
        lines.append(f"{k:<16}{getattr(p, k):>12.5g}   [{lo:.4g}, {hi:.4g}]{flag}")
    lines.append(f"C0_bar by simple regression (beta_tilde = C0_bar*C through origin): "
                 f"{fit.C0_bar_regression:.3f}")
    lines.append(f"rms relative residual: beta_tilde {fit.rms_rel_beta:.4f}, C {fit.rms_rel_C:.4f}")
    lines.append(f"scaled Jacobian condition number {fit.condition_number:.3g}; singular values "
                 + ", ".join(f"{s:.3g}" for s in fit.singular_values))
    return "\n".join(lines)


def fit_inertia(args: argparse.Namespace) -> int:
    """``omni fit-inertia TABLE.csv [--out FILE]``."""
    if args.out:
        check_output_file(args.out)
    fit, result = fit_inertia_table(args.table, check_pose=omni_pose_check())
    print(format_inertia_fit(fit))
    if args.out:
        atomic_write_text(args.out, json.dumps(result, indent=2) + "\n")
        print(f"wrote {args.out}")
    return 0


def validate(args: argparse.Namespace) -> int:
    """``omni validate DATA --params FILE --out DIR [--force]``."""
    check_output_dir(args.out, getattr(args, "force", False), inputs=(args.data, args.params))
    params = read_params(args.params)
    runs = read_omni_runs(args.data, "validate")
    check_run_poses(runs, args.data)
    check_closed_loop_runs(runs, "validate", args.data)
    for run in runs:
        params.linear_coefficients(run)  # a run at a pose the params cannot predict: refused here
    val = validate_runs(runs, params)
    with atomic_output_dir(args.out, force=getattr(args, "force", False)) as tmp:
        write_predictions(tmp, runs, val.predictions)
        (tmp / "summary.json").write_text(json.dumps(val.summary.to_json(), indent=2) + "\n")
        (tmp / "scores.json").write_text(json.dumps(val.to_json(), indent=2) + "\n")
    _print_scores(val.summary)
    print(f"wrote {args.out}/summary.json and predictions/")
    return 0


def _print_scores(s: ValidationSummary) -> None:
    """validate's printed summary: both models, or the linear one and why the α one is not
    scored."""
    alpha = s.alpha_not_scored is None
    st, sn = s.step, s.sine
    if st and alpha:
        print(f"step: median |error| linear {st.median_abs_error_linear_rad:.4f} rad, alpha "
              f"{st.median_abs_error_alpha_rad:.4f} rad (ratio {st.ratio_of_medians:.2f}); "
              f"alpha better at {st.alpha_better_poses}/{st.n_poses} poses "
              f"({st.alpha_better_runs}/{st.n_runs} runs)")
    elif st:
        print(f"step: median |error| linear {st.median_abs_error_linear_rad:.4f} rad over "
              f"{st.n_runs} run(s) at {st.n_poses} pose(s)")
    if sn and alpha:
        print(f"sine: magnitude p90 linear {sn.magnitude_p90_linear:.3f}, alpha "
              f"{sn.magnitude_p90_alpha:.3f}; phase p90 linear {sn.phase_p90_linear_deg:.1f} deg, "
              f"alpha {sn.phase_p90_alpha_deg:.1f} deg")
    elif sn:
        print(f"sine: magnitude p90 linear {sn.magnitude_p90_linear:.3f}; phase p90 linear "
              f"{sn.phase_p90_linear_deg:.1f} deg")
    if not alpha:
        print(f"alpha model not scored (linear model only): {s.alpha_not_scored}")
