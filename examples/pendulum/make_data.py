"""Generate the lab pendulum's "measured" runs from ``truth.xml`` (the stand-in for the real
device), in the dataset contract that ``omni discrepancy`` reads.

Every run goes through the project's one closed loop (:mod:`omni_sim.device`) on the TRUTH
model: at each 1 ms control period the encoder reads the pivot angle (rounded to its counts
after white noise is added), the P law ``i = clip(kp (r - y), -command_limit, command_limit)``
computes the current command, the amplifier clips it to its ``ctrlrange`` and holds it for the
period.  The workflow later sees only these files and ``model.xml``.

Experiments (the closed loop's resonance with ``model.xml``'s numbers: stiffness
kp*gear + m*g*l = 0.70 + 0.314 N*m/rad, inertia 7.96e-3 kg*m^2 -> ~1.8 Hz):

* sines below (0.5, 1.0 Hz), near (1.8 Hz) and above (3.0 Hz) the resonance, each at two
  amplitudes (0.05 and 0.2 rad), 2 s to settle then 4 s of whole cycles, from rest at 0;
* square waves of +-0.1 and +-0.3 rad at 0.5 Hz for 6 s, from rest at -A.

Usage::

    python examples/pendulum/make_data.py --out pendulum_measured          # the full example
    python examples/pendulum/make_data.py --out pendulum_quick --quick     # 4 short runs (tests)
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from identification.dataset import Run, atomic_output_dir, write_run
from omni_sim import model as om
from omni_sim.device import CONTROL_PERIOD_S, Device, Encoder, run_p_loop

HERE = Path(__file__).resolve().parent
#: The stand-in for the real device (hidden bearing friction, see its header).
TRUTH = HERE / "truth.xml"
#: The model the user gives the workflow.
MODEL = HERE / "model.xml"
#: The controlled hinge and its actuator (``--joint pivot --actuator servo``).
TARGET = om.Target("pivot", "servo")

#: P gain [A/rad]: with the motor's 0.07 N*m/A a servo stiffness of 0.70 N*m/rad, about twice
#: the pendulum's gravity stiffness (0.314 N*m/rad), so gravity matters in every run.
KP = 10.0
#: The controller's software current limit [A]: 80 % of the amplifier's 5 A peak (model.xml
#: ctrlrange), the usual margin that keeps the amplifier out of its own limit; the P law
#: saturates here (metadata ``command_limit``), below the actuator's ctrlrange.
COMMAND_LIMIT = 4.0
#: Encoder: a 2500-line quadrature encoder read in 4x mode, 10000 counts per revolution.
ENCODER_COUNTS = 10000
ENCODER_STEP_RAD = 2 * math.pi / ENCODER_COUNTS
#: White noise [rad] added before quantisation (a stand-in for timing jitter and electrical
#: noise; the same level the project's hidden-effect bank uses).
NOISE_RAD = 1e-4

SINE_FREQUENCIES_HZ = (0.5, 1.0, 1.8, 3.0)
SINE_AMPLITUDES_RAD = (0.05, 0.2)
SQUARE_AMPLITUDES_RAD = (0.1, 0.3)
SQUARE_FREQUENCY_HZ = 0.5
SETTLE_S, RECORD_S, SQUARE_S = 2.0, 4.0, 6.0


def experiments(quick: bool = False) -> list[dict]:
    """The runs to perform: name, kind, reference (one sample per ms), metadata, start angle.

    ``quick``: four short runs for tests (sines at 0.5 and 1.8 Hz, 0.05 rad, and at 1 Hz,
    0.2 rad, each 0.5 s to settle then >= 1.5 s of whole cycles; a +-0.1 rad square wave of 2 s)."""
    dt = CONTROL_PERIOD_S
    out = []
    if quick:
        sines = [(0.5, 0.05), (1.8, 0.05), (1.0, 0.2)]
        squares = [(0.1,)]
        settle, record, square_s = 0.5, 1.5, 2.0
    else:
        sines = [(f, a) for a in SINE_AMPLITUDES_RAD for f in SINE_FREQUENCIES_HZ]
        squares = [(a,) for a in SQUARE_AMPLITUDES_RAD]
        settle, record, square_s = SETTLE_S, RECORD_S, SQUARE_S
    for f, a in sines:
        cycles = math.ceil(record * f - 1e-9)
        n = int(round((settle + cycles / f) / dt))
        t = np.arange(n) * dt
        out.append({"name": f"sine_f{f:04.2f}_a{a:.2f}".replace(".", "p"), "kind": "sine",
                    "r": a * np.sin(2 * np.pi * f * t), "frequency_hz": f, "amplitude_rad": a,
                    "theta0": 0.0})
    for (a,) in squares:
        n = int(round(square_s / dt))
        t = np.arange(n) * dt
        phase = (t * SQUARE_FREQUENCY_HZ) % 1.0
        out.append({"name": f"square_a{a:.2f}".replace(".", "p"), "kind": "step",
                    "r": np.where(phase < 0.5 - 1e-12, a, -a), "frequency_hz": SQUARE_FREQUENCY_HZ,
                    "amplitude_rad": a, "theta0": -a})
    return out


def generate(quick: bool = False, seed: int = 1, truth: Path = TRUTH,
             noise_rad: float = NOISE_RAD, quantize: bool = True) -> list[Run]:
    """Run every experiment on ``truth`` through the device's closed loop; the measured runs."""
    device = Device(om.load_model(truth, target=TARGET), CONTROL_PERIOD_S, target=TARGET)
    encoder = Encoder(quantize=quantize, noise_rad=noise_rad, seed=seed, step_rad=ENCODER_STEP_RAD)
    runs = []
    for e in experiments(quick):
        r = e["r"][None, :]
        n = r.shape[1]
        with device.engine([e["theta0"]], [None], nthread=1) as engine:
            out = run_p_loop(engine, r, KP, encoder.noise(e["name"], n)[None, :],
                             encoder.quantum_rad, command_limit=COMMAND_LIMIT)
        meta = {"kind": e["kind"], "kp": KP, "command_limit": COMMAND_LIMIT,
                "frequency_hz": e["frequency_hz"], "amplitude_rad": e["amplitude_rad"],
                "theta0_rad": e["theta0"], "encoder_quantized": quantize,
                "encoder_step_rad": ENCODER_STEP_RAD if quantize else 0.0,
                "encoder_noise_rad": noise_rad,
                "units": {"r": "rad", "theta": "rad", "v": "A (motor current command)",
                          "kp": "A/rad", "command_limit": "A"},
                "device": "lab pendulum on a direct-drive servo (examples/pendulum/truth.xml)"}
        runs.append(Run(e["name"], np.arange(n) * CONTROL_PERIOD_S, e["r"], out["theta"][0],
                        out["v"][0], meta))
    return runs


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, help="output folder of the measured runs")
    p.add_argument("--quick", action="store_true", help="four short runs (for tests)")
    p.add_argument("--seed", type=int, default=1, help="encoder noise seed (default 1)")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")
    args = p.parse_args(argv)
    runs = generate(quick=args.quick, seed=args.seed)
    with atomic_output_dir(Path(args.out), force=args.force) as tmp:
        for run in runs:
            write_run(tmp, run)
    print(f"{len(runs)} runs ({sum(len(r.t) for r in runs)} samples) in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
