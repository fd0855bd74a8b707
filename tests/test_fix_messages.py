"""Messages that tell the user the fix: what a new user with a single-joint robot of
their own meets on a fresh clone -- a model without the Omni's names, a CSV separated by ';' or
tabs, a folder given as the model, a file given as the dataset, runs without a control period.

Each refusal runs ``omni_app.cli.main`` as :mod:`test_bad_input` does (the long work patched to
raise, so a refusal after it fails): exit status 2, one stderr line ``error: ...``, no
traceback, nothing written, and the message's hint.  The model files here are written by the
tests, so the names the messages list are known without reading the code that lists them.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_bad_input import LongWorkReached, _forbid_long_work, _make, _snapshot, run_cli

from omni_app.cli import main
from omni_sim import model as om

#: A single-joint robot of the user's own: the hinge ``hinge`` driven by the actuator ``motor``,
#: with a slide joint ``rail`` (not a hinge: never offered as --joint) and a 1 ms timestep.
ROBOT = """<mujoco model="robot">
  <option timestep="0.001"/>
  <worldbody>
    <body name="cart">
      <joint name="rail" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.05 0.05 0.05" mass="1"/>
      <body name="arm">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.01" mass="0.2"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="motor" joint="hinge" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""
OWN = ["--joint", "hinge", "--actuator", "motor"]
HINT = "for a single-joint robot of your own, name its joint and actuator: --joint NAME --actuator NAME"


def _csv(dt: float = 0.001, n: int = 600, sep: str = ",") -> str:
    """A run's CSV: a 1 Hz sine tracked at 90 %, ``n`` samples ``dt`` apart, columns separated by ``sep``."""
    t = np.arange(n) * dt
    r = 0.1 * np.sin(2 * math.pi * t)
    rows = [sep.join(f"{x:.6f}" for x in row) for row in zip(t, r, 0.9 * r, 2.0 * 0.1 * r)]
    return "\n".join([sep.join(["t", "r", "theta", "v"]), *rows]) + "\n"


def _meta(**changes) -> str:
    """A run's JSON without an arm pose (a single-joint robot's)."""
    meta = {"kind": "sine", "kp": 2.0, "frequency_hz": 1.0, "amplitude_rad": 0.1}
    meta.update(changes)
    return json.dumps({k: v for k, v in meta.items() if v is not None})


def robot_data(csv: str | None = None, dt: float = 0.001, **meta_changes) -> dict:
    """The model ``robot.xml`` and a two-run dataset ``data`` (``csv``, ``meta_changes``: both runs')."""
    csv = _csv(dt) if csv is None else csv
    return {"robot.xml": ROBOT, "data/a.csv": csv, "data/a.json": _meta(**meta_changes),
            "data/b.csv": csv, "data/b.json": _meta(**meta_changes)}


def refused(argv: list[str], files: dict, tmp_path, monkeypatch, capsys) -> str:
    """Run the command on ``files`` in ``tmp_path``; check the refusal's form; return its line."""
    monkeypatch.chdir(tmp_path)
    _make(files)
    _forbid_long_work(monkeypatch)
    before = _snapshot(tmp_path)
    code, _, err, _ = run_cli(argv, capsys)
    lines = err.splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error:"), err
    assert "Traceback" not in err
    assert _snapshot(tmp_path) == before
    return lines[0]


# -- 1. a model without the Omni's joints: name yours --------------------------------------------
@pytest.mark.parametrize("argv", [
    "discrepancy --measured data --model robot.xml --out o",
    "generate --model robot.xml --out o",
])
def test_forgotten_joint_names_the_flags_and_the_models_hinges(argv, tmp_path, monkeypatch, capsys):
    line = refused(argv.split(), robot_data(), tmp_path, monkeypatch, capsys)
    assert "robot.xml: model lacks the contract's joint(s) yaw, shoulder, elbow" in line
    assert HINT in line
    # the slide joint "rail" is not offered: --joint must be a hinge
    assert "the model has hinge joints: hinge; actuators: motor" in line


@pytest.mark.parametrize("flags, words", [
    (["--joint", "hing", "--actuator", "motor"], "model has no joint 'hing'"),
    (["--joint", "hinge", "--actuator", "motr"], "model has no actuator 'motr'"),
    (["--joint", "rail", "--actuator", "motor"], "joint 'rail' must be a hinge"),
])
def test_a_misspelt_name_lists_the_models_names(flags, words, tmp_path, monkeypatch, capsys):
    line = refused(["discrepancy", "--measured", "data", "--model", "robot.xml", "--out", "o", *flags],
                   robot_data(), tmp_path, monkeypatch, capsys)
    assert words in line and "the model has hinge joints: hinge; actuators: motor" in line


def test_joint_without_model_asks_for_the_model(tmp_path, monkeypatch, capsys):
    line = refused(["discrepancy", "--measured", "data", "--out", "o", *OWN], robot_data(),
                   tmp_path, monkeypatch, capsys)
    assert "model has no joint 'hinge'" in line
    assert "give its model with --model FILE (the default is the virtual Omni's)" in line


def test_runs_without_a_pose_on_the_omni_name_the_flags(tmp_path, monkeypatch, capsys):
    """A single-joint robot's runs (no arm pose) given to the default model (the Omni's)."""
    line = refused(["discrepancy", "--measured", "data", "--out", "o"], robot_data(), tmp_path,
                   monkeypatch, capsys)
    assert line.startswith("error: data/a.json: no arm pose (gamma1_deg, gamma2_deg [deg]), which the "
                           "Omni's model needs")
    assert HINT in line and "give its model: --model FILE" in line


def test_identify_names_the_pose_keys(tmp_path, monkeypatch, capsys):
    line = refused(["identify", "data", "--out", "o"], robot_data(), tmp_path, monkeypatch, capsys)
    # the run is named with the keys it lacks, and what to run instead
    assert "data/a.json: no arm pose (gamma1_deg, gamma2_deg)" in line
    assert "gravity-free yaw axis" in line and "run omni discrepancy --measured data" in line
    assert "--joint J --actuator A" in line


# -- 2. a CSV separated by something else than commas ------------------------------------------
@pytest.mark.parametrize("sep, shown", [(";", "';'"), ("\t", "'\\t'"), (" ", "' '")])
@pytest.mark.parametrize("argv", [
    ["discrepancy", "--measured", "data", "--model", "robot.xml", "--out", "o", *OWN],
    ["identify", "data", "--out", "o"],
])
def test_csv_separator_is_named(sep, shown, argv, tmp_path, monkeypatch, capsys):
    files = robot_data(csv=_csv(sep=sep), gamma1_deg=60.9, gamma2_deg=86.8)
    line = refused(argv, files, tmp_path, monkeypatch, capsys)
    assert line.startswith(f"error: data/a.csv: columns must be separated by commas (found {shown} in "
                           "the header)"), line
    assert "save the file with ',' between columns and '.' as the decimal point" in line


def test_reference_csv_separator_is_named(tmp_path, monkeypatch, capsys):
    line = refused(["generate", "--reference", "ref.csv", "--out", "o"], {"ref.csv": "t;r\n0;0\n1;0,1\n"},
                   tmp_path, monkeypatch, capsys)
    assert "ref.csv: columns must be separated by commas (found ';' in the header)" in line


def test_a_misnamed_column_is_not_blamed_on_the_separator(tmp_path, monkeypatch, capsys):
    csv = _csv().replace("t,r,theta,v", "t,r,theta,volts", 1)
    line = refused(["identify", "data", "--out", "o"], robot_data(csv=csv, gamma1_deg=60.9, gamma2_deg=86.8),
                   tmp_path, monkeypatch, capsys)
    assert "data/a.csv: missing column(s): v (need t, r, theta, v)" in line
    assert "separated" not in line


# -- 3. a folder given as the model --------------------------------------------------------------
@pytest.mark.parametrize("command", ["discrepancy", "generate"])
def test_model_folder_names_the_file_inside(command, tmp_path, monkeypatch, capsys):
    folder = om.SERVO_PENDULUM_DIR
    argv = (["discrepancy", "--measured", "data", *OWN] if command == "discrepancy" else ["generate"])
    line = refused([*argv, "--model", str(folder), "--out", "o"], robot_data(), tmp_path, monkeypatch, capsys)
    assert line == (f"error: {folder}: is a folder, not a model file; give the MJCF file inside it, e.g. "
                    f"{folder / 'servo_pendulum.xml'}")


def test_model_folder_with_several_files_lists_them(tmp_path, monkeypatch, capsys):
    files = {**robot_data(), "mine/robot.xml": ROBOT, "mine/scene.xml": ROBOT, "mine/notes.txt": "x\n"}
    line = refused(["discrepancy", "--measured", "data", "--model", "mine", "--out", "o", *OWN], files,
                   tmp_path, monkeypatch, capsys)
    assert line == ("error: mine: is a folder, not a model file; give the MJCF file inside it, e.g. "
                    "mine/scene.xml (its .xml files: robot.xml, scene.xml)")


def test_model_folder_without_xml(tmp_path, monkeypatch, capsys):
    line = refused(["discrepancy", "--measured", "data", "--model", "mine", "--out", "o", *OWN],
                   {**robot_data(), "mine/notes.txt": "x\n"}, tmp_path, monkeypatch, capsys)
    assert line == "error: mine: is a folder, not a model file, and holds no .xml file; give the model's MJCF file"


# -- 4. a file given as the dataset ------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    "discrepancy --measured data/a.csv --model robot.xml --out o --joint hinge --actuator motor",
    "identify data/a.csv --out o",
])
def test_dataset_file_names_its_folder(argv, tmp_path, monkeypatch, capsys):
    line = refused(argv.split(), robot_data(), tmp_path, monkeypatch, capsys)
    assert line == ("error: data/a.csv: is a file, not a dataset folder (a dataset is a folder of NAME.csv "
                    "+ NAME.json pairs, one per run); give the folder that holds it: data")


def test_dataset_file_without_json_gets_no_folder(tmp_path, monkeypatch, capsys):
    line = refused(["identify", "log.csv", "--out", "o"], {"log.csv": _csv()}, tmp_path, monkeypatch, capsys)
    assert "log.csv: is a file, not a dataset folder (a dataset is a folder of NAME.csv" in line
    assert "give the folder" not in line


# -- 5. runs without control_period_s --------------------------------------------------------------
NOTE = ("note: data: {n} run(s) give no control_period_s: their loop is replayed at the sample period "
        '(5 ms); a servo that closes its loop faster says so in NAME.json, e.g. "control_period_s": 0.001')


@pytest.mark.parametrize("periods, n", [((None, None), 2), ((0.005, None), 1), ((0.005, 0.005), 0)])
def test_a_missing_control_period_is_noted_once(periods, n, tmp_path, monkeypatch, capsys):
    """A 200 Hz log: the note names the runs without ``control_period_s`` and their 5 ms sample
    period, on one stderr line for the dataset, once the inputs passed every check (the long
    work is patched to raise where it begins: the nominal replay)."""
    from discrepancy import workflow

    monkeypatch.chdir(tmp_path)
    files = robot_data(dt=0.005)
    for name, period in zip("ab", periods):
        files[f"data/{name}.json"] = _meta(control_period_s=period)
    _make(files)

    def boom(*args, **kwargs):
        raise LongWorkReached("replay_nominal")

    monkeypatch.setattr(workflow, "replay_nominal", boom)
    with pytest.raises(LongWorkReached):
        main(["discrepancy", "--measured", "data", "--model", "robot.xml", "--out", "o", *OWN])
    err = capsys.readouterr().err.splitlines()
    assert err == ([NOTE.format(n=n)] if n else []), err


def test_no_note_before_an_error(tmp_path, monkeypatch, capsys):
    """A refusal stays one line: the note waits for the workflow's checks (one run is too few)."""
    files = {k: v for k, v in robot_data(dt=0.005).items() if "/b." not in k}
    line = refused(["discrepancy", "--measured", "data", "--model", "robot.xml", "--out", "o", *OWN], files,
                   tmp_path, monkeypatch, capsys)
    assert "at least 2 runs" in line


def test_the_report_records_whether_the_period_was_given(tmp_path):
    """The report's sampling rows say whether the metadata gave the loop period; the page says
    which runs did not, and a report without the field (an older record) reads as before."""
    from identification.dataset import Run
    from omni_app import discrepancy_report as rp
    from discrepancy.replay import prepare_runs
    from discrepancy.report import sampling
    from omni_sim.device import Device

    t = np.arange(200) * 0.005
    r = 0.1 * np.sin(2 * math.pi * t)
    runs = [Run(name, t, r, r, r, json.loads(_meta(control_period_s=period)))
            for name, period in (("given", 0.005), ("guessed", None))]
    target = om.Target("hinge", "motor")
    (tmp_path / "robot.xml").write_text(ROBOT)
    device = Device(om.load_model(tmp_path / "robot.xml", target=target), 0.005, target=target)
    rows = [sampling(x) for x in prepare_runs(runs, device)]
    assert [row["control_period_given"] for row in rows] == [True, False]
    assert all(row["control_period_s"] == 0.005 for row in rows)
    page = "\n".join(rp._md_sampling({"sampling": rows}))
    assert "1 run(s) give no `control_period_s` in their metadata (guessed): their loop period is " \
           "the sample period." in page
    old = [{k: v for k, v in row.items() if k != "control_period_given"} for row in rows]
    assert "control_period_s`" not in "\n".join(rp._md_sampling({"sampling": old}))



def test_the_library_refuses_runs_without_a_pose():
    """From Python as from the command line: identify_runs and validate_runs refuse runs of a
    robot without the Omni's arm in the same one line (it was a KeyError deep in the fit)."""
    from identification import identify_runs, validate_runs
    from identification.dataset import Run
    from identification.errors import UserError

    t = np.arange(2000) * 1e-3
    run = Run("a", t, 0.1 * np.sin(2 * np.pi * t), 0.1 * np.sin(2 * np.pi * t), np.zeros_like(t),
              {"kind": "sine", "kp": 2.0, "frequency_hz": 1.0, "amplitude_rad": 0.1})
    for call in (lambda: identify_runs([run]), lambda: validate_runs([run], None)):
        with pytest.raises(UserError, match=r"run a: no arm pose \(gamma1_deg, gamma2_deg\).*"
                                            r"omni discrepancy --measured DATA"):
            call()
    half = Run("a", t, run.r, run.theta, run.v, {**run.meta, "gamma1_deg": 65.0})
    with pytest.raises(UserError, match="run a: missing required key.*gamma2_deg"):
        identify_runs([half])
