"""The compact experiment set of the hidden-effect cases and their measurement: where their
"measured" runs come from (the demo, :mod:`.demo`; the validation bank's cases, ``bank.hidden``,
with ``omni sweep``'s discrepancy pipeline and the bank's studies).

16 runs of 2 s by default: sines at 2 amplitudes x 3 frequencies (below, near and above the
~3.4 Hz resonance) plus square waves of 2 sizes, at a folded and a stretched arm pose; the
encoder quantised to 15000 counts/rev with white noise of :data:`NOISE_RAD` that the controller
sees, as on the device.
"""

from __future__ import annotations

from omni_sim import experiments as ex

#: Poses [deg] (set points) of the compact experiment set: a folded and a stretched arm
#: (yaw inertia and the arm's mass moment differ by ~2x between them).
POSES = ((65.0, 90.0), (25.0, 115.0))
#: Sine frequencies [Hz] (below, near and above the ~3.4 Hz resonance) and amplitudes [rad].
FREQUENCIES_HZ = (1.5, 3.0, 5.0)
AMPLITUDES_RAD = (0.04, 0.15)
#: Square waves: amplitudes [rad], 0.5 Hz so a 2 s record holds two edges plus the start.
STEP_AMPLITUDES_RAD = (0.05, 0.2)
#: Run length [s] (sines: 0.5 s settling plus whole cycles for >= 1.5 s).
DURATION_S = 2.0
#: Encoder noise [rad] (std, on top of the 15000 counts/rev quantisation): ~1/4 count, the
#: order of the jitter of a quadrature count sampled asynchronously (estimate).
NOISE_RAD = 1e-4


def experiments(poses=POSES, frequencies_hz=FREQUENCIES_HZ, amplitudes_rad=AMPLITUDES_RAD,
                step_amplitudes_rad=STEP_AMPLITUDES_RAD, duration_s: float = DURATION_S) -> list[ex.Experiment]:
    """The compact, informative experiment set: sines at 2 amplitudes x 3 frequencies plus
    square waves of 2 sizes, at each pose (16 runs of 2 s by default); any part can be
    narrowed (a quicker set for the tests, one amplitude of a sweep's variant)."""
    out = []
    for g1, g2 in poses:
        for f in frequencies_hz:
            for a in amplitudes_rad:
                e = ex.sine_experiment(g1, g2, f, a, settle_s=0.5, record_s=duration_s - 0.5)
                n = int(round(duration_s / ex.CONTROL_PERIOD_S))
                out.append(ex.Experiment(f"{e.name}_a{a * 1000:03.0f}", "sine", g1, g2, e.r[:n], f, a))
        for a in step_amplitudes_rad:
            e = ex.square_experiment(g1, g2, 0.5, a, duration_s)
            out.append(ex.Experiment(f"{e.name}_a{a * 1000:03.0f}", "step", g1, g2, e.r, 0.5, a,
                                     theta0_rad=e.theta0_rad))
    return out


def measurement(exact: bool = False, seed: int = 1, noise_rad: float | None = None) -> ex.Settings:
    """The measurement settings: the quantised encoder plus noise (default :data:`NOISE_RAD`),
    or, ``exact``, neither."""
    if exact:
        return ex.Settings(quantize=False, noise_rad=0.0, seed=seed)
    return ex.Settings(quantize=True, noise_rad=NOISE_RAD if noise_rad is None else noise_rad, seed=seed)
