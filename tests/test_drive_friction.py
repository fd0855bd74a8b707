"""The drive's friction laws the engine applies (omni_sim.device.DriveFriction): friction set by
the torque the gearbox transmits (``load_friction``) and direction-dependent Coulomb friction
(``friction_asymmetry``), against closed-form steady states of a damped hinge."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from identification.errors import UserError
from omni_sim import model as om
from omni_sim.device import Device, Engine, run_p_loop

TARGET = om.Target("hinge", "drive")
FC, B = 0.05, 0.02  # Coulomb level [N*m], viscous damping [N*m*s/rad]


def _model(load=None, asym=None, sensor=True, external=0.0, integrator="implicitfast"):
    custom = ""
    if load is not None:
        custom += f'<numeric name="load_friction" data="{load[0]} {load[1]}"/>'
    if asym is not None:
        custom += f'<numeric name="friction_asymmetry" data="{asym}"/>'
    sens = '<sensor><actuatorfrc actuator="drive"/></sensor>' if sensor else ""
    ext = (f'<general name="load" joint="hinge" gainprm="0" biastype="affine" biasprm="{external} 0 0" '
           'ctrllimited="false"/>') if external else ""
    xml = f"""<mujoco><option timestep="0.001" gravity="0 0 0" integrator="{integrator}"/>
    <worldbody><body><joint name="hinge" axis="0 0 1" damping="{B}" frictionloss="{FC}"/>
    <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody>
    <actuator><motor name="drive" joint="hinge" gear="2" ctrllimited="true" ctrlrange="-1 1"/>{ext}</actuator>
    {sens}<custom>{custom}</custom></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml.replace("<custom></custom>", ""))


def _steady_velocity(model, v, periods=12000):  # 24 time constants J/b = 0.5 s
    eng = Engine([Device(model, 0.001, TARGET)], [0.0], [None])
    for _ in range(periods):
        eng.apply([v])
    return float(eng.yaw_velocity()[0])


@pytest.mark.parametrize("v", [0.4, -0.4])
def test_load_friction_when_the_motor_drives(v):
    """Motor torque tau = 2 v drives the joint: friction Fc + mu_drive |tau|, so the steady
    velocity is (|tau| (1 - mu_drive) - Fc) / b, signed.  MuJoCo's frictionloss is a soft
    constraint: steady sliding at 1e-6 relative (measured 1e-9 here)."""
    tau = 2 * v
    w = _steady_velocity(_model(load=(0.25, 0.6)), v)
    want = np.sign(tau) * (abs(tau) * (1 - 0.25) - FC) / B
    assert w == pytest.approx(want, rel=1e-6)
    assert _steady_velocity(_model(), v) == pytest.approx(np.sign(tau) * (abs(tau) - FC) / B, rel=1e-6)


def test_load_friction_when_the_load_back_drives():
    """A constant external torque 0.9 N*m drives the joint against a motor holding back with
    tau = -0.4 N*m: the load back-drives the motor, friction Fc + mu_back |tau|; steady
    velocity (0.9 - 0.4 - Fc - mu_back 0.4) / b.  With mu_back = 2 the friction (0.85) plus
    the motor (0.4) exceed the load: the gearbox self-locks, and the joint creeps as MuJoCo's
    soft frictionloss creeps under a stuck load: as fast as a plain joint whose frictionloss is
    that level (0.85 N*m), 100x slower than with mu_back = 0."""
    w = _steady_velocity(_model(load=(0.25, 0.6), external=0.9), -0.2)
    assert w == pytest.approx((0.9 - 0.4 - FC - 0.6 * 0.4) / B, rel=1e-6)
    locked = _steady_velocity(_model(load=(0.25, 2.0), external=0.9), -0.2)
    plain = _model(external=0.9)
    plain.dof_frictionloss[0] = FC + 2.0 * 0.4
    assert locked == pytest.approx(_steady_velocity(plain, -0.2), rel=1e-6)
    assert 0 < locked < 0.01 * _steady_velocity(_model(load=(0.25, 0.0), external=0.9), -0.2)


def test_asymmetric_coulomb_friction():
    """Levels Fc + a moving positive, Fc - a moving negative (a = 0.02 N*m)."""
    m = _model(asym=0.02)
    assert _steady_velocity(m, 0.4) == pytest.approx((0.8 - FC - 0.02) / B, rel=1e-6)
    assert _steady_velocity(m, -0.4) == pytest.approx(-(0.8 - FC + 0.02) / B, rel=1e-6)


def test_zero_coefficients_are_the_plain_model_and_the_paths_agree():
    """mu = 0, a = 0: the law writes the model's own frictionloss at every period, so the
    trajectory is the plain model's bit for bit (the same mj_step arithmetic); with the law on,
    one-row (mj_step) and batch (rollout) engines agree to the last bits (the load law's blend
    carries last-bit differences of their velocities into the level: 3.3e-16 rad measured)."""
    t = np.arange(1500) * 0.001
    r = np.where(t % 0.5 < 0.25, 0.3, -0.3)[None, :]
    plain = run_p_loop(Engine([Device(_model(), 0.001, TARGET)], [0.0], [None]), r, 3.0)["theta"]
    zero = run_p_loop(Engine([Device(_model(load=(0, 0), asym=0.0), 0.001, TARGET)], [0.0], [None]),
                      r, 3.0)["theta"]
    assert np.array_equal(plain, zero)
    dev = Device(_model(load=(0.25, 0.6), asym=0.01), 0.001, TARGET)
    one = run_p_loop(Engine([dev], [0.0], [None]), r, 3.0)["theta"]
    batch = run_p_loop(Engine([dev, dev], [0.0, 0.0], [None, None], nthread=2), np.vstack([r, r]), 3.0)["theta"]
    assert np.max(np.abs(batch - one)) < 1e-12 and np.array_equal(batch[0], batch[1])
    assert np.max(np.abs(one - plain)) > 1e-3  # and the law changes the trajectory
    assert dev.model.dof_frictionloss[0] == FC  # the device's own model is left as it was


def test_load_friction_needs_its_sensor_and_sane_values():
    with pytest.raises(UserError, match="actuatorfrc"):
        Device(_model(load=(0.2, 0.5), sensor=False), 0.001, TARGET)
    with pytest.raises(UserError, match="two coefficients"):
        Device(_model(load=(-0.2, 0.5)), 0.001, TARGET)


def test_a_batch_may_mix_rows_with_and_without_the_laws():
    """A candidate model without the laws batched with one that has them (same sizes: the
    asymmetry needs no sensor) keeps its own friction: each row equals its one-row engine."""
    t = np.arange(800) * 0.001
    r = np.where(t % 0.4 < 0.2, 0.3, -0.3)[None, :]
    plain, law = Device(_model(sensor=False), 0.001, TARGET), Device(_model(asym=0.02, sensor=False), 0.001, TARGET)
    both = run_p_loop(Engine([plain, law], [0.0, 0.0], [None, None], nthread=1), np.vstack([r, r]), 3.0)["theta"]
    for b, dev in enumerate((plain, law)):
        one = run_p_loop(Engine([dev], [0.0], [None]), r, 3.0)["theta"]
        assert np.array_equal(both[b], one[0])


def test_a_law_a_user_writes(monkeypatch):
    """A drive law registered by a user (``register_drive_law``) is declared in MJCF like the
    library's: a viscous-like friction ``c |w|`` added to the Coulomb level.  Steady sliding
    under motor torque tau then solves tau - Fc - c w - b w = 0 (w > 0): w = (tau - Fc) / (b + c),
    against MuJoCo's soft frictionloss at 1e-6 relative, as above; a bad value is refused
    with the law's own message; the registry keeps its order and refuses a second law of a
    name it holds."""
    from omni_sim import device as dv

    law = dv.DriveLaw("speed_friction", ("c",), lambda v, w, tau: v[:, 0] * np.abs(w),
                      lambda v: None if len(v) == 1 and v[0] >= 0 else "must hold one c >= 0 [N*m*s/rad]")
    registry = dict(dv.DRIVE_LAWS)  # the registry's room (device.laws) and its name in the package
    monkeypatch.setattr(dv.laws, "DRIVE_LAWS", registry)
    monkeypatch.setattr(dv, "DRIVE_LAWS", registry)
    dv.register_drive_law(law)
    assert list(dv.DRIVE_LAWS) == [dv.FRICTION_ASYMMETRY, dv.LOAD_FRICTION, dv.FRICTION_FAMILY, "speed_friction"]
    with pytest.raises(ValueError, match="exists already"):
        dv.register_drive_law(law)

    base = _model()
    xml = f"""<mujoco><option timestep="0.001" gravity="0 0 0"/>
    <worldbody><body><joint name="hinge" axis="0 0 1" damping="{B}" frictionloss="{FC}"/>
    <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody>
    <actuator><motor name="drive" joint="hinge" gear="2" ctrllimited="true" ctrlrange="-1 1"/></actuator>
    <custom><numeric name="speed_friction" data="{{c}}"/></custom></mujoco>"""
    c = 0.03
    w = _steady_velocity(mujoco.MjModel.from_xml_string(xml.format(c=c)), 0.4)
    assert w == pytest.approx((0.8 - FC) / (B + c), rel=1e-6)
    assert _steady_velocity(base, 0.4) == pytest.approx((0.8 - FC) / B, rel=1e-6)
    with pytest.raises(UserError, match="speed_friction.*must hold one c >= 0"):
        Device(mujoco.MjModel.from_xml_string(xml.format(c=-1)), 0.001, TARGET)


def test_load_friction_reads_the_motors_net_torque_with_a_back_emf():
    """``load_friction``'s optional third entry b_emf takes the back-EMF out of the transmitted
    torque: F = mu |tau - b_emf w| (the motor's net torque kt i = kt/R u - kt^2/R w of a
    voltage-driven servo whose back-EMF the model writes as damping); two entries read b_emf 0."""
    from omni_sim.device import DRIVE_LAWS, LOAD_FRICTION
    law = DRIVE_LAWS[LOAD_FRICTION]
    w, tau = np.array([2.0, -2.0, 3.0]), np.array([1.0, -1.0, 0.5])
    v = np.array([[0.2, 0.2, 0.36]] * 3)  # equal coefficients: the blend plays no part
    np.testing.assert_allclose(law.term(v, w, tau), 0.2 * np.abs(tau - 0.36 * w), rtol=0, atol=1e-15)
    np.testing.assert_allclose(law.term(v[:, :2], w, tau), 0.2 * np.abs(tau), rtol=0, atol=1e-15)
    assert law.check(np.array([0.1, 0.2])) is None and law.check(np.array([0.1, 0.2, 0.3])) is None
    assert law.check(np.array([0.1, 0.2, -0.3])) and law.check(np.array([0.1, 0.2, 0.3, 0.4]))
