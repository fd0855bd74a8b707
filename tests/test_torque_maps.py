"""omni_app/torque_maps.py draws the missing torque's four maps into one PNG."""

import numpy as np

from omni_app import torque_maps
from discrepancy.torque import MissingTorque


def _result(name, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(0.2, 4.8, 0.02)
    q = 0.4 * np.sin(2 * np.pi * 0.5 * t)
    qd = np.gradient(q, t)
    qdd = np.gradient(qd, t)
    motor = 0.5 * np.sin(2 * np.pi * 0.5 * t + 0.3)
    tau = -0.02 * np.sign(qd) + rng.normal(0, 0.002, len(t))
    trusted = np.ones(len(t), bool)
    trusted[:5] = False
    return MissingTorque(name, t, q, qd, qdd, motor, tau, np.full(len(t), 0.006), trusted,
                         np.abs(qd) > 0.1)


def test_draw_writes_a_png(tmp_path):
    path = torque_maps.draw([_result("a", 1), _result("b", 2)], tmp_path / "torque_maps.png",
                            title="servo pendulum")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


def test_stack_leaves_out_untrusted_samples():
    r = _result("a", 1)
    s = torque_maps._stack([r, r])
    assert len(s["tau"]) == 2 * int(r.trusted.sum())
    assert np.all(np.diff(s["t"][: int(r.trusted.sum())]) > 0)
    assert s["t"][int(r.trusted.sum())] > s["t"][int(r.trusted.sum()) - 1]
