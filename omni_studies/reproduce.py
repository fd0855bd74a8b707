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
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

from identification.dataset import Run
from identification.errors import UserError
from identification.identify import Identification, identify_runs
from identification.validation import Params, validate_runs

if TYPE_CHECKING:  # the simulator (and MuJoCo) is imported by the stages that run it, so that a
    # figure worker unpickling a result (omni_app.reproduce) does not import it
    from omni_sim.device import Device

#: The stages a progress callback hears of, in order (:func:`run_reproduce`).
STAGES = ("simulating the paper campaign", "identifying", "validating", "ground truth")


class _Record:
    """A frozen dataclass whose field names are the keys of its JSON object, in order."""

    def to_json(self) -> dict:
        """The JSON object (plain dicts, lists, numbers and strings), keys in field order."""
        return {f.name: _json(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_json(cls, d: dict):
        """The record of the JSON object ``d`` (the keys must be exactly the fields)."""
        return cls(**d)


def _json(value):
    """``value`` as JSON: records as objects, tuples as lists, the rest as it is."""
    if isinstance(value, _Record):
        return value.to_json()
    if isinstance(value, tuple):
        return [_json(v) for v in value]
    return value


@dataclass(frozen=True)
class InertiaPose(_Record):
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
class InertiaTruth(_Record):
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
class SineSummary(_Record):
    """Table 8 over poses (``summary.json``'s ``sine``): the mean over poses of each pose's 90th
    percentile over frequencies."""

    magnitude_p90_linear: float | None  #: fundamental magnitude error |theta|/A_r, linear model [-]
    phase_p90_linear_deg: float | None  #: phase error, linear model [deg]
    magnitude_p90_alpha: float | None  #: the same, α-invariant model [-] (None: no α model)
    phase_p90_alpha_deg: float | None  #: the same, α-invariant model [deg] (None: no α model)
    n_poses: int  #: poses with sine runs
    statistic: str  #: the statistic, in words


@dataclass(frozen=True)
class StepWindow(_Record):
    """The step responses' absolute angle errors over one window, over runs and poses
    (``summary.json``'s ``step.windows.<window>``).  Medians and p90s are per run, then the
    median (or ``mean_``: the mean) over runs."""

    median_abs_error_linear_rad: float  #: [rad]
    mean_median_abs_error_linear_rad: float  #: [rad]
    p90_abs_error_linear_rad: float  #: [rad]
    mean_p90_abs_error_linear_rad: float  #: [rad]
    median_abs_error_alpha_rad: float  #: [rad]
    mean_median_abs_error_alpha_rad: float  #: [rad]
    p90_abs_error_alpha_rad: float  #: [rad]
    mean_p90_abs_error_alpha_rad: float  #: [rad]
    ratio_of_medians: float  #: linear / α of the medians [-]
    ratio_of_means: float  #: linear / α of the means of the run medians [-]
    alpha_better_poses: int  #: poses where α's median error is smaller at every run
    alpha_better_poses_p90: int  #: the same by the p90
    n_poses: int  #: distinct poses
    n_runs: int  #: step runs scored
    alpha_better_runs: int  #: runs where α's median error is smaller
    alpha_better_runs_p90: int  #: the same by the p90


@dataclass(frozen=True)
class StepWindows(_Record):
    """The two scoring windows of the step responses."""

    whole_record: StepWindow  #: the whole record
    after_edges: StepWindow  #: the first second after each edge

    @classmethod
    def from_json(cls, d: dict) -> StepWindows:
        return cls(StepWindow(**d["whole_record"]), StepWindow(**d["after_edges"]))


@dataclass(frozen=True)
class StepSummary(_Record):
    """Table 11 over poses (``summary.json``'s ``step``): the headline figures over the whole
    record, the rest of the story beside them, the paper's Table 11 reduced with the same
    statistics and both windows in full."""

    median_abs_error_linear_rad: float  #: [rad], whole record
    median_abs_error_alpha_rad: float  #: [rad], whole record
    alpha_better_poses: int  #: by the median, whole record
    n_poses: int  #: distinct poses (the paper's count)
    n_runs: int  #: step runs scored
    alpha_better_runs: int  #: by the median, whole record
    ratio_of_medians: float  #: linear / α [-], whole record
    statistic: str  #: the headline statistic, in words
    ratio_of_means: float  #: [-], whole record (the paper's "2.6" is one)
    p90_abs_error_linear_rad: float  #: [rad], whole record
    p90_abs_error_alpha_rad: float  #: [rad], whole record
    alpha_better_poses_p90: int  #: by the p90, whole record
    alpha_better_poses_after_edges: int  #: by the median, first second after each edge
    ratio_of_medians_after_edges: float  #: [-], first second after each edge
    paper_table11: dict  #: the paper's Table 11 reduced alike (:func:`identification.paper.table11_summary`)
    windows: StepWindows  #: both windows in full

    @classmethod
    def from_json(cls, d: dict) -> StepSummary:
        return cls(**{**d, "windows": StepWindows.from_json(d["windows"])})


@dataclass(frozen=True)
class AlphaSimulation(_Record):
    """The α model's quasilinear iteration over every run (``summary.json``'s
    ``alpha_simulation``)."""

    steps: int  #: control steps simulated
    steps_not_converged: int  #: steps neither the iteration nor the bisection solved
    steps_solved_by_bisection: int  #: steps the iteration did not, a bracketed bisection did


@dataclass(frozen=True)
class RunInfo(_Record):
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
class ReproduceSummary(_Record):
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
    scores, predictions = validate_runs(runs, params)
    progress(STAGES[3])
    inertia = truth.inertia_truth(device, ident.inertia.params)
    lin = truth.linear_truth(device, ident)
    meta = runs[0].meta
    run = RunInfo(simulated_time_s=sum(len(r.t) for r in runs) * ex.CONTROL_PERIOD_S,
                  wall_s_before_writing=time.perf_counter() - sim.started,
                  model=device.label, model_sha256=meta["model_sha256"], friction=meta["friction"])
    summary = ReproduceSummary.from_json({**scores["summary"], "inertia": inertia, "run": run.to_json()})
    return ReproduceResult(device=device, runs=sim.runs, ident=ident, params=params_dict, summary=summary,
                           sine_rows=tuple(scores["sine"]), step_rows=tuple(scores["step"]),
                           predictions=predictions, linear_truth=tuple(lin))
