"""Score the global linear model (26) and the α-invariant model (37) against a dataset.

``omni validate DATA --params FILE --out DIR`` (and the validation stage of ``omni reproduce``):

1. every run is simulated with both models under the run's P gain and reference, from the
   run's first measured angle (at rest for ``step`` runs, as (47) says; otherwise with the
   velocity of the first two samples);
2. sine runs are scored as the paper's Table 8 (per pose: 90th percentile over frequencies of
   the absolute fundamental-magnitude and phase errors), step runs as Table 11 (per run: median
   and 90th percentile of the absolute angle error), in two windows: the whole record and the
   first second after each edge (labelled; the window changes the ratio more than the model);
3. ``summary.json`` (contract keys plus details) and ``predictions/NAME.csv`` (``t, theta,
   theta_linear, theta_alpha``) are written.

:func:`validate_runs` returns a frozen :class:`Validation`: ``summary`` (a
:class:`ValidationSummary`, typed sections :class:`SineSummary`, :class:`StepSummary` with its
:class:`StepWindows`, :class:`AlphaSimulation`), the per-pose and per-run rows and the
predictions; ``to_json()`` is ``scores.json``, ``summary.to_json()`` is ``summary.json``.

Without an α model (``params.json``'s ``alpha_model`` null or empty: what ``omni identify``
writes when it cannot fit one) the linear model is scored alone: every α score in
``summary.json`` and ``scores.json`` is null, ``summary["alpha_not_scored"]`` says why (the
identification's own warning when the file has it), ``alpha_simulation`` is null, and the
predictions keep their ``theta_alpha`` column, filled with ``nan``.

Runs the paper's closed loop does not describe (torque-off samples, a control period other
than the sample period) are refused, and so are sine runs too short for the steady-state fit,
before any simulation (:func:`identification.identify.check_closed_loop_runs`,
:func:`identification.identify.check_sine_record`).

The inertia of a run is the identified inertia model (6) at the run's actual angles; without an
inertia model, runs at an identified pose use that pose's 1/beta_tilde_linear, and other runs
are an error.  Step-run poses that were not among the identification poses are marked
``"fitted_pose": false``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import paper, scoring
from .csvformat import format_rows
from .dataset import Run
from .errors import UserError
from .identify import check_closed_loop_runs, check_pose_runs, check_sine_record
from .inertia import InertiaParameters
from .nonlinear import AlphaModel
from .records import Record
from .simulate import simulate_alpha_batch, simulate_linear
from .sine_fit import fundamentals

#: A pose of a run counts as an identification pose if both angles agree within this [deg].
POSE_MATCH_DEG = 0.5


@dataclass
class Params:
    """The parts of ``params.json`` that validation needs.

    ``alpha`` None: no α model (the linear model is scored alone); ``alpha_missing``: why."""

    inertia: InertiaParameters | None
    alpha: AlphaModel | None
    poses: list = field(default_factory=list)
    alpha_missing: str = "params has no alpha_model"

    @classmethod
    def from_dict(cls, d: dict, source: str = "params") -> "Params":
        if not isinstance(d, dict) or "poses" not in d or "alpha_model" not in d:
            raise UserError(f"{source}: not a params.json written by omni identify "
                            "(needs keys poses, inertia_model, alpha_model)")
        im = d.get("inertia_model")
        inertia = None
        if im:
            try:
                inertia = InertiaParameters(**{k: float(im[k]) for k in (
                    "I_base", "I1", "I2", "I3", "gamma_offs_deg", "C0_bar")})
            except (KeyError, TypeError, ValueError) as exc:
                raise UserError(f"{source}: malformed inertia_model ({exc})") from None
            _check_inertia(inertia, source)
        alpha = AlphaModel.from_dict(d["alpha_model"]) if d["alpha_model"] else None
        return cls(inertia, alpha, _checked_poses(d["poses"], source), _alpha_missing(d, source))

    def fitted_pose(self, run: Run) -> dict | None:
        """The identification pose of a run, if its actual angles match one."""
        for p in self.poses:
            if (abs(p["gamma1_deg"] - run.gamma1_deg) <= POSE_MATCH_DEG
                    and abs(p["gamma2_deg"] - run.gamma2_deg) <= POSE_MATCH_DEG):
                return p
        return None

    def linear_coefficients(self, run: Run) -> tuple[float, float, float]:
        """(I, C_linear, beta_tilde_linear) of a run by (6), (24)-(25) [paper units]."""
        if self.inertia is not None:
            I = float(self.inertia.inertia(run.gamma1_deg, run.gamma2_deg))
            return I, 1.0 / (self.inertia.C0_bar * I), 1.0 / I
        pose = self.fitted_pose(run)
        if pose is None:
            raise UserError(f"{run.name}: pose ({run.gamma1_deg:.2f}, {run.gamma2_deg:.2f}) deg was "
                            "not identified and params has no inertia model to predict it")
        return 1.0 / pose["beta_tilde_linear"], pose["C_linear"], pose["beta_tilde_linear"]


def _alpha_missing(d: dict, source: str) -> str:
    """Why a params file has no α model: identify's own warning if it wrote one."""
    warnings = d.get("warnings") if isinstance(d.get("warnings"), list) else []
    said = [w for w in warnings if isinstance(w, str) and w.startswith("alpha-invariant model not fitted")]
    return f"{source}: " + (said[0] if said else "has no alpha_model")


def _check_inertia(inertia: InertiaParameters, source: str) -> None:
    """The inertia model's values inside the fit's bounds (:func:`identification.inertia.
    fit_inertia_model`: ``I_base, I1, I2, I3 >= 0``, ``C0_bar > 0``), all finite."""
    values = inertia.to_dict()
    bad = [k for k, v in values.items() if not math.isfinite(v)]
    bad += [k for k in ("I_base", "I1", "I2", "I3") if values[k] < 0]
    bad += ["C0_bar"] if not values["C0_bar"] > 0 else []
    if bad:
        raise UserError(f"{source}: inertia_model: {bad[0]} = {values[bad[0]]!r} is not a value the "
                        "fit gives (finite; I_base, I1, I2, I3 >= 0; C0_bar > 0)")


def _checked_poses(poses, source: str) -> list:
    """``params["poses"]``: a list of objects whose angles and linear coefficients are numbers."""
    if not isinstance(poses, list):
        raise UserError(f"{source}: poses must be a list of pose objects, got {type(poses).__name__}")
    for i, p in enumerate(poses):
        if not isinstance(p, dict):
            raise UserError(f"{source}: poses[{i}] must be an object, got {p!r}")
        for k in ("gamma1_deg", "gamma2_deg", "C_linear", "beta_tilde_linear"):
            v = p.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise UserError(f"{source}: poses[{i}].{k} must be a finite number, got {v!r}")
    return list(poses)


def read_params(path) -> Params:
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: params file not found")
    try:
        d = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not valid JSON ({exc})") from None
    return Params.from_dict(d, str(path))


def _reference_derivatives(run: Run) -> tuple[np.ndarray, np.ndarray]:
    """(r_dot, r_ddot): analytic for sines and square waves, numerical otherwise."""
    if run.kind == "step":
        z = np.zeros_like(run.r)  # piecewise constant: derivatives vanish between edges
        return z, z
    if run.kind == "sine":
        w = 2 * math.pi * run.frequency_hz
        # the reference's own phase (robust to a file whose time origin is not at r = 0)
        basis = np.column_stack([np.sin(w * run.t), np.cos(w * run.t)])
        (a, b), *_ = np.linalg.lstsq(basis, run.r, rcond=None)
        if np.max(np.abs(basis @ [a, b] - run.r)) <= 1e-6 * max(1e-12, np.max(np.abs(run.r))):
            rd = w * (a * np.cos(w * run.t) - b * np.sin(w * run.t))
            return rd, -w * w * run.r
    rd = np.gradient(run.r, run.t)
    return rd, np.gradient(rd, run.t)


def _initial_velocity(run: Run) -> float:
    return 0.0 if run.kind == "step" else float((run.theta[1] - run.theta[0]) / run.dt)


def simulate_runs(runs: list[Run], params: Params) -> dict[str, dict]:
    """Simulate both models for every run.

    The linear model is batched over runs of equal length, dt and gain; the α model runs all
    runs of one dt in one time loop (:func:`simulate_alpha_batch`), with those same batches as
    its ``groups`` so that every number is the one of a per-batch :func:`simulate_alpha` call.
    Without an α model (``params.alpha`` None) ``theta_alpha`` is ``nan`` throughout.
    """
    out: dict[str, dict] = {}
    groups: dict = {}
    for run in runs:
        groups.setdefault((len(run.t), round(run.dt, 12), run.kp), []).append(run)
    by_dt: dict = {}
    for gid, ((_, dt, kp), group) in enumerate(groups.items()):
        I, Cl, bl, th0, ph0 = (np.array(x) for x in zip(*[
            (*params.linear_coefficients(r), r.theta[0], _initial_velocity(r)) for r in group]))
        r = np.vstack([g.r for g in group])
        lin = simulate_linear(Cl, bl, r, dt, kp, theta0=th0, phi0=ph0)
        for j, run in enumerate(group):
            out[run.name] = {"theta_linear": lin.theta[j], "I": float(I[j])}
            by_dt.setdefault(dt, []).append((run, gid, I[j], Cl[j], bl[j], th0[j], ph0[j], kp))
    if params.alpha is None:  # the linear model alone: theta_alpha kept as a column of nan
        by_dt = {}
        for run in runs:
            out[run.name].update(theta_alpha=np.full(len(run.t), np.nan), n_not_converged=0,
                                 n_bracketed=0)
    for dt, items in by_dt.items():
        rs, gids, I, Cl, bl, th0, ph0, kp = zip(*items)
        derivs = [_reference_derivatives(run) for run in rs]
        res = simulate_alpha_batch(params.alpha, I, [run.r for run in rs], dt, kp, C_linear=Cl,
                                   beta_tilde_linear=bl, theta0=th0, phi0=ph0,
                                   r_dot=[d[0] for d in derivs], r_ddot=[d[1] for d in derivs],
                                   groups=gids, keep=("theta",))
        for run, a in zip(rs, res):
            out[run.name].update(theta_alpha=a.theta, n_not_converged=int(a.n_not_converged),
                                 n_bracketed=int(a.n_bracketed))
    return {run.name: {k: out[run.name][k] for k in ("theta_linear", "theta_alpha", "n_not_converged",
                                                      "n_bracketed", "I")} for run in runs}


def _pose_key(run: Run) -> tuple[float, float]:
    """Set points [deg] when the metadata has them (they are optional), else actual angles."""
    g1, g2 = run.meta.get("gamma1_set_deg"), run.meta.get("gamma2_set_deg")
    if g1 is None or g2 is None:
        g1, g2 = run.gamma1_deg, run.gamma2_deg
    return round(float(g1), 2), round(float(g2), 2)


def _sine_rows(runs: list[Run], predictions: dict[str, dict], models: tuple) -> list[dict]:
    """Table 8 per pose for each of ``models`` (``"linear"``, ``"alpha"``); a model left out
    of ``models`` gets ``None``."""
    rows = []
    by_pose: dict = {}
    for run in runs:
        if run.kind == "sine":
            by_pose.setdefault(_pose_key(run), []).append(run)
    for key, group in sorted(by_pose.items()):
        group.sort(key=lambda r: r.frequency_hz)
        fits = [fundamentals(r, (r.theta, *(predictions[r.name][f"theta_{m}"] for m in models)))
                for r in group]
        ar = np.array([r.amplitude_rad for r in group])
        d1, d2 = np.array([f[0] for f in fits]).T
        row = {"gamma1_set_deg": key[0], "gamma2_set_deg": key[1],
               "frequencies_hz": [r.frequency_hz for r in group], "linear": None, "alpha": None}
        for i, label in enumerate(models, start=1):
            m1, m2 = np.array([f[i] for f in fits]).T
            sc = scoring.sine_pose_scores(d1, d2, m1, m2, ar)
            mag, ph = scoring.magnitude_phase(m1, m2, ar)
            row[label] = {**sc, "magnitude": mag.tolist(), "phase_deg": ph.tolist()}
        mag, ph = scoring.magnitude_phase(d1, d2, ar)
        row["data"] = {"magnitude": mag.tolist(), "phase_deg": ph.tolist()}
        rows.append(row)
    return rows


def _without_alpha(d: dict) -> dict:
    """``d`` with every α score and linear/α ratio set to None (the linear model alone)."""
    return {k: (None if "alpha" in k or k.startswith("ratio_") else v) for k, v in d.items()}


def _step_rows(runs: list[Run], params: Params, predictions: dict[str, dict]) -> tuple[list, dict | None]:
    """Table 11 per step run and its summary (:func:`scoring.step_summary`); without an α
    model the linear column stands in for the α one and every α entry is then set to None."""
    rows, keys = [], []
    for run in runs:
        if run.kind != "step":
            continue
        keys.append(_pose_key(run))
        p = predictions[run.name]
        alpha = p["theta_linear"] if params.alpha is None else p["theta_alpha"]
        sc = scoring.step_scores(run.t, run.theta, p["theta_linear"], alpha, r=run.r)
        sc.update(name=run.name, gamma1_set_deg=run.meta.get("gamma1_set_deg"),
                  gamma2_set_deg=run.meta.get("gamma2_set_deg"), gamma1_deg=run.gamma1_deg,
                  gamma2_deg=run.gamma2_deg, fitted_pose=params.fitted_pose(run) is not None)
        rows.append(sc)
    if not rows:
        return rows, None
    st = scoring.step_summary(rows)
    for w, summary in st.items():
        summary.update(_pose_counts(rows, keys, w))
    if params.alpha is None:
        st = {w: _without_alpha(v) for w, v in st.items()}
        for row in rows:
            row.update({w: _without_alpha(row[w]) for w in scoring.STEP_WINDOWS})
    return rows, st


def _pose_counts(rows: list[dict], keys: list[tuple], window: str) -> dict:
    """Runs and poses of the step rows in one window (``keys``: each row's pose,
    :func:`_pose_key`): ``n_runs``, ``n_poses`` (distinct poses, as the paper's Table 11
    counts them), ``alpha_better_runs`` / ``alpha_better_runs_p90`` (runs whose α median / p90
    error is below the linear one) and ``alpha_better_poses`` / ``alpha_better_poses_p90``
    (poses where that holds on every run of the pose; with one run per pose, as in the paper,
    the same counts as the runs')."""
    better = {"": [], "_p90": []}
    for row in rows:
        w = row[window]
        better[""].append(w["alpha"]["median_abs_error_rad"] < w["linear"]["median_abs_error_rad"])
        better["_p90"].append(w["alpha"]["p90_abs_error_rad"] < w["linear"]["p90_abs_error_rad"])
    out = {"n_runs": len(rows), "n_poses": len(set(keys))}
    for tag, flags in better.items():
        by_pose: dict = {}
        for key, ok in zip(keys, flags):
            by_pose[key] = by_pose.get(key, True) and ok
        out[f"alpha_better_runs{tag}"] = int(sum(flags))
        out[f"alpha_better_poses{tag}"] = int(sum(by_pose.values()))
    return out


@dataclass(frozen=True)
class SineSummary(Record):
    """Table 8 over poses (``summary.json``'s ``sine``): the mean over poses of each pose's 90th
    percentile over frequencies."""

    magnitude_p90_linear: float | None  #: fundamental magnitude error |theta|/A_r, linear model [-]
    phase_p90_linear_deg: float | None  #: phase error, linear model [deg]
    magnitude_p90_alpha: float | None  #: the same, α-invariant model [-] (None: no α model)
    phase_p90_alpha_deg: float | None  #: the same, α-invariant model [deg] (None: no α model)
    n_poses: int  #: poses with sine runs
    statistic: str  #: the statistic, in words


@dataclass(frozen=True)
class StepWindow(Record):
    """The step responses' absolute angle errors over one window, over runs and poses
    (``summary.json``'s ``step.windows.<window>``).  Medians and p90s are per run, then the
    median (or ``mean_``: the mean) over runs.  Without an α model every α figure, ratio and
    count is None."""

    median_abs_error_linear_rad: float  #: [rad]
    mean_median_abs_error_linear_rad: float  #: [rad]
    p90_abs_error_linear_rad: float  #: [rad]
    mean_p90_abs_error_linear_rad: float  #: [rad]
    median_abs_error_alpha_rad: float | None  #: [rad]
    mean_median_abs_error_alpha_rad: float | None  #: [rad]
    p90_abs_error_alpha_rad: float | None  #: [rad]
    mean_p90_abs_error_alpha_rad: float | None  #: [rad]
    ratio_of_medians: float | None  #: linear / α of the medians [-]
    ratio_of_means: float | None  #: linear / α of the means of the run medians [-]
    alpha_better_poses: int | None  #: poses where α's median error is smaller at every run
    alpha_better_poses_p90: int | None  #: the same by the p90
    n_poses: int  #: distinct poses
    n_runs: int  #: step runs scored
    alpha_better_runs: int | None  #: runs where α's median error is smaller
    alpha_better_runs_p90: int | None  #: the same by the p90


@dataclass(frozen=True)
class StepWindows(Record):
    """The two scoring windows of the step responses (:data:`identification.scoring.STEP_WINDOWS`)."""

    whole_record: StepWindow  #: the whole record
    after_edges: StepWindow  #: the first second after each edge

    @classmethod
    def from_json(cls, d: dict) -> StepWindows:
        return cls(StepWindow(**d["whole_record"]), StepWindow(**d["after_edges"]))


@dataclass(frozen=True)
class StepSummary(Record):
    """Table 11 over poses (``summary.json``'s ``step``): the headline figures over the whole
    record, the rest of the story beside them, the paper's Table 11 reduced with the same
    statistics and both windows in full.  Without an α model every α figure is None."""

    median_abs_error_linear_rad: float  #: [rad], whole record
    median_abs_error_alpha_rad: float | None  #: [rad], whole record
    alpha_better_poses: int | None  #: by the median, whole record
    n_poses: int  #: distinct poses (the paper's count)
    n_runs: int  #: step runs scored
    alpha_better_runs: int | None  #: by the median, whole record
    ratio_of_medians: float | None  #: linear / α [-], whole record
    statistic: str  #: the headline statistic, in words
    ratio_of_means: float | None  #: [-], whole record (the paper's "2.6" is one)
    p90_abs_error_linear_rad: float  #: [rad], whole record
    p90_abs_error_alpha_rad: float | None  #: [rad], whole record
    alpha_better_poses_p90: int | None  #: by the p90, whole record
    alpha_better_poses_after_edges: int | None  #: by the median, first second after each edge
    ratio_of_medians_after_edges: float | None  #: [-], first second after each edge
    paper_table11: dict  #: the paper's Table 11 reduced alike (:func:`identification.paper.table11_summary`)
    windows: StepWindows  #: both windows in full

    @classmethod
    def from_json(cls, d: dict) -> StepSummary:
        return cls(**{**d, "windows": StepWindows.from_json(d["windows"])})


@dataclass(frozen=True)
class AlphaSimulation(Record):
    """The α model's quasilinear iteration over every run (``summary.json``'s
    ``alpha_simulation``)."""

    steps: int  #: control steps simulated
    steps_not_converged: int  #: steps neither the iteration nor the bisection solved
    steps_solved_by_bisection: int  #: steps the iteration did not, a bracketed bisection did


@dataclass(frozen=True)
class ValidationSummary(Record):
    """``omni validate``'s ``summary.json``.  Its ``inertia`` key is always null (validate has
    no model to compare the inertia model with; ``omni reproduce``'s summary fills it), so it
    is written but not stored."""

    sine: SineSummary | None  #: Table 8 over poses (None: no sine runs)
    step: StepSummary | None  #: Table 11 over poses (None: no step runs)
    alpha_simulation: AlphaSimulation | None  #: the α model's iteration (None: no α model)
    alpha_not_scored: str | None = None  #: why the α model was not scored (None: it was)

    def to_json(self) -> dict:
        """The ``summary.json`` object: ``inertia`` null first, ``alpha_not_scored`` only when
        the α model was not scored."""
        out = {"inertia": None, **super().to_json()}
        if self.alpha_not_scored is None:
            del out["alpha_not_scored"]
        return out

    @classmethod
    def from_json(cls, d: dict) -> ValidationSummary:
        return cls(None if d["sine"] is None else SineSummary(**d["sine"]),
                   None if d["step"] is None else StepSummary.from_json(d["step"]),
                   None if d["alpha_simulation"] is None else AlphaSimulation(**d["alpha_simulation"]),
                   d.get("alpha_not_scored"))


@dataclass(frozen=True)
class Validation:
    """Both models scored against runs (:func:`validate_runs`).

    ``scores, predictions = validate_runs(...)`` still unpacks as before this was an object
    (``scores``: :meth:`to_json`, a new dict each time)."""

    summary: ValidationSummary  #: the figures of ``summary.json``
    sine_rows: tuple[dict, ...]  #: Table 8 per pose (``scores.json``'s ``sine`` rows)
    step_rows: tuple[dict, ...]  #: Table 11 per step run (``scores.json``'s ``step`` rows)
    #: per run name: ``theta_linear``, ``theta_alpha`` [rad], ``n_not_converged``,
    #: ``n_bracketed``, ``I`` (``predictions/``)
    predictions: dict

    def to_json(self) -> dict:
        """``scores.json``: the summary (:meth:`ValidationSummary.to_json`) and the rows."""
        return {"summary": self.summary.to_json(), "sine": list(self.sine_rows),
                "step": list(self.step_rows)}

    def __iter__(self):
        """``(self.to_json(), self.predictions)``: what :func:`validate_runs` returned before."""
        return iter((self.to_json(), self.predictions))


def _sine_summary(sine_rows: list[dict]) -> SineSummary | None:
    """Table 8 over poses from the per-pose rows (None: no sine runs)."""
    if not sine_rows:
        return None
    avg = {}
    for label in ("linear", "alpha"):
        rows = [r[label] for r in sine_rows if r[label] is not None]
        avg[f"magnitude_p90_{label}"] = float(np.mean([r["magnitude_p90"] for r in rows])) if rows else None
        avg[f"phase_p90_{label}_deg"] = float(np.mean([r["phase_p90_deg"] for r in rows])) if rows else None
    return SineSummary(**avg, n_poses=len(sine_rows), statistic="mean over poses of the per-pose "
                       "90th percentile over frequencies (Table 8 'Average')")


def _step_summary(st: dict | None) -> StepSummary | None:
    """Table 11 over poses from :func:`_step_rows`' per-window summary (None: no step runs)."""
    if st is None:
        return None
    whole, edges = st["whole_record"], st["after_edges"]
    return StepSummary(
        **{k: whole[k] for k in ("median_abs_error_linear_rad", "median_abs_error_alpha_rad",
                                 "alpha_better_poses", "n_poses", "n_runs", "alpha_better_runs",
                                 "ratio_of_medians")},
        statistic="median over runs of each run's median |error| over the whole record",
        # the rest of the story beside the headline (docs/studies/reproduce/results.md): the same ratio
        # with means (the paper's "2.6" is a ratio of means), the whole-record p90 and the
        # pose counts by p90 and in the first second after the edges
        **{k: whole[k] for k in ("ratio_of_means", "p90_abs_error_linear_rad", "p90_abs_error_alpha_rad",
                                 "alpha_better_poses_p90")},
        alpha_better_poses_after_edges=edges["alpha_better_poses"],
        ratio_of_medians_after_edges=edges["ratio_of_medians"],
        # Table 11 reduced with the same statistics (like for like; not measured here)
        paper_table11=paper.table11_summary(),
        windows=StepWindows.from_json(st))


def score(runs: list[Run], params: Params, predictions: dict[str, dict]) -> Validation:
    """Tables 8 and 11 for both models (the linear one alone without an α model), and the
    summary (contract keys plus details)."""
    models = ("linear",) if params.alpha is None else ("linear", "alpha")
    sine_rows = _sine_rows(runs, predictions, models)
    step_rows, st = _step_rows(runs, params, predictions)
    if params.alpha is None:
        alpha_simulation, missing = None, params.alpha_missing
    else:
        alpha_simulation = AlphaSimulation(
            steps=sum(len(r.t) for r in runs),
            steps_not_converged=sum(p["n_not_converged"] for p in predictions.values()),
            steps_solved_by_bisection=sum(p.get("n_bracketed", 0) for p in predictions.values()))
        missing = None
    summary = ValidationSummary(_sine_summary(sine_rows), _step_summary(st), alpha_simulation, missing)
    return Validation(summary, tuple(sine_rows), tuple(step_rows), predictions)


def write_predictions(folder: Path, runs: list[Run], predictions: dict[str, dict]) -> None:
    (folder / "predictions").mkdir()
    for run in runs:
        p = predictions[run.name]
        data = np.column_stack([run.t, run.theta, p["theta_linear"], p["theta_alpha"]])
        with open(folder / "predictions" / f"{run.name}.csv", "wb") as fh:
            fh.write(b"t,theta,theta_linear,theta_alpha\n")
            fh.write(format_rows(data))  # "%.17g" per number, ASCII


def validate_runs(runs: list[Run], params: Params) -> Validation:
    """Simulate and score; returns the scores and the predictions as a frozen
    :class:`Validation` (``scores, predictions = validate_runs(...)`` unpacks it as before:
    ``scores`` is its :meth:`~Validation.to_json`, ``scores.json``).

    Raises
    ------
    UserError
        No sine or step run; a run refused by :func:`check_closed_loop_runs` or a sine run by
        :func:`check_sine_record` (both before any simulation); a run at a pose the params
        cannot predict."""
    scored = [r for r in runs if r.kind in ("sine", "step")]
    if not scored:
        raise UserError("dataset has no sine or step runs to score")
    check_pose_runs(runs, "validate")
    check_closed_loop_runs(runs, "validate")
    for r in runs:
        if r.kind == "sine":
            check_sine_record(r)
    predictions = simulate_runs(runs, params)
    return score(runs, params, predictions)
