"""The reproduce study: the paper, end to end, on the virtual Omni, checked against ground truth.

Stages: generate the paper campaign (Table 1 sines, Table 2 squares) on a :class:`Device`
-> identify (2.1-2.3.5) -> validate both models (Tables 8, 11) -> compare the identified
inertia model with MuJoCo's mass matrix at the 25 Table 2 poses.  :func:`run_reproduce`
returns everything in memory; :mod:`omni_app.reproduce` writes it (``summary.json``,
``predictions/``, ``params.json``, ``report.md``, the figures and the dataset).
"""

from __future__ import annotations

import time

from identification.errors import UserError
from identification.identify import identify_runs
from identification.validation import Params, validate_runs
from omni_sim import experiments as ex
from omni_sim import truth
from omni_sim.device import Device

#: The stages a progress callback hears of, in order (:func:`run_reproduce`).
STAGES = ("simulating the paper campaign", "identifying", "validating", "ground truth")


def _no_progress(stage: str) -> None:
    """A progress callback that says nothing."""


def run_reproduce(device: Device | None = None, jobs: int | None = None, campaign="paper",
                  progress=_no_progress) -> dict:
    """Run every stage in memory (:func:`simulate_campaign`, then :func:`analyse`); returns
    everything the writers need.

    ``device``: the model to run (default: the built-in scene, :meth:`Device.load`);
    ``campaign``: the campaign to generate (name or file,
    :func:`omni_sim.experiments.campaign`); ``progress``: called with each stage's name
    (:data:`STAGES`) as it starts.

    Raises
    ------
    UserError
        The model or campaign is bad, or identification failed (no inertia or alpha model).
    """
    return analyse(simulate_campaign(device, jobs, campaign, progress), progress)


def simulate_campaign(device: Device | None = None, jobs: int | None = None, campaign="paper",
                      progress=_no_progress) -> dict:
    """The first stage: the campaign's runs on the device (arguments: :func:`run_reproduce`);
    returns the stages' shared state (``device``, ``model``, ``runs``, ``t0``, ``run_meta``)."""
    from .accel import install
    install()  # the compiled α loop (loaded at its first use)
    device = Device.load() if device is None else device
    t0 = time.perf_counter()
    progress(STAGES[0])
    runs = ex.simulate(device, ex.campaign(campaign), jobs=jobs)
    run_meta = {"model": device.label,
                "model_sha256": runs[0].meta["model_sha256"],
                "friction": runs[0].meta["friction"]}
    return {"model": device.model, "device": device, "runs": runs, "t0": t0, "run_meta": run_meta}


def analyse(res: dict, progress=_no_progress) -> dict:
    """The other stages on :func:`simulate_campaign`'s runs: identify, validate both models,
    compare with the ground truth; adds ``ident``, ``params``, ``scores``, ``predictions`` and
    ``linear_truth`` to ``res`` and returns it."""
    runs, device = res["runs"], res["device"]
    progress(STAGES[1])
    ident = identify_runs(runs)
    if ident.inertia is None or ident.alpha_model is None:
        raise UserError("identification failed on the generated campaign: " + "; ".join(ident.warnings))
    params_dict = ident.to_params()
    progress(STAGES[2])
    params = Params(ident.inertia.params, ident.alpha_model, params_dict["poses"])
    scores, predictions = validate_runs(runs, params)
    progress(STAGES[3])
    scores["summary"]["inertia"] = truth.inertia_truth(device, ident.inertia.params)
    lin = truth.linear_truth(device, ident)
    sim_time = sum(len(r.t) for r in runs) * ex.CONTROL_PERIOD_S
    scores["summary"]["run"] = {"simulated_time_s": sim_time,
                                "wall_s_before_writing": time.perf_counter() - res["t0"],
                                **res["run_meta"]}
    res.update(ident=ident, params=params_dict, scores=scores, predictions=predictions,
               linear_truth=lin)
    return res
