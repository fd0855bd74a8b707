"""The sweep's pipelines (:mod:`omni_studies.sweep`, the engine; its docstring describes them):
one variant run on a Dask worker (:func:`run_variant`)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from identification.errors import UserError

from .sweep_results import (DiscrepancyFigures, ReproduceFigures, SimulateFigures, VariantOutput,
                            VariantResult)


def _settings(values: dict, seed: int, pipeline: str):
    from omni_sim import experiments as ex
    from discrepancy import experiment_set

    disc = pipeline == "discrepancy"
    return ex.Settings(kp=values.get("kp", ex.KP_DEFAULT),
                       quantize=bool(values.get("quantize", 1.0 if disc else 0.0)),
                       noise_rad=values.get("noise_rad", experiment_set.NOISE_RAD if disc else 0.0),
                       seed=seed)


def _campaign(pipe: dict):
    from omni_sim import experiments as ex

    if pipe["campaign_text"] is None:
        return ex.load_campaign(pipe["campaign_source"])
    return ex.parse_campaign(pipe["campaign_text"], pipe["campaign_source"])


def _reproduce(spec, model, values: dict, settings, pipe: dict) -> tuple[ReproduceFigures, dict]:
    """The reproduce job's stages (:func:`omni_studies.reproduce.run_reproduce`) with run settings."""
    from identification.identify import identify_runs
    from identification.validation import Params, validate_runs
    from omni_sim import experiments as ex
    from omni_sim import truth
    from omni_sim.device import Device

    from .accel import install
    install()  # the compiled α loop (loaded at its first use)
    exps = _campaign(pipe).experiments(values.get("amplitude_rad"))
    device = Device(model, settings.control_period_s)
    runs = ex.simulate(device, exps, settings, jobs=1)
    ident = identify_runs(runs)
    if ident.inertia is None or ident.alpha_model is None:
        raise UserError("identification failed: " + "; ".join(w for w in ident.warnings if "not fitted" in w))
    params_dict = ident.to_params()
    params = Params(ident.inertia.params, ident.alpha_model, params_dict["poses"])
    s = {**validate_runs(runs, params).summary.to_json(),  # "inertia" (null) stays the first key
         "inertia": truth.inertia_truth(device, ident.inertia.params)}
    win = s["step"]["windows"]
    fig = ReproduceFigures(
        inertia_max_rel_error=s["inertia"]["max_rel_error"],
        step_ratio_of_medians_whole_record=win["whole_record"]["ratio_of_medians"],
        step_ratio_of_medians_after_edges=win["after_edges"]["ratio_of_medians"],
        **{f"sine_{k}": s["sine"][k] for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg",
                                               "magnitude_p90_linear", "magnitude_p90_alpha")})
    return fig, {"summary.json": json.dumps(s, indent=2) + "\n",
                 "params.json": json.dumps(params_dict, indent=2) + "\n"}


def _simulate(spec, model, values, settings, pipe) -> tuple[SimulateFigures, dict]:
    import numpy as np

    from omni_sim import experiments as ex
    from omni_sim.device import Device

    exps = _campaign(pipe).experiments(values.get("amplitude_rad"))
    runs = ex.simulate(Device(model), exps, settings, jobs=1)
    err = {r.name: np.asarray(r.theta) - np.asarray(r.r) for r in runs}
    if not all(np.all(np.isfinite(e)) for e in err.values()):
        raise UserError("the simulation diverged (non-finite yaw angle)")
    kinds = {e.name: e.kind for e in exps}

    def rms(names):
        names = list(names)
        if not names:
            return float("nan")
        return float(np.sqrt(np.mean(np.concatenate([err[n] ** 2 for n in names]))))

    fig = SimulateFigures(rms_error_rad=rms(err),
                          max_abs_error_rad=float(max(np.max(np.abs(e)) for e in err.values())),
                          rms_error_sine_rad=rms(n for n in err if kinds[n] == "sine"),
                          rms_error_step_rad=rms(n for n in err if kinds[n] == "step"))
    return fig, {}


def _discrepancy(spec, model, values, settings, pipe) -> tuple[DiscrepancyFigures, dict]:
    import tempfile

    from omni_sim import experiments as ex
    from omni_sim.device import Device
    from discrepancy import experiment_set
    from discrepancy.workflow import run_discrepancy

    from .bank_link import load as load_bank

    hidden = load_bank("omni sweep's discrepancy pipeline").hidden
    case = hidden.case(pipe["hidden"])
    amp = values.get("amplitude_rad")
    exps = experiment_set.experiments(amplitudes_rad=experiment_set.AMPLITUDES_RAD if amp is None else (amp,),
                                      duration_s=pipe["duration_s"])
    truth_model = hidden.truth_spec(case, base=spec.copy()).compile()
    runs = ex.simulate(Device(truth_model), exps, settings, jobs=1)
    xml = spec.to_xml()
    with tempfile.TemporaryDirectory(prefix="omni-sweep-") as d:
        nominal = Path(d) / "nominal.xml"
        nominal.write_text(xml)
        out = run_discrepancy(runs, nominal, jobs=1)
    rep = out.report
    # the nominal model is written beside report.json, which names it there (not the temporary
    # folder's path: the same study gives the same bytes)
    rep = {**rep, "settings": {**rep["settings"], "model": "nominal.xml"}}
    ok, why = hidden.assess(case, rep)
    fig = DiscrepancyFigures(effects="+".join(e["name"] for e in rep["effects"]), passed=int(ok),
                             assessment=why, shrink_factor=rep["shrink_factor"],
                             gap_before_rad=rep["gap_before"], gap_after_rad=rep["gap_after"],
                             unexplained=int(rep["unexplained"]))
    rep = {k: v for k, v in rep.items() if k != "timings"}
    return fig, {"report.json": json.dumps(rep, indent=2, default=float) + "\n", "nominal.xml": xml}


_PIPELINE_FUNCS = {"reproduce": _reproduce, "simulate": _simulate, "discrepancy": _discrepancy}


def run_variant(job: dict) -> VariantOutput:
    """Run one variant (on a worker, one thread); never raises for a failing variant: its error
    is the result.  Returns a frozen :class:`VariantOutput` (``.result``: ``result.json``'s
    :class:`VariantResult`, ``.files``: the pipeline's files, name -> text)."""
    from omni_sim import variants as va

    t0 = time.perf_counter()
    values = {**job["fixed"], **job["values"]}
    name = job["pipeline"]["name"]
    figures, files, error = None, {}, ""
    try:
        spec = va.base_spec(job["base"]["model"], job["base"]["friction"])
        spec, model = va.build(spec, values)
        settings = _settings(values, job["seed"], name)
        figures, files = _PIPELINE_FUNCS[name](spec, model, values, settings, job["pipeline"])
    except Exception as exc:  # a variant that fails is a result, not a lost task
        error = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    result = VariantResult(id=job["id"], seed=job["seed"], params=job["values"], fixed=job["fixed"],
                           pipeline=name, status="failed" if error else "ok", error=error,
                           figures=figures, wall_s=time.perf_counter() - t0)
    return VariantOutput(result, files)
