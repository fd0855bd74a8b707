"""Each fact about a device is computed in one place: :class:`omni_sim.device.Device` (the
package :mod:`omni_sim.device`: each fact in one of its rooms, named below).

Searched in the source tree (the packages and scripts; tests may probe the pieces directly):
the contract's name index is built only by ``Device`` and the loader that checks a file; the
drive's gear is read off a compiled model only by the device (``Device`` and the
``DriveFriction`` it holds); the friction family, the arm
servos' control, the yaw inertia from the mass matrix, the equilibrium solve and the encoder's
count are each defined once.  Writers of model *parameters* (the discrepancy effects, the
calibration, the hidden-effect bank, which must stay independent of the library) edit specs;
they are not what this test is about.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The device package's rooms that hold the facts (omni_sim/device/).
CORE = "omni_sim/device/core.py"  # Device: name index, gear, arm, inertia, equilibrium
PARAMETERS = "omni_sim/device/parameters.py"  # its named parameters, the drive's dry friction
LAWS = "omni_sim/device/laws.py"  # the drive laws (DriveFriction reads the gear it scales by)
ENCODER = "omni_sim/device/encoder.py"
SOURCES = sorted(p for d in ("omni_sim", "omni_studies", "omni_app", "identification", "scripts", "examples")
                 for p in (ROOT / d).rglob("*.py"))


@functools.cache  # each file parsed once for all the searches of this module
def _code(path: Path) -> str:
    """The file's code without docstrings and comments (mentions are not uses)."""
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant) \
                    and isinstance(body[0].value.value, str):
                body[0] = ast.Pass()
    return ast.unparse(tree)


def _where(pattern: str, sources=SOURCES) -> set[str]:
    rx = re.compile(pattern)
    return {str(p.relative_to(ROOT)) if ROOT in p.parents else p.name
            for p in sources if rx.search(_code(p))}


def test_the_name_index_is_built_by_the_device_and_the_loader_only():
    # om.index(...), model.index(...), or a bare index(model...) inside omni_sim/model.py
    assert _where(r"\b(om|model)\.index\(") == {CORE}
    assert _where(r"(?<![.\w])index\(model") == {"omni_sim/model.py"}  # load_model's check


#: The geared-servo bank case's truth: a servo loop written independently of the device (it
#: must not use it, tests/test_discrepancy_bank.py), so it reads the gear itself.
INDEPENDENT_TRUTH = "bank/servo_truth.py"


def test_the_gear_is_read_in_one_place():
    assert _where(r"actuator_gear\[") - {INDEPENDENT_TRUTH} == {CORE, LAWS}


def test_friction_family_arm_control_inertia_and_encoder_are_defined_once():
    assert _where(r"def friction_family\(") == {PARAMETERS}
    assert _where(r"def (lugre_actuators|scale_friction)\(") == {PARAMETERS}
    assert _where(r"def (set_arm_control|check_pose)\(") == {CORE}
    assert _where(r"mj_fullM\(") == {CORE}
    assert _where(r"qfrc_bias") == {CORE}  # the arm's equilibrium solve
    assert _where(r"/ 15000\b") == {ENCODER}  # the encoder's count
    # the arm servos' set points are written into ctrl only by the device
    assert _where(r"ctrl\[[^\]]*(shoulder|elbow)") == {CORE}


def test_the_search_would_see_a_second_copy(tmp_path):
    """The searches are not vacuous: a module that re-reads the gear is found, one that only
    mentions it in a docstring is not."""
    extra = tmp_path / "copy.py"
    extra.write_text("def gear(m, a):\n    return m.actuator_gear[a, 0]\n")
    quiet = tmp_path / "quiet.py"
    quiet.write_text('"""reads model.actuator_gear[a, 0]"""\n')
    assert _where(r"actuator_gear\[", SOURCES + [extra, quiet]) - {INDEPENDENT_TRUTH} == {CORE, LAWS, "copy.py"}


def test_calibration_writes_structure_not_text():
    """The calibrated values reach the MJCF through an XML tree (calibration.set_attributes),
    never through regular expressions on the file's text."""
    code = _code(ROOT / "omni_studies" / "calibration.py")
    assert not re.search(r"^\s*(import re\b|from re import)", code, re.M)
    assert "xml.etree.ElementTree" in code
