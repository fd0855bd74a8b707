"""The missing torque under a model with LuGre bristles (the Omni's default scene), and the
estimator's own error taken from it (discrepancy/bristles.py, discrepancy/evidence.py).

Truths: MuJoCo's own stepping of a LuGre ``dcmotor``; the bank's Omni cases (the device's
closed loop on the truth model, quantised noisy encoder)."""

import mujoco
import numpy as np
import pytest

import omni_sim
from bank import hidden
from discrepancy import bristles, evidence, experiment_set
from discrepancy.replay import Replayer, prepare_runs
from omni_sim import model as om
from omni_sim.device import Device


@pytest.mark.parametrize("sigma1", [0.0, 0.7])
def test_bristle_torque_is_mujocos(sigma1):
    """Along a motion MuJoCo steps (a sine torque on the yaw), the bristle torque from the
    steps' start velocities equals the LuGre actuator's joint torque MuJoCo computed, to 1e-9 of
    its size, with and without bristle damping."""
    spec = mujoco.MjSpec.from_file(str(omni_sim.DEFAULT_SCENE))
    spec.actuator("yaw_friction").dynprm[6] = sigma1
    model = spec.compile()
    data = mujoco.MjData(model)
    a = bristles.with_bristles(model, Device(model).lugre_actuators())
    assert len(a) == 1
    v, force = [], []
    for k in range(600):
        data.qfrc_applied[0] = 0.05 * np.sin(2 * np.pi * 2 * k * model.opt.timestep)
        mujoco.mj_forward(model, data)
        v.append(data.qvel[0])
        force.append(model.actuator_gear[a[0], 0] * data.actuator_force[a[0]])
        mujoco.mj_step(model, data)
    ours = bristles.torque(bristles.parameters(model, a[0]), np.array(v), model.opt.timestep)
    assert np.max(np.abs(ours - np.array(force))) < 1e-9 * np.max(np.abs(force))


def _runs(case: str):
    """Four runs of a bank case: 1.5 Hz 0.04 rad, 3 Hz 0.15 rad (near the resonance: 12.9
    rad/s, the arm swings), a 0.2 rad step, at the first pose."""
    keep = [e for e in experiment_set.experiments()
            if e.name.startswith(("sine_g65_090_f1p50_a040", "sine_g65_090_f3p00_a150", "step_g65_090_a200"))]
    assert len(keep) == 3
    return hidden.generate(hidden.case(case), keep)


@pytest.fixture(scope="module")
def omni():
    spec = mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))
    return spec, spec.copy().compile()


def _evidence(omni, case, reference=True):
    spec, model = omni
    rr = prepare_runs(_runs(case), Device(model))
    ref = None
    if reference:
        with Replayer(1) as rep:
            ref = evidence.replayed_runs(model, rr, rep)
    return evidence.missing_torque_evidence(spec, model, rr, om.OMNI, reference=ref)


def _rms_mnm(ev):
    return [1e3 * float(np.sqrt(np.mean(t.tau_miss[t.trusted] ** 2))) for t in ev.torques]


def test_the_true_omni_lacks_nothing_once_the_estimators_own_error_is_taken(omni):
    """Under the true model (bank case none): without the reference the 3 Hz run shows the
    estimator's own error, over 5 mN*m rms (the window and the arm the inverse holds still);
    with it every run is under 0.5 mN*m rms (the LuGre's sliding level is 12.9 mN*m).  Measured:
    0.20, 15.8, 1.36 mN*m without; 0.128, 0.037, 0.064 with."""
    raw = _rms_mnm(_evidence(omni, "none", reference=False))
    assert max(raw) > 5.0
    ev = _evidence(omni, "none")
    assert ev.available and max(_rms_mnm(ev)) < 0.5


def test_a_hidden_coulomb_friction_on_the_lugre_omni_ranks_first(omni):
    """The bank's coulomb_friction case (15 mN*m over the LuGre scene): coulomb_friction first by
    equation error, its level within 10 % (measured 14.1 mN*m, 93 % of the missing torque
    explained)."""
    ev = _evidence(omni, "coulomb_friction")
    assert ev.best.name == "coulomb_friction"
    assert ev.best.x[0] == pytest.approx(0.015, rel=0.1)
