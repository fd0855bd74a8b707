"""Identification of a whole dataset: sine fits, per-pose linear models, inertia and alpha models.

:func:`identify_runs` is the core: runs in, an :class:`Identification` out
(:meth:`Identification.to_params` gives the ``params.json`` dict of ``omni identify``).

Pose grouping: sine runs are grouped by their set points ``(gamma1_set_deg, gamma2_set_deg)``
rounded to 0.01° when a run has both, else by the actual angles rounded to 0.01°.  A pose's
actual angles are the mean over its runs.  All runs of a pose must share ``kp``.

Poses whose global linear model is non-physical (C_linear or β_linear ≤ 0) are kept in
``poses`` but left out of the inertia fit.  With fewer than
:data:`identification.inertia.MIN_POSES` usable poses the inertia model is not fitted:
``"inertia_model": null`` and the reason is in ``"warnings"`` (per-pose results are still
written); likewise ``"alpha_model": null`` when the α model cannot be fitted (``omni validate``
then scores the linear model alone).  Step and other runs are ignored by ``identify``.

Minimum record: a sine run is fitted on its steady state (:mod:`identification.sine_fit`): the
first ``max(SETTLE_S, SETTLE_FRACTION x the run)`` is discarded (2 s, half the run) and at least
``MIN_CYCLES`` (3) whole cycles must follow, so the shortest run at f Hz lasts
:func:`minimum_sine_record_s` (6 s at 1 Hz, 3.5 s at 2 Hz).  :func:`check_sine_record` refuses
a shorter run with that minimum, before any fit.

Servo logs: the paper's model (13) and the quasilinear α model close the P loop once per
sample with the actuator always on.  A run with torque-off samples (column ``enabled`` 0) or a
``control_period_s`` other than its sample period is a different closed loop (a free swing; a
loop running several times between samples), which this method does not represent: fitting (19)
-(22) to it gives wrong coefficients without any sign.  :func:`check_closed_loop_runs` refuses
such runs with one line that names the run, the reason and the command that handles them
(``omni discrepancy`` replays torque-off spans and runs the device's loop at its control period).
``identify`` checks the runs it fits (sine runs), ``validate`` every run it simulates.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .dataset import POSE_KEYS, UNIFORM_RTOL, Run
from .errors import UserError
from .inertia import MIN_POSES, InertiaFit, fit_inertia_model
from .linear import PoseLinearModel, fit_pose
from .nonlinear import AlphaModel, fit_alpha_model
from .sine_fit import MIN_CYCLES, SETTLE_FRACTION, SETTLE_S, fit_run, steady_state_window

#: Relative difference [-] within which a run's ``control_period_s`` counts as its sample
#: period: the dataset's tolerance on the sample spacing itself (``UNIFORM_RTOL``, 1e-3), far
#: above text round-off (times written with 3 decimals at 1 kHz: ~1e-13 relative) and far
#: below any real loop-to-log ratio (a 1 kHz loop logged at 200 Hz: a factor of 5).
CONTROL_PERIOD_RTOL = UNIFORM_RTOL


@dataclass
class Identification:
    """Everything ``omni identify`` found: per-pose linear models and the inertia fit.

    Attributes
    ----------
    poses : list of PoseLinearModel
    inertia : InertiaFit or None
        None when there are too few usable poses (see ``warnings``).
    warnings : list of str
    ignored_runs : list of str
        Non-sine runs.
    """

    poses: list
    inertia: InertiaFit | None
    warnings: list = field(default_factory=list)
    ignored_runs: list = field(default_factory=list)
    alpha_model: AlphaModel | None = None

    def pose_inertia(self, pose: PoseLinearModel) -> float:
        """Inertia of a pose [paper units]: the inertia model (6) if fitted, else 1/beta_tilde_linear."""
        if self.inertia is not None:
            return float(self.inertia.params.inertia(pose.gamma1_deg, pose.gamma2_deg))
        return 1.0 / pose.beta_tilde_linear

    def to_params(self) -> dict:
        """The ``params.json`` dict (contract shape)."""
        return {
            "poses": [p.to_dict() for p in self.poses],
            "inertia_model": self.inertia.params.to_dict() if self.inertia else None,
            "inertia_fit": self.inertia.diagnostics() if self.inertia else None,
            "alpha_model": self.alpha_model.to_dict() if self.alpha_model else None,
            "warnings": list(self.warnings),
        }


def _pose_key(run: Run):
    m = run.meta
    if m.get("gamma1_set_deg") is not None and m.get("gamma2_set_deg") is not None:
        try:
            return ("set", round(float(m["gamma1_set_deg"]), 2), round(float(m["gamma2_set_deg"]), 2))
        except (TypeError, ValueError):
            raise UserError(f"{run.name}: gamma1_set_deg/gamma2_set_deg must be numbers") from None
    return ("actual", round(run.gamma1_deg, 2), round(run.gamma2_deg, 2))


def minimum_sine_record_s(frequency_hz: float) -> float:
    """The shortest sine run [s] the steady-state rule accepts at ``frequency_hz`` [Hz]: the
    discarded start ``max(SETTLE_S, SETTLE_FRACTION * D)`` plus ``MIN_CYCLES`` periods must fit
    in the record D, so ``D >= SETTLE_S + MIN_CYCLES / f`` and
    ``D >= MIN_CYCLES / (f (1 - SETTLE_FRACTION))``."""
    cycles_s = MIN_CYCLES / frequency_hz
    return max(SETTLE_S + cycles_s, cycles_s / (1.0 - SETTLE_FRACTION))


def check_sine_record(run: Run) -> None:
    """Refuse a sine run too short for the steady-state fit, naming the minimum record.

    Raises
    ------
    UserError
        Fewer than ``MIN_CYCLES`` whole cycles after the discarded start (the message of
        :func:`identification.sine_fit.steady_state_window` with :func:`minimum_sine_record_s`).
    """
    try:
        steady_state_window(run.t, run.frequency_hz, name=run.name)
    except UserError as exc:
        f = run.frequency_hz
        if not (f > 0 and math.isfinite(f)):
            raise
        raise UserError(f"{exc}: at {f:g} Hz the minimum record is {minimum_sine_record_s(f):.4g} s "
                        f"(the first max({SETTLE_S:g} s, {SETTLE_FRACTION:g} of the run) is discarded, "
                        f"then {MIN_CYCLES} whole cycles are fitted)") from None


def check_pose_runs(runs: list[Run], command: str, source=None) -> None:
    """Refuse runs without the Omni arm's pose: the paper's method is for the Omni's
    gravity-free (vertical) yaw axis, whose inertia the pose sets.

    A run without ``gamma1_deg`` and ``gamma2_deg`` (a single-joint device of your own) is
    refused in one line that says what to run instead (``omni discrepancy``); a run with one of
    them names the other.  Nothing here can tell a made-up pose from a real one.

    ``command``: the command's name for the message; ``source``: the dataset folder, to name
    the run's file and the command to run instead (else the run's name).

    Raises
    ------
    UserError
        A run without the pose, or with half of it."""
    for run in runs:
        have = [k for k in POSE_KEYS if run.meta.get(k) is not None]
        where = f"{Path(source) / run.name}.json" if source is not None else f"run {run.name}"
        if not have:
            data = source if source is not None else "DATA"
            raise UserError(
                f"{where}: no arm pose (gamma1_deg, gamma2_deg): omni {command} is the paper's method "
                "for the Omni's gravity-free yaw axis, not for a single-joint robot of your own; run "
                f"omni discrepancy --measured {data} --model FILE --joint J --actuator A")
        if len(have) < len(POSE_KEYS):
            missing = [k for k in POSE_KEYS if k not in have]
            raise UserError(f"{where}: missing required key(s): {', '.join(missing)}")


def check_closed_loop_runs(runs: list[Run], command: str, source=None) -> None:
    """Refuse runs the paper's closed loop does not describe (module docstring, "Servo logs").

    ``command``: the command's name for the message (``"identify"``, ``"validate"``);
    ``source``: the dataset folder, to name the run's file (else the run's name).

    Raises
    ------
    UserError
        A run whose ``enabled`` column holds a 0 (torque off), or whose ``control_period_s``
        differs from its sample period by more than :data:`CONTROL_PERIOD_RTOL`.
    """
    def where(run, ext):
        return f"{Path(source) / run.name}.{ext}" if source is not None else f"run {run.name}"

    for run in runs:
        on = run.enabled
        if on is not None and not on.all():
            k = int(np.argmin(on))
            raise UserError(
                f"{where(run, 'csv')}: torque off (column 'enabled' 0) at {int((~on).sum())} of "
                f"{on.size} samples, first at t = {run.t[k]:.6g} s; omni {command} models the P loop "
                "closed at every sample and cannot simulate a free swing: leave torque-off runs "
                "out of the dataset (omni discrepancy replays them)")
        cp = run.meta.get("control_period_s")
        if cp is not None and abs(cp - run.dt) > CONTROL_PERIOD_RTOL * run.dt:
            raise UserError(
                f"{where(run, 'json')}: control_period_s {cp:g} s is not the sample period "
                f"{run.dt:.6g} s; omni {command} models the P loop closed once per sample: give a "
                "log sampled at the control period (omni discrepancy runs the loop at "
                "control_period_s)")


def identify_runs(runs: list[Run], linear_only: bool = False) -> Identification:
    """Fit sines, local and global linear models per pose, and the inertia model.

    Parameters
    ----------
    runs : list of Run
        A dataset (any kinds; only ``kind == "sine"`` runs are used).
    linear_only : bool
        Stop after the per-pose linear models (no inertia or alpha model).

    Raises
    ------
    UserError
        No sine runs, a sine run with torque off or another control period
        (:func:`check_closed_loop_runs`), too few steady-state cycles
        (:func:`check_sine_record`), mixed kp within a pose, a pose with too few frequencies.
    """
    sines = [r for r in runs if r.kind == "sine"]
    ignored = [r.name for r in runs if r.kind != "sine"]
    if not sines:
        raise UserError("dataset has no sine runs (kind \"sine\"); identify needs sine sweeps")
    check_pose_runs(sines, "identify")
    check_closed_loop_runs(sines, "identify")
    for r in sines:
        check_sine_record(r)
    groups: dict = {}
    for r in sines:
        groups.setdefault(_pose_key(r), []).append(r)
    poses, warnings = [], []
    for key in sorted(groups):
        members = groups[key]
        kps = {r.kp for r in members}
        label = (f"set ({key[1]:g}, {key[2]:g}) deg" if key[0] == "set"
                 else f"actual ({key[1]:.2f}, {key[2]:.2f}) deg")
        if len(kps) > 1:
            raise UserError(f"pose {label}: runs {', '.join(r.name for r in members)} have different "
                            f"kp {sorted(kps)}; one pose needs one kp")
        fits = [fit_run(r) for r in members]
        g1 = float(np.mean([r.gamma1_deg for r in members]))
        g2 = float(np.mean([r.gamma2_deg for r in members]))
        pose = fit_pose(fits, kps.pop(), g1, g2, label=label,
                        gamma1_set_deg=key[1] if key[0] == "set" else None,
                        gamma2_set_deg=key[2] if key[0] == "set" else None)
        poses.append(pose)
        warnings.extend(pose.warnings)
    usable = [p for p in poses if p.physical]
    inertia = None
    if linear_only:
        return Identification(poses, None, warnings, ignored)
    if len(usable) >= MIN_POSES:
        inertia = fit_inertia_model([p.gamma1_deg for p in usable], [p.gamma2_deg for p in usable],
                                    [p.C_linear for p in usable], [p.beta_tilde_linear for p in usable])
        if inertia.poorly_determined:
            warnings.append("inertia model: poorly determined parameter(s): "
                            + ", ".join(inertia.poorly_determined))
    else:
        warnings.append(f"inertia model not fitted: {len(usable)} pose(s) with a physical global "
                        f"linear model; the inertia model (6)-(8) needs >= {MIN_POSES} poses")
    ident = Identification(poses, inertia, warnings, ignored)
    ident.alpha_model = _fit_alpha(ident)
    return ident


def _fit_alpha(ident: Identification) -> AlphaModel | None:
    """The alpha-invariant model (38)-(42) across the physical poses (2.3.5), or None."""
    poses = []
    for p in ident.poses:
        if not p.physical:
            continue
        pts = p.frequencies
        poses.append({
            "I": ident.pose_inertia(p),
            "alpha": [q.alpha for q in pts],
            "C_data": [q.C_data for q in pts],
            "beta_tilde_data": [q.beta_tilde_data for q in pts],
            "frequency_hz": [q.frequency_hz for q in pts],
            "beta_linear": p.beta_linear,
            "amplitude": [math.hypot(q.A1, q.A2) for q in pts],
        })
    if not poses:
        ident.warnings.append("alpha-invariant model not fitted: no pose with a physical linear model")
        return None
    try:
        return fit_alpha_model(poses)
    except UserError as exc:
        ident.warnings.append(f"alpha-invariant model not fitted: {exc}")
        return None


def identify_dataset(runs: list[Run]) -> dict:
    """Build the ``params.json`` dict from a dataset's runs (see :func:`identify_runs`)."""
    return identify_runs(runs).to_params()


TABLE_COLUMNS = ("gamma1_deg", "gamma2_deg", "C_linear", "beta_tilde_linear")


def read_linear_table(path) -> dict:
    """Read a CSV with columns gamma1_deg, gamma2_deg, C_linear, beta_tilde_linear (more allowed).

    Returns
    -------
    dict of str to ndarray

    Raises
    ------
    UserError
        Missing file or columns, non-numeric or non-finite values.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: file not found")
    try:
        with open(path, newline="") as fh:
            reader = csv.reader(fh)
            header = [h.strip() for h in next(reader, [])]
            rows = [row for row in reader if any(c.strip() for c in row)]
    except (UnicodeDecodeError, csv.Error) as exc:
        raise UserError(f"{path}: malformed CSV ({exc})") from None
    missing = [c for c in TABLE_COLUMNS if c not in header]
    if missing:
        raise UserError(f"{path}: missing column(s): {', '.join(missing)} (need {','.join(TABLE_COLUMNS)})")
    out = {c: [] for c in TABLE_COLUMNS}
    for i, row in enumerate(rows, start=2):
        if len(row) != len(header):
            raise UserError(f"{path}: line {i} has {len(row)} values but the header has {len(header)}")
        for c in TABLE_COLUMNS:
            text = row[header.index(c)].strip()
            try:
                val = float(text)
            except ValueError:
                raise UserError(f"{path}: line {i}, column {c}: not a number: {text!r}") from None
            if not math.isfinite(val):
                raise UserError(f"{path}: line {i}, column {c}: non-finite value {text!r}")
            out[c].append(val)
    return {c: np.array(v) for c, v in out.items()}


def fit_inertia_table(path, check_pose=None) -> tuple[InertiaFit, dict]:
    """Fit the inertia model to a table file; returns the fit and its JSON dict.

    ``check_pose(gamma1_deg, gamma2_deg)``: raises UserError for a pose no device has (the
    command passes the Omni's joint ranges; this package never loads a model).  It is applied
    to tables long enough for the fit: a shorter one gets the fit's own message first."""
    tab = read_linear_table(path)
    if check_pose is not None and len(tab["gamma1_deg"]) >= MIN_POSES:
        for i, (g1, g2) in enumerate(zip(tab["gamma1_deg"], tab["gamma2_deg"]), start=2):
            try:
                check_pose(float(g1), float(g2))
            except UserError as exc:
                raise UserError(f"{path}: line {i}: {exc}") from None
    try:
        fit = fit_inertia_model(tab["gamma1_deg"], tab["gamma2_deg"], tab["C_linear"],
                                tab["beta_tilde_linear"])
    except UserError as exc:
        raise UserError(f"{path}: {exc}") from None
    p = fit.params
    rows = [{"gamma1_deg": float(a), "gamma2_deg": float(b), "C_linear": float(c),
             "beta_tilde_linear": float(d), "C_model": float(p.C(a, b)),
             "beta_tilde_model": float(p.beta_tilde(a, b)), "inertia": float(p.inertia(a, b))}
            for a, b, c, d in zip(*(tab[k] for k in TABLE_COLUMNS))]
    return fit, {"inertia_model": p.to_dict(), "inertia_fit": fit.diagnostics(), "poses": rows}
