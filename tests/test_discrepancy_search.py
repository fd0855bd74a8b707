"""``run_discrepancy`` given a loaded device (``device=``): the same report as from the model's
file, without compiling the model again; the refusals of a device it cannot use."""

from __future__ import annotations

import os

import numpy as np
import pytest

from identification.errors import UserError
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device
from discrepancy.workflow import run_discrepancy

JOBS = 1 if os.environ.get("PYTEST_XDIST_WORKER") else None
#: A small search: one candidate, one round (the report's content, not the naming, is compared).
SMALL = dict(k=3, max_effects=1, candidates=("viscous_damping",), jobs=JOBS)


@pytest.fixture(scope="module")
def runs():
    """Two short runs of the built-in scene with 30 % more viscous damping than its file."""
    device = Device.load()
    device.model.dof_damping[device.ix.yaw_dof] *= 1.3
    exps = [ex.sine_experiment(65, 90, 2.0), ex.square_experiment(65, 90)]
    exps = [ex.Experiment(e.name, e.kind, e.gamma1_set_deg, e.gamma2_set_deg, e.r[:500], e.frequency_hz,
                          e.amplitude_rad, e.theta0_rad) for e in exps]
    return ex.simulate(device, exps)


def _without_timings(report: dict) -> dict:
    return {k: v for k, v in report.items() if k != "timings"}


def test_a_loaded_device_gives_the_files_report(runs, monkeypatch):
    by_file = run_discrepancy(runs, None, **SMALL)
    device = Device.load()

    def compile_again(*args, **kwargs):
        raise AssertionError("the device's model was compiled again")

    monkeypatch.setattr(om, "load_model", compile_again)
    by_device = run_discrepancy(runs, device=device, **SMALL)
    assert by_file.report["settings"]["model"] == by_device.report["settings"]["model"] == str(om.DEFAULT_SCENE)
    # the comparison sees a difference (a search that found nothing would compare trivially)
    assert by_file.report["gap_after"] < 0.5 * by_file.report["gap_before"]
    assert repr(_without_timings(by_device.report)) == repr(_without_timings(by_file.report))
    for a, b in zip(by_device.theta_after, by_file.theta_after):
        np.testing.assert_array_equal(a, b)
    assert by_device.spec.to_xml() == by_file.spec.to_xml()


def test_a_device_it_cannot_use_is_refused(runs, tmp_path):
    device = Device.load()
    with pytest.raises(UserError, match="not both"):
        run_discrepancy(runs, om.DEFAULT_SCENE, device=device, **SMALL)
    with pytest.raises(UserError, match="not the target"):
        run_discrepancy(runs, device=device, target=om.Target("hinge", "motor"), **SMALL)
    in_memory = Device(om.load_model())
    with pytest.raises(UserError, match="compiled in memory"):
        run_discrepancy(runs, device=in_memory, **SMALL)
