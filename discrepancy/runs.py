"""A measured run prepared for replay (:class:`ReplayRun`): plain arrays and numbers, shared
by the replay (:mod:`.replay`, which makes them from measured runs) and the statistics
(:mod:`.fit`, :mod:`.select`, :mod:`.uncertainty`, :mod:`.localise`), which need no MuJoCo."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: A logged time within this fraction of a control period of a grid time is on the grid [-]:
#: times written as text carry ~1e-9 s of rounding (1e-6 of a 1 ms period); a host's jitter
#: below 1e-3 of a period (1 us at 1 kHz) moves the angle by far less than an encoder count.
ON_GRID = 1e-3


@dataclass
class ReplayRun:
    """A measured run prepared for replay.

    Attributes
    ----------
    name, kind : str
    t, r, theta, v : ndarray
        Logged time [s] (any spacing, strictly increasing), reference [rad], measured yaw
        [rad], measured command [V].
    dt : float [s]
        Sample period (the median spacing of an irregular log).
    kp : float [V/rad]
        The P law's gain (in the actuator's control units per rad).
    gamma_set_deg : tuple of float [deg]
        Arm servo set points used in the replay; the empty tuple for a model without the
        Omni's arm (no pose).
    frequency_hz, amplitude_rad : float
    meta : dict
        The run's metadata; a checked ``command_limit`` (:attr:`command_limit`) lives here, so
        copies of a run made with the positional constructor keep it.
    control_period_s : float [s]
        The device's own loop period (metadata ``control_period_s``; 0: the sample period).
    enabled : ndarray of bool, optional
        Per logged sample, whether the actuator was on (None: always).

    The replay steps the device's loop on the *control grid* ``t[0] + j * control_period_s``,
    ``j = 0 .. steps - 1`` (:attr:`steps`): the reference and the ``enabled`` switch of grid
    time ``tau_j`` are those of the last logged sample at or before it (a servo holds its goal
    between host updates; :meth:`grid_inputs`), and the model's angle is read at every logged
    time by linear interpolation between the two grid samples around it
    (:meth:`at_logged_times`; exact, no interpolation, where a logged time falls on the grid,
    as every sample of a log taken at the control period does).
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
    control_period_s: float = 0.0
    enabled: np.ndarray | None = field(default=None, repr=False)

    @property
    def n(self) -> int:
        return len(self.r)

    @property
    def period(self) -> float:
        """The control period [s] the replay steps at."""
        return self.control_period_s if self.control_period_s > 0 else self.dt

    def _positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Grid index ``j`` and fraction ``f`` of each logged time: ``t_i = t_0 + (j + f) T``;
        a fraction within :data:`ON_GRID` of a whole period counts as on the grid (f = 0)."""
        s = (self.t - self.t[0]) / self.period
        j = np.floor(s + ON_GRID).astype(np.int64)
        f = s - j
        f[np.abs(f) < ON_GRID] = 0.0
        return j, np.clip(f, 0.0, 1.0)

    @property
    def steps(self) -> int:
        """Control periods the replay simulates: up to the grid sample at or after the last
        logged time."""
        j, f = self._positions()
        return int(j[-1] + (1 if f[-1] > 0 else 0) + 1)

    def grid_inputs(self, steps: int | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Reference [rad] and ``enabled`` switch (None if the run has none) on the control
        grid, ``steps`` samples (default :attr:`steps`): each grid time takes the last logged
        sample at or before it; past the log's end, the last sample."""
        n = self.steps if steps is None else steps
        tau = np.arange(n) * self.period
        i = np.searchsorted(self.t - self.t[0], tau + ON_GRID * self.period, side="right") - 1
        i = np.clip(i, 0, self.n - 1)
        return self.r[i], (None if self.enabled is None else self.enabled[i])

    def at_logged_times(self, grid: np.ndarray) -> np.ndarray:
        """A trajectory on the control grid (at least :attr:`steps` samples) read at the logged
        times."""
        j, f = self._positions()
        out = grid[j].copy()
        m = f > 0
        out[m] += f[m] * (grid[j[m] + 1] - grid[j[m]])
        return out

    @property
    def command_limit(self) -> float:
        """The P law's saturation [control units]: metadata ``command_limit``, inf if absent
        (then only the drive's ``ctrlrange`` clips)."""
        c = self.meta.get("command_limit")
        return math.inf if c is None else float(c)

    def first_seconds(self, seconds: float) -> "ReplayRun":
        """The run's first ``seconds`` [s] (the samples logged before ``t[0] + seconds``, half a
        sample period of tolerance; at least two samples)."""
        n = int(np.count_nonzero(self.t - self.t[0] < seconds - 0.5 * self.dt))
        return self.truncated(max(2, n))

    def truncated(self, nmax: int) -> "ReplayRun":
        """The first ``nmax`` samples of the run (the replay starts from the same state)."""
        if nmax >= self.n:
            return self
        k = slice(0, nmax)
        return ReplayRun(self.name, self.kind, self.t[k], self.r[k], self.theta[k], self.v[k],
                         self.dt, self.kp, self.gamma_set_deg, self.frequency_hz,
                         self.amplitude_rad, self.meta, self.control_period_s,
                         None if self.enabled is None else self.enabled[k])
