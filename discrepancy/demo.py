"""The demo's hidden effect (``omni discrepancy --demo``): a 4 ms loop delay written into a
copy of the virtual Omni with MuJoCo's own actuator delay, and its "measured" runs.

The truth and the data are those of the validation bank's ``time_delay`` case (``bank/hidden.py``
of the source checkout, a separate distribution that a plain install does not have): the same
model, written the same way as the bank's truth writer writes it (``bank/omni_truths.py``), and
the same runs (the compact experiment set of :mod:`.experiment_set`, quantised, noisy encoder,
seed 1).  ``tests/test_demo.py`` checks that they agree.  Like the bank's truths this module does
not use the effect library (:mod:`discrepancy.effects`): the workflow must find the delay, not
recognise its own writing.  (The library's ``time_delay`` writer gives the motor a longer control
history, 40 samples instead of the 6 written here, so its model is not this one.)
"""

from __future__ import annotations

import math

import mujoco

from identification.dataset import Run

from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device
from . import experiment_set

#: The demo's case: its name (the bank's case of the same name), the effect hidden and its value.
CASE = "time_delay"
DELAY_S = 0.004
EFFECTS = (("time_delay", (DELAY_S,)),)
#: Why the magnitude is realistic (the bank case's note, word for word).
NOTE = ("4 ms loop delay: USB frames of 1 ms plus the driver's scheduling on 700-900 Hz "
        "units (models/omni/README.md: servo loop 700-900 Hz measured on some USB units)")


def truth_spec(base: mujoco.MjSpec | None = None) -> mujoco.MjSpec:
    """The virtual Omni (a copy of ``base``, default the built-in scene) with the loop delay:
    MuJoCo's actuator delay on the yaw motor, a ring buffer of its control history two samples
    longer than the delay needs, read with linear interpolation."""
    spec = (base or mujoco.MjSpec.from_file(str(om.DEFAULT_SCENE))).copy()
    a = spec.actuator(om.OMNI.actuator)
    a.nsample = int(math.ceil(DELAY_S / float(spec.option.timestep))) + 2
    a.interp = 1
    a.delay = DELAY_S
    return spec


def generate(seed: int = 1, jobs: int | None = None) -> list[Run]:
    """The demo's "measured" runs: the truth model through the device's closed loop on the
    compact experiment set, encoder quantised to 15000 counts/rev plus
    :data:`~discrepancy.experiment_set.NOISE_RAD` of noise that the controller sees."""
    m = truth_spec().compile()
    settings = experiment_set.measurement(False, seed)
    return ex.simulate(Device(m), experiment_set.experiments(), settings, jobs=jobs, force_reference=True)
