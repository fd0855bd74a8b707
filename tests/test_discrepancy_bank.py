"""The hidden-effect bank: its truth models are independent of the effect library (a syntax
check of the truth side's modules -- truth models, cases, ranges, experiment set, the demo's
truth -- and their
imports followed through the project; the compiled truth models read field by field), the
whole bank through the workflow (slow) and the coverage study's script (slow, small)."""

import ast
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from omni_sim import model as om
from bank import hidden, omni_truths, ranges
from discrepancy import effects as fx

ROOT = Path(__file__).resolve().parent.parent
#: The truth side: the modules that write truth models, hold the hidden cases and their
#: experiments, judge a report or draw magnitudes.  None may use the effect library.
TRUTH_SIDE = ("bank.omni_truths", "bank.hidden", "bank.ranges", "bank.servo_truth",
              "discrepancy.experiment_set", "discrepancy.demo")


def _source(module: str) -> str:
    return ROOT.joinpath(*module.split(".")).with_suffix(".py").read_text()


#: The library's writers: calling any of them (as a name or an attribute) writes a truth model
#: with the library, which the truth side must not do.
WRITERS = ("apply", "compile_with", "write", "nominal_values")
#: The project's top-level packages: imports into them are followed, others (numpy, mujoco,
#: the standard library) are not.
PROJECT_PACKAGES = ("omni_sim", "discrepancy", "omni_studies", "identification", "omni_app", "bank")
EFFECTS = "discrepancy.effects"


def writer_uses(source: str) -> list[str]:
    """Where ``source`` imports the effect library or uses one of its writers (:data:`WRITERS`):
    an import of a module named ``effects`` (``from . import effects``, ``from .effects import
    apply``, ``import discrepancy.effects``), a writer's name called or read (``apply``
    bound by an import, or an alias of it), an attribute named like a writer (``fx.apply``,
    ``Effect.write``), a ``getattr(..., "apply")``.  Each hit is ``"line N: what"``."""
    hits = []
    for node in ast.walk(ast.parse(source)):
        line = getattr(node, "lineno", "?")
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if "effects" in mod.split("."):
                hits.append(f"line {line}: imports from {mod}")
            for a in node.names:
                if a.name == "effects":
                    hits.append(f"line {line}: imports effects")
                elif a.name in WRITERS:
                    hits.append(f"line {line}: imports {a.name}")
        elif isinstance(node, ast.Import):
            for a in node.names:
                if "effects" in a.name.split("."):
                    hits.append(f"line {line}: imports {a.name}")
        elif isinstance(node, ast.Name) and node.id in WRITERS:
            hits.append(f"line {line}: uses {node.id}")
        elif isinstance(node, ast.Attribute) and node.attr in WRITERS:
            hits.append(f"line {line}: .{node.attr}")
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr"
              and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant)
              and node.args[1].value in WRITERS):
            hits.append(f"line {line}: getattr {node.args[1].value!r}")
    return hits


@pytest.mark.parametrize("module", TRUTH_SIDE)
def test_truth_side_does_not_use_the_effect_writers(module):
    """The truth side writes its truth models itself: no import of the effect library, no call
    of its writers (``apply``, ``compile_with``, ``Effect.write``) -- read from the syntax tree."""
    assert writer_uses(_source(module)) == []


@pytest.mark.parametrize("src, expected", [
    # the import and the call through the alias
    ("from . import effects as fx\nspec = fx.apply(base, changes)\n",
     ["line 1: imports effects", "line 2: .apply"]),
    # a writer imported by name and called directly
    ("from .effects import apply\nspec = apply(base, changes)\n",
     ["line 1: imports from effects", "line 1: imports apply", "line 2: uses apply"]),
    # ... under another name (the import gives it away)
    ("from discrepancy.effects import compile_with as build\nm = build(spec)\n",
     ["line 1: imports from discrepancy.effects", "line 1: imports compile_with"]),
    # the module imported by its full name, the writer reached through attributes
    ("import discrepancy.effects\ndiscrepancy.effects.LIBRARY[0].write(spec, v)\n",
     ["line 1: imports discrepancy.effects", "line 2: .write"]),
    # a writer of an object that came from elsewhere (no import in this file)
    ("def f(effect, spec, v):\n    effect.write(spec, v)\n", ["line 2: .write"]),
    ("w = getattr(lib, 'apply')\n", ["line 1: getattr 'apply'"]),
    # MuJoCo's own features are not writers of the library
    ("spec.joint('yaw').damping[0] = 0.01\nspec.compile()\n", []),
])
def test_the_syntax_check_would_catch_a_writer_call(src, expected):
    """The check the truth side passes flags each way of reaching a writer (so it can fail)."""
    assert sorted(writer_uses(src)) == sorted(expected)


def _module_file(name: str, root: Path, packages) -> Path | None:
    """The source file of module ``name`` under ``root`` (a package's ``__init__.py``), None if
    it is not a module of ``packages``."""
    if name.split(".")[0] not in packages:
        return None
    p = root.joinpath(*name.split("."))
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    if p.with_suffix(".py").is_file():
        return p.with_suffix(".py")
    return None


def bound_imports(source: str, module: str, is_package: bool, root: Path, packages) -> set[str]:
    """The project modules whose names ``source`` (module ``module``) binds by its imports, at
    any depth of the file (imports inside functions too).

    ``import a.b.c`` binds ``a`` and reaches ``a``, ``a.b``, ``a.b.c``; ``from P import n`` binds
    the submodule ``P.n`` if it is one, else a name of ``P``'s ``__init__`` (then ``P``);
    ``importlib.import_module("a.b")`` reaches ``a.b``.  Not followed: the parent packages whose
    ``__init__`` Python runs before a module without binding any of their names in it."""
    pkg = module if is_package else module.rpartition(".")[0]
    out = set()

    def add(name):
        if _module_file(name, root, packages) is not None:
            out.add(name)

    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                for i in range(1, len(parts) + 1):
                    add(".".join(parts[:i]))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")[:len(pkg.split(".")) - (node.level - 1)]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module
            for a in node.names:
                if _module_file(f"{base}.{a.name}", root, packages) is not None:
                    out.add(f"{base}.{a.name}")
                else:
                    add(base)
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and ((isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                   or (isinstance(node.func, ast.Name) and node.func.id in ("import_module", "__import__")))):
            add(node.args[0].value)
    return out


def reachable(source: str, module: str, root: Path = ROOT, packages=PROJECT_PACKAGES) -> dict[str, list[str]]:
    """Every project module reached from ``source`` (the text of module ``module``) by following
    :func:`bound_imports` transitively, with the chain of imports that reaches it."""
    seen = {module: [module]}
    todo = [(module, source, False)]
    while todo:
        name, src, is_pkg = todo.pop()
        for nxt in sorted(bound_imports(src, name, is_pkg, root, packages)):
            if nxt in seen:
                continue
            f = _module_file(nxt, root, packages)
            seen[nxt] = seen[name] + [nxt]
            todo.append((nxt, f.read_text(), f.name == "__init__.py"))
    del seen[module]
    return seen


def library_modules(reached) -> list[str]:
    """The modules of the effect library (the package and its modules) among ``reached``."""
    return [m for m in reached if m == EFFECTS or m.startswith(EFFECTS + ".")]


@pytest.mark.parametrize("module", TRUTH_SIDE)
def test_truth_side_reaches_no_effect_library_through_other_modules(module):
    """Each truth-side module's imports, followed through the project's packages (omni_sim,
    identification, omni_app), never reach the effect library (the package
    ``discrepancy/effects/``, any of its modules), nor any module of the discrepancy
    package or of the bank outside the truth side.

    What ``hidden`` reaches today: ``omni_truths`` and ``experiment_set``,
    ``identification.dataset`` (the ``Run`` it returns), ``omni_sim.model`` and
    ``omni_sim.experiments`` (the nominal scene's path, the device's closed loop that makes the
    data) and what those import (``omni_sim.device``, ``identification.errors``,
    ``identification.paper``, ``identification.csvformat``, ``omni_sim._resources``): none of
    them writes a model with the library.  Not followed: ``omni_sim/__init__`` and
    ``discrepancy/__init__`` (the latter re-exports the library), which Python runs
    before these modules without binding a name in them; a ``from . import X`` that binds a
    name of that ``__init__`` (e.g. ``LIBRARY``) is followed and reaches the library."""
    reached = reachable(_source(module), module)
    library = library_modules(reached)
    assert not library, " -> ".join(reached[library[0]])
    others = [m for m in reached if m.split(".")[0] in ("discrepancy", "bank") and m not in TRUTH_SIDE]
    assert not others, [" -> ".join(reached[m]) for m in others]
    if module == "bank.hidden":
        # the walk does follow the imports (a walk that found nothing would pass trivially)
        assert {"identification.dataset", "omni_sim.experiments", "omni_sim.device",
                "bank.omni_truths", "discrepancy.experiment_set"} <= set(reached)


@pytest.mark.parametrize("src", [
    "from . import workflow\n",  # workflow.py imports the library: one module in between
    "from .workflow import run_discrepancy\n",  # a name of it
    "from .effects import friction\n",  # one of the library's modules
    "from . import LIBRARY\n",  # a name of the package's __init__, which re-exports the library
    "def f():\n    from omni_app.discrepancy import demo\n    return demo\n",  # the app, inside a function
    "import importlib\nm = importlib.import_module('discrepancy.workflow')\n",
])
def test_the_import_check_follows_other_modules(src):
    """A truth-side module that imports (at any depth) a module that imports the library fails
    the walk."""
    assert library_modules(reachable(src, "discrepancy.demo"))


def test_the_import_check_follows_the_bank():
    """... and a module of the bank that imports one of the bank's studies (which use the
    library) fails it too: the walk follows the bank's own imports."""
    assert library_modules(reachable("from .studies import valley_scan\n", "bank.hidden"))
    assert not library_modules(reachable("from . import servo_truth\n", "bank.hidden"))


def test_the_import_check_follows_a_chain(tmp_path):
    """On a package of its own: bank -> mid -> util -> effects is found, with its chain."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "effects.py").write_text("def apply(spec, v):\n    return spec\n")
    (pkg / "util.py").write_text("from .effects import apply as put\n")
    (pkg / "mid.py").write_text("import pkg.util\n")
    (pkg / "clean.py").write_text("import math\n")
    src = "from . import mid, clean\n"
    assert writer_uses(src) == []  # the syntax check alone does not see it
    reached = reachable(src, "pkg.bank", tmp_path, ("pkg",))
    assert reached["pkg.effects"] == ["pkg.bank", "pkg.mid", "pkg.util", "pkg.effects"]
    assert "pkg.effects" not in reachable("from . import clean\n", "pkg.bank", tmp_path, ("pkg",))


# --- the compiled truth models hold the values the cases state ------------------------------
@pytest.fixture(scope="module")
def nominal():
    return mujoco.MjModel.from_xml_path(str(om.DEFAULT_SCENE))


def _yaw_mass(m):
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    return M[m.jnt_dofadr[m.joint("yaw").id], m.jnt_dofadr[m.joint("yaw").id]]


def compiled_values(name: str, m: mujoco.MjModel, nominal: mujoco.MjModel) -> list[float]:
    """The parameters of library effect ``name`` as the compiled model ``m`` holds them, read
    from MjModel fields (not through the library's readers)."""
    j = m.joint("yaw").id
    dof = m.jnt_dofadr[j]
    a = m.actuator("yaw_motor").id
    gear = float(m.actuator_gear[a, 0])
    if name == "coulomb_friction":
        return [m.dof_frictionloss[dof]]
    if name == "viscous_damping":
        return [m.dof_damping[dof]]
    if name == "joint_stiffness":
        return [m.jnt_stiffness[j], m.qpos_spring[m.jnt_qposadr[j]]]
    if name == "gravity_tilt":
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        g = d.xmat[m.body("base").id].reshape(3, 3).T @ m.opt.gravity  # gravity in the base frame
        return [math.asin(g[0] / np.linalg.norm(g)), math.asin(g[1] / np.linalg.norm(g))]
    if name == "armature":
        total = m.dof_armature[dof] + gear**2 * m.actuator_armature[a]
        # the mass matrix agrees: it grew by exactly the added armature
        extra = total - nominal.dof_armature[dof] - gear**2 * nominal.actuator_armature[a]
        assert _yaw_mass(m) - _yaw_mass(nominal) == pytest.approx(extra, rel=1e-9)
        return [total]
    if name == "actuator_lag":
        assert m.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_FILTEREXACT
        return [m.actuator_dynprm[a, 0]]
    if name == "time_delay":
        assert m.actuator_history[a, 0] * m.opt.timestep > m.actuator_delay[a]  # the buffer holds it
        return [m.actuator_delay[a]]
    if name == "torque_saturation":
        assert m.actuator_forcelimited[a]
        lo, hi = m.actuator_forcerange[a]
        assert lo == -hi
        return [gear * hi]
    if name == "torque_gain":
        return [gear]
    if name == "position_offset":
        assert m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
        assert not np.any(m.actuator_biasprm[a, 1:])
        return [m.actuator_biasprm[a, 0]]
    # passive dcmotors: LuGre sigma0, sigma1 compile to dynprm[5:7], Fc, Fs, vs to biasprm[3:6];
    # cogging (amplitude, periods, phase) to biasprm[0:3] (layout checked in tests/test_effects_library.py)
    extra = list(range(nominal.nactuator, m.nactuator))  # actuators the truth added
    if name == "cogging":
        found = [i for i in extra if m.actuator_biasprm[i, 1] == omni_truths.COGGING_PERIODS_PER_TURN]
        assert len(found) == 1 and found[0] >= m.nu  # passive: no control
        return [m.actuator_biasprm[found[0], 0], m.actuator_biasprm[found[0], 2]]
    if name == "presliding_friction":
        f = m.actuator("yaw_friction").id
        n = nominal.actuator("yaw_friction").id
        assert m.actuator_dynprm[f, 6] == nominal.actuator_dynprm[n, 6]  # sigma1 kept
        return [m.actuator_dynprm[f, 5], *m.actuator_biasprm[f, 3:6]]
    if name == "stribeck_friction":
        found = [i for i in extra if m.actuator_dynprm[i, 5] > 0]
        assert len(found) == 1 and found[0] >= m.nu
        assert tuple(m.actuator_dynprm[found[0], 5:7]) == omni_truths.STRIBECK_SIGMA
        return list(m.actuator_biasprm[found[0], 3:6])
    if name in ("drive_compliance", "backlash"):
        t = _cable(m)
        if name == "backlash":
            assert m.tendon_limited[t]
            lo, hi = m.tendon_range[t]
            assert lo == -hi
            return [hi]
        # the rotor's inertia: its diagonal element of the mass matrix (nothing else moves it)
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        return [m.tendon_stiffness[t], m.tendon_damping[t], M[dof, dof]]
    if name == "arm_mass":
        out = []
        for b in ("upper_arm", "forearm"):
            i, k = m.body(b).id, nominal.body(b).id
            ratio = m.body_mass[i] / nominal.body_mass[k]
            np.testing.assert_allclose(m.body_inertia[i], nominal.body_inertia[k] * ratio, rtol=1e-12)
            np.testing.assert_array_equal(m.body_ipos[i], nominal.body_ipos[k])
            out.append(m.body_mass[i])
        return out
    raise KeyError(name)


def _cable(m):
    """The fixed tendon q_yaw - q_yaw_output of a two-mass drive."""
    yaw, out = m.joint("yaw").id, m.joint("yaw_output").id
    for t in range(m.ntendon):
        adr, num = m.tendon_adr[t], m.tendon_num[t]
        if num == 2 and m.wrap_type[adr] == mujoco.mjtWrap.mjWRAP_JOINT:
            pairs = {(int(m.wrap_objid[adr + i]), float(m.wrap_prm[adr + i])) for i in range(2)}
            if pairs == {(yaw, 1.0), (out, -1.0)}:
                # the turret (output) joint is the old yaw joint: same body, axis
                assert m.body(m.jnt_bodyid[out]).name == "turret"
                return t
    raise AssertionError("no cable tendon yaw - yaw_output")


#: The Omni's cases with library effects written by :mod:`omni_truths` (the geared-servo cases'
#: truth is a per-step law of its own, tests/test_servo_truth.py).
LIBRARY_CASES = [c for c in hidden.CASES if c.effects and not c.outside and c.truth == "omni"]
#: Library effects whose truth is a simulation of its own, not a model written by
#: :mod:`omni_truths` (the servo pendulum's load-dependent and direction-dependent gearbox
#: friction).
SIMULATED = {n for c in hidden.CASES if c.truth != "omni" for n, _ in c.effects}


@pytest.mark.parametrize("case_name", [c.name for c in LIBRARY_CASES])
def test_omni_truths_hold_the_stated_values(case_name, nominal):
    case = hidden.case(case_name)
    m = hidden.truth_spec(case).compile()
    for name, values in case.effects:
        np.testing.assert_allclose(compiled_values(name, m, nominal), values, rtol=1e-12, atol=1e-15,
                                   err_msg=f"{case_name}: {name}")


def test_outside_effects_hold_the_stated_values(nominal):
    m = hidden.truth_spec(hidden.case("gain_slope")).compile()
    a = m.actuator("yaw_motor").id
    assert m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_AFFINE
    # gain = 1 + gainprm[1] * length with length = gear * theta: slope per rad = gainprm[1] * gear
    assert m.actuator_gainprm[a, 1] * m.actuator_gear[a, 0] == pytest.approx(0.5, rel=1e-12)
    m = hidden.truth_spec(hidden.case("end_stop")).compile()
    j = m.joint("yaw").id
    assert m.jnt_range[j, 1] == 0.17 and m.jnt_range[j, 0] == nominal.jnt_range[j, 0]
    assert m.jnt_solref[j, 0] == 0.01


def test_bank_covers_the_library():
    """Every library effect has a single-effect case, a truth writer and a coverage range; the
    bank holds the null cases (with and without noise), pairs, a triple and >= 2 effects
    outside the library."""
    singles = {c.effects[0][0] for c in hidden.CASES if len(c.effects) == 1 and not c.outside}
    nameable = set(fx.NAMES) | {e.name for e in fx.STAGED}  # the nested variants are named too
    missing = sorted(nameable - singles)
    assert not missing, f"no single-effect bank case for: {', '.join(missing)}"
    written = set(fx.NAMES) - SIMULATED  # the rest have a truth simulation of their own
    assert written <= set(omni_truths.TRUTH) and written <= set(ranges.RANGES)
    assert SIMULATED == {"load_friction", "asymmetric_friction", "current_limit", "friction_family_stribeck",
                         "load_friction_smooth"}
    assert not SIMULATED & set(omni_truths.TRUTH)
    assert {c.name for c in hidden.CASES if c.expect == ("none",)} >= {"none", "none_exact"}
    assert hidden.case("none_exact").exact and not hidden.case("none").exact
    assert any(len(c.effects) == 2 for c in hidden.CASES) and any(len(c.effects) == 3 for c in hidden.CASES)
    outside = {o[0] for c in hidden.CASES for o in c.outside}
    assert len(outside) >= 2 and not outside & set(fx.NAMES)
    for c in hidden.CASES:
        assert c.note, c.name
        if c.outside:
            assert c.gap_lives, c.name


def effect_state(name: str, m: mujoco.MjModel) -> tuple:
    """The MjModel fields library effect ``name``'s truth writer writes, read in any model (no
    assertion: the nominal model too), as a flat tuple of numbers.  An element the model does
    not have reads as its compiled default (dynamics type none, delay 0, no force limit, no bias
    type) or as absent (no cogging or Stribeck actuator, no two-mass cable: ``()``)."""
    j = m.joint("yaw").id
    dof = m.jnt_dofadr[j]
    a = m.actuator("yaw_motor").id
    if name == "coulomb_friction":
        return (m.dof_frictionloss[dof],)
    if name == "viscous_damping":
        return (m.dof_damping[dof],)
    if name == "joint_stiffness":
        return (m.jnt_stiffness[j], m.qpos_spring[m.jnt_qposadr[j]])
    if name == "gravity_tilt":
        return (*m.body_quat[m.body("base").id], *m.opt.gravity)
    if name == "armature":
        return (m.dof_armature[dof], m.actuator_armature[a])
    if name == "actuator_lag":
        return (m.actuator_dyntype[a], *m.actuator_dynprm[a], m.actuator_actnum[a])
    if name == "time_delay":
        return (m.actuator_delay[a], *m.actuator_history[a])
    if name == "torque_saturation":
        return (m.actuator_forcelimited[a], *m.actuator_forcerange[a])
    if name == "torque_gain":
        return tuple(m.actuator_gear[a])
    if name == "position_offset":
        return (m.actuator_biastype[a], *m.actuator_biasprm[a])
    if name == "presliding_friction":
        f = m.actuator("yaw_friction").id
        return (*m.actuator_dynprm[f], *m.actuator_biasprm[f])
    if name == "cogging":  # every actuator with a cogging term of the bank's period count
        return tuple(v for i in range(m.nactuator) if m.actuator_biasprm[i, 1] == omni_truths.COGGING_PERIODS_PER_TURN
                     for v in (i, *m.actuator_biasprm[i, :3]))
    if name == "stribeck_friction":  # every actuator with the bank's stiff Stribeck bristle
        return tuple(v for i in range(m.nactuator) if tuple(m.actuator_dynprm[i, 5:7]) == omni_truths.STRIBECK_SIGMA
                     for v in (i, *m.actuator_dynprm[i, 5:7], *m.actuator_biasprm[i, 3:6]))
    if name in ("drive_compliance", "backlash"):
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "yaw_output") < 0:
            return ()  # a rigid drive: no rotor, no cable
        t = _cable(m)
        if name == "backlash":
            return (m.tendon_limited[t], *m.tendon_range[t], *m.tendon_solref_lim[t], *m.tendon_solimp_lim[t])
        return (m.tendon_stiffness[t], m.tendon_damping[t], *m.body_inertia[m.body("truth_rotor").id])
    if name == "arm_mass":
        return tuple(v for b in omni_truths.ARM_LINKS for v in (m.body_mass[m.body(b).id], *m.body_inertia[m.body(b).id]))
    raise KeyError(name)


def _same(a: tuple, b: tuple) -> bool:
    return len(a) == len(b) and bool(np.allclose(a, b, rtol=1e-12, atol=0.0))


#: What the nominal model holds in the fields of the 8 effects it lacks (stated, not read):
#: the motor has no activation dynamics (dyntype none, no activation state), no delay buffer,
#: no force limit, no bias; no cogging or Stribeck element and no two-mass cable exist.
NOMINAL_LACKS = {
    "actuator_lag": lambda s: s[0] == mujoco.mjtDyn.mjDYN_NONE and s[-1] == 0,
    "time_delay": lambda s: s == (0.0, 0, 0),
    "torque_saturation": lambda s: s[0] == 0,
    "position_offset": lambda s: s[0] == mujoco.mjtBias.mjBIAS_NONE and not any(s[1:]),
    "cogging": lambda s: s == (),
    "stribeck_friction": lambda s: s == (),
    "drive_compliance": lambda s: s == (),
    "backlash": lambda s: s == (),
}
#: Effects whose fields another hidden effect moves as part of its own writing: the joint's
#: armature (moved into the rotor body of a two-mass drive) and the two-mass drive's
#: (compliance and backlash build the same rotor and cable).
SHARED = {
    "armature": {"drive_compliance", "backlash"},
    "drive_compliance": {"backlash"},
    "backlash": {"drive_compliance"},
}


def test_truth_changes_the_physics(nominal):
    """Each truth model differs from the nominal model in every field its effects write (for the
    8 effects the nominal model lacks: the element is absent or at its default in the nominal
    model and present in the truth), and in no field another effect writes (a writer that
    touched a second field would show)."""
    base = {n: effect_state(n, nominal) for n in omni_truths.TRUTH}
    for n, lacks in NOMINAL_LACKS.items():
        assert lacks(base[n]), (n, base[n])
    assert set(base) == set(fx.NAMES) - SIMULATED
    for c in LIBRARY_CASES:
        m = hidden.truth_spec(c).compile()
        hidden_names = {n for n, _ in c.effects}
        for n, v0 in base.items():
            v = effect_state(n, m)
            if n in hidden_names:
                assert not _same(v, v0), f"{c.name}: {n} left as in the nominal model"
                if n in NOMINAL_LACKS:
                    assert not NOMINAL_LACKS[n](v), f"{c.name}: {n} absent from the truth"
            elif not hidden_names & SHARED.get(n, set()):
                assert _same(v, v0), f"{c.name} changed {n}: {v0} -> {v}"


# --- hidden.assess on hand-made reports (fast) ----------------------------------------------
def _effect(name, params, half, confidence="high"):
    return {"name": name, "parameters": dict(params), "confidence": confidence,
            "uncertainty": {p: h for p, h in zip(dict(params), half)}}


def _report(*effects, shrink=100.0, unexplained=False):
    return {"effects": list(effects), "shrink_factor": shrink, "unexplained": unexplained}


TILT = hidden.case("gravity_tilt")  # truth (0.035, -0.02)
GOOD_TILT = _effect("gravity_tilt", {"tilt_x_rad": 0.0351, "tilt_y_rad": -0.0199}, (2e-4, 2e-4))


def test_assess_passes_a_good_report():
    assert hidden.assess(TILT, _report(GOOD_TILT)) == (True, "ok")
    assert hidden.assess(TILT, _report(GOOD_TILT, shrink=math.inf))[0]  # gap left exactly 0


def test_assess_wants_high_confidence():
    ok, why = hidden.assess(TILT, _report({**GOOD_TILT, "confidence": "low"}))
    assert not ok and "gravity_tilt (low)" in why
    ok, why = hidden.assess(TILT, _report({k: v for k, v in GOOD_TILT.items() if k != "confidence"}))
    assert not ok and "high confidence" in why


@pytest.mark.parametrize("bad", [math.inf, math.nan, None])
def test_assess_fails_a_half_width_that_is_not_finite(bad):
    ok, why = hidden.assess(TILT, _report(_effect("gravity_tilt", {"tilt_x_rad": 0.9, "tilt_y_rad": -0.0199},
                                                (bad, 2e-4))))
    assert not ok and why.startswith("tilt_x_rad: half-width") and "not finite" in why
    # even with the fitted value on the truth: an infinite interval shows nothing
    ok, _ = hidden.assess(TILT, _report(_effect("gravity_tilt", {"tilt_x_rad": 0.035, "tilt_y_rad": -0.02},
                                              (2e-4, bad))))
    assert not ok


def test_assess_fails_a_fitted_value_that_is_not_finite():
    ok, why = hidden.assess(TILT, _report(_effect("gravity_tilt", {"tilt_x_rad": math.nan, "tilt_y_rad": -0.02},
                                                (2e-4, 2e-4))))
    assert not ok and why == "tilt_x_rad: fitted nan"


def test_assess_fails_parameter_lists_of_another_length():
    short = _effect("gravity_tilt", {"tilt_x_rad": 0.035}, (2e-4,))  # zip would check one and pass
    ok, why = hidden.assess(TILT, _report(short))
    assert not ok and why == "gravity_tilt: 1 parameters reported (tilt_x_rad), the truth holds 2"
    long = _effect("gravity_tilt", {"a": 0.035, "b": -0.02, "c": 7.0}, (2e-4, 2e-4, 1e-9))
    ok, why = hidden.assess(TILT, _report(long))
    assert not ok and "3 parameters reported" in why


def test_assess_outside_the_interval_and_small_shrink():
    ok, why = hidden.assess(TILT, _report(_effect("gravity_tilt", {"tilt_x_rad": 0.036, "tilt_y_rad": -0.02},
                                                (2e-4, 2e-4))))
    assert not ok and why.startswith("tilt_x_rad: 0.036 vs truth 0.035")
    assert hidden.assess(TILT, _report(GOOD_TILT, shrink=2.9)) == (False, "gap shrank only x2.9")
    assert not hidden.assess(TILT, _report(GOOD_TILT, shrink=math.nan))[0]
    ok, why = hidden.assess(TILT, _report(GOOD_TILT, _effect("armature", {"a": 1e-4}, (1e-6,))))
    assert not ok and why.startswith("named ['gravity_tilt', 'armature']")


def test_assess_null_cases():
    none = {"name": "none", "parameters": {}, "uncertainty": {}}
    assert hidden.assess(hidden.case("none"), _report(none, shrink=1.0)) == (True, "none")
    assert not hidden.assess(hidden.case("none"), _report(GOOD_TILT))[0]


END_STOP = hidden.case("end_stop")  # expect: none, torque_saturation, joint_stiffness


def test_assess_outside_effects_are_checked_against_expect():
    none = {"name": "none", "parameters": {}, "uncertainty": {}}
    assert hidden.assess(END_STOP, _report(none, shrink=1.0, unexplained=True)) == (True, "unexplained (none)")
    stand_in = _effect("joint_stiffness", {"k": 0.1}, (0.5,), confidence="low")
    assert hidden.assess(END_STOP, _report(stand_in, unexplained=True)) == (True, "nearest candidate, low confidence")
    # a name outside the case's expect list fails even with low confidence
    stray = _effect("presliding_friction", {"s0": 0.66}, (0.62,), confidence="low")
    ok, why = hidden.assess(END_STOP, _report(stray, unexplained=True))
    assert not ok and why.startswith("named ['presliding_friction'], not among the acceptable")
    # an acceptable stand-in with high confidence fails, whatever the unexplained flag says
    sure = _effect("joint_stiffness", {"k": 0.1}, (0.5,), confidence="high")
    ok, why = hidden.assess(END_STOP, _report(sure, unexplained=True))
    assert not ok and why.startswith("confidently misnamed")
    ok, _ = hidden.assess(END_STOP, _report(stand_in, {**sure, "name": "torque_saturation"}))
    assert not ok
    # gain_slope's list is its own: joint_stiffness is not acceptable there
    assert not hidden.assess(hidden.case("gain_slope"), _report(stand_in, unexplained=True))[0]


# --- the whole bank (slow) -----------------------------------------------------------------
#: Cases the workflow fails, by the bank's criteria, on record (docs/studies/discrepancy/bank.md): run
#: as strict xfails, so each still runs, and a change of its outcome either way is reported.
KNOWN_FAILURES = {
    "gain_slope": "since joint_stiffness got its rest angle (9e96c32) it names joint_stiffness with low "
                  "confidence (stiffness -0.0745 +- 0.03 N*m/rad about a rest of 0.194 +- 0.11 rad, x1.54): "
                  "a preloaded spring stands in for the torque constant's slope; not on the case's list "
                  "(none, torque_gain), which is not widened (docs/studies/discrepancy/bank.json at 8df8d13; "
                  "torque_gain, low, x1.34 before)",
    "end_stop": "names presliding_friction with low confidence (x2.58), a stand-in not on the case's "
                "expect list (none, torque_saturation, joint_stiffness); the list was set before any "
                "run and is not widened to the result (docs/studies/discrepancy/bank.json at 397d76b and 86e7a53; "
                "viscous_damping, low, x2.0 at 84fc339)",
    "asymmetric_friction": "with the effect in the library (commit 33a9091) it was named with high "
                           "confidence and a = 7.57 +- 0.33 mN*m covered the truth 7.5, but the "
                           "held-out gap shrank only x2.6 (1.54e-3 -> 6.04e-4 rad, noise floor "
                           "6.3e-4): the effect left the library again, so the workflow cannot "
                           "name it (docs/studies/discrepancy/bank.md)",
}


@pytest.mark.slow
@pytest.mark.bank
@pytest.mark.parametrize("case_name", [
    pytest.param(c.name, marks=pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[c.name]))
    if c.name in KNOWN_FAILURES else c.name for c in hidden.CASES + hidden.NOMINAL_OFF_CASES])
def test_bank(case_name):
    from discrepancy.workflow import run_discrepancy
    case = hidden.case(case_name)
    model, target = hidden.nominal(case)  # None, None: the Omni
    rep = run_discrepancy(hidden.generate(case), model, target=target).report
    ok, why = hidden.assess(case, rep)
    assert ok, (why, rep["effects"])


#: The gear_efficiency case (a truth of another form, servo_truth.simulate_efficiency) on record
#: (docs/studies/discrepancy/bank_gear_efficiency.json): None while the workflow does what the case asks
#: (servo_truth.assess_efficiency), else the measured figures of its failure (the docs test checks
#: them against the record).
GEAR_EFFICIENCY_FAILURE = (
    "the workflow (commit 8f96418, the smooth load variant and its two starts in) names "
    "load_friction_smooth with high confidence (round 1's best, load_friction_smooth 0.89 of the "
    "corrections' gap) and the held-out gap 0.0194 -> 0.00109 rad (x17.8), with mu_drive 0.155 < "
    "mu_back 0.441 for 0.15 < 0.45 (both intervals hold them), but the case asks for load_friction "
    "itself (its expectation was set before the family's variants existed and is kept as written: "
    "the named law is the variant nested in it); damping 0.37 -> 0.3657, frictionloss "
    "0.03 -> 0.03185 N*m; noise floor 0.000597 rad (docs/studies/discrepancy/bank.md)")


@pytest.mark.slow
@pytest.mark.bank
@pytest.mark.xfail(GEAR_EFFICIENCY_FAILURE is not None, strict=True, reason=GEAR_EFFICIENCY_FAILURE or "")
def test_bank_gear_efficiency():
    """The geared servo whose gearbox losses are a gear efficiency law with a smooth sign
    (another form than the engine's law the library fits): a correct workflow names load_friction
    first, with mu_back > mu_drive, and shrinks the held-out gap >= 3x
    (servo_truth.GEAR_EFFICIENCY_CASE, stated before the run)."""
    from bank import servo_truth
    from discrepancy.workflow import run_discrepancy
    rep = run_discrepancy(servo_truth.generate_efficiency(), servo_truth.model_path(),
                          target=servo_truth.target()).report
    ok, why = servo_truth.assess_efficiency(rep)
    assert ok, (why, rep["effects"])


def test_docs_gear_efficiency_section_is_the_record():
    """docs/studies/discrepancy/bank.md ends with the gear_efficiency section rendered from its record;
    the record's verdict is what assess_efficiency says of its report, its case is the truth's
    as the code states it now, and the slow test's expected outcome is the record's."""
    from bank import servo_truth
    from bank.writers import bank_report
    rec = json.loads(bank_report.EFFICIENCY_JSON.read_text())
    assert servo_truth.assess_efficiency(rec["report"]) == (rec["pass"], rec["why"])
    assert rec["case"] == json.loads(json.dumps(servo_truth.GEAR_EFFICIENCY_CASE))
    page = bank_report.DEFAULT_OUT.read_text()
    assert page.endswith("\n" + bank_report.efficiency_section(rec))
    bank_data = json.loads(bank_report.DEFAULT_OUT.with_suffix(".json").read_text())
    assert page == bank_report.bank_page(bank_data, bank_report.DEFAULT_OUT)
    assert (GEAR_EFFICIENCY_FAILURE is None) == rec["pass"]
    if GEAR_EFFICIENCY_FAILURE is not None:  # the reason's figures are the record's
        rep = rec["report"]
        named = [e["name"] for e in rep["effects"]]
        assert f"commit {rec['meta']['commit']}" in GEAR_EFFICIENCY_FAILURE
        assert f"names {', '.join(named)}" in GEAR_EFFICIENCY_FAILURE
        assert f"{rep['gap_before']:.3g} -> {rep['gap_after']:.3g} rad (x{rep['shrink_factor']:.3g}" in GEAR_EFFICIENCY_FAILURE
        assert f"noise floor {rep['noise_floor_rad']:.3g} rad" in GEAR_EFFICIENCY_FAILURE
        for c in rep.get("corrections", []):
            if c["parameter"] in ("damping_nms_per_rad", "frictionloss_nm"):
                assert f"{c['nominal']:.4g} -> {c['fitted']:.4g}" in GEAR_EFFICIENCY_FAILURE, c["parameter"]
        shares = {c["name"]: c for c in rep["candidates"][0]}
        # the law's form: load_friction, or the family's variant that stands in its place
        law = "load_friction" if "load_friction" in shares else rep["rounds"][0]["variants"]["chosen"]
        for name in (rep["rounds"][0]["best"], law):  # the round's best, the law's form
            assert f"{name} {shares[name]['share']:.2g}" in GEAR_EFFICIENCY_FAILURE, name
        p = shares[law]["parameters"]
        sign = ">" if p["mu_drive"] > p["mu_back"] else "<"
        assert f"mu_drive {p['mu_drive']:.3g} {sign} mu_back {p['mu_back']:.3g}" in GEAR_EFFICIENCY_FAILURE


@pytest.mark.slow
def test_coverage_script_small(tmp_path):
    """The coverage study runs end to end on 3 draws of 2 effects (noisy data, the small
    experiment set) and writes its JSON and figure."""
    from bank.studies import discrepancy_coverage as cov
    rc = _coverage_script("--effects", "time_delay", "coulomb_friction", "--n", "3", "--conditions", "noisy",
                          "--experiments", "small", "--out", str(tmp_path)).returncode
    res = json.loads((tmp_path / "coverage.json").read_text())
    assert (tmp_path / "coverage.png").stat().st_size > 10_000
    assert len(res["draws"]) == 6
    for d in res["draws"]:
        assert d["named"] == [d["effect"]] and len(d["covered"]) == len(d["truth"])
        lo, hi = ranges.RANGES[d["effect"]][0][:2]
        assert lo <= d["truth"][0] <= hi
    cov_noisy = res["overall"]["noisy"]
    assert cov_noisy["parameters_checked"] == 6
    assert rc == (0 if cov_noisy["coverage"] >= cov.TARGET else 1)


def _coverage_script(*args: str) -> subprocess.CompletedProcess:
    """``scripts/discrepancy_coverage.py`` run with ``args``, its output captured."""
    return subprocess.run([sys.executable, str(ROOT / "scripts" / "discrepancy_coverage.py"), *args],
                          capture_output=True, text=True, timeout=3600)


def test_coverage_script_bad_effect(tmp_path):
    proc = _coverage_script("--effects", "no_such_effect", "--out", str(tmp_path))
    assert proc.returncode == 2
    err = proc.stderr
    assert err.startswith("error:") and "no_such_effect" in err and err.count("\n") == 1


def test_coverage_merge_refuses_other_settings(tmp_path):
    """--merge of draws made with another experiment set is an error, not a mislabelled study."""
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"settings": {"seed": 0, "experiments": "small"}, "draws": []}))
    proc = _coverage_script("--summarise-only", "--merge", str(other), "--out", str(tmp_path / "o"))
    assert proc.returncode == 2
    err = proc.stderr
    assert err.startswith("error: --merge") and "--experiments small" in err and err.count("\n") == 1


# --- docs/method/discrepancy.md's figures are the JSONs' -------------------------------------------
PAGE = ROOT / "docs" / "method" / "discrepancy.md"


def _section(title: str, next_title: str) -> str:
    text = PAGE.read_text()
    return text[text.index(title):text.index(next_title)]


def _flat(text: str) -> str:
    return " ".join(text.split())


def _pct(x: float) -> str:
    return f"{100 * x:.1f}".removesuffix(".0")


def _sci(x: float) -> str:
    m, e = f"{x:.1e}".split("e")
    return f"{m}e{int(e)}"


def test_docs_coverage_figures_are_the_json():
    """The coverage study's section of docs/method/discrepancy.md says what docs/studies/discrepancy/coverage.json holds:
    the experiment set (and its size), the table's figures, the fit times, the lowest effect."""
    from bank.studies import discrepancy_coverage as cov
    res = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "coverage.json").read_text())
    sec = _flat(_section("## Uncertainty that holds", "## Your own robot"))
    kind = res["settings"]["experiments"]
    assert [m for m in ("bank", "small") if f"--experiments {m}" in sec] == [kind]
    exps = cov.experiments(kind)
    assert f"{len(exps)} runs of {len(exps[0].r) * 1e-3:g} s" in sec
    for cond, label in (("exact", "exact (no noise, no quantisation)"), ("noisy", "noisy (quantised + 1e-4 rad)")):
        o = res["overall"][cond]
        per = {d["effect"] for d in res["draws"] if d["condition"] == cond}
        n = {sum(d["effect"] == e and d["condition"] == cond for d in res["draws"]) for e in per}
        assert len(n) == 1, n
        lo, hi = o["coverage_wilson95"]
        row = (f"| {label} | {n.pop()} (all {len(per)} effects) | {o['parameters_checked']} | "
               f"**{_pct(o['coverage'])} %** (Wilson 95 %: {_pct(lo)}–{_pct(hi)} %) | "
               f"{_sci(o['median_rel_half_width'])} |")
        assert row in sec, row
    secs = {c: [d["seconds"] for d in res["draws"] if d["condition"] == c] for c in ("exact", "noisy")}
    every = secs["exact"] + secs["noisy"]
    assert (f"Each fit took {min(every):.0f}-{max(every):.0f} s (median {np.median(secs['exact']):.0f} s "
            f"exact, {np.median(secs['noisy']):.0f} s noisy)") in sec
    worst = min(res["per_effect"], key=lambda r: r["coverage"])
    assert (f"The lowest is {worst['effect']} on {worst['condition']} data, {worst['covered']} of "
            f"{worst['parameters_checked']} ({_pct(worst['coverage'])} %)") in sec
    ratio = [abs(hidden.error(p, f, t)) / h for d in res["draws"] if d["condition"] == "noisy" and d["covered"]
             for p, f, t, h in zip(d["parameters"], d["fitted"], d["truth"], d["half_width"])]
    assert f"percentile of |error| / half-width is {np.percentile(ratio, 95):.2f}" in sec


def test_docs_fold_cost_figures_are_the_record():
    """The method page's "The cost" quotes this bank's record (bank.json) and the bench's
    (docs/reference/bench.json) beside the landed estimator with every runner-up refitted, the
    estimator before held-out folds and the variants tried, as
    docs/studies/discrepancy/honest_folds.json records them; the unconverged folds it names are
    the bank record's."""
    rec = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "honest_folds.json").read_text())
    text = PAGE.read_text()
    par = _flat(text[text.index("The count and the race were set"):text.index("From the second round on (and")])
    bank, bench = rec["bank"], rec["bench"]
    here = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "bank.json").read_text())["cases"]
    total = sum(c["report"]["timings"]["physics_steps"] for c in here.values() if isinstance(c.get("report"), dict))
    passed = sum(bool(c["pass"]) for c in here.values())
    every, before = bank["every_runner_up_confirmed"], bank["earlier"]
    assert (f"the whole bank took {total / 1e6:.0f} M physics steps ({passed} of {len(here)} passing), where "
            f"it took {every['physics_steps'] / 1e6:.0f} M ({every['passed']} of {every['cases']}) with every "
            f"runner-up refitted and the folds that started from the all-runs fit took "
            f"{before['physics_steps'] / 1e6:.0f} M ({before['passed']} of {before['cases']})") in par
    ranked = bank["ranked"]
    st = ranked["stribeck_friction"]
    assert st["named"] == ["stribeck_friction", "presliding_friction"]
    assert set(ranked["failed"]) - set(before["failed"]) == {"stribeck_friction"}
    mine = here["stribeck_friction"]
    assert mine["pass"]
    r1 = next(c for c in mine["report"]["candidates"][0] if c["name"] == "stribeck_friction" and c["method"] == "refit")
    assert (f"`presliding_friction` named second, round 1 held out {st['round1_heldout_gap_rad']:.2e} rad "
            f"against {r1['heldout_gap_rad']:.2e} with the race)").replace("e-0", "e-") in par

    def figures(b):
        return f"{b['physics_steps'] / 1e6:.1f} M steps, {b['wall_s']:.0f} s and {b['peak_rss_mb']:.0f} MB"
    srv = json.loads((ROOT / "docs" / "reference" / "bench.json").read_text())["discrepancy_servo"]
    assert (f"`omni bench --only discrepancy_servo` {figures(srv)} against {figures(bench['every_runner_up_confirmed'])} "
            "with every runner-up refitted, on one machine one after the other") in par
    assert ("within the bench's 180 s target" in par) == (srv["wall_s"] <= 180)
    assert all(b["passes_bank_criteria"] for b in bench.values()) and srv["passes_bank_criteria"]
    unconverged = [(name, c["name"], c["unconverged_folds"]) for name, case in here.items()
                   for rnd in case["report"]["candidates"] for c in rnd if c.get("unconverged_folds")]
    assert unconverged == [("delay+friction+armature", "stribeck_friction", 1), ("gain_slope", "presliding_friction", 2)]
    assert ("Three folds of the bank stopped unconverged (one of `stribeck_friction` in `delay+friction+armature`, "
            "two of `presliding_friction` in `gain_slope`)"
            in par)


BANK_TABLE_START = "<!-- bank table: made by `python scripts/discrepancy_bank.py --table` from docs/studies/discrepancy/bank.json -->"
BANK_TABLE_END = "<!-- end of bank table -->"


def test_docs_bank_table_is_the_json():
    """docs/method/discrepancy.md's bank table is exactly what ``discrepancy_bank.py --table`` makes from
    docs/studies/discrepancy/bank.json; the JSON's verdicts are what bank.assess says of its reports;
    the bank section links the table's current location and no stale one."""
    from bank.writers import bank_report
    data = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "bank.json").read_text())
    assert list(data["cases"]) == [c.name for c in hidden.CASES]  # every case, in the bank's order
    for name, c in data["cases"].items():
        if "report" in c:
            assert hidden.assess(hidden.case(name), c["report"]) == (c["pass"], c["why"]), name
    sec = _section("## The hidden-effect bank: what it proves", "## Uncertainty that holds")
    block = sec[sec.index(BANK_TABLE_START) + len(BANK_TABLE_START):sec.index(BANK_TABLE_END)]
    assert block.strip("\n") == bank_report.readme_table(data).strip("\n")
    assert "docs/studies/discrepancy/bank.md" in sec
    for stale in ("docs/discrepancy_bank.md", "bank_rerun.md"):
        assert stale not in PAGE.read_text() and stale not in (ROOT / "README.md").read_text()
    assert bank_report.DEFAULT_OUT == ROOT / "docs" / "studies" / "discrepancy" / "bank.md"


def test_docs_search_examples_are_the_bank_json():
    """The two examples of the search docs/method/discrepancy.md quotes are what the bank's run did: the stand-in
    pair of delay+friction+armature (Coulomb + a lag beats Coulomb + delay, whose Coulomb and
    delay stand in for the armature) and the set backlash+coulomb's backward step thinned."""
    data = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "bank.json").read_text())
    sec = _flat(_section("# Where model and measurements disagree", "## The hidden-effect bank"))
    rep = data["cases"]["delay+friction+armature"]["report"]
    pairs = {c["name"]: c for rnd in rep["candidates"] for c in rnd if c["method"] != "prescreen"}
    best_pair = max((c for n, c in pairs.items() if n.count("+") == 1), key=lambda c: c["share"])
    assert best_pair["name"] == "coulomb_friction+actuator_lag"
    cd = pairs["coulomb_friction+time_delay"]
    assert cd["share"] < best_pair["share"]
    assert (f"whose fit makes up for the missing armature with {cd['parameters']['frictionloss_nm'] * 1e3:.0f} "
            f"mN m and {cd['parameters']['delay_s'] * 1e3:.1f} ms") in sec
    rounds = data["cases"]["backlash+coulomb"]["report"]["rounds"]
    assert rounds[0]["pair_search"]["best"] == "coulomb_friction+armature"
    assert any(r.get("tie") and r.get("runner_up") == "joint_stiffness" for r in rounds if r["round"] == 1)
    thinned = [r for r in rounds if "backward_step" in r]
    assert [(r["best"], r["backward_step"]["dropped"]) for r in thinned] == \
        [("coulomb_friction+joint_stiffness+backlash", "joint_stiffness")]
    assert ("the pair search accepts Coulomb + an armature, tied with Coulomb + a spring; the beam's best "
            "set is Coulomb + spring + backlash, and the spring is dropped") in sec


def test_docs_confirmation_gate_figures_are_the_record():
    """The method page's confirmation gate quotes docs/studies/discrepancy/confirmation_log.json
    (every runner-up refitted), whose summary is what bank.studies.confirmation_log.summary reads
    from its cases with the library's CONFIRM_WITHIN; "38 %" and "1.25 times" follow from the
    gate's factor and the tie margin."""
    from bank.studies import confirmation_log as cl
    from discrepancy import select as sel

    rec = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "confirmation_log.json").read_text())
    s = cl.summary(rec["cases"])
    assert {k: v for k, v in s.items() if k != "events"} == rec["summary"] and s["events"] == rec["events"]
    assert s["violations"] == 0  # the check the gate was fixed with
    par = _flat(PAGE.read_text())
    w = sel.CONFIRM_WITHIN
    assert w == 2 and f"{cl.LOW_CONFIDENCE_RATIO:.2f}" == "1.25"
    assert f"lands {100 * (1 - cl.LOW_CONFIDENCE_RATIO / w):.1f}".rstrip("0").rstrip(".") + " % below" in par
    worst = s["lowest_r2_over_s2_at"]
    assert (f"of its {s['confirmations_of_two']} confirmations of two, {s['far']} had the runner-up screened at "
            f"twice the best's gap or more, and none of those came within 1.25 times after its refit (the "
            f"closest at {s['closest_far_r2_over_r1']:.2f} times); the largest fall from screen to refit was a "
            f"LuGre fit's, to {s['lowest_r2_over_s2']:.2f} of its screen, where the screen had put it at "
            f"{worst['s2'] / worst['r1']:.0f} times the best") in par
    assert worst["runner_up"] == "presliding_friction"  # "a LuGre fit's"


def test_docs_friction_family_figures_are_the_record():
    """The method page's sentence on the friction family in the bank quotes bank.json: the
    Stribeck case's kept variant, both held-out gaps, its fitted rise, speed and shape with their
    intervals; the load_friction case's tie and its physics steps."""
    here = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "bank.json").read_text())["cases"]
    par = _flat(PAGE.read_text())
    ffs, lf = here["friction_family_stribeck"]["report"], here["load_friction"]["report"]
    var = [r["variants"] for r in ffs["rounds"] if r.get("variants")][0]
    assert var["chosen"] == "friction_family_stribeck" and ffs["effects"][0]["name"] == var["chosen"]
    p, u = ffs["effects"][0]["parameters"], ffs["effects"][0]["uncertainty"]
    assert (f"held out at {var['friction_family_stribeck']['heldout_gap_rad']:.2e} rad against "
            f"`load_friction`'s {var['load_friction']['heldout_gap_rad']:.2e}, with rise "
            f"{p['rise_nm']:.3g} ± {u['rise_nm']:.2g} N m, ωs {p['omega_s_rad_s']:.3g} ± "
            f"{u['omega_s_rad_s']:.2g} rad/s and δ {p['delta']:.3g} ± {u['delta']:.2g}") in par
    tie = [r["variants"] for r in lf["rounds"] if r.get("variants")][0]
    assert tie["chosen"] == "load_friction" == lf["effects"][0]["name"]
    assert (f"the two tie ({tie['load_friction']['heldout_gap_rad']:.2e} and "
            f"{tie['friction_family_stribeck']['heldout_gap_rad']:.2e} rad)") in par
    assert f"at {lf['timings']['physics_steps'] / 1e6:.1f} M physics steps" in par


def test_the_bank_script_refuses_a_case_it_cannot_run(capsys, tmp_path):
    """``--cases`` with a name outside the record's cases (here a nominal-off case, which runs as a
    test only) stops with one error line, exit 2, before any work (it was silently dropped)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("bank_script", ROOT / "scripts" / "discrepancy_bank.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--cases", "load_friction", "load_friction_nominal_off", "--out", str(tmp_path / "no" / "x.md")]) == 2
    assert not (tmp_path / "no").exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "load_friction_nominal_off" in err[0]


def test_docs_smooth_sign_figures_are_the_record():
    """The method page's paragraph on the two forms of the load law quotes the record
    docs/studies/discrepancy/smooth_sign.json (scripts/smooth_sign.py), and the record's fits
    are on the case and law it names."""
    root = Path(__file__).resolve().parents[1]
    rec = json.loads((root / "docs" / "studies" / "discrepancy" / "smooth_sign.json").read_text())
    assert rec["case"] == "i_users_pendulum" and rec["truth"]["mu_drive"] == rec["truth"]["mu_back"] == 0.2
    flat = " ".join((root / "docs" / "method" / "discrepancy.md").read_text().split())
    stick, smooth = rec["forms"]["stick"], rec["forms"]["smooth"]

    def e(x):  # the page writes 2.30e-3
        return f"{x:.2e}".replace("e-0", "e-")

    assert (f"At the truth's values the sticking form leaves {e(stick['rms_at_truth_rad'])} rad, "
            f"the smooth one {e(smooth['rms_at_truth_rad'])}.") in flat
    v = smooth["fit_from_truth"]["values"]
    assert (f"smooth form stays there (gear {v['gear_nm_per_v']:.4f} for {rec['truth']['gear_nm_per_v']:.4f} "
            f"N m/V, μ {v['mu_drive']:.4f} and {v['mu_back']:.4f}, ω_s {v['w_s_rad_s']:.4f} rad/s; "
            f"{e(smooth['fit_from_truth']['rms_rad'])} rad)") in flat
    s = stick["fit_from_truth"]
    assert (f"the sticking form stops at {e(s['rms_rad'])} rad with the gear at "
            f"{s['values']['gear_nm_per_v']:.4f}") in flat
    far = (stick["fit_from_nominal"]["rms_rad"], smooth["fit_from_nominal"]["rms_rad"])
    assert f"both stop far from the truth ({e(far[0])} and {e(far[1])} rad)" in flat
    assert all(abs(x["fit_from_nominal"]["values"]["gear_nm_per_v"] - rec["truth"]["gear_nm_per_v"]) > 0.005
               for x in (stick, smooth))


def test_docs_users_pendulum_is_the_record():
    """The method page's users_pendulum paragraph quotes the bank record's run of the case
    (docs/studies/discrepancy/bank.json): its commit, the variants' held-out gaps, the named
    law's values and half-widths, the shrink, the torque gain's correction and the ridge's two
    products of the gain and the coefficients."""
    case = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "bank.json").read_text())["cases"]["users_pendulum"]
    rep = case["report"]
    text = _flat(PAGE.read_text())
    par = text[text.index("**`users_pendulum`**"):text.index("**`asymmetric_friction` fails**")]
    assert f"Run at commit {case['commit']}" in par
    v = rep["rounds"][0]["variants"]
    assert (f"held out {v['load_friction_smooth']['heldout_gap_rad']:.2e} rad against `load_friction`'s "
            f"{v['load_friction']['heldout_gap_rad']:.2e} and the Stribeck variant's "
            f"{v['friction_family_stribeck']['heldout_gap_rad']:.2e}").replace("e-04", "e-4") in par
    (e,) = rep["effects"]
    p, u = e["parameters"], e["uncertainty"]
    assert e["name"] == "load_friction_smooth"
    for name, word in (("mu_drive", "mu_drive"), ("mu_back", "mu_back"), ("b_emf_nms_per_rad", "b_emf"),
                       ("w_s_rad_s", "w_s")):
        assert f"{word} {p[name]:.2g} ± {u[name]:.2g}" in par or f"{word} {p[name]:.3f} ± {u[name]:.2g}" in par, name
    assert f"gap ×{rep['shrink_factor']:.1f}" in par
    (gain,) = [c for c in rep["corrections"] if c["parameter"] == "gear_nm_per_v"]
    assert f"torque gain came back at {gain['fitted']:.3f} ± {gain['half_width_95']:.2g}" in par
    truth = 0.3  # servo_truth's gear, the nominal's
    assert f"for the truth's 0.3 ({100 * (gain['fitted'] / truth - 1):+.1f} %: within the issue's 2 %" in par
    assert abs(gain["fitted"] / truth - 1) <= 0.02 and abs(gain["fitted"] - truth) <= gain["half_width_95"]
    (mixed,) = gain["confounded_with"]
    assert mixed["effect"] == "load_friction_smooth" and f"(multiple correlation {mixed['correlation']:.2f})" in par
    assert f"gear·(1 − μ_drive) = {gain['fitted'] * (1 - p['mu_drive']):.3f}" in par
    assert f"gear·(1 + μ_back) = {gain['fitted'] * (1 + p['mu_back']):.3f}" in par


def test_docs_gain_slope_is_the_record():
    """The method page's gain_slope sentence and the strict xfail's reason quote the bank record
    (docs/studies/discrepancy/bank.json): the stand-in named, its confidence, values, half-widths
    and shrink."""
    case = json.loads((ROOT / "docs" / "studies" / "discrepancy" / "bank.json").read_text())["cases"]["gain_slope"]
    rep = case["report"]
    (e,) = rep["effects"]
    assert e["name"] == "joint_stiffness" and e["confidence"] == "low" and not case["pass"]
    p, u = e["parameters"], e["uncertainty"]
    text = _flat(PAGE.read_text())
    par = text[text.index("**`gain_slope` fails**"):text.index("**`end_stop` fails**")]
    assert f"(×{rep['shrink_factor']:.2f};" in par and f"about {p['rest_rad']:.2f} rad" in par
    reason = KNOWN_FAILURES["gain_slope"]
    assert (f"stiffness {p['stiffness_nm_per_rad']:.3g} +- {u['stiffness_nm_per_rad']:.1g} N*m/rad about a rest of "
            f"{p['rest_rad']:.3g} +- {u['rest_rad']:.2g} rad, x{rep['shrink_factor']:.2f}") in reason
    assert f"bank.json at {case['commit']}" in reason
