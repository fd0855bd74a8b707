"""Packaging: the model files ship inside the package (``omni_sim.models``), so a regular
(non-editable) install finds them; every Python package of the checkout is listed."""

import tomllib
from importlib import resources
from pathlib import Path

from omni_sim import model as om

ROOT = Path(__file__).resolve().parent.parent


def _setuptools():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


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


def test_package_data_covers_the_data_files():
    data = _setuptools()["package-data"]
    covered = {(pkg, pat) for pkg, pats in data.items() for pat in pats}
    for name in ("omni.xml", "scene.xml", "calibration.json", "README.md"):
        assert (ROOT / "models" / name).is_file(), name
        assert ("omni_sim.models", "*" + Path(name).suffix) in covered, name
    assert ("identification.data", "*.csv") in covered
    assert ("omni_sim.campaigns", "*.toml") in covered
    listed = set(_setuptools()["packages"])
    for folder in ("identification/data", "omni_sim/campaigns", "models"):
        pkg = {"models": "omni_sim.models"}.get(folder, folder.replace("/", "."))
        assert pkg in listed, f"{folder} ships data but is not a listed (data) package"


def test_models_dir_is_the_data_package_on_disk():
    where = Path(str(resources.files("omni_sim.models")))
    assert om.MODELS_DIR == where and om.MODELS_DIR.is_dir()
    assert om.DEFAULT_SCENE == om.MODELS_DIR / "scene.xml" and om.DEFAULT_SCENE.is_file()
    assert (om.MODELS_DIR / "omni.xml").is_file()
    om.load_model()  # scene.xml includes omni.xml from the same folder
