"""How the device measures the yaw angle: the :class:`Encoder` (quantisation, white noise,
seeded per-run streams) and the reading itself (:func:`encoder_reader`, :func:`read_encoder`).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

from identification.errors import UserError

#: Encoder resolution [rad]: 15000 counts per revolution (models/omni/README.md).
ENCODER_STEP_RAD = 2 * math.pi / 15000


@dataclass(frozen=True)
class Encoder:
    """How the device measures the yaw angle.

    Attributes
    ----------
    quantize : bool
        Round the reading to the encoder's counts (``step_rad``).
    noise_rad : float [rad]
        Standard deviation of white measurement noise, added before quantisation.
    seed : int
        Seed of the per-run noise streams (:meth:`noise`).
    step_rad : float [rad]
        One count: 2 pi / 15000 (the Omni's encoders).
    """

    quantize: bool = False
    noise_rad: float = 0.0
    seed: int = 0
    step_rad: float = ENCODER_STEP_RAD

    def __post_init__(self):
        if not (self.noise_rad >= 0 and math.isfinite(self.noise_rad)):
            raise UserError(f"noise must be a finite standard deviation >= 0, got {self.noise_rad}")

    @property
    def exact(self) -> bool:
        """True when the reading is the true angle."""
        return not self.quantize and self.noise_rad == 0

    @property
    def quantum_rad(self) -> float:
        """The rounding step [rad] (0 when not quantising)."""
        return self.step_rad if self.quantize else 0.0

    def noise(self, name: str, n: int) -> np.ndarray:
        """The noise samples [rad] of run ``name``: one stream per (seed, run name), so a run's
        noise does not depend on which other runs are simulated or in which order."""
        if self.noise_rad <= 0:
            return np.zeros(n)
        digest = hashlib.sha256(f"{self.seed}:{name}".encode()).digest()
        rng = np.random.default_rng(int.from_bytes(digest[:8], "little"))
        return rng.normal(0.0, self.noise_rad, n)


def encoder_reader(quantum_rad):
    """The encoder for a fixed rounding step ``quantum_rad`` [rad] (scalar, or one per row; 0:
    no rounding): a function ``read(theta, noise)`` giving ``theta + noise`` rounded to the
    step.  A count of zero reads +0.0, never -0.0 (as an integer count would).  The arrays
    that depend only on the step are made once, for loops that read every control period."""
    q = np.asarray(quantum_rad, dtype=float)
    if not np.any(q > 0):
        return lambda theta, noise: np.asarray(theta, dtype=float) + noise
    rounds = q > 0
    qdiv = np.where(rounds, q, 1.0)

    def read(theta, noise):
        y = np.asarray(theta, dtype=float) + noise
        return np.where(rounds, np.round(y / qdiv) * qdiv + 0.0, y)

    return read


def read_encoder(theta, noise, quantum_rad):
    """The encoder's reading of the true yaw ``theta`` [rad] (elementwise; scalars or arrays):
    :func:`encoder_reader` for one call."""
    return encoder_reader(quantum_rad)(theta, noise)
