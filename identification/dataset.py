"""The dataset contract: a folder of runs, each ``NAME.csv`` + ``NAME.json``.

CSV: one header line, one row per uniformly spaced sample; required columns ``t`` [s],
``r`` [rad] (yaw reference), ``theta`` [rad] (measured yaw), ``v`` [V] (command voltage);
more columns are allowed and kept.

JSON: ``kind`` ("sine" | "step" | "other"), ``gamma1_deg``, ``gamma2_deg`` (actual arm
angles [deg]), ``kp`` [V/rad], ``frequency_hz`` [Hz], ``amplitude_rad`` [rad]; optional
``gamma1_set_deg``, ``gamma2_set_deg``; anything else is kept.  A single-joint device
without the Omni's arm (``omni discrepancy --joint``) has no pose: its runs are read with
``require_pose=False``, which makes ``gamma1_deg``/``gamma2_deg`` optional (finite if given),
and may carry ``command_limit`` (the P law's saturation).

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
    def dt(self) -> float:
        """Sample period [s]."""
        return float(self.t[1] - self.t[0])



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


def read_run(csv_path: str | os.PathLike, require_pose: bool = True) -> Run:
    """Read and validate one run from its CSV path (the JSON beside it is read too).

    ``require_pose`` False: ``gamma1_deg``/``gamma2_deg`` may be absent (a device without the
    Omni's arm); if present they must still be finite numbers.

    Raises
    ------
    UserError
        Missing files, missing columns or keys, non-finite samples, non-uniform sampling,
        unknown ``kind``, fewer than 2 samples.
    """
    csv_path = Path(csv_path)
    json_path = csv_path.with_suffix(".json")
    if not csv_path.is_file():
        raise _fail(csv_path, "file not found")
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
        raise _fail(json_path, f"missing required key(s): {', '.join(missing)}")
    if meta["kind"] not in KINDS:
        raise _fail(json_path, f"kind must be one of {', '.join(KINDS)}, got {meta['kind']!r}")
    for k in [k for k in REQUIRED_KEYS[1:] if k in meta]:
        val = meta[k]
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
            raise _fail(json_path, f"{k} must be a finite number, got {val!r}")
    try:
        with open(csv_path) as fh:
            header = fh.readline().strip().split(",")
            header = [h.strip() for h in header]
            data = np.loadtxt(fh, delimiter=",", ndmin=2)
    except (ValueError, UnicodeDecodeError) as exc:
        raise _fail(csv_path, f"malformed CSV ({exc})") from None
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise _fail(csv_path, f"missing column(s): {', '.join(missing)} (need t, r, theta, v)")
    if data.shape[1] != len(header):
        raise _fail(csv_path, f"{data.shape[1]} values per row but {len(header)} header names")
    if data.shape[0] < 2:
        raise _fail(csv_path, "fewer than 2 samples")
    if not np.all(np.isfinite(data)):
        row, col = np.argwhere(~np.isfinite(data))[0]
        raise _fail(csv_path, f"non-finite value in column {header[col]!r} at sample {row}")
    cols = {h: data[:, i] for i, h in enumerate(header)}
    t = cols["t"]
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise _fail(csv_path, "time column t is not strictly increasing")
    if np.max(np.abs(dt - dt.mean())) > UNIFORM_RTOL * dt.mean():
        raise _fail(csv_path, "non-uniform sampling (the contract requires a constant time step)")
    extra = {h: cols[h] for h in header if h not in REQUIRED_COLUMNS}
    return Run(csv_path.stem, t, cols["r"], cols["theta"], cols["v"], meta, extra)


def read_dataset(folder: str | os.PathLike, require_pose: bool = True) -> list[Run]:
    """Read every run in ``folder`` (sorted by name); ``require_pose``: see :func:`read_run`.

    Raises
    ------
    UserError
        The folder does not exist or holds no ``.csv`` run, or any run is invalid.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: dataset folder not found")
    paths = sorted(folder.glob("*.csv"))
    if not paths:
        raise UserError(f"{folder}: no runs (NAME.csv + NAME.json) in this folder")
    return [read_run(p, require_pose) for p in paths]


@contextmanager
def atomic_output_dir(out: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """Yield a temporary folder beside ``out``; on success move it to ``out``.

    Nothing half-written is ever left at ``out``: if the body raises, the temporary folder
    is removed and ``out`` is untouched.  An existing non-empty ``out`` is an error unless
    ``force`` is given, in which case it is replaced only after the new output is complete.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise UserError(f"{out}: output folder exists and is not empty (use --force to replace it)")
    parent = out.resolve().parent
    if not parent.is_dir():
        raise UserError(f"{out}: parent folder {parent} does not exist")
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
    parent = path.resolve().parent
    if not parent.is_dir():
        raise UserError(f"{path}: parent folder {parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=parent)
    try:
        with os.fdopen(fd, "w", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
