"""The hidden-effect bank: its truth models are independent of the effect library (a syntax
check of bank.py and the compiled truth models read field by field), the whole bank through
the workflow (slow) and the coverage study's script (slow, small)."""

import ast
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from omni_sim import model as om
from omni_sim.discrepancy import bank
from omni_sim.discrepancy import effects as fx

ROOT = Path(__file__).resolve().parent.parent
BANK_PY = ROOT / "omni_sim" / "discrepancy" / "bank.py"


def test_bank_does_not_use_the_effect_writers():
    """bank.py writes its truth models itself: no import of the effect library, no call of its
    writers (``apply``, ``compile_with``, ``Effect.write``) -- read from the syntax tree."""
    tree = ast.parse(BANK_PY.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            assert "effects" not in mod.split("."), f"line {node.lineno}: imports from {mod}"
            assert "effects" not in [a.name for a in node.names], f"line {node.lineno}: imports effects"
        if isinstance(node, ast.Import):
            assert not any("effects" in a.name.split(".") for a in node.names), f"line {node.lineno}"
        if isinstance(node, ast.Name):
            assert node.id != "fx", f"line {node.lineno}: uses fx"
        if isinstance(node, ast.Attribute):
            assert node.attr not in ("apply", "compile_with", "write", "nominal_values"), \
                f"line {node.lineno}: .{node.attr}"


def test_the_syntax_check_would_catch_a_writer_call(tmp_path):
    """The check above fails on the old bank's line (so it can fail)."""
    src = "from . import effects as fx\nspec = fx.apply(base, changes)\n"
    tree = ast.parse(src)
    hits = [n for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == "apply"]
    hits += [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and "effects" in [a.name for a in n.names]]
    assert len(hits) == 2


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
        assert m.qpos_spring[m.jnt_qposadr[j]] == 0.0
        return [m.jnt_stiffness[j]]
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
        found = [i for i in extra if m.actuator_biasprm[i, 1] == bank.COGGING_PERIODS_PER_TURN]
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
        assert tuple(m.actuator_dynprm[found[0], 5:7]) == bank.STRIBECK_SIGMA
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


LIBRARY_CASES = [c for c in bank.CASES if c.effects and not c.outside]


@pytest.mark.parametrize("case_name", [c.name for c in LIBRARY_CASES])
def test_truth_models_hold_the_stated_values(case_name, nominal):
    hidden = bank.case(case_name)
    m = bank.truth_spec(hidden).compile()
    for name, values in hidden.effects:
        np.testing.assert_allclose(compiled_values(name, m, nominal), values, rtol=1e-12, atol=1e-15,
                                   err_msg=f"{case_name}: {name}")


def test_outside_effects_hold_the_stated_values(nominal):
    m = bank.truth_spec(bank.case("gain_slope")).compile()
    a = m.actuator("yaw_motor").id
    assert m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_AFFINE
    # gain = 1 + gainprm[1] * length with length = gear * theta: slope per rad = gainprm[1] * gear
    assert m.actuator_gainprm[a, 1] * m.actuator_gear[a, 0] == pytest.approx(0.5, rel=1e-12)
    m = bank.truth_spec(bank.case("end_stop")).compile()
    j = m.joint("yaw").id
    assert m.jnt_range[j, 1] == 0.17 and m.jnt_range[j, 0] == nominal.jnt_range[j, 0]
    assert m.jnt_solref[j, 0] == 0.01


def test_bank_covers_the_library():
    """Every library effect has a single-effect case, a truth writer and a coverage range; the
    bank holds the null cases (with and without noise), pairs, a triple and >= 2 effects
    outside the library."""
    singles = {c.effects[0][0] for c in bank.CASES if len(c.effects) == 1 and not c.outside}
    assert set(fx.NAMES) <= singles
    assert set(fx.NAMES) <= set(bank.TRUTH) and set(fx.NAMES) <= set(bank.RANGES)
    assert {c.name for c in bank.CASES if c.expect == ("none",)} >= {"none", "none_exact"}
    assert bank.case("none_exact").exact and not bank.case("none").exact
    assert any(len(c.effects) == 2 for c in bank.CASES) and any(len(c.effects) == 3 for c in bank.CASES)
    outside = {o[0] for c in bank.CASES for o in c.outside}
    assert len(outside) >= 2 and not outside & set(fx.NAMES)
    for c in bank.CASES:
        assert c.note, c.name
        if c.outside:
            assert c.gap_lives, c.name


def test_truth_changes_the_physics(nominal):
    """Each truth model differs from the nominal model in its effect only: the values the other
    effects read stay nominal (a writer that touched a second field would show)."""
    nominal_vals = {}
    for n in bank.TRUTH:
        try:
            nominal_vals[n] = compiled_values(n, nominal, nominal)
        except (AssertionError, KeyError):  # the nominal model has no such element
            nominal_vals[n] = None
    for c in LIBRARY_CASES:
        m = bank.truth_spec(c).compile()
        hidden = {n for n, _ in c.effects}
        for n, v0 in nominal_vals.items():
            if n in hidden or v0 is None:
                continue
            if n == "armature" and hidden & {"torque_gain", "drive_compliance", "backlash", "arm_mass"}:
                continue  # reflected by the gear, moved into the rotor body, or the arm changed
            np.testing.assert_allclose(compiled_values(n, m, nominal), v0, rtol=1e-12,
                                       err_msg=f"{c.name} changed {n}")


# --- the whole bank (slow) -----------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("case_name", [c.name for c in bank.CASES])
def test_bank(case_name):
    from omni_sim.discrepancy.workflow import run_discrepancy
    hidden = bank.case(case_name)
    rep = run_discrepancy(bank.generate(hidden), None).report
    ok, why = bank.assess(hidden, rep)
    assert ok, (why, rep["effects"])


@pytest.mark.slow
def test_coverage_script_small(tmp_path):
    """The coverage study runs end to end on 3 draws of 2 effects (noisy data, the small
    experiment set) and writes its JSON and figure."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("cov", ROOT / "scripts" / "discrepancy_coverage.py")
    cov = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cov)
    rc = cov.main(["--effects", "time_delay", "coulomb_friction", "--n", "3", "--conditions", "noisy",
                   "--experiments", "small", "--out", str(tmp_path)])
    res = json.loads((tmp_path / "coverage.json").read_text())
    assert (tmp_path / "coverage.png").stat().st_size > 10_000
    assert len(res["draws"]) == 6
    for d in res["draws"]:
        assert d["named"] == [d["effect"]] and len(d["covered"]) == len(d["truth"])
        lo, hi = bank.RANGES[d["effect"]][0][:2]
        assert lo <= d["truth"][0] <= hi
    cov_noisy = res["overall"]["noisy"]
    assert cov_noisy["parameters_checked"] == 6
    assert rc == (0 if cov_noisy["coverage"] >= cov.TARGET else 1)


def test_coverage_script_bad_effect(capsys):
    import importlib.util
    spec = importlib.util.spec_from_file_location("cov", ROOT / "scripts" / "discrepancy_coverage.py")
    cov = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cov)
    assert cov.main(["--effects", "no_such_effect"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "no_such_effect" in err and err.count("\n") == 1
