"""Packaging: the model files ship inside the package (``omni_sim.models``, one data package per
device folder), so a regular (non-editable) install finds them; every Python package of the
checkout is listed."""

import os
import subprocess
import sys
import tomllib
import zipfile
from importlib import resources
from pathlib import Path

import pytest

from omni_sim import model as om

ROOT = Path(__file__).resolve().parent.parent
#: The device folders of ``models/`` and the files each one has (after MuJoCo Menagerie: the
#: model, its provenance, the history of its files and its license).
DEVICES = {"omni": ("omni.xml", "scene.xml", "scene_lugre.xml", "scene_coulomb.xml", "scene_matched.xml",
                    "stage.xml", "calibration.json", "calibration_coulomb.json",
                    "calibration_matched.json"),
           "servo_pendulum": ("servo_pendulum.xml",)}
FOLDER_FILES = ("README.md", "CHANGELOG.md", "LICENSE")


def _setuptools():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def _package_dir(pkg: str, cfg: dict | None = None) -> Path:
    """A listed package's source folder, as setuptools maps it (the longest ``package-dir``
    prefix, else the dotted name's folders)."""
    mapped = (cfg or _setuptools()).get("package-dir", {})
    parts = pkg.split(".")
    for n in range(len(parts), 0, -1):
        head = ".".join(parts[:n])
        if head in mapped:
            return ROOT / mapped[head] / Path(*parts[n:]) if parts[n:] else ROOT / mapped[head]
    return ROOT / Path(*parts)


def _shipped(cfg: dict | None = None) -> dict[Path, str]:
    """Every file a wheel gets from the listed packages: modules and package data, each with
    the package that ships it (what setuptools' build_py does with this configuration)."""
    cfg = cfg or _setuptools()
    out = {}
    for pkg in cfg["packages"]:
        folder = _package_dir(pkg, cfg)
        for f in folder.glob("*.py"):
            out[f] = pkg
        for pattern in cfg.get("package-data", {}).get(pkg, []):
            for f in folder.glob(pattern):
                if f.is_file():
                    out[f] = pkg
    return out


def _model_files() -> list[Path]:
    return sorted(f for f in (ROOT / "models").rglob("*")
                  if f.is_file() and "__pycache__" not in f.parts and f.suffix != ".pyc")


def test_every_package_is_listed():
    """``packages`` is an explicit list (``omni_sim.models`` is mapped, not found): a new
    subpackage must be added to it or a regular install would silently lack it."""
    listed = set(_setuptools()["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for top in ("omni_sim", "omni_studies", "identification", "omni_app")
             for p in (ROOT / top).rglob("__init__.py")}
    assert found <= listed, sorted(found - listed)
    assert "omni_sim.models" in listed
    assert _setuptools()["package-dir"]["omni_sim.models"] == "models"


def _bank_setuptools():
    return tomllib.loads((ROOT / "bank" / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_the_bank_is_a_distribution_of_its_own():
    """The bank (``bank/``) is its own distribution: its pyproject maps the folder as the package
    ``bank`` and lists every subpackage of it; the project's lists none of it (a regular install
    of the library ships no bank), and the bank depends on the project."""
    cfg = _bank_setuptools()
    assert cfg["package-dir"] == {"bank": "."}
    found = {".".join(("bank",) + p.parent.relative_to(ROOT / "bank").parts)
             for p in (ROOT / "bank").rglob("__init__.py")
             if not {"build", "__pycache__"} & set(p.relative_to(ROOT / "bank").parts)}
    assert set(cfg["packages"]) == found, sorted(found ^ set(cfg["packages"]))
    assert not [p for p in _setuptools()["packages"] if p.split(".")[0] == "bank"]
    assert "bank" not in _setuptools().get("package-dir", {})
    project = tomllib.loads((ROOT / "bank" / "pyproject.toml").read_text())["project"]
    main = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert main["name"] in project["dependencies"]
    data = [f for f in (ROOT / "bank" / "test_half").iterdir() if f.is_file() and f.suffix not in (".py", ".pyc")]
    pats = cfg["package-data"]["bank.test_half"]
    assert data and all(any(f.match(pat) for pat in pats) for f in data), data


def test_package_data_covers_the_data_files():
    data = _setuptools()["package-data"]
    covered = {(pkg, pat) for pkg, pats in data.items() for pat in pats}
    assert ("identification.data", "*.csv") in covered
    assert ("omni_sim.campaigns", "*.toml") in covered
    listed = set(_setuptools()["packages"])
    for folder in ("identification/data", "omni_sim/campaigns", "models", "models/omni", "models/servo_pendulum"):
        pkg = ("omni_sim." + folder) if folder.startswith("models") else folder
        pkg = pkg.replace("/", ".")
        assert pkg in listed, f"{folder} ships data but is not a listed (data) package"
        assert _package_dir(pkg) == ROOT / folder


def test_every_model_file_ships():
    """Each file of ``models/`` (the device folders included) is in a wheel: its folder is a
    listed (data) package whose ``package-data`` matches it -- a new device folder or a new
    kind of file must be listed, or a regular install would lack it."""
    shipped = _shipped()
    missing = [str(f.relative_to(ROOT)) for f in _model_files() if f not in shipped]
    assert not missing, f"not in a wheel (pyproject.toml packages / package-data): {missing}"
    for f in _model_files():
        assert shipped[f] == "omni_sim." + ".".join(f.parent.relative_to(ROOT).parts)


def test_the_file_lister_sees_what_is_left_out():
    """:func:`_shipped` matches package-data patterns per folder: a device folder that is not
    a listed package, or a pattern left out, leaves its files out of the wheel."""
    cfg = _setuptools()
    pendulum, scene = ROOT / "models" / "servo_pendulum" / "servo_pendulum.xml", ROOT / "models" / "omni" / "scene.xml"
    assert {pendulum, scene} <= set(_shipped(cfg))
    without = dict(cfg, packages=[p for p in cfg["packages"] if p != "omni_sim.models.servo_pendulum"])
    assert pendulum not in _shipped(without) and scene in _shipped(without)
    fewer = dict(cfg, **{"package-data": dict(cfg["package-data"], **{"omni_sim.models.omni": ["*.xml"]})})
    assert ROOT / "models" / "omni" / "calibration.json" not in _shipped(fewer)


@pytest.mark.parametrize("device", DEVICES)
def test_device_folder(device):
    """One folder per device: its model files, README.md (provenance), CHANGELOG.md (the
    history of its files), LICENSE; nothing of it left directly in ``models/``; the index
    ``models/README.md`` links it."""
    folder = ROOT / "models" / device
    for name in DEVICES[device] + FOLDER_FILES:
        assert (folder / name).is_file(), f"models/{device}/{name}"
    assert f"]({device}/README.md)" in (ROOT / "models" / "README.md").read_text()
    assert (folder / "LICENSE").read_text() == (ROOT / "LICENSE").read_text()  # the project's terms
    assert {f.name for f in (ROOT / "models").iterdir() if f.is_file()} == {"README.md", "__init__.py"}


def test_models_dir_is_the_data_package_on_disk():
    where = Path(str(resources.files("omni_sim.models")))
    assert om.MODELS_DIR == where and om.MODELS_DIR.is_dir()
    assert om.OMNI_DIR == om.MODELS_DIR / "omni" and om.OMNI_DIR.is_dir()
    assert om.DEFAULT_SCENE == om.OMNI_DIR / "scene.xml" and om.DEFAULT_SCENE.is_file()
    assert (om.OMNI_DIR / "omni.xml").is_file()
    assert om.SERVO_PENDULUM == om.MODELS_DIR / "servo_pendulum" / "servo_pendulum.xml"
    assert om.SERVO_PENDULUM.is_file()
    om.load_model()  # scene.xml includes omni.xml from the same folder


_PROBE = """
import sys, sysconfig
from pathlib import Path
import omni_sim
from omni_sim import model as om
site = Path(sys.argv[1]).resolve()
for p in (Path(omni_sim.__file__), om.MODELS_DIR, om.DEFAULT_SCENE, om.SERVO_PENDULUM):
    assert site in p.resolve().parents, f"{p} is not in {site}"
for fam in om.FRICTION_FAMILIES:
    om.load_model(friction=fam)
om.load_model()
om.load_model(om.SERVO_PENDULUM, target=om.Target("pivot", "servo"))
print("ok")
"""


@pytest.mark.slow
def test_wheel_ships_the_device_folders(tmp_path):
    """A wheel built as ``pip wheel .`` builds it (from a copy: the build writes into the tree)
    holds every model file in its device folder and no file of the bank, and unpacked as a
    regular install it loads every built-in scene and the servo pendulum from its own files
    (~20 s)."""
    import shutil

    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    tops = {_package_dir(p).relative_to(ROOT).parts[0] for p in _setuptools()["packages"]}
    for top in tops:
        shutil.copytree(ROOT / top, src / top, ignore=shutil.ignore_patterns("__pycache__"))
    out = subprocess.run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "-q",
                          "-w", str(tmp_path / "dist")], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    wheel = next((tmp_path / "dist").glob("*.whl"))
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        want = {"omni_sim/models/" + str(f.relative_to(ROOT / "models")) for f in _model_files()}
        assert want <= names, sorted(want - names)
        assert not [n for n in names if n.startswith("omni_sim/models/") and n.count("/") == 2
                    and not n.endswith((".py", ".md"))]  # none left outside a device folder
        assert not [n for n in names if n.split("/")[0] == "bank"]  # the bank ships apart
        site = tmp_path / "site"
        z.extractall(site)
    env = dict(os.environ, PYTHONPATH=str(site))
    probe = subprocess.run([sys.executable, "-c", _PROBE, str(site)], capture_output=True, text=True,
                           env=env, cwd=tmp_path)
    assert probe.returncode == 0 and probe.stdout.strip() == "ok", probe.stderr[-3000:]
