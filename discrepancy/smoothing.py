"""The derivative estimator of the missing torque (:mod:`.torque`): the logged angle and
command smoothed by one window, the states as the model's discrete-time derivatives, and the
linear weights that carry the log's noise into them.

The estimator (:class:`Estimator`, :func:`smooth`)
--------------------------------------------------
The logged angle ``theta_i`` at times ``t_i`` (any spacing, quantised) is interpolated linearly
onto the model's timestep grid ``tau_k = t_0 + k dt`` and smoothed by a Hann window of
half-width ``h``::

    K(s) = (1 + cos(pi s / h)) / (2 h)   for |s| <= h,   q_f = K * theta,

with ``h = 0.360 / f_c`` (:data:`HANN_CUTOFF`), so that the window passes ``1/sqrt(2)`` of a
sine at the stated bandwidth ``f_c`` [Hz].  The states are the discrete derivatives of ``q_f``
at each output time ``tau_k``::

    q = q_f[k],  qd_start = (q_f[k] - q_f[k-1]) / dt,  qdd = (q_f[k+1] - 2 q_f[k] + q_f[k-1]) / dt^2

(output times every ``step_s``, default ``h / 4``; ``qd_start`` is the velocity at the start
of MuJoCo's step, ``qdd`` its acceleration: the model's own discrete time, so the model's replay gives ``tau_miss`` = 0 up to the noise).  The
logged command ``v`` (linear between log samples, 0 while ``enabled`` is 0) is smoothed by the
same window: *consistent filtering* -- every linear term of ``M qdd + D qd + ... = gear v +
tau_miss`` sees the same low-pass, so the window's attenuation cancels and what is estimated
is ``K * tau_miss``, the missing torque seen through the window (a jump, e.g. a missing Coulomb
level at a reversal, appears as a ramp over ``2 h``).  The model's Coulomb friction is filtered
the same way (:mod:`.torque`).  The first and last ``2 h`` of a run give no estimate (the
friction's direction reads the fine grid's smoothed velocity a half-window further).

The weights: every state is a linear map of the logged angles, ``x = W theta`` (rows of the
interpolation and the window), kept (sparse) for the noise band (:meth:`.torque.InverseModel.band`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from identification.errors import UserError

from .runs import ReplayRun

#: ``f_c h`` at which the Hann window of half-width ``h`` passes 1/sqrt(2) of a sine of
#: frequency ``f_c`` (computed numerically; tests/test_torque.py checks it).
HANN_CUTOFF = 0.3601
#: The band's width in standard deviations of the estimator's noise.
BAND_SIGMAS = 3.0
#: Width of the window the friction's direction and sticking are read on, as a share of the
#: smoothing window.  Under the true model (the Omni's Coulomb scene with 18.8 mN*m of dry
#: friction, a 1.5 Hz sine and two step runs) the inverse's RMS missing torque was 3.6-4.5 mN*m at
#: 1, 0.4-1.7 at 0.5, 0.03-0.6 at 0.25 and 0.02-0.4 at 0.125 (the share of steady samples
#: falling with it): 0.25, the middle of where the bias is gone, keeps more steady samples.
STICK_SHARE = 0.25


@dataclass(frozen=True)
class Estimator:
    """The derivative estimator's settings.

    Attributes
    ----------
    bandwidth_hz : float [Hz]
        ``f_c``: the window passes 1/sqrt(2) of a sine at ``f_c``; half-width ``h = 0.360 / f_c``.
    step_s : float [s], optional
        Spacing of the output times (default ``h / 4``, rounded to the model's timestep: the
        estimates are smooth on the scale of ``h``).
    noise_rad : float [rad], optional
        The logged angle's noise sigma (default: from the run, see the module docstring).
    """

    bandwidth_hz: float = 5.0
    step_s: float | None = None
    noise_rad: float | None = None

    @property
    def half_window_s(self) -> float:
        return HANN_CUTOFF / self.bandwidth_hz


@dataclass(frozen=True)
class Smoothed:
    """The smoothed states of one run at its output times (model-independent but for the
    timestep): what :class:`~.torque.InverseModel` reads.  ``weights``: ``W0, W1, W2`` map the
    logged angles to ``q``, ``qd_start``, ``qdd`` (sparse, one row per output time), then
    ``(Wv, sigma_cmd)``, the logged command's map to ``v`` and its noise sigma (0 when logged
    every control period); ``fine``: the window's rows ``G0`` on the fine grid, the fine grid's
    velocity and acceleration of the angle smoothed by the :data:`STICK_SHARE` window (the
    friction's direction and sticking) and their noise sigmas; ``v_fine``: the command on the
    fine grid (``v = G0 v_fine``), for a command another law makes of it."""

    name: str
    t: np.ndarray
    q: np.ndarray
    qd_start: np.ndarray
    qdd: np.ndarray
    v: np.ndarray
    on: np.ndarray
    fine: tuple
    trusted: np.ndarray
    weights: tuple
    sigma_rad: float
    dt: float
    pose: tuple
    half_window_s: float
    v_fine: np.ndarray | None = None

    @property
    def qd(self) -> np.ndarray:
        """Velocity [rad/s] at the output time (the mean of the step's start and end)."""
        return self.qd_start + 0.5 * self.dt * self.qdd


def hann_taps(h: float, dt: float) -> np.ndarray:
    """The Hann window ``K(s) = (1 + cos(pi s/h)) / (2h)`` at ``s = j dt``, ``|s| <= h``,
    scaled so that ``sum(K) dt = 1``; returned already multiplied by ``dt`` (taps)."""
    J = max(1, int(math.floor(h / dt)))
    s = np.arange(-J, J + 1) * dt
    k = 1.0 + np.cos(np.pi * s / h)
    return k / k.sum()


def noise_sigma(run: ReplayRun, est: Estimator) -> float:
    """The logged angle's noise sigma [rad] (module docstring: the estimator's, the run's
    metadata, else 1.4826 MAD(third differences) / sqrt(20), at least the quantisation noise
    ``q / sqrt(12)`` of the smallest step ``q`` the log takes: a quantised angle at rest for
    most of a run has third differences mostly 0, whose MAD is 0, and a band of 0 would weigh
    those samples without bound)."""
    if est.noise_rad is not None:
        return float(est.noise_rad)
    step = run.meta.get("encoder_step_rad")
    if step is not None:
        return math.sqrt(float(step) ** 2 / 12 + float(run.meta.get("encoder_noise_rad", 0.0)) ** 2)
    moves = np.abs(np.diff(np.asarray(run.theta, float)))
    moves = moves[moves > 0]
    floor = float(moves.min()) / math.sqrt(12.0) if len(moves) else 0.0
    return max(_mad_sigma(run.theta), floor)


def _interp_matrix(t_fine: np.ndarray, t_log: np.ndarray) -> sparse.csr_matrix:
    """Sparse ``L``: ``L @ y_log`` is ``np.interp(t_fine, t_log, y_log)``."""
    j = np.clip(np.searchsorted(t_log, t_fine, side="right") - 1, 0, len(t_log) - 2)
    f = np.clip((t_fine - t_log[j]) / (t_log[j + 1] - t_log[j]), 0.0, 1.0)
    rows = np.repeat(np.arange(len(t_fine)), 2)
    cols = np.stack([j, j + 1], axis=1).ravel()
    vals = np.stack([1.0 - f, f], axis=1).ravel()
    return sparse.csr_matrix((vals, (rows, cols)), shape=(len(t_fine), len(t_log)))


def _rows(taps: np.ndarray, centres: np.ndarray, nfine: int) -> sparse.csr_matrix:
    """Sparse rows applying ``taps`` (odd length, centred) at the fine indices ``centres``."""
    J = len(taps) // 2
    cols = centres[:, None] + np.arange(-J, J + 1)[None, :]
    rows = np.repeat(np.arange(len(centres)), len(taps))
    return sparse.csr_matrix((np.tile(taps, len(centres)), (rows, cols.ravel())),
                             shape=(len(centres), nfine))


def _derivative_taps(K: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Taps of ``q_f[k]``, ``(q_f[k] - q_f[k-1]) / dt`` and the second difference over
    ``dt^2``, on one common (padded) support."""
    k = np.concatenate([[0.0, 0.0], K, [0.0, 0.0]])
    # q_f[k + m] = sum_j K_j y[k + m + j]: the tap of y[k + i] is K_{i - m} (np.roll by m)
    shifted = {m: np.roll(k, m) for m in (-1, 0, 1)}
    g0 = shifted[0]
    g1 = (shifted[0] - shifted[-1]) / dt
    g2 = (shifted[-1] - 2 * shifted[0] + shifted[1]) / dt ** 2
    return g0, g1, g2


def smooth(run: ReplayRun, dt: float, est: Estimator = Estimator()) -> Smoothed:
    """The smoothed states of ``run`` on the model's timestep ``dt`` (module docstring).

    Raises
    ------
    UserError
        The run is shorter than the window (``2 h``) plus two output steps.
    """
    h = est.half_window_s
    t_log = np.asarray(run.t, float)
    nfine = int(math.floor((t_log[-1] - t_log[0]) / dt + 1e-9)) + 1
    K = hann_taps(h, dt)
    J = len(K) // 2 + 2  # support of the padded derivative taps
    stride = max(1, int(round((est.step_s if est.step_s else h / 4) / dt)))
    # two half-windows from either end: the fine grid's smoothed velocity read by the
    # friction's direction (InverseModel.direction) has its whole window there too
    centres = np.arange(2 * J, nfine - 2 * J, stride)
    if len(centres) < 2:
        raise UserError(f"run {run.name!r} lasts {t_log[-1] - t_log[0]:.3g} s, shorter than twice the "
                        f"estimator's window {2 * h:.3g} s (bandwidth {est.bandwidth_hz:g} Hz): "
                        "raise the bandwidth or use a longer run")
    t_fine = t_log[0] + np.arange(nfine) * dt
    L = _interp_matrix(t_fine, t_log)
    W = tuple((_rows(g, centres, nfine) @ L).tocsr() for g in _derivative_taps(K, dt))
    theta = np.asarray(run.theta, float)
    on_fine = _held(run, t_fine)
    v_fine = np.where(on_fine, np.interp(t_fine, t_log, np.asarray(run.v, float)), 0.0)
    G0 = _rows(K, centres, nfine)
    sigma = noise_sigma(run, est)
    W = W + (((G0 @ L).tocsr(), command_noise(run)),)
    # the friction's direction and sticking are read on a window STICK_SHARE as wide: the
    # smoothing's own window leaks a motion's onset back by h, so the rest before a step counts
    # as sliding (on the Omni's Coulomb scene, 2-7 mN*m of bias under the true model itself)
    Ks = hann_taps(h * STICK_SHARE, dt)
    q_s = np.convolve(L @ theta, Ks, mode="same")
    vel = np.diff(q_s, prepend=q_s[0]) / dt  # start-of-step velocity
    acc = np.diff(vel, append=vel[-1]) / dt
    _, g1, g2 = _derivative_taps(Ks, dt)
    lin = float(np.mean(row_norms(L)))
    fine = (G0, vel, acc, sigma * float(np.linalg.norm(g1)) * lin, sigma * float(np.linalg.norm(g2)) * lin)
    return Smoothed(run.name, t_fine[centres], W[0] @ theta, W[1] @ theta, W[2] @ theta,
                    G0 @ v_fine, on_fine[centres], fine, _away_from_switches(on_fine, centres, len(K) // 2 + 1), W, sigma, dt,
                    tuple(run.gamma_set_deg), h, v_fine)


def _mad_sigma(x: np.ndarray) -> float:
    """White-noise sigma of a smooth signal's samples: 1.4826 MAD of its third differences
    over sqrt(20) (a third difference of white noise has variance 20 sigma^2)."""
    d3 = np.diff(np.asarray(x, float), 3)
    return float(1.4826 * np.median(np.abs(d3 - np.median(d3))) / math.sqrt(20.0))


def command_noise(run: ReplayRun) -> float:
    """The logged command's noise sigma [control units]: 0 when logged every control period
    (what the drive applied, exactly); a coarser log misses the command's sample-to-sample
    noise (a quantised P loop's), taken as white noise of the logged samples (:func:`_mad_sigma`)."""
    return _mad_sigma(run.v) if run.dt > 1.01 * run.period else 0.0


def _away_from_switches(on_fine: np.ndarray, centres: np.ndarray, reach: int) -> np.ndarray:
    """Output times farther than ``reach`` fine samples from every torque on/off switch."""
    ok = np.ones(len(centres), bool)
    for s in np.flatnonzero(np.diff(on_fine.astype(int)) != 0):
        ok &= np.abs(centres - s) > reach
    return ok


def _held(run: ReplayRun, t_fine: np.ndarray) -> np.ndarray:
    """``enabled`` on the fine grid: that of the last logged sample at or before each time
    (a servo holds its switch between host writes; all True without the column)."""
    if run.enabled is None:
        return np.ones(len(t_fine), bool)
    i = np.clip(np.searchsorted(run.t, t_fine + 1e-9, side="right") - 1, 0, len(run.t) - 1)
    return np.asarray(run.enabled, bool)[i]


def row_norms(W: sparse.csr_matrix) -> np.ndarray:
    return np.sqrt(np.asarray(W.multiply(W).sum(axis=1)).ravel())
