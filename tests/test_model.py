"""The MJCF model: loads, steps without warnings, follows the contract, and its yaw inertia
agrees with the paper's analytic inertia (5)."""

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

import omni_sim
from identification.errors import UserError
from omni_sim import model as om
from omni_sim.device import Device
from omni_sim.experiments import TABLE1_POSES, TABLE2_POSES


@pytest.fixture(scope="module")
def model():
    return om.load_model()


SCENES = ["scene.xml", "scene_lugre.xml", "scene_coulomb.xml", "scene_matched.xml", "omni.xml"]


@pytest.mark.parametrize("name", SCENES)
def test_steps_without_warnings(name):
    m = om.load_model(om.OMNI_DIR / name)
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    rng = np.random.default_rng(0)
    for k in range(3000):
        d.ctrl[om.index(m).yaw_act] = rng.uniform(-1.3, 1.3) if k % 200 < 100 else 0.0
        mujoco.mj_step(m, d)
    assert np.all(d.warning.number == 0), d.warning.number
    assert np.all(np.isfinite(d.qpos))


def test_every_element_named_and_home_key():
    for name in SCENES + ["stage.xml"]:
        root = ET.parse(om.OMNI_DIR / name).getroot()
        for default in root.iter("default"):  # class defaults are templates, not elements
            default.clear()
        for tag in ("body", "joint", "geom", "site", "motor", "position", "dcmotor", "key", "light",
                    "camera"):
            for el in root.iter(tag):
                assert el.get("name"), f"{name}: unnamed <{tag}>"
    m = om.load_model()
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home") >= 0


def test_friction_families():
    """Each family's scene: the coulomb one has the design card's joint frictionloss and no
    LuGre element; the lugre one the LuGre drive and no hard stick; scene.xml is lugre; both
    share the robot (same masses, inertias, servos) and differ only in the yaw drive."""
    coul = om.load_model(friction="coulomb")
    lug = om.load_model(friction="lugre")
    dflt = om.load_model()
    fc, fl = Device(coul).friction(), Device(lug).friction()
    assert fc["frictionloss"] > 0 and not Device(coul).lugre_actuators()
    assert coul.nactuator == coul.nu  # no passive element at all
    assert fl["frictionloss"] == 0 and fl["lugre_Fc"] > 0 and len(Device(lug).lugre_actuators()) == 1
    assert Device(dflt).friction() == fl
    for name in ("body_mass", "body_inertia", "dof_armature", "actuator_gear", "jnt_range"):
        a, b = getattr(coul, name), getattr(lug, name)
        n = min(len(a), len(b))  # lugre has one more actuator
        np.testing.assert_array_equal(a[:n], b[:n], err_msg=name)
    arm = [om.index(lug).yaw_dof + 1, om.index(lug).yaw_dof + 2]
    np.testing.assert_array_equal(coul.dof_frictionloss[arm], 0)  # the yaw friction stays on the yaw
    np.testing.assert_array_equal(coul.dof_damping[arm], lug.dof_damping[arm])
    with pytest.raises(om.UserError, match="unknown friction family"):
        om.load_model(friction="dahl")
    with pytest.raises(om.UserError, match="either"):
        om.load_model(om.DEFAULT_SCENE, friction="lugre")


def test_contract_names(model):
    dev = Device(model)
    ix = dev.ix
    # the torque constant is the yaw motor's gear, fixed at 0.5 N*m/V (models/omni/README.md)
    assert dev.torque_constant == model.actuator_gear[ix.yaw_act, 0] == 0.5
    yaw = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "yaw")
    assert np.allclose(model.jnt_axis[yaw], [0, 0, 1]), "yaw axis must be vertical"
    f = Device(model).friction()
    assert f["frictionloss"] + f["lugre_Fc"] > 0
    assert model.dof_damping[ix.yaw_dof] > 0
    assert model.dof_armature[ix.yaw_dof] > 0


def _rod_model_parameters(m):
    """Masses and lengths of the model, as the thin-rod inertia (5) sees them."""
    bid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n)  # noqa: E731
    turret, upper, fore, stylus = (bid(n) for n in ("turret", "upper_arm", "forearm", "stylus"))
    yaw_dof = om.index(m).yaw_dof
    L1 = m.body_pos[fore][0]
    L2 = -m.body_pos[stylus][0]
    offset = m.body_ipos[stylus][2]
    params = dict(
        I_base=m.body_inertia[turret][2] + m.dof_armature[yaw_dof],
        m1=m.body_mass[upper], L1=L1, m2=m.body_mass[fore], L2=L2,
        m_tip=m.body_mass[stylus], L_tip=math.hypot(L2, offset),
        tip_offs_deg=-math.degrees(math.atan2(offset, L2)),
    )
    # What (5) leaves out: the links' own inertia beyond a thin rod (tube radius terms) and the
    # stylus's own inertia tensor.  Their yaw share is at most the largest such principal value.
    ignored = 0.0
    for b, L in ((upper, L1), (fore, L2)):
        ignored += max(m.body_inertia[b][0], m.body_inertia[b][1] - m.body_mass[b] * L**2 / 12)
    ignored += max(m.body_inertia[stylus])
    return params, ignored


def test_yaw_inertia_matches_analytic_5(model):
    """MuJoCo's mass matrix vs (5) from the model's own masses and lengths.

    Tolerance: the inertia that (5)'s thin rods and point mass ignore (tube radius terms and
    the stylus's own inertia), summed over bodies -- a bound derived from the model, 4.9e-6
    kg*m^2 for the calibrated model, 0.60 % of the smallest yaw inertia in the joint range.
    """
    params, ignored = _rod_model_parameters(model)
    assert ignored < 1e-5
    worst = 0.0
    for g1 in np.linspace(0, 100, 11):
        for g2 in np.linspace(45, 160, 9):
            truth = omni_sim.yaw_inertia(g1, g2, model=model)
            analytic = om.analytic_yaw_inertia(g1, g2, **params)
            assert abs(analytic - truth) <= ignored, (g1, g2, analytic, truth)
            worst = max(worst, abs(analytic / truth - 1))
    # the comparison is not vacuous: the pose dependence is large against the tolerance
    i_min = omni_sim.yaw_inertia(65, 70, model=model)
    i_max = omni_sim.yaw_inertia(20, 115, model=model)
    assert i_max / i_min > 1.5
    assert worst > 0  # the rod model is an approximation, and we measured how good


def test_yaw_inertia_public_signature():
    a = omni_sim.yaw_inertia(65.0, 90.0)
    b = omni_sim.yaw_inertia(65.0, 90.0, model_path=om.DEFAULT_SCENE)
    assert a == b and 1e-3 < a < 3e-3  # estimate in models/omni/README.md: 1-3e-3 kg*m^2


def test_arm_sags_below_set_points(model):
    """Table 3: the P-held arm sags under gravity; gamma1 always below its set point."""
    for g1, g2 in TABLE1_POSES + TABLE2_POSES:
        a1, a2 = Device(model).equilibrium(g1, g2)
        assert 0.5 < g1 - a1 < 8, (g1, g2, a1)
        # the elbow sags when the forearm is above vertical-down (cos psi > 0)
        if math.cos(math.radians(a1 + g2 - 180)) > 0.1:
            assert a2 < g2, (g1, g2, a2)


def test_equilibrium_is_static(model):
    """Started at the computed equilibrium, the arm does not move."""
    a1, a2 = Device(model).equilibrium(45, 90)
    d = mujoco.MjData(model)
    d.qpos[1:3] = np.radians([a1, a2])
    Device(model).set_arm_control(d, 45, 90)
    for _ in range(500):
        mujoco.mj_step(model, d)
    assert np.degrees(abs(d.qpos[1] - math.radians(a1))) < 1e-6
    assert np.degrees(abs(d.qpos[2] - math.radians(a2))) < 1e-6


def test_pose_out_of_range(model):
    with pytest.raises(UserError, match="outside the joint range"):
        Device(model).equilibrium(120, 90)


def test_model_files_in_their_device_folders():
    """One folder per device: the Omni's files in ``OMNI_DIR`` (the default scene, each
    family's scene, the robot, the stage), the servo pendulum in its own folder; the built-in
    scenes are recognised by their paths there."""
    from bank import servo_truth

    assert om.OMNI_DIR == om.MODELS_DIR / "omni" and omni_sim.OMNI_DIR == om.OMNI_DIR
    assert om.DEFAULT_SCENE == om.OMNI_DIR / "scene.xml" == om.scene_path() == om.model_path()
    for fam in om.FRICTION_FAMILIES:
        path = om.scene_path(fam)
        assert path == om.OMNI_DIR / f"scene_{fam}.xml" == om.model_path(friction=fam)
        assert path.is_file() and om.builtin_family(path) == fam
    assert om.builtin_family(om.DEFAULT_SCENE) == om.DEFAULT_FRICTION
    assert om.builtin_family(om.SERVO_PENDULUM) is None
    for name in ("omni.xml", "stage.xml"):
        assert (om.OMNI_DIR / name).is_file()
    assert om.SERVO_PENDULUM == om.SERVO_PENDULUM_DIR / "servo_pendulum.xml" == servo_truth.model_path()
    assert om.SERVO_PENDULUM_DIR == om.MODELS_DIR / "servo_pendulum" and om.SERVO_PENDULUM.is_file()
    assert not list(om.MODELS_DIR.glob("*.xml")) and not list(om.MODELS_DIR.glob("*.json"))
    # a scene's digest covers its own folder's files only
    assert om.model_digest(om.DEFAULT_SCENE) != om.model_digest(om.SERVO_PENDULUM)


def test_a_flat_path_names_the_device_folder(tmp_path):
    """A built-in file named where it is not (``models/NAME``): the error names its place in
    its device's folder; any other missing file gets the plain error."""
    for name, folder in (("scene.xml", "omni"), ("scene_coulomb.xml", "omni"), ("omni.xml", "omni"),
                         ("servo_pendulum.xml", "servo_pendulum")):
        with pytest.raises(UserError) as err:
            om.load_model(f"models/{name}")
        assert str(err.value) == (f"models/{name}: model file not found (the built-in model files "
                                  f"are in one folder per device: models/{folder}/{name})")
    assert om.model_not_found(tmp_path / "models" / "scene.xml").endswith(
        str(tmp_path / "models" / "omni" / "scene.xml") + ")")
    assert om.model_not_found("models/mine.xml") == "models/mine.xml: model file not found"
    assert om.model_not_found("elsewhere/scene.xml") == "elsewhere/scene.xml: model file not found"


def test_bad_models(tmp_path):
    with pytest.raises(UserError, match="not found"):
        om.load_model(tmp_path / "nope.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(UserError, match="not a valid MJCF"):
        om.load_model(bad)
    nojoint = tmp_path / "nojoint.xml"
    nojoint.write_text('<mujoco><worldbody><body><joint name="yaw"/><geom size="0.1"/>'
                       "</body></worldbody></mujoco>")
    with pytest.raises(UserError, match="shoulder, elbow"):
        om.load_model(nojoint)


def _yaw_under_torque(model, torque, seconds):
    """Yaw angle under an applied torque ``torque(t)``, motor off, arm at home."""
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, 0) if model.nkey else mujoco.mj_resetData(model, d)
    ix = om.index(model)
    theta = []
    for _ in range(int(round(seconds / model.opt.timestep))):
        d.qfrc_applied[ix.yaw_dof] = torque(d.time)
        mujoco.mj_step(model, d)
        theta.append(d.qpos[ix.yaw_qpos])
    return np.array(theta)


def test_yaw_friction_pre_sliding_is_elastic_and_sliding_starts_above_Fs():
    """The LuGre friction of the yaw drive (models/omni/README.md, "Friction").  Loaded slowly from
    rest (speed << vs, so the level is Fs) the bristle state obeys dz/dtheta = 1 - sigma0 z / Fs
    and rests where sigma0 z = tau: theta = -(Fs/sigma0) ln(1 - tau/Fs), about tau/sigma0 for
    small tau (analytic).  Above Fs the drive slides away."""
    m = om.load_model(om.OMNI_DIR / "scene.xml")
    f = Device(m).friction()
    assert f["frictionloss"] == 0 and 0 < f["lugre_Fc"] <= f["lugre_Fs"]
    s0, fs = f["lugre_sigma0"], f["lugre_Fs"]
    for frac in (0.2, 0.5):
        tau = frac * fs
        theta = _yaw_under_torque(m, lambda t: tau * min(t / 8.0, 1.0), 12.0)
        want = -(fs / s0) * math.log(1 - frac)
        assert theta[7999] == pytest.approx(want, rel=0.01), (frac, theta[7999], want)
        # then held: the small oscillation the end of the ramp excites lets LuGre's bristle
        # state ratchet a little further (a known LuGre trait), and the drive comes to rest
        assert np.ptp(theta[-500:]) < 0.01 * want
        assert want <= theta[-1] <= 1.06 * want, (frac, theta[-1], want)
    slide = _yaw_under_torque(m, lambda t: 1.2 * fs, 0.5)
    assert slide[-1] > 0.1  # slides away: 0.1 rad in 0.5 s is far beyond any pre-sliding
