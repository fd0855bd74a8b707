"""Bad input across the CLI: every command refuses it with exactly one stderr line
``error: ...``, exit status 2, no traceback, nothing written, and before any long computation.

The table :data:`CASES` lists each input: the command line, the files to create first (path ->
text; a path ending in ``/`` is a folder) and a substring of the expected message.  Each case
runs ``omni_app.cli.main`` in this process with every long computation patched to raise
(:data:`LONG_WORK`: the physics, the identification, the fits, the discrepancy replays, the
benchmark, the sweep's cluster), so a refusal that came only after the work fails the test.
"""

from __future__ import annotations

import hashlib
import importlib
import io
import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from omni_app.cli import main

ROOT = Path(__file__).resolve().parents[1]

#: The long computations, patched to raise: ``(module, attribute)``, an attribute of a class
#: as ``module:Class.attribute``.
LONG_WORK = (
    ("omni_sim.experiments", "run_fast"),        # the physics of generate, reproduce, --demo
    ("omni_sim.experiments", "run_reference"),
    ("omni_app.commands", "identify_runs"),      # identify's fits
    ("omni_app.commands", "validate_runs"),      # validate's simulations
    ("identification.inertia", "_profile_minima"),  # fit-inertia's search
    ("omni_app.reproduce", "worker_pool"),       # reproduce's worker processes
    ("discrepancy.replay:Replayer", "__init__"),  # every replay of the discrepancy search
    ("omni_studies.bench", "run_bench"),
    ("omni_studies.sweep", "_client"),           # the Dask cluster
    ("omni_studies.sweep", "run_variant"),
)
#: A refusal's wall time bound [s].  Refusals measured here take 0.01-0.3 s (the slowest: sweep
#: compiling its study's base model); the long work is patched to raise, so this only bounds
#: the checks themselves, with room for a loaded 2-core machine.
MAX_WALL_S = 5.0


class LongWorkReached(Exception):
    """A long computation started before the input was refused."""


def _forbid_long_work(monkeypatch) -> None:
    for where, name in LONG_WORK:
        module, _, cls = where.partition(":")
        obj = importlib.import_module(module)
        if cls:
            obj = getattr(obj, cls)

        def boom(*args, _what=f"{where}.{name}", **kwargs):
            raise LongWorkReached(_what)

        monkeypatch.setattr(obj, name, boom)  # raising=True: a renamed target fails loudly


# -- files -----------------------------------------------------------------------------------
def _csv(kind: str = "sine", n: int = 600, dt: float = 0.001, extra: str = "") -> str:
    """A run's CSV: 0.6 s at 1 kHz of a 2 Hz sine (or a 0.5 Hz square wave) tracked at 90 %."""
    t = np.arange(n) * dt
    r = 0.05 * np.sin(2 * math.pi * 2.0 * t) if kind == "sine" else 0.07 * np.sign(np.cos(math.pi * t))
    theta = 0.9 * r
    v = 2.0 * (r - theta)
    head = "t,r,theta,v" + (",enabled" if extra else "")
    rows = [f"{a:.3f},{b:.6f},{c:.6f},{d:.6f}" + (f",{extra}" if extra else "")
            for a, b, c, d in zip(t, r, theta, v)]
    return "\n".join([head, *rows]) + "\n"


def _meta(kind: str = "sine", **changes) -> str:
    """A run's JSON at the Omni's pose (65, 90) deg set, (60.9, 86.8) deg actual."""
    meta = {"kind": kind, "gamma1_deg": 60.9, "gamma2_deg": 86.8, "gamma1_set_deg": 65,
            "gamma2_set_deg": 90, "kp": 2.0, "frequency_hz": 2.0 if kind == "sine" else 0.5,
            "amplitude_rad": 0.05 if kind == "sine" else 0.07, "control_period_s": 0.001}
    meta.update(changes)
    return json.dumps(meta)


def _edit(text: str, line: int, column: int, value: str) -> str:
    lines = text.splitlines()
    parts = lines[line].split(",")
    parts[column] = value
    lines[line] = ",".join(parts)
    return "\n".join(lines) + "\n"


def data(csv: str | None = None, folder: str = "data", **meta_changes) -> dict:
    """A two-run dataset (a sine ``a`` and a square wave ``b``); ``csv`` and ``meta_changes``
    replace run ``a``'s CSV text and metadata keys."""
    return {f"{folder}/a.csv": _csv() if csv is None else csv, f"{folder}/a.json": _meta(**meta_changes),
            f"{folder}/b.csv": _csv("step"), f"{folder}/b.json": _meta("step")}


GOOD = data()
#: A params.json that omni validate accepts: the committed identification of the lugre family.
PARAMS_DICT = json.loads((ROOT / "docs" / "studies" / "friction" / "lugre" / "params.json").read_text())
PARAMS = {"params.json": json.dumps(PARAMS_DICT)}


def params(**changes) -> dict:
    """That params.json with top-level keys or ``inertia_model`` values (``im_KEY``) changed."""
    d = json.loads(json.dumps(PARAMS_DICT))
    for k, v in changes.items():
        if k.startswith("im_"):
            d["inertia_model"][k[3:]] = v
        else:
            d[k] = v
    return {"params.json": json.dumps(d)}


CAMPAIGN = """[sine]
poses_deg = [[65, 90]]
frequencies_hz = [2.0]
amplitude_rad = 0.05
settle_s = 0.5
record_s = 1.0
"""
STUDY = """[base]
friction = "lugre"
[pipeline]
name = "simulate"
campaign = "step"
"""
TABLE_HEAD = "gamma1_deg,gamma2_deg,C_linear,beta_tilde_linear\n"
TABLE9 = "".join(f"{g1},{g2},{6 + g1 / 100},{200 + g1 + g2}\n" for g1 in (21.5, 40.7, 60.7)
                 for g2 in (69.5, 88.5, 112.4))
A_FILE = {"afile": "not a folder\n"}
FULL = {"full/old.txt": "earlier output\n"}

CASES = [
    # -- identify (the three first)
    ("identify data --out o", data(gamma1_deg=1e9), "shoulder angle 1e+09 deg is outside the joint range"),
    ("identify data --out o", data(csv=""), "a.csv: empty file"),
    ("identify data --out o", data(csv="t,r,theta,v\n"), "a.csv: no data rows"),
    ("identify data --out o", data(gamma2_set_deg=400), "gamma1_set_deg, gamma2_set_deg: elbow angle 400"),
    ("identify data --out o", data(kp=-2.0), "kp must be > 0"),
    ("identify data --out o", data(kp=0), "kp must be > 0"),
    ("identify data --out o", {**data(), "data/a.json": _meta().replace('"kp": 2.0', '"kp": NaN')},
     "kp must be a finite number"),
    ("identify data --out o", data(frequency_hz=0.0), "frequency_hz must be > 0 for a sine"),
    ("identify data --out o", data(amplitude_rad=-0.05), "amplitude_rad must be > 0 for a sine"),
    ("identify data --out o", data(csv=_edit(_csv(), 5, 0, "0.003")), "t is not strictly increasing"),
    ("identify data --out o", data(csv=_edit(_csv(), 5, 2, "nan")), "non-finite value in column 'theta'"),
    ("identify data --out o", data(csv="t,r,v\n0,0,0\n0.001,0,0\n"), "missing column(s): theta"),
    ("identify data --out o", data(csv=_csv(extra="2")), "column 'enabled' must hold 0 or 1, got 2 at"),
    ("identify data --out o", data(control_period_s=0.01), "control_period_s 0.01 s is longer than the sample"),
    ("identify data --out o", data(control_period_s=0), "control_period_s must be a number of seconds"),
    ("identify data --out o", data(command_limit=-1), "command_limit must be > 0"),
    ("identify data --out o", data(csv=_csv(extra="0")), "data/a.csv: torque off (column 'enabled' 0)"),
    ("identify data --out o", data(control_period_s=0.0005), "data/a.json: control_period_s 0.0005 s is not"),
    ("identify data --out afile", {**GOOD, **A_FILE}, "afile: exists and is not a folder"),
    ("identify data --out nowhere/o", GOOD, "parent folder"),
    ("identify data --out afile/o", {**GOOD, **A_FILE}, "afile is not a folder"),
    ("identify data --out full", {**GOOD, **FULL}, "use --force"),
    ("identify nodata --out o", {}, "nodata: dataset folder not found"),
    ("identify data --out . --force", GOOD, ".: is or holds the current folder"),
    ("identify data --out data --force", GOOD, "data: is or holds data, which the output would replace"),
    # -- generate
    ("generate --campaign c.toml --out afile", {"c.toml": CAMPAIGN, **A_FILE}, "exists and is not a folder"),
    ("generate --campaign c.toml --out nowhere/o", {"c.toml": CAMPAIGN}, "parent folder"),
    ("generate --campaign c.toml --out o", {"c.toml": CAMPAIGN + "bogus = 1\n"}, "sine.bogus: unknown key"),
    ("generate --campaign c.toml --out o", {"c.toml": CAMPAIGN.replace("record_s = 1.0", "record_s = -1.0")},
     "sine.record_s"),
    ("generate --campaign c.toml --out o", {"c.toml": CAMPAIGN.replace("[[65, 90]]", "[[1e9, 90]]")},
     "c.toml: run sine_"),
    ("generate --campaign nosuch --out o", {}, "unknown campaign 'nosuch'"),
    ("generate --model m.xml --out o", {"m.xml": "<mujoco><worldbody>"}, "m.xml: not a valid MJCF model"),
    ("generate --model m.xml --friction lugre --out o", {"m.xml": "<mujoco/>"}, "not both"),
    # a built-in file's flat path (models/NAME): refused with its device folder's place
    ("generate --model models/scene.xml --out o", {}, "models/scene.xml: model file not found (the built-in "
     "model files are in one folder per device: models/omni/scene.xml)"),
    ("generate --reference ref.csv --out o", {"ref.csv": "t,r\n0,0\n"}, "ref.csv: fewer than 2 samples"),
    ("generate --reference ref.csv --out o", {"ref.csv": "t,r\n"}, "ref.csv: no data rows"),
    ("generate --reference ref.csv --out o", {"ref.csv": "t,r\n0,0\n0.2,0.1\n0.1,0\n"}, "increasing t"),
    ("generate --reference ref.csv --gamma1 1e9 --out o", {"ref.csv": "t,r\n0,0\n1,0.1\n"},
     "--gamma1/--gamma2: run ref: shoulder angle"),
    ("generate --noise -1 --out o", {}, "--noise must be"),
    ("generate --jobs 0 --out o", {}, "--jobs: must be >= 1"),
    # -- fit-inertia
    ("fit-inertia t.csv", {"t.csv": TABLE_HEAD + "65,90,6,200\n45,90,6,210\n"}, "needs >= 6 poses"),
    ("fit-inertia t.csv", {"t.csv": TABLE_HEAD + TABLE9.replace("60.7,", "1e9,", 1)},
     "t.csv: line 8: shoulder angle 1e+09 deg is outside"),
    ("fit-inertia t.csv --out nowhere/fit.json", {"t.csv": TABLE_HEAD + TABLE9}, "parent folder"),
    ("fit-inertia t.csv --out full", {"t.csv": TABLE_HEAD + TABLE9, **FULL}, "full: is a folder"),
    # -- validate
    ("validate data --params p.json --out o", {**GOOD, "p.json": "{"}, "p.json: not valid JSON"),
    ("validate data --params p.json --out o", {**GOOD, "p.json": '{"poses": [], "alpha_model": null}'},
     "was not identified and params has no inertia model"),
    ("validate data --params params.json --out o", {**data(gamma1_deg=-90), **PARAMS},
     "shoulder angle -90 deg is outside"),
    ("validate data --params params.json --out o", {**data(csv=""), **PARAMS}, "a.csv: empty file"),
    ("validate data --params params.json --out o", {**data(csv=_csv(extra="0")), **PARAMS},
     "data/a.csv: torque off (column 'enabled' 0)"),
    ("validate data --params params.json --out o", {**data(control_period_s=0.0005), **PARAMS},
     "data/a.json: control_period_s 0.0005 s is not"),
    ("validate data --params params.json --out afile", {**GOOD, **PARAMS, **A_FILE}, "exists and is not a folder"),
    ("validate data --params params.json --out o", {**GOOD, **params(poses=5)}, "poses must be a list"),
    ("validate data --params params.json --out o", {**GOOD, **params(poses=[1])}, "poses[0] must be an object"),
    ("validate data --params params.json --out o", {**GOOD, **params(poses=[{"gamma1_deg": 60}])},
     "poses[0].gamma2_deg must be a finite number"),
    ("validate data --params params.json --out o", {**GOOD, **params(im_I_base=math.nan)},
     "inertia_model: I_base = nan"),
    ("validate data --params params.json --out o", {**GOOD, **params(im_C0_bar=-1.0)},
     "inertia_model: C0_bar = -1.0"),
    # -- reproduce
    ("reproduce --out afile", A_FILE, "afile: exists and is not a folder"),
    ("reproduce --friction all --out afile", A_FILE, "afile: exists and is not a folder"),
    ("reproduce --out nowhere/o", {}, "parent folder"),
    ("reproduce --out full", FULL, "use --force"),
    ("reproduce --out .. --force", {}, "is or holds the current folder"),
    ("reproduce --friction all --out . --force", {}, "is or holds the current folder"),
    ("reproduce --model m.xml --out o", {"m.xml": "plain text"}, "m.xml: not a valid MJCF model"),
    ("reproduce --friction all --model m.xml --out o", {"m.xml": "<mujoco/>"}, "not both"),
    ("reproduce --jobs 0 --out o", {}, "--jobs: must be >= 1"),
    ("reproduce --model models/scene_coulomb.xml --out o", {}, "models/scene_coulomb.xml: model file not found "
     "(the built-in model files are in one folder per device: models/omni/scene_coulomb.xml)"),
    # -- discrepancy
    ("discrepancy --measured data --out afile", {**GOOD, **A_FILE}, "afile: exists and is not a folder"),
    ("discrepancy --measured data --out nowhere/o", GOOD, "parent folder"),
    ("discrepancy --demo --out afile", A_FILE, "afile: exists and is not a folder"),
    ("discrepancy --measured sub/data --out sub --force", data(folder="sub/data"), "is or holds sub/data"),
    ("discrepancy --measured data --out o --joint nosuch", GOOD, "no joint 'nosuch'"),
    ("discrepancy --measured data --out o --actuator nosuch", GOOD, "no actuator 'nosuch'"),
    ("discrepancy --measured data --out o --model m.xml", {**GOOD, "m.xml": "<x>"}, "not a valid MJCF model"),
    ("discrepancy --measured data --out o --model models/servo_pendulum.xml --joint pivot --actuator servo", GOOD,
     "models/servo_pendulum.xml: model file not found (the built-in model files are in one folder per device: "
     "models/servo_pendulum/servo_pendulum.xml)"),
    ("discrepancy --measured data --out o", data(gamma1_deg=1e9), "gamma1_deg, gamma2_deg: shoulder angle 1e+09"),
    ("discrepancy --measured data --out o", data(gamma1_set_deg=1e9), "shoulder angle 1e+09"),
    ("discrepancy --measured data --out o", data(kp=-2.0), "kp must be > 0"),
    ("discrepancy --measured data --out o", data(control_period_s=0.005), "longer than the sample period"),
    ("discrepancy --measured data --out o", {k: v for k, v in GOOD.items() if "/a." in k}, "at least 2 runs"),
    ("discrepancy --measured data --out o", data(csv="t,r,theta,v\n"), "no data rows"),
    ("discrepancy --demo --friction coulomb --out o", {}, "--demo hides its effect"),
    # -- bench
    ("bench --out full", FULL, "full: is a folder"),
    ("bench --out nowhere/b.json", {}, "parent folder"),
    ("bench --out afile/b.json", A_FILE, "afile is not a folder"),
    ("bench --jobs 0", {}, "--jobs: must be >= 1"),
    # -- sweep
    ("sweep s.toml --out o", {"s.toml": STUDY + "[grid]\nbogus = [1, 2]\n"}, "grid.bogus: not a run setting"),
    ("sweep s.toml --out o", {"s.toml": "bogus = 1\n" + STUDY + "[grid]\nkp = [1, 2]\n"}, "bogus: unknown key"),
    ("sweep s.toml --out o", {"s.toml": STUDY + "[fixed]\nkp = -1\n[grid]\nnoise_rad = [0, 1e-4]\n"},
     "fixed.kp: must be > 0"),
    ("sweep s.toml --out o", {"s.toml": STUDY + "[grid]\nkp = [0, 2]\n"}, "grid.kp: must be > 0"),
    ("sweep s.toml --out afile", {"s.toml": STUDY + "[grid]\nkp = [1, 2]\n", **A_FILE}, "exists and is not a folder"),
    ("sweep s.toml --out nowhere/o", {"s.toml": STUDY + "[grid]\nkp = [1, 2]\n"}, "parent folder"),
    ("sweep s.toml --out full", {"s.toml": STUDY + "[grid]\nkp = [1, 2]\n", **FULL}, "holds no study"),
    ("sweep s.toml --out o --workers 2 --scheduler tcp://127.0.0.1:1",
     {"s.toml": STUDY + "[grid]\nkp = [1, 2]\n"}, "not with --scheduler"),
    ("sweep nosuch.toml --out o", {}, "nosuch.toml: study file not found"),
    ("sweep s.toml --out o", {"s.toml": STUDY.replace('friction = "lugre"', 'model = "models/omni.xml"')
                              + "[grid]\nkp = [1, 2]\n"}, "models/omni/omni.xml)"),
    # -- the parser
    ("bogus", {}, "invalid choice: 'bogus'"),
]


def _make(files: dict) -> None:
    for name, text in files.items():
        path = Path(name)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def _snapshot(root: Path) -> dict:
    """Every file and folder under ``root`` with its content's digest."""
    return {str(p.relative_to(root)): (hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir")
            for p in sorted(root.rglob("*"))}


def run_cli(argv: list[str], capsys) -> tuple[int, str, str, float]:
    t0 = time.perf_counter()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's errors and --version
        code = exc.code
    wall = time.perf_counter() - t0
    out, err = capsys.readouterr()
    return code, out, err, wall


# a warning printed before the error line (numpy's on an empty CSV) fails the case: pytest
# would capture it, not show it on stderr
@pytest.mark.filterwarnings("error::UserWarning", "error::RuntimeWarning")
@pytest.mark.parametrize("argv, files, expected", CASES, ids=[f"{i:02d}-{c[0].split()[0]}" for i, c in enumerate(CASES)])
def test_bad_input_is_refused_before_any_work(argv, files, expected, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    _make(files)
    _forbid_long_work(monkeypatch)
    before = _snapshot(tmp_path)
    code, _, err, wall = run_cli(argv.split(), capsys)
    lines = err.splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error:"), err
    assert "Traceback" not in err and "Warning" not in err
    assert expected in lines[0], lines[0]
    assert _snapshot(tmp_path) == before  # nothing written: no output, no temporary folder
    assert wall < MAX_WALL_S


def test_the_table_covers_every_command():
    commands = {c[0].split()[0] for c in CASES}
    assert {"generate", "identify", "fit-inertia", "validate", "reproduce", "discrepancy", "bench",
            "sweep"} <= commands
    assert len(CASES) >= 23


def test_version(capsys):
    from importlib.metadata import version

    code, out, err, _ = run_cli(["--version"], capsys)
    assert code == 0 and err == ""
    assert out.strip() == f"omni {version('omni-alpha')}"


@pytest.mark.parametrize("argv, files, reached", [
    ("identify data --out o", GOOD, "identify_runs"),
    ("validate data --params params.json --out o", {**GOOD, **PARAMS}, "validate_runs"),
    ("discrepancy --measured data --out o", GOOD, "Replayer"),
    ("generate --campaign c.toml --out o", {"c.toml": CAMPAIGN}, "omni_sim.experiments.run_"),
    ("fit-inertia t.csv --out fit.json", {"t.csv": TABLE_HEAD + TABLE9}, "_profile_minima"),
    ("sweep s.toml --out o", {"s.toml": STUDY + "[grid]\nkp = [1, 2]\n"}, "_client"),
    ("reproduce --out o", {}, "worker_pool"),
    ("bench --out b.json", {}, "run_bench"),
])
def test_the_undamaged_inputs_reach_the_work(argv, files, reached, tmp_path, monkeypatch):
    """The table's files without their damage pass every check and reach the long work
    (patched to raise): each case above is refused for its damage, not for the rest."""
    monkeypatch.chdir(tmp_path)
    _make(files)
    _forbid_long_work(monkeypatch)
    with pytest.raises(LongWorkReached, match=reached):
        main(argv.split())


@pytest.mark.parametrize("argv", [
    "generate --model {omni}/scene_coulomb.xml --out o",
    "generate --model {omni}/scene.xml --out o",
    "generate --friction matched --out o",
    "reproduce --model {omni}/scene_matched.xml --out o",
])
def test_the_built_in_files_reach_the_work(argv, tmp_path, monkeypatch):
    """A built-in scene named by its path in the Omni's folder (``--model``) or by its family
    (``--friction``) passes every check and reaches the long work (patched to raise)."""
    from omni_sim import model as om

    monkeypatch.chdir(tmp_path)
    _forbid_long_work(monkeypatch)
    with pytest.raises(LongWorkReached):
        main(argv.format(omni=om.OMNI_DIR).split())


class _ClosedPipe(io.StringIO):
    """A stdout whose reader has left (``omni ... | head``)."""

    def __init__(self, fd: int):
        super().__init__()
        self._fd = fd

    def write(self, text):
        raise BrokenPipeError(32, "Broken pipe")

    def fileno(self):
        return self._fd


def test_a_closed_stdout_ends_quietly(tmp_path, monkeypatch, capsys):
    """``omni sweep --example | head -0``: no traceback, the shell's status of a SIGPIPE."""
    import sys

    with open(tmp_path / "stdout", "w") as fh:
        monkeypatch.setattr(sys, "stdout", _ClosedPipe(fh.fileno()))
        code = main(["sweep", "--example"])
    assert code == 141
    assert capsys.readouterr().err == ""
