"""``load_friction_smooth``: the load-dependent friction behind a smooth sign (no stick), applied
by the engine (one row, a batch, torque off) and by the runtime in plain MuJoCo.

The reference is a plain ``mujoco.mj_step`` loop written here from the law's equation
(:data:`omni_sim.device.LOAD_FRICTION_SMOOTH`'s docstring): at each control period's start,
``tau = gear * (the actuator force of the last physics step) - b_emf w``,
``L = (mu_drive if tau w > 0 else mu_back) |tau|``, the joint force ``-L tanh(w / w_s)``
applied linearly implicitly (the slope ``L (1 - tanh^2) / w_s`` added to the joint's damping,
``-L tanh + slope w`` to ``qfrc_applied``).
"""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np
import pytest

from identification.errors import UserError
from omni_sim import model as om
from omni_sim import runtime
from omni_sim.device import Device, Engine, run_p_loop
from omni_sim.device.laws import smooth_load_force

SERVO = om.Target("pivot", "servo")
#: mu_drive, mu_back, b_emf, w_s: the user's pendulum's law (0.2 both ways, w_s 0.02 rad/s) with
#: the servo's back-EMF, and an asymmetric one
LAWS = [(0.2, 0.2, 0.36, 0.02), (0.1, 0.4, 0.36, 0.05)]


def _servo(law=None, sensor=True) -> mujoco.MjModel:
    """The geared-servo pendulum (models/servo_pendulum/) with ``law`` as its smooth load law
    (its load_friction numeric left at 0 0)."""
    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    if law is not None:
        spec.add_numeric(name="load_friction_smooth", data=[float(x) for x in law])
    if not sensor:
        spec.delete(spec.sensors[0])
    return spec.compile()


def _runs(n: int) -> list[tuple[float, np.ndarray, float]]:
    t = np.arange(n) * 1e-3
    return [(0.0, np.where(t % 0.5 < 0.25, 0.4, -0.2), 30.0), (0.3, 0.3 * np.sin(2 * np.pi * 2 * t), 30.0),
            (-0.1, np.full(n, 0.6), 30.0)]


def _reference(model: mujoco.MjModel, law, theta0: float, r: np.ndarray, kp: float) -> np.ndarray:
    """The P loop with the law, in plain MuJoCo and plain Python floats (one physics step per
    1 ms period: the servo pendulum's timestep)."""
    m = copy.deepcopy(model)
    d = mujoco.MjData(m)
    j, a = m.joint("pivot"), m.actuator("servo").id
    q, dof = int(j.qposadr[0]), int(j.dofadr[0])
    gear, limit, base = float(m.actuator_gear[a, 0]), float(m.actuator_ctrlrange[a, 1]), float(m.dof_damping[dof])
    mu_d, mu_b, b_emf, w_s = law
    d.qpos[q] = theta0
    mujoco.mj_forward(m, d)
    theta, force = np.empty(len(r)), 0.0
    for k in range(len(r)):
        theta[k] = d.qpos[q]
        d.ctrl[a] = min(max(kp * (r[k] - theta[k]), -limit), limit)
        w = float(d.qvel[dof])
        tau = gear * force - b_emf * w
        level = (mu_d if tau * w > 0 else mu_b) * abs(tau)
        th = math.tanh(w / w_s)
        slope = level * (1.0 - th * th) / w_s
        m.dof_damping[dof] = base + slope
        d.qfrc_applied[dof] = -level * th + slope * w
        mujoco.mj_step(m, d)
        force = float(d.actuator_force[a])
    return theta


def _engine(model, runs, batch=True) -> np.ndarray:
    dev = Device(model, 1e-3, SERVO)
    if not batch:
        return np.vstack([run_p_loop(Engine([dev], [th0], [None]), r[None], kp)["theta"] for th0, r, kp in runs])
    return run_p_loop(Engine([dev] * len(runs), [th0 for th0, _, _ in runs], [None] * len(runs), nthread=2),
                      np.vstack([r for _, r, _ in runs]), np.array([kp for *_, kp in runs]))["theta"]


def test_the_law_and_its_slope():
    """The force is -mu |tau - b_emf w| tanh(w / w_s) with mu by the quadrant; the slope is
    minus its derivative in w at fixed transmitted torque (central differences)."""
    v = np.array([[0.2, 0.5, 0.3, 0.05]] * 4)
    w = np.array([0.01, -0.02, 0.3, -0.1])
    tau = np.array([1.0, 1.0, -0.5, -2.0])
    f, slope = smooth_load_force(v, w, tau)
    net = tau - 0.3 * w
    mu = np.where(net * w > 0, 0.2, 0.5)
    assert np.allclose(f, -mu * np.abs(net) * np.tanh(w / 0.05), rtol=0, atol=1e-15)
    # at fixed net torque (the slope's definition): h = 1e-7 rad/s, truncation ~1e-9 relative
    h = 1e-7
    fp = -mu * np.abs(net) * np.tanh((w + h) / 0.05)
    fm = -mu * np.abs(net) * np.tanh((w - h) / 0.05)
    assert np.allclose(slope, -(fp - fm) / (2 * h), rtol=1e-6)


@pytest.mark.parametrize("law", LAWS)
def test_the_engine_applies_the_law(law):
    """One row and a batch of three against the plain loop written from the equation, to
    1e-9 rad (np.tanh and math.tanh may differ in the last bit, and a stick of the joint's
    own frictionloss can grow such a bit); without the law the runs are another model."""
    model = _servo(law)
    runs = _runs(1500)
    ref = np.vstack([_reference(model, law, th0, r, kp) for th0, r, kp in runs])
    assert np.max(np.abs(_engine(model, runs, batch=False) - ref)) < 1e-9
    assert np.max(np.abs(_engine(model, runs) - ref)) < 1e-9
    assert np.max(np.abs(_engine(_servo(), runs) - ref)) > 1e-3


def test_a_batch_mixes_rows_with_and_without_the_law():
    """Rows of different models in one batch (a fit's candidates): each row as it runs alone."""
    models = [_servo(LAWS[0]), _servo(), _servo(LAWS[1])]
    runs = _runs(800)
    devs = [Device(m, 1e-3, SERVO) for m in models]
    batch = run_p_loop(Engine(devs, [th0 for th0, _, _ in runs], [None] * 3, nthread=2),
                       np.vstack([r for _, r, _ in runs]), np.array([kp for *_, kp in runs]))["theta"]
    alone = np.vstack([run_p_loop(Engine([d], [th0], [None]), r[None], kp)["theta"]
                       for d, (th0, r, kp) in zip(devs, runs)])
    assert np.max(np.abs(batch - alone)) < 1e-9


def test_torque_off_keeps_the_back_emf_friction():
    """With the drive off (command 0) the law still acts on the back-EMF's torque -b_emf w: the
    pendulum let go at 0.8 rad creeps down as the plain loop at 0 V says (one row and a batch),
    held back by the law (higher at the end than without it)."""
    n, law = 1200, (0.2, 0.6, 0.36, 0.02)
    out = {}
    for name, model in (("law", _servo(law)), ("none", _servo())):
        dev = Device(model, 1e-3, SERVO)
        out[name] = run_p_loop(Engine([dev], [0.8], [None]), np.zeros((1, n)), 30.0,
                               enabled=np.zeros((1, n), bool))["theta"][0]
        two = run_p_loop(Engine([dev] * 2, [0.8, 0.8], [None] * 2, nthread=2), np.zeros((2, n)),
                         np.array([30.0, 30.0]), enabled=np.zeros((2, n), bool))["theta"]
        assert np.max(np.abs(two - out[name])) < 1e-9
    ref = _reference(_servo(law), law, 0.8, np.zeros(n), 0.0)
    assert np.max(np.abs(out["law"] - ref)) < 1e-9
    assert out["law"][-1] > out["none"][-1] + 0.01 > 0.01


@pytest.mark.parametrize("law", LAWS)
def test_the_runtime_replays_like_the_engine(law):
    """A user's plain mj_step loop with the runtime's callback equals the one-row engine bit
    for bit (the same law arithmetic, qfrc_applied held for the period)."""
    model = _servo(law)
    runs = _runs(1000)
    plain = []
    for th0, r, kp in runs:
        m = copy.deepcopy(model)
        cb = runtime.drive_laws(m, control_period_s=1e-3, joint="pivot", actuator="servo")
        d = mujoco.MjData(m)
        d.qpos[0] = th0
        mujoco.mj_forward(m, d)
        theta = np.empty(len(r))
        for k in range(len(r)):
            theta[k] = d.qpos[0]
            d.ctrl[0] = np.clip(kp * (r[k] - theta[k]), -12.0, 12.0)
            cb(m, d)
            mujoco.mj_step(m, d)
        plain.append(theta)
    assert np.array_equal(np.vstack(plain), _engine(model, runs, batch=False))
    needs, lines = runtime.runtime_note(model)
    assert needs and "load_friction_smooth (mu_drive=" in lines[0]


def test_bad_values_and_a_missing_sensor_are_refused():
    with pytest.raises(UserError, match="load_friction_smooth.*w_s > 0"):
        Device(_servo((0.2, 0.2, 0.36, 0.0)), 1e-3, SERVO)
    with pytest.raises(UserError, match="load_friction_smooth.*w_s > 0"):
        Device(_servo((-0.1, 0.2, 0.36, 0.02)), 1e-3, SERVO)
    with pytest.raises(UserError, match="'load_friction_smooth' needs the transmitted torque"):
        Device(_servo(LAWS[0], sensor=False), 1e-3, SERVO)


def test_a_batch_on_the_pool_threads():
    """A batch at or above the engine's SERIAL_BELOW rows goes to the pool's threads: the same
    trajectories as the rows alone, to 1e-9 rad."""
    from omni_sim.device.engine import SERIAL_BELOW
    models = [_servo(LAWS[b % 2]) if b % 3 else _servo() for b in range(SERIAL_BELOW)]
    runs = [_runs(400)[b % 3] for b in range(SERIAL_BELOW)]
    devs = [Device(m, 1e-3, SERVO) for m in models]
    batch = run_p_loop(Engine(devs, [th0 for th0, _, _ in runs], [None] * len(devs), nthread=2),
                       np.vstack([r for _, r, _ in runs]), np.array([kp for *_, kp in runs]))["theta"]
    for b in (0, 1, 2, SERIAL_BELOW - 1):
        th0, r, kp = runs[b]
        alone = run_p_loop(Engine([devs[b]], [th0], [None]), r[None], kp)["theta"][0]
        assert np.max(np.abs(batch[b] - alone)) < 1e-9, b
