"""The coverage study's random magnitudes: a realistic range of each library effect's
parameters.

The bank is the set of hidden-effect cases (:data:`bank.hidden.CASES`: truth models written
independently of the effect library, :mod:`.omni_truths`) run through the workflow by
``scripts/discrepancy_bank.py`` and the tests, each judged by :func:`~bank.hidden.assess`.
The coverage study (:mod:`bank.studies.discrepancy_coverage`, ``scripts/discrepancy_coverage.py``)
hides each effect at magnitudes drawn from these ranges instead of the cases' fixed ones.
"""

from __future__ import annotations

import math

import numpy as np


#: Realistic ranges of each library effect's parameters for random hidden magnitudes
#: (``scripts/discrepancy_coverage.py``): per parameter ``(low, high, signed)``; the magnitude is
#: drawn uniformly in ``[low, high]`` and, when ``signed``, given a random sign.  Ranges from the
#: device estimates quoted in the cases' notes; each lower end keeps the effect visible above
#: the encoder noise (a magnitude the data cannot show is not a test of an interval).
RANGES = {
    # dry friction on top of the LuGre drive: the 5-20 mN*m estimate of the waist
    "coulomb_friction": ((0.005, 0.020, False),),
    # 0.6x..2x the calibrated 6.9e-3 N*m*s/rad (grease temperature, amplifier impedance)
    "viscous_damping": ((0.004, 0.014, False),),
    # cable springs: 1..10 mN*m at 0.1 rad
    "joint_stiffness": ((0.01, 0.10, False), (0.0, 0.0, False)),
    # a desk or cart off level by 0.9..2.3 deg about each axis, either way
    "gravity_tilt": ((0.015, 0.04, True), (0.015, 0.04, True)),
    # total reflected rotor inertia: 1.5x..4x the nominal 1e-4 (estimate 5e-5..2e-4 + capstan)
    "armature": ((1.5e-4, 4e-4, False),),
    # drive lag 0.5..4 ms (motor L/R 0.1-1 ms plus amplifier filtering)
    "actuator_lag": ((0.0005, 0.004, False),),
    # loop delay 1..6 ms (USB frames, 700-900 Hz servo loops)
    "time_delay": ((0.001, 0.006, False),),
    # torque limit 50..300 mN*m (the 0.2 rad steps ask for up to 400 mN*m)
    "torque_saturation": ((0.05, 0.30, False),),
    # torque constant 0.5 N*m/V off by 6..20 % either way (datasheet tolerance +-10 %, drift)
    "torque_gain": ((0.06, 0.20, True),),
    # drive offset 5..40 mV either way
    "position_offset": ((0.005, 0.04, True),),
    # LuGre drive friction of another unit: bristle stiffness 1.5..10 N*m/rad, Coulomb 6..18,
    # static 20..35 mN*m (up to the back-drive bound), Stribeck speed 0.2..1 rad/s
    "presliding_friction": ((1.5, 10.0, False), (0.006, 0.018, False), (0.020, 0.035, False),
                            (0.2, 1.0, False)),
    # a second stiction source: Coulomb 3..8, static 8..15 mN*m, Stribeck speed 0.05..0.3 rad/s
    "stribeck_friction": ((0.003, 0.008, False), (0.008, 0.015, False), (0.05, 0.3, False)),
    # cable 8..40 N*m/rad (modes ~45-100 Hz), damping 0.5..4e-3 N*m*s/rad, rotor 0.7..2e-4
    "drive_compliance": ((8.0, 40.0, False), (0.0005, 0.004, False), (7e-5, 2e-4, False)),
    # slack 0.5..3 mrad (1-7 encoder counts)
    "backlash": ((0.0005, 0.003, False),),
    # link masses +-(5..25) % around the calibrated 68.8 and 59.5 g
    "arm_mass": ((0.05, 0.25, True), (0.05, 0.25, True)),
    # cogging 1.5..6 mN*m at the turret, any phase (in [-pi, pi))
    "cogging": ((0.0015, 0.006, False), (-math.pi, math.pi, False)),
}
#: Nominal values the signed ranges of :data:`RANGES` are offsets from, as fractions
#: (``torque_gain``: the scene's gear; ``arm_mass``: the calibrated link masses; models/omni/omni.xml);
#: other effects are drawn as absolute values.
RANGE_CENTRE = {"torque_gain": (0.5,), "arm_mass": (0.0687884, 0.0594899)}


def draw(effect: str, rng: np.random.Generator) -> tuple[float, ...]:
    """A random realistic magnitude of ``effect`` (:data:`RANGES`)."""
    centre = RANGE_CENTRE.get(effect)
    out = []
    for i, (lo, hi, signed) in enumerate(RANGES[effect]):
        v = rng.uniform(lo, hi)
        if signed and rng.random() < 0.5:
            v = -v
        out.append(float(centre[i] * (1 + v)) if centre else float(v))
    return tuple(out)
