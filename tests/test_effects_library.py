"""The library's drive effects (presliding_friction, stribeck_friction, drive_compliance,
backlash, arm_mass, cogging): each writes what it says into the MJCF, reads it back, compiles
from its XML, keeps the model's size for every value (the replay batches them), works on the
built-in Omni and on another single-joint robot, and its physics agrees with an independent
truth: the LuGre and Stribeck formulas, the two-mass natural frequency, the dead band, the
parallel-axis theorem and the cogging formula."""

import math

import mujoco
import numpy as np
import pytest

from omni_sim import model as om
from discrepancy import effects as fx
from omni_sim.device import Device

NEW = ("presliding_friction", "stribeck_friction", "drive_compliance", "backlash", "arm_mass", "cogging")
COUNT = 2 * math.pi / 15000  # one encoder count [rad] (models/omni/README.md)

#: A single-joint robot that is not the Omni: a pendulum on the hinge ``pivot`` driven by the
#: motor ``servo``, with a sensor and a keyframe naming the joint, and elements already called
#: like the ones the effects add (the new elements must not collide with them).
PENDULUM = """
<mujoco model="pendulum">
  <compiler angle="radian"/>
  <option timestep="0.001" integrator="implicitfast"/>
  <worldbody>
    <body name="pivot_rotor" pos="0 0.5 1"><geom type="sphere" size="0.02" mass="0.1"/></body>
    <body name="arm" pos="0 0 1">
      <joint name="pivot" type="hinge" axis="0 1 0" damping="0.05" armature="2e-4"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02" mass="0.5"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="servo" joint="pivot" gear="2" ctrlrange="-1 1"/>
    <motor name="pivot_cogging" joint="pivot" gear="1"/>
  </actuator>
  <sensor><jointpos name="angle" joint="pivot"/></sensor>
  <keyframe><key name="start" qpos="0.3" ctrl="0 0"/></keyframe>
</mujoco>
"""
PENDULUM_TARGET = om.Target("pivot", "servo")


def _omni(scene="scene.xml"):
    return mujoco.MjSpec.from_file(str(om.OMNI_DIR / scene))


def _pendulum():
    return mujoco.MjSpec.from_string(PENDULUM)


def _compiled_arrays(m):
    return {k: getattr(m, k).copy() for k in (
        "actuator_gainprm", "actuator_biasprm", "actuator_dynprm", "actuator_trnid", "actuator_actnum",
        "dof_armature", "dof_damping", "jnt_stiffness", "tendon_stiffness", "tendon_damping",
        "tendon_range", "tendon_limited", "tendon_lengthspring", "body_mass", "body_inertia", "key_qpos")}


@pytest.mark.parametrize("scene,target", [("scene.xml", om.OMNI), ("scene_coulomb.xml", om.OMNI),
                                          ("pendulum", PENDULUM_TARGET)])
def test_write_read_xml_and_sizes(scene, target):
    """write -> read gives the values back; the patched MJCF compiles from its XML into the same
    arrays; two values of one effect give models of one size (the replay batches them)."""
    spec = _pendulum() if scene == "pendulum" else _omni(scene)
    names = fx.applicable(spec, target)
    assert ("arm_mass" in names) == (scene != "pendulum")
    for name in NEW:
        if name not in names:
            continue
        eff = fx.get(name)
        x0 = fx.nominal_values(eff, spec, target)
        xs = [eff.clip(x0 + 3 * eff.scales()), eff.clip(x0 + 7 * eff.scales())]
        sizes = []
        for x in xs:
            s2 = fx.apply(spec, [(eff, x)], target)
            np.testing.assert_allclose(eff.read(s2, target), x, rtol=1e-12, err_msg=name)
            m = s2.compile()
            mx = mujoco.MjModel.from_xml_string(s2.to_xml())
            for k, v in _compiled_arrays(m).items():
                np.testing.assert_allclose(getattr(mx, k), v, rtol=1e-5, atol=1e-12, err_msg=f"{name} {k}")
            sizes.append((m.nq, m.nv, m.na, m.nu, m.nactuator, m.ntendon, m.nbody))
            if scene != "pendulum":
                om.index(mx)  # the contract holds: yaw_motor on yaw, passive actuators last
            # the controlled actuator still drives the target joint, with control index = id
            a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, target.actuator)
            assert m.actuator_trnid[a, 0] == mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, target.joint)
            assert m.actuator_ctrladr[a] == a
        assert sizes[0] == sizes[1], (name, sizes)
        # applying twice (e.g. a second round) changes values, not the structure
        s3 = fx.apply(fx.apply(spec, [(eff, xs[0])], target), [(eff, xs[1])], target)
        m3 = s3.compile()
        assert (m3.nq, m3.nv, m3.na, m3.nu, m3.nactuator, m3.ntendon, m3.nbody) == sizes[1]


def test_pendulum_names_do_not_collide():
    """The pendulum already has a body ``pivot_rotor`` and an actuator ``pivot_cogging`` (not a
    cogging element): the effects add their own elements under other names and find them."""
    spec = _pendulum()
    t = PENDULUM_TARGET
    s2 = fx.apply(spec, [(fx.get("cogging"), [0.01, 0.2]), (fx.get("drive_compliance"), [5.0, 0.0, 2e-4])], t)
    m = s2.compile()
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(m.nactuator)]
    assert names == ["servo", "pivot_cogging", "pivot_cogging_2"]
    assert m.actuator_gear[1, 0] == 1 and m.actuator_biastype[1] == 0  # the user's motor untouched
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pivot_rotor_2") >= 0
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "pivot_output_2") >= 0
    np.testing.assert_allclose(fx.get("cogging").read(s2, t), [0.01, 0.2])
    np.testing.assert_allclose(fx.get("drive_compliance").read(s2, t), [5.0, 0.0, 2e-4])
    # the keyframe starts the rotor where the pendulum is (cable unstretched)
    ko = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "pivot_output_2")]
    kr = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "pivot")]
    assert m.key_qpos[0, ko] == m.key_qpos[0, kr] == 0.3


def test_added_dcmotor_equals_the_mjcf_element():
    """An added LuGre / cogging element compiles to the same arrays as MuJoCo's own
    ``<dcmotor input="none" resistance="1" lugre=... cogging=...>`` (the MJCF semantics)."""
    spec = _omni("scene_coulomb.xml")
    s2 = fx.apply(spec, [(fx.get("presliding_friction"), [3.0, 0.01, 0.02, 0.4]),
                         (fx.get("cogging"), [0.002, 0.7])])
    m = s2.compile()
    xml = (om.OMNI_DIR / "scene_coulomb.xml").read_text().replace(
        '</mujoco>',
        '<actuator><dcmotor name="p" joint="yaw" input="none" resistance="1" lugre="3 0 0.01 0.02 0.4"/>'
        f'<dcmotor name="c" joint="yaw" input="none" resistance="1" cogging="0.002 {fx.COGGING_PERIODS} 0.7"/>'
        '</actuator></mujoco>')
    assert xml.count("<dcmotor") == 2
    for inc in ("omni.xml", "stage.xml"):
        xml = xml.replace(f'file="{inc}"', f'file="{om.OMNI_DIR / inc}"')
    ref = mujoco.MjModel.from_xml_string(xml)
    for k in ("actuator_gainprm", "actuator_biasprm", "actuator_dynprm", "actuator_gaintype",
              "actuator_biastype", "actuator_dyntype", "actuator_actnum", "actuator_ctrladr"):
        np.testing.assert_array_equal(getattr(m, k), getattr(ref, k), err_msg=k)
    assert m.nu == ref.nu == 3 and m.na == ref.na == 1


# --- physics ------------------------------------------------------------------------------
def _yaw_under_torque(m, torque, seconds, dof=None):
    """(yaw angle, output angle or None) under an applied yaw torque ``torque(t)``, motor off,
    arm at home."""
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    ix = om.index(m)
    dof = ix.yaw_dof if dof is None else dof
    th = []
    for _ in range(int(round(seconds / m.opt.timestep))):
        d.qfrc_applied[dof] = torque(d.time)
        mujoco.mj_step(m, d)
        th.append(d.qpos[ix.yaw_qpos])
    return np.array(th)


def _without_drive_friction(spec):
    """The coulomb scene's yaw without its frictionloss (viscous damping kept)."""
    spec.joint("yaw").frictionloss = 0.0
    return spec


@pytest.mark.parametrize("scene", ["scene.xml", "scene_coulomb.xml"])
def test_presliding_quasi_static_deflection(scene):
    """Loaded slowly from rest (speed << vs: level Fs), the LuGre bristle rests where
    sigma0 z = tau: theta = -(Fs/sigma0) ln(1 - tau/Fs) (analytic); above Fs the drive slides.
    The default scene's yaw_friction is changed in place; the coulomb scene gets one added."""
    spec = _omni(scene)
    if scene == "scene_coulomb.xml":
        _without_drive_friction(spec)
    s0, fc, fs, vs = 5.0, 0.01, 0.025, 0.5
    m = fx.compile_with(spec, [(fx.get("presliding_friction"), [s0, fc, fs, vs])])
    assert m.nactuator == 4  # one LuGre element on the yaw in both scenes
    for frac in (0.2, 0.5):
        tau = frac * fs
        th = _yaw_under_torque(m, lambda t: tau * min(t / 8.0, 1.0), 8.0)
        want = -(fs / s0) * math.log(1 - frac)
        assert th[-1] == pytest.approx(want, rel=0.02), (frac, th[-1], want)
    slide = _yaw_under_torque(m, lambda t: 1.2 * fs, 0.5)
    assert slide[-1] > 0.1  # 0.1 rad in 0.5 s: far beyond any pre-sliding range (3 mrad here)


def _stribeck_model(fc, fs, vs):
    spec = _without_drive_friction(_omni("scene_coulomb.xml"))
    return fx.compile_with(spec, [(fx.get("stribeck_friction"), [fc, fs, vs])])


def test_stribeck_steady_sliding_curve():
    """At a constant speed the element's torque settles at -(Fc + (Fs - Fc) exp(-(v/vs)^2))
    sign(v) (the Stribeck curve); the yaw is driven at each speed by setting its velocity."""
    fc, fs, vs = 0.01, 0.03, 0.2
    m = _stribeck_model(fc, fs, vs)
    ix = om.index(m)
    a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "yaw_stribeck")
    d = mujoco.MjData(m)
    for v in (0.05, 0.15, 0.3, 0.8, -0.3):
        mujoco.mj_resetDataKeyframe(m, d, 0)
        for _ in range(300):
            d.qvel[ix.yaw_dof] = v
            mujoco.mj_step(m, d)
        want = -(fc + (fs - fc) * math.exp(-(v / vs) ** 2)) * math.copysign(1, v)
        assert d.actuator_force[a] == pytest.approx(want, rel=1e-3), (v, d.actuator_force[a], want)


def test_stribeck_breaks_away_near_fs_without_presliding():
    """A slow torque ramp: below 0.95 Fs the yaw moves less than one encoder count (no
    pre-sliding range to see); it leaves the count (breaks away) between 0.95 Fs and 1.05 Fs
    and then slides away."""
    fc, fs, vs = 0.01, 0.03, 0.2
    m = _stribeck_model(fc, fs, vs)
    rate = fs / 4.0  # [N*m/s]: Fs reached after 4 s
    th = _yaw_under_torque(m, lambda t: rate * t, 5.0)
    tau = rate * (np.arange(len(th)) + 1) * m.opt.timestep
    assert np.max(np.abs(th[tau < 0.95 * fs])) < COUNT
    moved = tau[np.argmax(np.abs(th) > COUNT)]
    assert 0.95 * fs < moved < 1.05 * fs, moved / fs
    assert abs(th[-1]) > 0.05  # sliding: 0.05 rad by the end


def _two_mass_ids(m):
    jr = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "yaw")
    jo = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "yaw_output")
    return jr, jo


def test_drive_compliance_two_mass_frequency():
    """Motor off, no damping: the linearised patched Omni (mjd_transitionFD) has the two-mass
    mode omega^2 = k (1/J_rotor + 1/J_out), J_out the turret+arm inertia from MuJoCo's mass
    matrix; compared through the integrator's discrete map (symplectic Euler: 2 asin(w dt/2))."""
    spec = _omni("scene_coulomb.xml")
    _without_drive_friction(spec)
    spec.joint("yaw").damping[0] = 0.0
    k, jrot = 5.0, 1e-4
    m = fx.compile_with(spec, [(fx.get("drive_compliance"), [k, 0.0, jrot])])
    jr, jo = _two_mass_ids(m)
    assert m.jnt_bodyid[jr] != m.jnt_bodyid[jo] and m.dof_armature[m.jnt_dofadr[jr]] == jrot
    assert m.dof_armature[m.jnt_dofadr[jo]] == 0 and m.dof_damping[m.jnt_dofadr[jr]] == 0
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    j_out = M[m.jnt_dofadr[jo], m.jnt_dofadr[jo]]
    assert M[m.jnt_dofadr[jr], m.jnt_dofadr[jr]] == pytest.approx(jrot, rel=1e-6)
    w = math.sqrt(k * (1 / jrot + 1 / j_out))
    dt = m.opt.timestep
    n = 2 * m.nv + m.na
    A = np.zeros((n, n))
    mujoco.mjd_transitionFD(m, d, 1e-7, True, A, None, None, None)
    s = np.log(np.linalg.eigvals(A).astype(complex)) / dt
    got = np.max(np.abs(s.imag))
    assert got == pytest.approx(2 * math.asin(w * dt / 2) / dt, rel=2e-3), (got, w)
    # and the continuous value within the integrator's known error (w dt)^2/24 = 0.2 %
    assert got == pytest.approx(w, rel=5e-3)


def test_backlash_rotor_moves_freely_inside_the_band():
    """A torque on the rotor (motor side) turns it through the band with the turret at rest;
    only beyond +-b is torque transmitted and the turret moves."""
    b = 3 * COUNT
    spec = _without_drive_friction(_omni("scene_coulomb.xml"))
    m = fx.compile_with(spec, [(fx.get("backlash"), [b])])
    jr, jo = _two_mass_ids(m)
    qr, qo = m.jnt_qposadr[jr], m.jnt_qposadr[jo]
    d = mujoco.MjData(m)
    for sign in (1, -1):
        mujoco.mj_resetDataKeyframe(m, d, 0)
        rot, out = [], []
        for _ in range(400):
            d.qfrc_applied[m.jnt_dofadr[jr]] = sign * 0.005
            mujoco.mj_step(m, d)
            rot.append(d.qpos[qr])
            out.append(d.qpos[qo])
        rot, out = np.array(rot) * sign, np.array(out) * sign
        inside = rot < 0.98 * b
        assert inside[:5].all() and not inside.all()
        assert np.max(np.abs(out[inside])) == 0.0  # the turret did not move at all
        assert out[-1] > 10 * COUNT  # beyond the band the turret is driven
        assert np.max(rot - out) < b + 0.3 * COUNT  # and the rotor leads it by ~b


def _yaw_inertia(m, g1, g2):
    d = mujoco.MjData(m)
    ix = om.index(m)
    d.qpos[ix.shoulder_qpos], d.qpos[ix.elbow_qpos] = math.radians(g1), math.radians(g2)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    return M[ix.yaw_dof, ix.yaw_dof], d


def test_arm_mass_changes_the_yaw_inertia_by_the_parallel_axis_theorem():
    """The yaw inertia (MuJoCo's mass matrix) changes by sum over the two links of
    dm r^2 + (f - 1) e_z' I_c e_z (the parallel-axis theorem: r the CoM's distance from the yaw
    axis, I_c the link's own inertia, scaled by f = m_new/m), different at each pose, so no
    armature (the same at every pose) reproduces both."""
    spec = _omni()
    m0 = spec.compile()
    new = np.array([0.09, 0.075])
    m1 = fx.compile_with(spec, [(fx.get("arm_mass"), new)])
    old = fx.get("arm_mass").read(spec)
    dI = []
    for g1, g2 in ((65.0, 90.0), (25.0, 115.0)):
        i0, d = _yaw_inertia(m0, g1, g2)
        i1, _ = _yaw_inertia(m1, g1, g2)
        want = 0.0
        axis = np.array([0.0, 0.0, 1.0])
        for name, mo, mn in zip(fx.ARM_BODIES, old, new):
            b = mujoco.mj_name2id(m0, mujoco.mjtObj.mjOBJ_BODY, name)
            r = d.xipos[b] - d.xanchor[om.index(m0).yaw_qpos]
            r_perp = r - axis * (r @ axis)
            R = d.ximat[b].reshape(3, 3)
            own = axis @ R @ np.diag(m0.body_inertia[b]) @ R.T @ axis
            want += (mn - mo) * (r_perp @ r_perp) + (mn / mo - 1) * own
        assert i1 - i0 == pytest.approx(want, rel=1e-9), (g1, g2, i1 - i0, want)
        dI.append(i1 - i0)
    assert dI[0] > 0 and dI[1] > 1.5 * dI[0]  # the stretched pose gains more than the folded one


def _added_force(spec, name, values, target, field, qs):
    """The joint force ``field`` (``qfrc_actuator``, ``qfrc_spring``) that effect ``name`` at
    ``values`` adds to ``spec``'s target joint, at rest at each angle of ``qs``."""
    m = fx.compile_with(spec, [(fx.get(name), values)], target)
    m0 = spec.compile()
    j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, target.joint)
    d, d0 = mujoco.MjData(m), mujoco.MjData(m0)
    out = []
    for q in qs:
        d.qpos[m.jnt_qposadr[j]] = d0.qpos[m0.jnt_qposadr[j]] = q
        mujoco.mj_forward(m, d)
        mujoco.mj_forward(m0, d0)
        dof = m.jnt_dofadr[j]
        out.append(getattr(d, field)[dof] - getattr(d0, field)[dof])
    return out


@pytest.mark.parametrize("scene,target", [("scene_coulomb.xml", om.OMNI), ("pendulum", PENDULUM_TARGET)])
def test_cogging_torque_formula(scene, target):
    """The torque on the joint is a sin(n q + phi) at any angle (n = COGGING_PERIODS)."""
    spec = _pendulum() if scene == "pendulum" else _omni(scene)
    a, ph = 0.004, 0.7
    qs = np.linspace(-0.9, 0.9, 13)
    for q, tau in zip(qs, _added_force(spec, "cogging", [a, ph], target, "qfrc_actuator", qs)):
        assert tau == pytest.approx(a * math.sin(fx.COGGING_PERIODS * q + ph), abs=1e-12), q


@pytest.mark.parametrize("scene,target", [("scene.xml", om.OMNI), ("pendulum", PENDULUM_TARGET)])
def test_joint_stiffness_is_a_preloaded_spring(scene, target):
    """joint_stiffness's torque on the joint is Hooke's law about its rest angle, -k (q - rest),
    at any angle, and reads back what it wrote (rest 0: the plain spring)."""
    spec = _pendulum() if scene == "pendulum" else _omni(scene)
    qs = np.linspace(-0.9, 0.9, 7)
    for k, rest in ((0.6, 0.25), (0.06, 0.0), (0.2, -0.4)):
        for q, tau in zip(qs, _added_force(spec, "joint_stiffness", [k, rest], target, "qfrc_spring", qs)):
            assert tau == pytest.approx(-k * (q - rest), abs=1e-12), (k, rest, q)
        s2 = spec.copy()
        fx.get("joint_stiffness").write(s2, [k, rest], target)
        assert list(fx.get("joint_stiffness").read(s2, target)) == [k, rest]


def test_separating_experiments_name_library_effects():
    for pair, text in fx.SEPARATING_EXPERIMENTS.items():
        assert len(pair) == 2 and set(pair) <= set(fx.NAMES) and len(text) > 40
    for a, b in (("presliding_friction", "coulomb_friction"), ("stribeck_friction", "coulomb_friction"),
                 ("drive_compliance", "armature"), ("drive_compliance", "actuator_lag"),
                 ("backlash", "coulomb_friction"), ("arm_mass", "armature"), ("cogging", "gravity_tilt"),
                 ("cogging", "joint_stiffness")):
        assert frozenset({a, b}) in fx.SEPARATING_EXPERIMENTS


@pytest.mark.parametrize("name,x", [("drive_compliance", [10.0, 0.001, 1e-4]), ("backlash", [3 * COUNT])])
@pytest.mark.parametrize("scene", ["scene.xml", "scene_coulomb.xml"])
def test_two_mass_drive_starts_at_rest(scene, name, x):
    """A P-held run of the patched Omni at its set point stays there: the device starts the
    rotor and the turret at the same angle (cable unstretched), so there is no start
    transient; and a step of 0.1 rad still reaches the set point."""
    from omni_sim import experiments as ex

    m = fx.compile_with(_omni(scene), [(fx.get(name), x)])
    r = np.full(1000, 0.1)
    rest = ex.simulate(Device(m), [ex.Experiment("rest", "step", 65.0, 90.0, r, 0.0, 0.0, theta0_rad=0.1)], jobs=1)[0]
    assert np.max(np.abs(rest.theta - 0.1)) < 1e-9
    step = ex.simulate(Device(m), [ex.Experiment("step", "step", 65.0, 90.0, r, 0.0, 0.0, theta0_rad=0.0)], jobs=1)[0]
    assert abs(step.theta[-1] - 0.1) < 0.02


def test_bounds_fit_the_nominal_model():
    """The library's bounds are the Omni's: on the default scene every effect is unchanged;
    a geared servo's reflected rotor (0.0119 kg*m^2, above the 0.01 bound) gets its bound moved
    to 3x its value, so the fit starts at the nominal model instead of a clipped one."""
    import mujoco

    from omni_sim import model as om
    from discrepancy import effects as fx

    omni = mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))
    assert all(fx.for_model(e, omni, om.OMNI) is e for e in fx.LIBRARY if e.applies(omni, om.OMNI))
    servo = mujoco.MjSpec.from_string(
        '<mujoco><worldbody><body><joint name="h" axis="0 1 0" armature="0.0119"/>'
        '<geom size="0.02" mass="1"/></body></worldbody><actuator><motor name="m" joint="h"/>'
        '</actuator></mujoco>')
    target = om.Target("h", "m")
    b = fx.ModelBuilder(servo, target)
    arm = b.effect("armature")
    assert arm.params[0].upper == pytest.approx(3 * 0.0119)
    assert b.nominal_values(arm)[0] == pytest.approx(0.0119)  # not clipped to 0.01
    assert b.effect("coulomb_friction") is fx.get("coulomb_friction")
