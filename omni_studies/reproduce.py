"""The reproduce study: the paper, end to end, on the virtual Omni, checked against ground truth.

Stages: generate the paper campaign (Table 1 sines, Table 2 squares) on a :class:`Device`
-> identify (2.1-2.3.5) -> validate both models (Tables 8, 11) -> compare the identified
inertia model with MuJoCo's mass matrix at the 25 Table 2 poses.  :func:`run_reproduce`
returns everything in memory as a :class:`ReproduceResult` (frozen: nothing downstream changes
it); :mod:`omni_app.reproduce` writes it (``summary.json``, ``predictions/``, ``params.json``,
``report.md``, the figures and the dataset).  ``ReproduceResult.summary.to_json(wall_s_total)``
is ``summary.json``, ``ReproduceResult.to_json(wall_s_total)`` is ``scores.json``: the writer
measures its own wall time and passes it in; it is never stored in the result.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from identification.dataset import Run
from identification.errors import UserError
from identification.identify import Identification, identify_runs
from identification.records import Record
# the validation's sections (validate's summary.json has them too)
from identification.validation import AlphaSimulation, Params, SineSummary, StepSummary, validate_runs

if TYPE_CHECKING:  # the simulator (and MuJoCo) is imported by the stages that run it, so that a
    # figure worker unpickling a result (omni_app.reproduce) does not import it
    from omni_sim.device import Device

#: The stages a progress callback hears of, in order (:func:`run_reproduce`).
STAGES = ("simulating the paper campaign", "identifying", "validating", "ground truth")


@dataclass(frozen=True)
class InertiaPose(Record):
    """One Table 2 pose of the inertia check (a row of ``summary.json``'s ``inertia.poses``)."""

    gamma1_set_deg: float  #: set pose [deg]
    gamma2_set_deg: float  #: set pose [deg]
    gamma1_deg: float  #: actual (sagged) pose [deg]
    gamma2_deg: float  #: actual (sagged) pose [deg]
    true_kg_m2: float  #: MuJoCo's yaw inertia there [kg m^2]
    identified_kg_m2: float  #: the identified inertia model (6) x beta_bar there [kg m^2]
    rel_error: float  #: identified / true - 1 [-]
    fitted_pose: bool  #: a Table 1 pose, whose sine sweeps the identification saw


@dataclass(frozen=True)
class InertiaTruth(Record):
    """The identified inertia model (6) x beta_bar against MuJoCo's mass matrix
    (:func:`omni_sim.truth.inertia_truth`; ``summary.json``'s ``inertia``)."""

    max_rel_error: float  #: largest |relative error| over the poses [-]
    mean_abs_rel_error: float  #: mean |relative error| over the poses [-]
    max_rel_error_unseen_poses: float | None  #: largest over the poses never fitted [-] (None: none)
    n_poses: int  #: poses checked
    n_unseen_poses: int  #: of which never fitted
    beta_bar_N_m_per_V: float  #: the model's torque constant [N m/V]
    poses: tuple[InertiaPose, ...]  #: one row per pose

    @classmethod
    def from_json(cls, d: dict) -> InertiaTruth:
        return cls(**{**d, "poses": tuple(InertiaPose(**r) for r in d["poses"])})


@dataclass(frozen=True)
class RunInfo(Record):
    """What ran (``summary.json``'s ``run`` without the writer's wall times)."""

    simulated_time_s: float  #: simulated time of the campaign [s]
    wall_s_before_writing: float  #: wall time of the study's stages [s] (measured: varies)
    model: str  #: the model's label
    model_sha256: str  #: its hash (first 16 hex digits)
    friction: str | None  #: its friction family

    def to_json(self, wall_s_total: float | None = None) -> dict:
        """``summary.json``'s ``run``; with the writer's ``wall_s_total`` [s] (None: left out) and
        the real-time factor it gives."""
        out = super().to_json()
        if wall_s_total is not None:
            out.update(wall_s_total=wall_s_total, real_time_factor=self.real_time_factor(wall_s_total))
        return out

    def real_time_factor(self, wall_s: float) -> float:
        """Simulated time over the wall time ``wall_s`` [s]."""
        return self.simulated_time_s / wall_s

    @classmethod
    def from_json(cls, d: dict) -> RunInfo:
        return cls(**{k: v for k, v in d.items() if k not in ("wall_s_total", "real_time_factor")})


@dataclass(frozen=True)
class ReproduceSummary(Record):
    """``summary.json``: every figure of the reproduction, per section."""

    inertia: InertiaTruth  #: the inertia model against MuJoCo's mass matrix
    sine: SineSummary | None  #: Table 8 over poses (None: no sine runs)
    step: StepSummary | None  #: Table 11 over poses (None: no step runs)
    alpha_simulation: AlphaSimulation  #: the α model's iteration
    run: RunInfo  #: what ran

    def to_json(self, wall_s_total: float | None = None) -> dict:
        """The ``summary.json`` object; ``wall_s_total``: the writer's whole wall time [s], with
        the real-time factor (None: both left out)."""
        return {**super().to_json(), "run": self.run.to_json(wall_s_total)}

    @classmethod
    def from_json(cls, d: dict) -> ReproduceSummary:
        return cls(InertiaTruth.from_json(d["inertia"]),
                   None if d["sine"] is None else SineSummary(**d["sine"]),
                   None if d["step"] is None else StepSummary.from_json(d["step"]),
                   AlphaSimulation(**d["alpha_simulation"]), RunInfo.from_json(d["run"]))


@dataclass(frozen=True)
class SimulatedCampaign:
    """The first stage's result (:func:`simulate_campaign`), the input of :func:`analyse`."""

    device: Device  #: the model the campaign ran on
    runs: tuple[Run, ...]  #: the campaign's runs, in its order
    started: float  #: when the study started (``time.perf_counter()``) [s]


@dataclass(frozen=True)
class ReproduceResult:
    """One reproduction in memory (:func:`run_reproduce`): the runs, the identification, both
    models' scores and predictions, and the ground truth."""

    device: Device  #: the model the campaign ran on
    runs: tuple[Run, ...]  #: the campaign's runs
    ident: Identification  #: the identification (:func:`identification.identify_runs`)
    params: dict  #: the identified parameters as ``params.json`` holds them
    summary: ReproduceSummary  #: the figures of ``summary.json``
    sine_rows: tuple[dict, ...]  #: Table 8 per pose (``scores.json``'s ``sine`` rows)
    step_rows: tuple[dict, ...]  #: Table 11 per step run (``scores.json``'s ``step`` rows)
    predictions: dict  #: per run name, both models' simulated yaw [rad] (``predictions/``)
    linear_truth: tuple[dict, ...]  #: per pose, C_linear, beta_linear beside the model's true values

    def to_json(self, wall_s_total: float | None = None) -> dict:
        """``scores.json``: the summary (:meth:`ReproduceSummary.to_json`) and the rows."""
        return {"summary": self.summary.to_json(wall_s_total), "sine": list(self.sine_rows),
                "step": list(self.step_rows)}


def _no_progress(stage: str) -> None:
    """A progress callback that says nothing."""


def run_reproduce(device: Device | None = None, jobs: int | None = None, campaign="paper",
                  progress=_no_progress) -> ReproduceResult:
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
                      progress=_no_progress) -> SimulatedCampaign:
    """The first stage: the campaign's runs on the device (arguments: :func:`run_reproduce`)."""
    from omni_sim import experiments as ex
    from omni_sim.device import Device

    from .accel import install
    install()  # the compiled α loop (loaded at its first use)
    device = Device.load() if device is None else device
    started = time.perf_counter()
    progress(STAGES[0])
    runs = ex.simulate(device, ex.campaign(campaign), jobs=jobs)
    return SimulatedCampaign(device, tuple(runs), started)


def analyse(sim: SimulatedCampaign, progress=_no_progress) -> ReproduceResult:
    """The other stages on :func:`simulate_campaign`'s runs: identify, validate both models,
    compare with the ground truth; returns a new :class:`ReproduceResult` (``sim`` is left as
    it is)."""
    from omni_sim import experiments as ex
    from omni_sim import truth

    runs, device = list(sim.runs), sim.device
    progress(STAGES[1])
    ident = identify_runs(runs)
    if ident.inertia is None or ident.alpha_model is None:
        raise UserError("identification failed on the generated campaign: " + "; ".join(ident.warnings))
    params_dict = ident.to_params()
    progress(STAGES[2])
    params = Params(ident.inertia.params, ident.alpha_model, params_dict["poses"])
    val = validate_runs(runs, params)
    progress(STAGES[3])
    inertia = truth.inertia_truth(device, ident.inertia.params)
    lin = truth.linear_truth(device, ident)
    meta = runs[0].meta
    run = RunInfo(simulated_time_s=sum(len(r.t) for r in runs) * ex.CONTROL_PERIOD_S,
                  wall_s_before_writing=time.perf_counter() - sim.started,
                  model=device.label, model_sha256=meta["model_sha256"], friction=meta["friction"])
    summary = ReproduceSummary(InertiaTruth.from_json(inertia), val.summary.sine, val.summary.step,
                               val.summary.alpha_simulation, run)
    return ReproduceResult(device=device, runs=sim.runs, ident=ident, params=params_dict, summary=summary,
                           sine_rows=val.sine_rows, step_rows=val.step_rows,
                           predictions=val.predictions, linear_truth=tuple(lin))
