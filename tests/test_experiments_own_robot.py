"""Experiments on a device without the Omni's arm (omni_sim.experiments): optional set points,
the P law's ``command_limit`` on both paths, the runs' metadata, pose-free campaign groups."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import omni_sim
from identification.errors import UserError
from omni_sim import experiments as ex
from omni_sim.device import Device

MODEL = Path(__file__).resolve().parents[1] / "examples" / "pendulum" / "model.xml"
TARGET = omni_sim.Target("pivot", "servo")  # a plain motor: the fast path applies


@pytest.fixture(scope="module")
def pendulum():
    return Device.load(MODEL, target=TARGET)


def _sine(name="s", f=1.0, amp=0.4, n=1500):
    t = np.arange(n) * 0.001
    return ex.Experiment(name, "sine", r=amp * np.sin(2 * np.pi * f * t), frequency_hz=f, amplitude_rad=amp)


def test_experiment_keeps_its_positional_and_keyword_forms():
    r = np.zeros(10)
    a = ex.Experiment("x", "step", 65.0, 90.0, r, 0.25, 0.07, theta0_rad=-0.07)
    b = ex.Experiment(name="x", kind="step", gamma1_set_deg=65.0, gamma2_set_deg=90.0, r=r,
                      frequency_hz=0.25, amplitude_rad=0.07, theta0_rad=-0.07)
    assert a.pose == b.pose == (65.0, 90.0) and a.r is b.r is r
    assert (a.frequency_hz, a.amplitude_rad, a.theta0_rad) == (b.frequency_hz, b.amplitude_rad, -0.07)
    c = ex.Experiment("y", "other", r=[0.0, 0.1])
    assert c.pose is None and c.r.dtype == float and (c.frequency_hz, c.amplitude_rad) == (0.0, 0.0)
    with pytest.raises(UserError, match="both arm set points"):
        ex.Experiment("z", "other", 65.0, None, r)
    with pytest.raises(TypeError, match="reference r is required"):
        ex.Experiment("z", "other")
    with pytest.raises(UserError, match="kind must be"):
        ex.Experiment("z", "sinus", r=r)


def test_command_limit_on_both_paths(pendulum):
    """The fast path (rollout, the P law in the model) and the device's engine agree with a
    limit that binds; the limit bounds every command and changes the run; it is recorded."""
    assert ex.fast_path_ok(pendulum, ex.Settings())
    exps = [_sine("a", 1.0), _sine("b", 2.0)]
    settings = ex.Settings(kp=20.0, command_limit=1.5)
    fast = ex.simulate(pendulum, exps, settings)
    ref = ex.simulate(pendulum, exps, settings, force_reference=True, jobs=1)
    free = ex.simulate(pendulum, exps, ex.Settings(kp=20.0))
    for f, r, u in zip(fast, ref, free):
        np.testing.assert_allclose(f.theta, r.theta, atol=1e-9)
        np.testing.assert_allclose(f.v, r.v, atol=1e-7)
        assert np.max(np.abs(f.v)) == pytest.approx(1.5)  # binds, and no more
        assert np.max(np.abs(u.v)) > 1.6  # without it the command goes beyond
        assert f.meta["command_limit"] == 1.5 and "command_limit" not in u.meta
    # the drive still clips at its own ctrlrange (5 A) when the limit is above it
    high = ex.simulate(pendulum, [_sine("c", 2.0, amp=1.0)], ex.Settings(kp=50.0, command_limit=50.0))[0]
    assert np.max(np.abs(high.v)) == pytest.approx(pendulum.voltage_limit)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), True])
def test_a_bad_command_limit_is_refused(pendulum, bad):
    with pytest.raises(UserError, match="command_limit must be > 0"):
        ex.simulate(pendulum, [_sine()], ex.Settings(command_limit=bad))


def test_runs_of_a_device_without_the_arm_claim_no_pose(pendulum):
    run = ex.simulate(pendulum, [_sine()])[0]
    assert not {"gamma1_deg", "gamma2_deg", "gamma1_set_deg", "gamma2_set_deg"} & set(run.meta)
    assert (run.meta["joint"], run.meta["actuator"]) == ("pivot", "servo")
    assert run.meta["source"] == "simulated single-joint device (omni_sim)"
    omni = ex.simulate(Device.load(), [ex.square_experiment(45, 90, duration_s=0.5)])[0]
    assert {"gamma1_deg", "gamma2_deg", "gamma1_set_deg", "gamma2_set_deg"} <= set(omni.meta)
    assert "joint" not in omni.meta and "command_limit" not in omni.meta  # the Omni's runs as before


def test_set_points_must_fit_the_device(pendulum):
    with pytest.raises(UserError, match="run p: this device has no arm"):
        ex.simulate(pendulum, [ex.Experiment("p", "other", 45.0, 90.0, np.zeros(5))])
    with pytest.raises(UserError, match="run q: this model has the Omni's arm"):
        ex.simulate(Device.load(), [ex.Experiment("q", "other", r=np.zeros(5))])


CAMPAIGN = """
[[sine]]
frequencies_hz = [1.0, 2.0]
amplitude_rad = 0.1
settle_s = 0.5
record_s = 1.0
[[sine]]
frequencies_hz = [1.0]
amplitude_rad = 0.3
settle_s = 0.5
record_s = 1.0
[step]
frequency_hz = 0.5
amplitude_rad = 0.2
duration_s = 2.0
"""


def test_pose_free_groups():
    c = ex.parse_campaign(CAMPAIGN, "c.toml")
    names = [e.name for e in c.experiments(arm=False)]
    assert names == ["sine_f1p00_a0p100", "sine_f2p00_a0p100", "sine_f1p00_a0p300", "step_f0p50_a0p200"]
    assert all(e.pose is None for e in c.experiments(arm=False))
    with pytest.raises(UserError, match=r"c.toml: sine\[0\].poses_deg: missing"):
        c.experiments()  # the Omni needs its poses
    posed = ex.load_campaign("paper")
    with pytest.raises(UserError, match=r"sine.poses_deg: this device has no arm to pose"):
        posed.experiments(arm=False)
    assert [e.name for e in omni_sim.campaign("sine")] == [e.name for e in ex.campaign("sine")]
