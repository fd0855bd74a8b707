"""A measured run prepared for replay (:class:`ReplayRun`): plain arrays and numbers, shared
by the replay (:mod:`.replay`, which makes them from measured runs) and the statistics
(:mod:`.fit`, :mod:`.select`, :mod:`.uncertainty`, :mod:`.localise`), which need no MuJoCo."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class ReplayRun:
    """A measured run prepared for replay.

    Attributes
    ----------
    name, kind : str
    t, r, theta, v : ndarray
        Time [s], reference [rad], measured yaw [rad], measured command [V].
    dt : float [s]
        Sample (= control) period.
    kp : float [V/rad]
        The P law's gain (in the actuator's control units per rad).
    gamma_set_deg : tuple of float [deg]
        Arm servo set points used in the replay; the empty tuple for a model without the
        Omni's arm (no pose).
    frequency_hz, amplitude_rad : float
    meta : dict
        The run's metadata; a checked ``command_limit`` (:attr:`command_limit`) lives here, so
        copies of a run made with the positional constructor keep it.
    """

    name: str
    kind: str
    t: np.ndarray
    r: np.ndarray
    theta: np.ndarray
    v: np.ndarray
    dt: float
    kp: float
    gamma_set_deg: tuple[float, float]
    frequency_hz: float
    amplitude_rad: float
    meta: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return len(self.r)

    @property
    def command_limit(self) -> float:
        """The P law's saturation [control units]: metadata ``command_limit``, inf if absent
        (then only the drive's ``ctrlrange`` clips)."""
        c = self.meta.get("command_limit")
        return math.inf if c is None else float(c)

    def truncated(self, nmax: int) -> "ReplayRun":
        """The first ``nmax`` samples of the run (the replay starts from the same state)."""
        if nmax >= self.n:
            return self
        k = slice(0, nmax)
        return ReplayRun(self.name, self.kind, self.t[k], self.r[k], self.theta[k], self.v[k],
                         self.dt, self.kp, self.gamma_set_deg, self.frequency_hz,
                         self.amplitude_rad, self.meta)
