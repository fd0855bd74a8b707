"""``omni identify`` and ``omni validate`` on a newcomer's servo logs: a pendulum-like joint
under a P loop, logged at 1 kHz in the dataset contract's format.

* the minimum record (the discarded start, the cycles needed) is named when a run is too short;
* runs the paper's closed loop does not describe (torque off: ``enabled`` 0; a loop faster than
  the log: ``control_period_s`` other than the sample period) are refused by both commands with
  one line, before any work, nothing written; a control period equal to the sample period
  within text round-off is accepted;
* without an α model (``params.json``'s ``"alpha_model": null``, what identify writes when it
  cannot fit one) validate scores the linear model alone and says so.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import cont2discrete

from identification.dataset import Run, read_dataset
from identification.errors import UserError
from identification.identify import (CONTROL_PERIOD_RTOL, check_sine_record, identify_runs,
                                     minimum_sine_record_s)
from identification.inertia import MIN_POSES
from identification.linear import MIN_FREQUENCIES
from identification.nonlinear import paper_alpha_model
from identification.sine_fit import MIN_CYCLES, SETTLE_FRACTION, SETTLE_S
from identification.validation import Params, validate_runs
from omni_app import commands
from omni_app.cli import main

FS_HZ = 1000.0
#: The joint: θ'' = -C θ' + β̃ v, v = kp (r - θ) held over each 1 ms sample (a servo's loop);
#: C [1/s] and β = kp β̃ [1/s²] of a light pendulum-like link (resonance near 2.8 Hz).
C, BETA, KP, AR = 4.0, 300.0, 2.0, 0.1
#: The pose: any the Omni can take (the commands check it); the runs share it.
POSE = {"gamma1_deg": 60.9, "gamma2_deg": 86.8}
SINE_HZ = (1.0, 2.0, 3.0)


def _closed_loop(r: np.ndarray) -> np.ndarray:
    """θ of the joint under the sampled P loop, from rest (exact ZOH discretisation)."""
    a = np.array([[0.0, 1.0], [0.0, -C]])
    b = np.array([[0.0], [BETA / KP]])
    ad, bd, *_ = cont2discrete((a, b, np.eye(2), np.zeros((2, 1))), 1 / FS_HZ, method="zoh")
    x, theta = np.zeros(2), np.empty_like(r)
    for k, rk in enumerate(r):
        theta[k] = x[0]
        x = ad @ x + bd[:, 0] * KP * (rk - x[0])
    return theta


def _write(folder, name, kind, f_hz, seconds=6.0, every=1, enabled=None, **meta):
    """One run as text: CSV (times with 3 decimals, as a logger writes them) and JSON; ``every``
    keeps every n-th sample (a slower log of the same 1 kHz loop)."""
    t = np.arange(int(round(seconds * FS_HZ))) / FS_HZ
    phase = 2 * math.pi * f_hz * t
    r = AR * np.sin(phase) if kind == "sine" else AR * np.where(np.sin(phase) >= 0, 1.0, -1.0)
    theta = _closed_loop(r)
    cols = [t, r, theta, KP * (r - theta)] + ([] if enabled is None else [enabled])
    head = "t,r,theta,v" + ("" if enabled is None else ",enabled")
    rows = [",".join(f"{x:.9f}" if j else f"{x:.3f}" for j, x in enumerate(row))
            for row in np.column_stack(cols)[::every]]
    (folder / f"{name}.csv").write_text("\n".join([head, *rows]) + "\n")
    (folder / f"{name}.json").write_text(json.dumps(
        {"kind": kind, **POSE, "kp": KP, "frequency_hz": f_hz, "amplitude_rad": AR, **meta}))


def _pendulum(folder, **sine1_changes):
    """Three sines and a square wave; ``sine1_changes``: :func:`_write` arguments of the
    1 Hz run."""
    folder.mkdir()
    for f in SINE_HZ:
        _write(folder, f"sine_{f:g}hz", "sine", f, **(sine1_changes if f == 1.0 else {}))
    _write(folder, "step_0.5hz", "step", 0.5)
    return folder


def _cli(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _one_error_line(code, err, *needles):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), err
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """The pendulum dataset and identify's output folder."""
    root = tmp_path_factory.mktemp("pendulum")
    data = _pendulum(root / "data")
    assert main(["identify", str(data), "--out", str(root / "ident")]) == 0
    return data, root / "ident"


# -- the minimum record ----------------------------------------------------------------------
@pytest.mark.parametrize("f_hz", [0.4, 1.0, 2.0, 7.0])
def test_minimum_record_is_the_shortest_accepted(f_hz):
    """A sine run of :func:`minimum_sine_record_s` (rounded up to whole samples) passes the
    steady-state rule, one sample less does not; below 1.5 Hz the half-run discard decides, above
    it the 2 s one (both sides covered)."""
    n = math.ceil(minimum_sine_record_s(f_hz) * FS_HZ - 1e-6)  # 1e-6 sample: float round-off of s*Hz
    for samples, ok in ((n, True), (n - 1, False)):
        t = np.arange(samples) / FS_HZ
        run = Run("r", t, np.sin(2 * math.pi * f_hz * t), np.zeros_like(t), np.zeros_like(t),
                  {"kind": "sine", **POSE, "kp": KP, "frequency_hz": f_hz, "amplitude_rad": 1.0})
        if ok:
            check_sine_record(run)
        else:
            with pytest.raises(UserError, match=f"minimum record is {minimum_sine_record_s(f_hz):.4g} s"):
                check_sine_record(run)


def test_identify_names_the_minimum_record(tmp_path, capsys):
    """A 1 Hz run of 4 s: identify's one error line says how long it must be (the minimum from
    the steady-state rule's constants) and nothing is written."""
    data = _pendulum(tmp_path / "data", seconds=4.0)
    out = tmp_path / "out"
    code, _, err = _cli(["identify", str(data), "--out", str(out)], capsys)
    need = max(SETTLE_S + MIN_CYCLES / 1.0, MIN_CYCLES / (1.0 - SETTLE_FRACTION))
    _one_error_line(code, err, "sine_1hz", f"minimum record is {need:.4g} s",
                    f"max({SETTLE_S:g} s", f"{MIN_CYCLES} whole cycles")
    assert not out.exists()


def test_validate_refuses_a_short_run_before_simulating(identified, tmp_path, monkeypatch):
    """validate checks the record before its simulations (patched to fail here)."""
    _, ident = identified
    data = _pendulum(tmp_path / "data", seconds=4.0)

    def boom(*args, **kwargs):
        raise AssertionError("simulated before refusing")

    monkeypatch.setattr("identification.validation.simulate_runs", boom)
    params = Params.from_dict(json.loads((ident / "params.json").read_text()))
    with pytest.raises(UserError, match="sine_1hz.*minimum record"):
        validate_runs(read_dataset(data), params)


def test_readme_states_the_minimum_record():
    """The README's Data section gives the rule's constants and its examples as the code has
    them (a changed constant fails here until the README follows)."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    data = readme.split("## Data: a folder of runs", 1)[1].split("\n## ", 1)[0]
    flat = " ".join(data.split())
    half = {0.5: "half the run"}[SETTLE_FRACTION]  # the README words the fraction
    for text in (f"max({SETTLE_S:g} s, {half})", f"at least {MIN_CYCLES} whole cycles",
                 f"max({SETTLE_S:g} s + {MIN_CYCLES}/f, {MIN_CYCLES / (1 - SETTLE_FRACTION):g}/f)",
                 *(f"{minimum_sine_record_s(f):g} s at {f:g} Hz" for f in (1.0, 2.0, 0.5)),
                 f"by more than {CONTROL_PERIOD_RTOL:g} of it", f"{MIN_FREQUENCIES} sine frequencies",
                 f"inertia model needs {MIN_POSES} poses"):
        assert text in flat, text


# -- servo logs: torque off, a loop faster than the log --------------------------------------
def _torque_off(n=6000):
    on = np.ones(n)
    on[2500:3500] = 0.0  # a second of free swing in the middle
    return on


SERVO_CASES = {
    "torque_off": ({"enabled": _torque_off()}, ["sine_1hz.csv", "torque off", "1000 of 6000",
                                                "t = 2.5 s", "omni discrepancy"]),
    "50hz_log_of_1khz_loop": ({"every": 20, "control_period_s": 0.001},
                              ["sine_1hz.json", "control_period_s 0.001 s", "sample period 0.02 s",
                               "omni discrepancy"]),
}


@pytest.mark.parametrize("command", ["identify", "validate"])
@pytest.mark.parametrize("case", sorted(SERVO_CASES))
def test_servo_runs_are_refused(identified, tmp_path, capsys, monkeypatch, command, case):
    """One error line naming the run, the reason and the command that replays such runs; exit
    2; nothing written; before the command's work (patched to fail here)."""
    _, ident = identified
    changes, needles = SERVO_CASES[case]
    data = _pendulum(tmp_path / "data", **changes)
    for work in ("identify_runs", "validate_runs"):
        monkeypatch.setattr(commands, work, lambda *a, **k: pytest.fail("reached the work"))
    out = tmp_path / "out"
    argv = [command, str(data), "--out", str(out)]
    if command == "validate":
        argv += ["--params", str(ident / "params.json")]
    code, _, err = _cli(argv, capsys)
    _one_error_line(code, err, f"omni {command}", *needles)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data"]


@pytest.mark.parametrize("case", sorted(SERVO_CASES))
def test_servo_runs_are_refused_by_the_library(identified, tmp_path, case):
    """identify_runs and validate_runs refuse them too (scripts that skip the command)."""
    _, ident = identified
    runs = read_dataset(_pendulum(tmp_path / "data", **SERVO_CASES[case][0]))
    params = Params.from_dict(json.loads((ident / "params.json").read_text()))
    with pytest.raises(UserError, match="run sine_1hz"):
        identify_runs(runs)
    with pytest.raises(UserError, match="run sine_1hz"):
        validate_runs(runs, params)


@pytest.mark.parametrize("period", [0.001, 0.0010000004])
def test_control_period_equal_to_the_sample_period_is_accepted(identified, tmp_path, capsys, period):
    """A 1 kHz log of a 1 kHz loop (0.0010000004: the period written with round-off in its 10th
    digit; the times themselves are written with 3 decimals), all samples ``enabled`` 1:
    identified and validated as the plain log is, to the same numbers."""
    base, ident = identified
    data = _pendulum(tmp_path / "data", control_period_s=period, enabled=np.ones(6000))
    code, _, err = _cli(["identify", str(data), "--out", str(tmp_path / "ident")], capsys)
    assert code == 0, err
    got = json.loads((tmp_path / "ident" / "params.json").read_text())
    want = json.loads((ident / "params.json").read_text())
    assert got["poses"] == want["poses"]
    code, _, err = _cli(["validate", str(data), "--params", str(ident / "params.json"),
                         "--out", str(tmp_path / "val")], capsys)
    assert code == 0, err


# -- validate without an alpha model --------------------------------------------------------
def test_identify_writes_null_when_no_alpha_model(identified):
    _, ident = identified
    params = json.loads((ident / "params.json").read_text())
    assert params["alpha_model"] is None
    assert any(w.startswith("alpha-invariant model not fitted") for w in params["warnings"])


def test_validate_scores_the_linear_model_alone(identified, tmp_path, capsys):
    """validate on identify's params (no α model): exit 0; the linear scores are the ones
    validate gives with an α model present (the paper's, put in for comparison), every α score
    null, the reason in ``alpha_not_scored``, a printed line saying the α model was not scored,
    and predictions with a ``theta_alpha`` column of nan."""
    data, ident = identified
    code, out, err = _cli(["validate", str(data), "--params", str(ident / "params.json"),
                           "--out", str(tmp_path / "lin")], capsys)
    assert code == 0, err
    assert re.search(r"^alpha model not scored \(linear model only\): .*alpha-invariant model not "
                     r"fitted", out, re.M), out
    lin = json.loads((tmp_path / "lin" / "summary.json").read_text())
    assert "alpha-invariant model not fitted" in lin["alpha_not_scored"]
    with_alpha = json.loads((ident / "params.json").read_text())
    with_alpha["alpha_model"] = paper_alpha_model().to_dict()
    (tmp_path / "alpha.json").write_text(json.dumps(with_alpha))
    code, _, err = _cli(["validate", str(data), "--params", str(tmp_path / "alpha.json"),
                         "--out", str(tmp_path / "both")], capsys)
    assert code == 0, err
    both = json.loads((tmp_path / "both" / "summary.json").read_text())
    assert "alpha_not_scored" not in both and lin["alpha_simulation"] is None
    for part in ("sine", "step"):
        for key, value in both[part].items():
            if "alpha" in key or key.startswith("ratio_"):
                assert lin[part][key] is None, (part, key)
            elif key != "windows":
                assert lin[part][key] == value, (part, key)
    for name in ("sine_1hz", "step_0.5hz"):
        pred = (tmp_path / "lin" / "predictions" / f"{name}.csv").read_text().splitlines()
        assert pred[0] == "t,theta,theta_linear,theta_alpha"
        ref = (tmp_path / "both" / "predictions" / f"{name}.csv").read_text().splitlines()
        assert len(pred) == len(ref)
        for a, b in zip(pred[1:], ref[1:]):
            assert a.split(",")[:3] == b.split(",")[:3] and a.split(",")[3] == "nan"

