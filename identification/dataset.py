"""The dataset contract: a folder of runs, each ``NAME.csv`` + ``NAME.json``.

CSV: one header line, one row per sample; required columns ``t`` [s], ``r`` [rad] (yaw
reference), ``theta`` [rad] (measured yaw), ``v`` [V] (command voltage); more columns are
allowed and kept.  An optional column ``enabled`` (0/1) says whether the actuator was on: while
0 the drive's command is zero (torque off: free swing, lift-and-drop, free decay).

Sampling: ``t`` strictly increasing.  Simulated data are uniformly sampled; a real log may have
any sample period and irregular timestamps (a host that polls its servo at 50-200 Hz with
jitter).  What each command does with them:

* ``omni discrepancy`` compares at the logged times (:func:`read_dataset` with
  ``purpose="discrepancy"``): the replay runs the device's loop at its own control period
  (metadata ``control_period_s``, default the median sample period) with the reference and the
  ``enabled`` switch held between log samples, as a servo holds its goal, and reads the model's
  angle at each logged time;
* ``omni identify``/``omni validate`` fit sines and step responses on a uniform grid: an
  irregular run is resampled onto the grid of its median period by linear interpolation of
  every column (:func:`resample_uniform`, ``enabled`` held, not interpolated).

A run whose longest gap exceeds :data:`MAX_GAP_PERIODS` median periods is refused: what the
reference and the switch did inside it is not known.  :func:`timing` reports a run's period,
jitter and longest gap.

JSON: ``kind`` ("sine" | "step" | "other"), ``gamma1_deg``, ``gamma2_deg`` (actual arm
angles [deg]), ``kp`` [V/rad], ``frequency_hz`` [Hz], ``amplitude_rad`` [rad]; optional
``gamma1_set_deg``, ``gamma2_set_deg``; ``command_limit`` (the P law's saturation, in the
actuator's control units); ``control_period_s`` [s] (the device's own loop period, e.g. 0.001
for a servo that closes its loop at 1 kHz and is logged at 200 Hz; default: the sample
period); anything else is kept.  A single-joint device without the Omni's arm
(``omni discrepancy --joint``) has no pose: its runs are read with ``require_pose=False``
(``read_dataset(folder, purpose="discrepancy")``), which makes ``gamma1_deg``/``gamma2_deg``
optional (finite if given).

Numbers no run has are refused (:func:`read_run`): ``kp`` <= 0; a negative ``frequency_hz``;
a ``frequency_hz`` or ``amplitude_rad`` that is not positive for a sine or a step (an "other"
run's amplitude is free: a move to -1.0 rad may say -1.0); ``command_limit`` <= 0; a
``control_period_s`` outside (0, 1] s or longer than the sample period (a log cannot sample
the device's loop faster than it runs: a period in milliseconds written as seconds shows
here).  Whether a pose is one the arm can take is the device's question
(``omni_sim.device.Device.check_pose``, the commands ask it).  Output folders and files are
checked before a command's work (:func:`check_output_dir`, :func:`check_output_file`) and
written atomically (:func:`atomic_output_dir`, :func:`atomic_write_text`).

This module is numpy-only so that data from a real Omni never needs the simulator.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from .csvformat import format_rows
from .errors import UserError

REQUIRED_COLUMNS = ("t", "r", "theta", "v")
REQUIRED_KEYS = ("kind", "gamma1_deg", "gamma2_deg", "kp", "frequency_hz", "amplitude_rad")
#: The arm pose keys, optional for a device without the Omni's arm (``require_pose=False``).
POSE_KEYS = ("gamma1_deg", "gamma2_deg")
KINDS = ("sine", "step", "other")
#: Relative tolerance on the sample spacing for "uniformly sampled" [-].  Text round trip of
#: times written with 9 decimals gives spacing errors of ~1e-9 s, far below this.
UNIFORM_RTOL = 1e-3
#: Longest gap between two samples a run may have, in median sample periods [-].  Inside a
#: gap the reference and the ``enabled`` switch are held at their last logged values (as a
#: servo holds its goal); a host that lost ten samples in a row may have sent goals that are
#: not in the log, so the replay would guess.  Real logs of a polled servo have gaps of 2-3
#: periods (the Feetech logs of examples/real_servo: at most 2.5).
MAX_GAP_PERIODS = 10.0
#: The optional on/off column.
ENABLED_COLUMN = "enabled"
#: Optional metadata numbers: absent or null, else finite (their rules: :func:`read_run`);
#: ``command_limit`` may also be ``Infinity`` (no saturation, as if absent).
OPTIONAL_NUMBER_KEYS = ("gamma1_set_deg", "gamma2_set_deg", "command_limit", "control_period_s")


@dataclass
class Run:
    """One experiment: samples plus metadata.

    Attributes
    ----------
    name : str
        File stem (``NAME`` of ``NAME.csv``/``NAME.json``).
    t, r, theta, v : ndarray
        Time [s], yaw reference [rad], measured yaw [rad], command voltage [V].
    meta : dict
        The JSON object (all keys kept).
    extra : dict of ndarray
        Further CSV columns, by header name.
    """

    name: str
    t: np.ndarray
    r: np.ndarray
    theta: np.ndarray
    v: np.ndarray
    meta: dict
    extra: dict = field(default_factory=dict)

    @property
    def kind(self) -> str:
        return self.meta["kind"]

    @property
    def gamma1_deg(self) -> float:
        return float(self.meta["gamma1_deg"])

    @property
    def gamma2_deg(self) -> float:
        return float(self.meta["gamma2_deg"])

    @property
    def kp(self) -> float:
        return float(self.meta["kp"])

    @property
    def frequency_hz(self) -> float:
        return float(self.meta["frequency_hz"])

    @property
    def amplitude_rad(self) -> float:
        return float(self.meta["amplitude_rad"])

    @property
    def uniform(self) -> bool:
        """Whether the samples are evenly spaced (within :data:`UNIFORM_RTOL`)."""
        return _is_uniform(self.t)

    @property
    def dt(self) -> float:
        """Sample period [s]: the first spacing of a uniform run, the median of an irregular one."""
        if self.uniform:
            return float(self.t[1] - self.t[0])
        return float(np.median(np.diff(self.t)))

    @property
    def enabled(self) -> np.ndarray | None:
        """The ``enabled`` column (True: actuator on), or None if the run has none."""
        e = self.extra.get(ENABLED_COLUMN)
        return None if e is None else np.asarray(e) > 0.5


def _is_uniform(t: np.ndarray) -> bool:
    dt = np.diff(t)
    return bool(np.max(np.abs(dt - dt.mean())) <= UNIFORM_RTOL * dt.mean())


def spacing(t: np.ndarray) -> dict:
    """How times ``t`` are spaced: ``period_s`` (median spacing), ``jitter_s`` (standard
    deviation of the spacing), ``max_gap_s`` (longest spacing)."""
    dt = np.diff(t)
    return {"period_s": float(np.median(dt)), "jitter_s": float(np.std(dt)),
            "max_gap_s": float(np.max(dt))}


def timing(run: Run) -> dict:
    """How a run was sampled: :func:`spacing` of its times, ``uniform`` (bool), ``samples``."""
    return {**spacing(run.t), "uniform": run.uniform, "samples": int(len(run.t))}


def resample_uniform(run: Run) -> Run:
    """``run`` on a uniform grid: its own samples if uniform, else the grid ``t0 + k T`` (T the
    median period, up to the last sample) with every column interpolated linearly and
    ``enabled`` held from the last sample at or before each grid time.  Metadata gains
    ``resampled_from`` (the original timing, :func:`timing`)."""
    if run.uniform:
        return run
    info = timing(run)
    period = info["period_s"]
    n = int(math.floor((run.t[-1] - run.t[0]) / period * (1 + 1e-12))) + 1
    t = run.t[0] + period * np.arange(n)

    def lin(x):
        return np.interp(t, run.t, x)

    extra = {}
    for k, x in run.extra.items():
        if k == ENABLED_COLUMN:
            i = np.searchsorted(run.t, t, side="right") - 1
            extra[k] = np.asarray(x)[np.clip(i, 0, len(x) - 1)]
        else:
            extra[k] = lin(x)
    meta = dict(run.meta, resampled_from=info)
    return Run(run.name, t, lin(run.r), lin(run.theta), lin(run.v), meta, extra)



def write_run(folder: str | os.PathLike, run: Run) -> None:
    """Write ``run`` as ``NAME.csv`` + ``NAME.json`` into ``folder`` (which must exist).

    Numbers are written with ``repr``-exact precision (``%.17g``, by the vectorised
    :func:`identification.csvformat.format_rows`) so a round trip is lossless and the same run
    always gives the same bytes.
    """
    folder = Path(folder)
    cols = {"t": run.t, "r": run.r, "theta": run.theta, "v": run.v, **run.extra}
    names = list(cols)
    data = np.column_stack([np.asarray(cols[k], dtype=float) for k in names])
    with open(folder / f"{run.name}.csv", "wb") as fh:  # ASCII bytes as they are
        fh.write((",".join(names) + "\n").encode("ascii"))
        fh.write(format_rows(data))
    with open(folder / f"{run.name}.json", "w", newline="\n") as fh:
        json.dump(run.meta, fh, indent=2, sort_keys=True)
        fh.write("\n")


def _fail(path: Path, problem: str) -> UserError:
    return UserError(f"{path}: {problem}")


def _is_number(val) -> bool:
    return not isinstance(val, bool) and isinstance(val, (int, float)) and math.isfinite(val)


def _read_meta(json_path: Path, require_pose: bool) -> dict:
    """The run's JSON object, its keys checked (:func:`read_run`'s rules)."""
    if not json_path.is_file():
        raise _fail(json_path, "metadata file not found (each run needs NAME.csv and NAME.json)")
    try:
        meta = json.loads(json_path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise _fail(json_path, f"not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise _fail(json_path, "metadata must be a JSON object")
    required = REQUIRED_KEYS if require_pose else tuple(k for k in REQUIRED_KEYS if k not in POSE_KEYS)
    missing = [k for k in required if k not in meta]
    if missing:
        pose = (" (the Omni arm's angles [deg]; the runs of a single-joint robot of your own need "
                "none in omni discrepancy --joint NAME --actuator NAME)") if set(missing) <= set(POSE_KEYS) else ""
        raise _fail(json_path, f"missing required key(s): {', '.join(missing)}{pose}")
    if meta["kind"] not in KINDS:
        raise _fail(json_path, f"kind must be one of {', '.join(KINDS)}, got {meta['kind']!r}")
    # optional numbers: absent or null, else finite
    for k in [k for k in REQUIRED_KEYS[1:] if k in meta] + [k for k in OPTIONAL_NUMBER_KEYS
                                                           if meta.get(k) is not None]:
        if not (_is_number(meta[k]) or (k == "command_limit" and meta[k] == math.inf)):
            raise _fail(json_path, f"{k} must be a finite number, got {meta[k]!r}")
    periodic = meta["kind"] in ("sine", "step")  # a sine or a square wave has a frequency
    rules = (("kp", meta["kp"] > 0, "must be > 0 (the P gain)"),
             ("frequency_hz", meta["frequency_hz"] > 0 if periodic else meta["frequency_hz"] >= 0,
              f"must be {'> 0 for a ' + meta['kind'] if periodic else '>= 0'}"),
             # an "other" run's amplitude is a description (a move to -1.0 rad may say -1.0)
             ("amplitude_rad", meta["amplitude_rad"] > 0 if periodic else True,
              f"must be > 0 for a {meta['kind']}"),
             ("command_limit", meta.get("command_limit") is None or meta["command_limit"] > 0,
              "must be > 0 (the P law's saturation, in the actuator's control units)"),
             ("control_period_s", meta.get("control_period_s") is None or 0 < meta["control_period_s"] <= 1.0,
              "must be a number of seconds in (0, 1]"))
    for key, ok, rule in rules:
        if not ok:
            raise _fail(json_path, f"{key} {rule}, got {meta[key]!r}")
    return meta


#: Column separators other than the comma that spreadsheets and loggers write.
OTHER_SEPARATORS = (";", "\t", "|", " ")


def _other_separator(header: list[str], required) -> str | None:
    """The separator a header that lacks ``required`` columns was written with instead of the
    comma: ``;``, a tab or ``|`` anywhere in it, or -- a single column -- the separator (also a
    space) that splits it into names including every required one; None if none fits."""
    line = ",".join(header)
    for sep in OTHER_SEPARATORS[:-1]:
        if sep in line:
            return sep
    if len(header) == 1:
        for sep in OTHER_SEPARATORS:
            if set(required) <= {h.strip() for h in header[0].split(sep)}:
                return sep
    return None


def read_table(csv_path: str | os.PathLike, required=REQUIRED_COLUMNS) -> tuple[list[str], np.ndarray]:
    """A numeric CSV file: its header names and its rows as a 2-D array of finite numbers, at
    least 2 rows (the samples of a run; ``required``: the columns it must have).

    Raises
    ------
    UserError
        The file is empty, lacks a required column, has no data rows, a malformed or
        non-finite value, a row of another length than the header, fewer than 2 rows."""
    csv_path = Path(csv_path)
    try:
        with open(csv_path) as fh:
            text = fh.read()
    except UnicodeDecodeError as exc:
        raise _fail(csv_path, f"malformed CSV ({exc})") from None
    lines = text.splitlines()
    need = ",".join(required)
    if not lines or not lines[0].strip():
        raise _fail(csv_path, f"empty file (need a header line {need} and one row per sample)")
    header = [h.strip() for h in lines[0].strip().split(",")]
    missing = [c for c in required if c not in header]
    if missing:
        sep = _other_separator(header, required)
        problem = f"missing column(s): {', '.join(missing)} (need {', '.join(required)})"
        if sep is not None:
            raise _fail(csv_path, f"columns must be separated by commas (found {sep!r} in the header): "
                                  f"{problem}; save the file with ',' between columns and '.' as "
                                  "the decimal point")
        raise _fail(csv_path, problem)
    rows = [ln for ln in lines[1:] if ln.strip()]
    if not rows:
        raise _fail(csv_path, "no data rows (only the header line)")
    try:
        data = np.loadtxt(rows, delimiter=",", ndmin=2)
    except ValueError as exc:
        raise _fail(csv_path, f"malformed CSV ({exc})") from None
    if data.shape[1] != len(header):
        raise _fail(csv_path, f"{data.shape[1]} values per row but {len(header)} header names")
    if data.shape[0] < 2:
        raise _fail(csv_path, "fewer than 2 samples")
    if not np.all(np.isfinite(data)):
        row, col = np.argwhere(~np.isfinite(data))[0]
        raise _fail(csv_path, f"non-finite value in column {header[col]!r} at sample {row}")
    return header, data


def _check_samples(csv_path: Path, json_path: Path, cols: dict, meta: dict) -> None:
    """Time strictly increasing, no long gap, ``enabled`` 0/1, a control period no longer than
    the sample period."""
    t = cols["t"]
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0)) + 1
        raise _fail(csv_path, f"time column t is not strictly increasing (sample {k})")
    period = float(np.median(dt))
    if dt.max() > MAX_GAP_PERIODS * period:
        k = int(np.argmax(dt))
        raise _fail(csv_path, f"a gap of {dt[k]:.4g} s after t = {t[k]:.6g} s is longer than "
                              f"{MAX_GAP_PERIODS:g} sample periods ({period:.4g} s): what the "
                              "reference did inside it is not known; split the run there")
    e = cols.get(ENABLED_COLUMN)
    if e is not None and not np.all((e == 0) | (e == 1)):
        k = int(np.argmax((e != 0) & (e != 1)))
        raise _fail(csv_path, f"column 'enabled' must hold 0 or 1, got {float(e[k]):g} at sample {k}")
    cp = meta.get("control_period_s")
    if cp is not None and cp > period * (1 + UNIFORM_RTOL):
        raise _fail(json_path, f"control_period_s {cp:g} s is longer than the sample period "
                               f"{period:.4g} s of {csv_path.name}: a log cannot sample the device's "
                               "loop faster than it runs (control_period_s is in seconds)")


def read_run(csv_path: str | os.PathLike, require_pose: bool = True, uniform: bool = True) -> Run:
    """Read and validate one run from its CSV path (the JSON beside it is read too).

    ``require_pose`` False: ``gamma1_deg``/``gamma2_deg`` may be absent (a device without the
    Omni's arm); if present they must still be finite numbers.  ``uniform`` True: an irregular
    run is resampled onto a uniform grid (:func:`resample_uniform`); False: kept at its logged
    times.

    Raises
    ------
    UserError
        Missing files, missing columns or keys, an empty file or one without data rows,
        non-finite samples, time not strictly increasing, a gap longer than
        :data:`MAX_GAP_PERIODS` periods, an ``enabled`` column with values other than 0/1,
        unknown ``kind``, fewer than 2 samples; a number no run has: ``kp`` <= 0, a negative
        ``frequency_hz`` or ``amplitude_rad`` (zero for a sine or a step), ``command_limit``
        <= 0, ``control_period_s`` outside (0, 1] s or longer than the sample period.  Pose
        angles are checked for being finite numbers only: the joint ranges are the device's
        (``omni_sim.device.Device.check_pose``, applied by the commands).
    """
    csv_path = Path(csv_path)
    json_path = csv_path.with_suffix(".json")
    if not csv_path.is_file():
        raise _fail(csv_path, "file not found")
    meta = _read_meta(json_path, require_pose)
    header, data = read_table(csv_path)
    cols = {h: data[:, i] for i, h in enumerate(header)}
    _check_samples(csv_path, json_path, cols, meta)
    extra = {h: cols[h] for h in header if h not in REQUIRED_COLUMNS}
    run = Run(csv_path.stem, cols["t"], cols["r"], cols["theta"], cols["v"], meta, extra)
    return resample_uniform(run) if uniform else run


#: What a dataset is read for (:func:`read_dataset`'s ``purpose``): ``require_pose``, ``uniform``.
PURPOSES = {"identify": (True, True), "discrepancy": (False, False)}


def read_dataset(folder: str | os.PathLike, require_pose: bool | None = None,
                 uniform: bool | None = None, purpose: str = "identify") -> list[Run]:
    """Read every run in ``folder`` (sorted by name).

    ``purpose`` says what the runs are for: ``"identify"`` (default; the paper's method,
    ``omni identify``/``validate``): the arm pose is required and an irregular run is resampled
    onto a uniform grid; ``"discrepancy"`` (``omni discrepancy``, your own single-joint robot):
    the pose is optional and the runs are kept at their logged times.  ``require_pose``,
    ``uniform`` (see :func:`read_run`), when given, override the purpose's.

    Raises
    ------
    UserError
        The folder does not exist (a file gets the folder to give) or holds no ``.csv`` run, or
        any run is invalid.
    """
    if purpose not in PURPOSES:
        raise ValueError(f"purpose must be one of {', '.join(PURPOSES)}, got {purpose!r}")
    pose, grid = PURPOSES[purpose]
    require_pose = pose if require_pose is None else require_pose
    uniform = grid if uniform is None else uniform
    folder = Path(folder)
    if folder.is_file():
        hint = ""
        if folder.suffix == ".csv" and folder.with_suffix(".json").is_file():
            hint = f"; give the folder that holds it: {folder.parent}"
        raise UserError(f"{folder}: is a file, not a dataset folder (a dataset is a folder of "
                        f"NAME.csv + NAME.json pairs, one per run){hint}")
    if not folder.is_dir():
        raise UserError(f"{folder}: dataset folder not found (a dataset is a folder of NAME.csv + "
                        "NAME.json pairs, one per run)")
    paths = sorted(folder.glob("*.csv"))
    if not paths:
        raise UserError(f"{folder}: no runs (NAME.csv + NAME.json) in this folder")
    return [read_run(p, require_pose, uniform) for p in paths]


def _check_parent(out: Path) -> Path:
    """The folder ``out`` will be written in: it must exist, be a folder and be writable."""
    parent = out.resolve().parent
    if not parent.exists():
        raise UserError(f"{out}: parent folder {parent} does not exist")
    if not parent.is_dir():
        raise UserError(f"{out}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"{out}: parent folder {parent} is not writable")
    return parent


def check_output_dir(out: str | os.PathLike, force: bool = False, inputs=()) -> Path:
    """Check that the output folder ``out`` can be written, before any long work; returns its
    parent folder.  ``inputs``: the files and folders the command reads (None entries
    ignored), which the output must not replace.

    Raises
    ------
    UserError
        ``out`` exists and is not a folder; it is a non-empty folder and ``force`` is not given;
        it is the current folder, holds it, or is or holds one of ``inputs`` (replacing it would
        remove them); its parent folder does not exist, is not a folder or is not writable.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise UserError(f"{out}: output folder exists and is not empty (use --force to replace it)")
    where = out.resolve()
    for kept, what in [(Path.cwd(), "the current folder")] + [(Path(p), str(p)) for p in inputs if p is not None]:
        kept = kept.resolve()
        if where == kept or where in kept.parents:
            raise UserError(f"{out}: is or holds {what}, which the output would replace; give an "
                            "output folder of its own")
    return _check_parent(out)


def check_output_file(path: str | os.PathLike) -> Path:
    """Check that the output file ``path`` can be written (replaced if it exists), before any
    long work; returns its parent folder.

    Raises
    ------
    UserError
        ``path`` is a folder; its parent folder does not exist, is not a folder or is not
        writable.
    """
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{path}: is a folder; give a file name")
    return _check_parent(path)


@contextmanager
def atomic_output_dir(out: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """Yield a temporary folder beside ``out``; on success move it to ``out``.

    Nothing half-written is ever left at ``out``: if the body raises, the temporary folder
    is removed and ``out`` is untouched.  An existing non-empty ``out`` is an error unless
    ``force`` is given, in which case it is replaced only after the new output is complete
    (the checks: :func:`check_output_dir`, which commands call before their work).
    """
    out = Path(out)
    parent = check_output_dir(out, force)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if out.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=parent))
        os.replace(out, old / "x")
        os.replace(tmp, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, out)


def write_dataset(runs, out: str | os.PathLike, force: bool = False) -> None:
    """Write ``runs`` as a dataset folder ``out`` atomically (:func:`atomic_output_dir`, then
    :func:`write_run` for each run)."""
    with atomic_output_dir(out, force=force) as tmp:
        for run in runs:
            write_run(tmp, run)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and rename (never half-written)."""
    path = Path(path)
    parent = check_output_file(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=parent)
    try:
        with os.fdopen(fd, "w", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
