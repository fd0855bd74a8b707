"""``omni discrepancy --demo``'s truth and data (:mod:`discrepancy.demo`, shipped with the
library) are the validation bank's ``time_delay`` case's: the same model, written the same way,
the same runs bit for bit, the same note (the bank is a separate distribution the demo must run
without)."""

import numpy as np

from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device
from discrepancy import demo, experiment_set
from bank import hidden


def test_demo_truth_is_the_bank_case():
    case = hidden.case(demo.CASE)
    assert demo.EFFECTS == case.effects and demo.NOTE == case.note
    assert case.expect == (demo.CASE,) and not case.outside and not case.exact and case.truth == "omni"
    assert demo.truth_spec().to_xml() == hidden.truth_spec(case).to_xml()
    m = demo.truth_spec().compile()
    a = m.actuator("yaw_motor").id
    assert m.actuator_delay[a] == demo.DELAY_S == 0.004


def test_demo_runs_are_the_bank_case_runs():
    ours, bank = demo.generate(jobs=1), hidden.generate(hidden.case(demo.CASE), jobs=1)
    assert [r.name for r in ours] == [r.name for r in bank] and len(ours) == 16
    for a, b in zip(ours, bank, strict=True):
        for field in ("t", "r", "theta", "v"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=f"{a.name}: {field}")
        assert a.meta == b.meta, a.name
    # the data hold the delay: not the nominal's runs
    nominal = ex.simulate(Device(om.load_model()), experiment_set.experiments()[:1],
                          experiment_set.measurement(False, 1), jobs=1, force_reference=True)
    assert not np.array_equal(nominal[0].theta, ours[0].theta)
