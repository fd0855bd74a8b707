"""The real-servo example (examples/real_servo/): the copied logs and their attribution, the
converter (contract columns and metadata, user errors), the nominal model, and the free-swing
check against the lift_and_drop log.  Needs no replay of the dataset contract."""

from __future__ import annotations

import csv
import hashlib
import importlib.util
import json
import re
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from omni_sim import model as om

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "real_servo"
DATA = EXAMPLE / "data"
LOGS = ("2024-10-26_12h23m27.json", "2024-10-26_12h23m42.json", "2024-10-26_12h24m55.json",
        "2024-10-26_12h27m27.json")


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"real_servo_{name}", EXAMPLE / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    out = tmp_path_factory.mktemp("rs") / "data"
    assert _load("convert").main(["--out", str(out)]) == 0
    return out


def _digests(path: Path) -> tuple[dict, dict, str]:
    """From a SHA256SUMS file: the SHA-256 of each log, its git blob id at the source commit
    (comment lines ``#   blob ID  NAME``), and the source commit."""
    sha, blob, commits = {}, {}, []
    for line in path.read_text().splitlines():
        if line.startswith("#"):
            commits += re.findall(r"\bcommit ([0-9a-f]{40})\b", line)
            m = re.fullmatch(r"#\s+blob ([0-9a-f]{40})\s+(\S+)", line)
            if m:
                blob[m[2]] = m[1]
        elif line.strip():
            digest, name = line.split()
            sha[name] = digest
    assert len(commits) == 1, commits
    return sha, blob, commits[0]


def _git_blob_id(data: bytes) -> str:
    """The id git gives a file's bytes (SHA-1 of ``blob <size>\\0`` and the bytes)."""
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def _check_logs(folder: Path) -> None:
    """The logs in ``folder`` are the bytes of the source commit, by the digests kept in the
    project (``folder/SHA256SUMS``): their SHA-256 and their git blob ids."""
    sha, blob, commit = _digests(folder / "SHA256SUMS")
    assert sorted(sha) == sorted(blob) == sorted(p.name for p in folder.glob("*.json")) == list(LOGS)
    for name in LOGS:
        data = (folder / name).read_bytes()
        assert hashlib.sha256(data).hexdigest() == sha[name], name
        assert _git_blob_id(data) == blob[name], name


def test_logs_and_attribution():
    """The logs are checked on every run against the digests kept beside them (with the source
    commit that NOTICE names)."""
    notice = (DATA / "NOTICE").read_text()
    for words in ("BAM", "Rhoban", "data_raw_feetech", "b53408c", "Apache"):
        assert words in notice
    _check_logs(DATA)
    sha, _, commit = _digests(DATA / "SHA256SUMS")
    assert commit.startswith("b53408c") and set(sha) == set(LOGS)


@pytest.mark.parametrize("damage", ["byte", "swap"])
def test_a_changed_log_is_caught(tmp_path, damage):
    """The check of the logs fails on a copy with one byte changed, or two logs' names swapped."""
    copy = tmp_path / "data"
    shutil.copytree(DATA, copy)
    _check_logs(copy)
    path = copy / LOGS[1]
    if damage == "byte":
        data = bytearray(path.read_bytes())
        data[len(data) // 2] ^= 1
        path.write_bytes(bytes(data))
    else:
        other = copy / LOGS[2]
        a, b = path.read_bytes(), other.read_bytes()
        path.write_bytes(b)
        other.write_bytes(a)
    with pytest.raises(AssertionError, match=LOGS[1]):
        _check_logs(copy)


def test_convert_writes_the_contract(converted):
    names = sorted(p.stem for p in converted.glob("*.csv"))
    assert names == ["lift_and_drop", "sin_sin", "sin_time_square", "up_and_down"]
    assert "Apache" in (converted / "NOTICE").read_text()
    for name in names:
        meta = json.loads((converted / f"{name}.json").read_text())
        assert meta["kind"] == "other" and meta["trajectory"] == name
        assert meta["kp"] == pytest.approx(12 * 0.166 * 32)
        assert meta["command_limit"] == pytest.approx(0.97 * 12)
        assert meta["control_period_s"] == 0.001
        assert "b53408c" in meta["attribution"]
        with open(converted / f"{name}.csv") as f:
            rows = list(csv.DictReader(f))
        assert list(rows[0])[:5] == ["t", "r", "theta", "v", "enabled"]
        t, r, th, v, on = (np.array([float(row[c]) for row in rows])
                           for c in ("t", "r", "theta", "v", "enabled"))
        assert t[0] == 0 and np.all(np.diff(t) > 0)
        assert set(np.unique(on)) <= {0.0, 1.0}
        assert meta["amplitude_rad"] == pytest.approx(np.abs(r).max())
        law = np.clip(meta["kp"] * (r - th), -meta["command_limit"], meta["command_limit"])
        assert np.allclose(v, np.where(on == 1, law, 0.0))
    lift = np.loadtxt(converted / "lift_and_drop.csv", delimiter=",", skiprows=1, usecols=4)
    assert lift[0] == 1 and lift[-1] == 0  # torque switched off during the run


def test_convert_user_errors(tmp_path, capsys):
    conv = _load("convert")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "x.json").write_text('{"mass": 1')
    cases = [
        ["--src", str(tmp_path / "none"), "--out", str(tmp_path / "o1")],
        ["--src", str(bad), "--out", str(tmp_path / "o2")],
        ["--out", str(tmp_path / "o3"), "--control-period", "0"],
        ["--out", str(tmp_path / "o4"), "--max-duty", "1.5"],
    ]
    log = json.loads((DATA / LOGS[0]).read_text())
    log["entries"][5]["timestamp"] = log["entries"][4]["timestamp"]
    dup = tmp_path / "dup"
    dup.mkdir()
    (dup / "a.json").write_text(json.dumps(log))
    cases.append(["--src", str(dup), "--out", str(tmp_path / "o5")])
    for argv in cases:
        capsys.readouterr()
        assert conv.main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith("error:") and "\n" not in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad", "dup"]  # nothing half-written
    with pytest.raises(SystemExit) as exc:
        conv.main([])  # --out missing: argparse's error, one line, status 2
    assert exc.value.code == 2
    assert capsys.readouterr().err.strip().startswith("error:")
    out = tmp_path / "once"
    assert conv.main(["--out", str(out)]) == 0
    assert conv.main(["--out", str(out)]) == 2  # exists
    assert conv.main(["--out", str(out), "--force"]) == 0


def test_model_numbers():
    m = mujoco.MjModel.from_xml_path(str(EXAMPLE / "model.xml"))
    om.index(m, EXAMPLE / "model.xml", om.Target("servo_axis", "servo"))
    assert m.opt.timestep == 0.001
    d = mujoco.MjData(m)
    d.ctrl[0] = 12.0
    mujoco.mj_forward(m, d)
    assert d.qfrc_actuator[0] == pytest.approx(4.903, abs=2e-3)  # the sheet's stall torque
    assert m.dof_damping[0] == pytest.approx(0.0349)  # the gearbox's; the back-EMF is the actuator's
    d.qvel[0] = 2.0
    mujoco.mj_forward(m, d)
    assert d.qfrc_actuator[0] == pytest.approx(4.903 - 0.6227 * 2.0, abs=2e-3)
    d.qvel[0] = 0.0
    assert d.M[0] == pytest.approx(1.13 * 0.12**2 + 1.81e-4 + 0.0119)
    # gravity restores towards q = 0 (hanging) from either side
    for q in (-0.5, 0.5):
        d.qpos[0], d.ctrl[0] = q, 0.0
        mujoco.mj_forward(m, d)
        assert np.sign(d.qfrc_bias[0]) == np.sign(q)  # bias = -(applied): gravity pulls back
        assert abs(d.qfrc_bias[0]) == pytest.approx(1.13 * 9.81 * 0.12 * np.sin(abs(q)), rel=1e-3)


def test_free_swing_figures():
    fs = _load("free_swing")
    r = fs.compare()
    assert r["release_rad"] == pytest.approx(-1.536, abs=1e-3)
    assert len(r["log"]["points"]) == 5
    assert r["log"]["half_period_s"] == pytest.approx(0.463, abs=0.005)
    assert len(r["brake"]["points"]) == 1  # the back-EMF over-damps: no swing
    assert len(r["coast"]["points"]) >= 3  # an open winding swings, as the log does
    assert r["coast"]["half_period_s"] == pytest.approx(0.504, abs=0.005)
    assert r["coast"]["rms_rad"] < r["brake"]["rms_rad"]
