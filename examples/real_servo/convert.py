"""Convert the Feetech STS3250 pendulum logs (BAM's JSON format) into a dataset folder of the
project's dataset contract: one run per log, ``NAME.csv`` + ``NAME.json``.

Columns written (one row per log sample, at the log's own irregular times):

* ``t`` [s]: the log's ``timestamp`` minus the first one;
* ``r`` [rad]: ``goal_position`` (the servo holds its goal between samples);
* ``theta`` [rad]: ``position`` (the servo's 12-bit encoder);
* ``v`` [V]: the command voltage, **not logged**: the estimate of the servo's P law
  ``v = vin * clip(error_gain * kp_firmware * (r - theta), -max_duty, max_duty)``, 0 while the
  torque is off.  ``error_gain`` (0.166 per kp unit per rad) and ``max_duty`` (0.97) were
  measured by the BAM project on the STS3215 sibling; for the STS3250 they are estimates;
* ``enabled``: ``torque_enable`` as 1/0 (0: the motor is switched off, the pendulum swings);
* the log's other fields, kept: ``speed`` [rad/s], ``load``, ``input_volts`` [V], ``temp`` [C].

Units of the actuator's control: volts.  So ``kp`` [V/rad] = vin * error_gain * kp_firmware
(12 * 0.166 * 32 = 63.74 V/rad) and ``command_limit`` [V] = max_duty * vin (11.64 V).

``control_period_s``: the servo's own position loop period.  Feetech does not publish the
loop's rate; its STS3250 sheet lists a "position update rate" of 1 ms (as quoted by third-party
tests of the servo), so the default is 1 ms (``--control-period``).  The model's timestep must
divide it.

Usage::

    python examples/real_servo/convert.py --out real_servo_data
    python examples/real_servo/convert.py --src DIR_OF_JSON --out DIR [--control-period 0.001]

Bad input prints one line ``error: ...`` and exits with status 2; the output folder is written
under a temporary name and renamed only when complete.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: The copied logs (see data/NOTICE for their provenance and licence).
DEFAULT_SRC = HERE / "data"

#: Duty cycle per (firmware kp unit x rad of error): measured by the BAM project with an
#: oscilloscope on the STS3215 sibling (bam/feetech/actuator.py); an estimate for the STS3250.
ERROR_GAIN = 0.166
#: The largest duty cycle the firmware applies (BAM, same source and caveat).
MAX_DUTY = 0.97
#: The servo's own position loop period [s] (see the module docstring).
CONTROL_PERIOD_S = 0.001

ATTRIBUTION = ("Derived from the BAM project (Better Actuator Models, Rhoban), folder "
               "data_raw_feetech/ at commit b53408c (2024-10-26), Apache License 2.0; "
               "see examples/real_servo/data/NOTICE")

#: Keys every log must have, and keys every entry must have.
LOG_KEYS = ("mass", "length", "kp", "vin", "trajectory", "entries")
ENTRY_KEYS = ("timestamp", "position", "goal_position", "torque_enable")
#: Entry fields copied as extra columns when every entry has them.
EXTRA_COLUMNS = ("speed", "load", "input_volts", "temp")


class ConvertError(Exception):
    """A user error: printed as one ``error:`` line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, status 2 (argparse would print the usage too)
        print(f"error: {message}", file=sys.stderr)
        raise SystemExit(2)


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConvertError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def read_log(path: Path) -> dict:
    """Load and check one BAM log; return it (ConvertError on any problem)."""
    try:
        log = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise ConvertError(f"{path}: cannot read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise ConvertError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(log, dict):
        raise ConvertError(f"{path}: expected a JSON object with 'entries'")
    missing = [k for k in LOG_KEYS if k not in log]
    if missing:
        raise ConvertError(f"{path}: missing key(s) {', '.join(missing)}")
    for k in ("mass", "length", "kp", "vin"):
        _number(log[k], f"{path}: {k!r}")
    entries = log["entries"]
    if not isinstance(entries, list) or len(entries) < 2:
        raise ConvertError(f"{path}: 'entries' must be a list of at least 2 samples")
    for i, e in enumerate(entries):
        if not isinstance(e, dict):
            raise ConvertError(f"{path}: entry {i} is not an object")
        gone = [k for k in ENTRY_KEYS if k not in e]
        if gone:
            raise ConvertError(f"{path}: entry {i} lacks {', '.join(gone)}")
        for k in ("timestamp", "position", "goal_position"):
            _number(e[k], f"{path}: entry {i} {k!r}")
        if not isinstance(e["torque_enable"], (bool, int)) or e["torque_enable"] not in (0, 1):
            raise ConvertError(f"{path}: entry {i} 'torque_enable' must be true/false")
    t = [float(e["timestamp"]) for e in entries]
    for i in range(1, len(t)):
        if not t[i] > t[i - 1]:
            raise ConvertError(f"{path}: timestamps not strictly increasing at entry {i} "
                               f"({t[i - 1]!r} then {t[i]!r})")
    return log


def p_law_volts(r: float, theta: float, enabled: bool, kp_v_per_rad: float,
                command_limit_v: float) -> float:
    """The servo's P law in volts: ``clip(kp (r - theta), +-limit)``, 0 with the torque off."""
    if not enabled:
        return 0.0
    return min(command_limit_v, max(-command_limit_v, kp_v_per_rad * (r - theta)))


def convert_log(log: dict, source: str, control_period_s: float, error_gain: float,
                max_duty: float) -> tuple[list[str], list[list], dict]:
    """One log -> (CSV header, rows, metadata) of the dataset contract."""
    vin = float(log["vin"])
    kp_fw = float(log["kp"])
    kp = vin * error_gain * kp_fw
    limit = max_duty * vin
    entries = log["entries"]
    extras = [c for c in EXTRA_COLUMNS if all(c in e for e in entries)]
    header = ["t", "r", "theta", "v", "enabled", *extras]
    t0 = float(entries[0]["timestamp"])
    rows = []
    for e in entries:
        r, th, on = float(e["goal_position"]), float(e["position"]), bool(e["torque_enable"])
        rows.append([float(e["timestamp"]) - t0, r, th, p_law_volts(r, th, on, kp, limit),
                     int(on), *(e[c] for c in extras)])
    meta = {
        "kind": "other",
        "kp": kp,
        "frequency_hz": 0.0,
        "amplitude_rad": max(abs(row[1]) for row in rows),
        "command_limit": limit,
        "control_period_s": control_period_s,
        "source_file": source,
        "trajectory": str(log["trajectory"]),
        "motor": str(log.get("motor", "sts3250")),
        "mass_kg": float(log["mass"]),
        "length_m": float(log["length"]),
        "vin_v": vin,
        "kp_firmware": kp_fw,
        "error_gain_per_kp_rad": error_gain,
        "max_duty": max_duty,
        "units": "r, theta [rad]; v [V] (actuator control in volts); kp [V/rad]; "
                 "command_limit [V]",
        "v_note": "v is not logged: it is the P-law estimate vin*clip(error_gain*kp_firmware*"
                  "(r-theta), +-max_duty), 0 while enabled is 0; error_gain and max_duty are "
                  "the BAM project's STS3215 values, estimates for the STS3250",
        "frequency_note": "not a sine or square wave: frequency_hz 0, amplitude_rad = max |r|",
        "attribution": ATTRIBUTION,
    }
    return header, rows, meta


def _cell(x) -> str:
    if isinstance(x, bool):
        return str(int(x))
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        return repr(x)
    return str(x)


def write_run(folder: Path, name: str, header, rows, meta) -> None:
    with open(folder / f"{name}.csv", "w", newline="") as f:
        f.write(",".join(header) + "\n")
        for row in rows:
            f.write(",".join(_cell(x) for x in row) + "\n")
    (folder / f"{name}.json").write_text(json.dumps(meta, indent=2) + "\n")


def run_names(logs: list[tuple[Path, dict]]) -> list[str]:
    """One file name per log: its trajectory, or trajectory_<file stem> if two logs share it."""
    trajs = [str(log["trajectory"]) for _, log in logs]
    safe = ["".join(c if c.isalnum() or c in "-_" else "_" for c in s) or "run" for s in trajs]
    return [s if safe.count(s) == 1 else f"{s}_{p.stem}" for s, (p, _) in zip(safe, logs)]


def convert(src: Path, out: Path, control_period_s: float = CONTROL_PERIOD_S,
            error_gain: float = ERROR_GAIN, max_duty: float = MAX_DUTY,
            force: bool = False) -> list[str]:
    """Convert every ``*.json`` log in ``src`` into the dataset folder ``out``; return the run
    names.  ``out`` is built under a temporary name beside it and renamed when complete."""
    if not src.is_dir():
        raise ConvertError(f"{src}: not a folder of JSON logs")
    files = sorted(src.glob("*.json"))
    if not files:
        raise ConvertError(f"{src}: no *.json logs")
    if not (control_period_s > 0 and math.isfinite(control_period_s)):
        raise ConvertError(f"--control-period: must be a positive number of seconds, got {control_period_s}")
    if not (error_gain > 0 and math.isfinite(error_gain)):
        raise ConvertError(f"--error-gain: must be positive, got {error_gain}")
    if not (0 < max_duty <= 1):
        raise ConvertError(f"--max-duty: must be in (0, 1], got {max_duty}")
    if out.exists() and not force:
        raise ConvertError(f"{out}: already exists (use --force to replace it)")
    logs = [(p, read_log(p)) for p in files]
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        names = run_names(logs)
        for name, (path, log) in zip(names, logs):
            header, rows, meta = convert_log(log, path.name, control_period_s, error_gain, max_duty)
            write_run(tmp, name, header, rows, meta)
        (tmp / "NOTICE").write_text(ATTRIBUTION + ".\n")
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return names


def main(argv=None) -> int:
    ap = _Parser(description="Convert the Feetech STS3250 pendulum logs (BAM JSON) into a "
                             "dataset folder for omni discrepancy (one run per log).")
    ap.add_argument("--src", type=Path, default=DEFAULT_SRC,
                    help=f"folder of BAM JSON logs (default: {DEFAULT_SRC})")
    ap.add_argument("--out", type=Path, required=True, help="dataset folder to write")
    ap.add_argument("--control-period", type=float, default=CONTROL_PERIOD_S, metavar="S",
                    help="the servo's own loop period [s] written as control_period_s "
                         "(default 0.001: the 1 ms position update rate of the STS3250 sheet)")
    ap.add_argument("--error-gain", type=float, default=ERROR_GAIN,
                    help="duty cycle per (firmware kp unit x rad) (default 0.166, BAM's "
                         "STS3215 value: an estimate)")
    ap.add_argument("--max-duty", type=float, default=MAX_DUTY,
                    help="the firmware's largest duty cycle (default 0.97, BAM's STS3215 value)")
    ap.add_argument("--force", action="store_true", help="replace --out if it exists")
    args = ap.parse_args(argv)
    try:
        names = convert(args.src, args.out, args.control_period, args.error_gain,
                        args.max_duty, args.force)
    except ConvertError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{len(names)} runs ({', '.join(names)}) in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
