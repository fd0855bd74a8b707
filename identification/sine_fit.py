"""Sinusoidal steady-state fit, paper equations (14)–(15).

The steady-state response to ``r(t) = A_r sin(ωt)`` is approximated by (14)

    θ(t) = A1 cos(ωt) + A2 sin(ωt)

and A1, A2 are found by the linear least squares (15).  Two additions to (15), both exact
for a pure sinusoid:

* a constant column is fitted too, so a DC offset (encoder zero, gravity sag, a reference that
  is not centred) does not leak into A1, A2;
* for a run, θ and the reference r are both fitted and θ is referred to the phase of the
  measured reference (see :func:`fit_run`), so the time origin of the file does not matter.

Steady-state rule (documented once, used everywhere)
----------------------------------------------------
Discard the first ``max(settle_s, settle_fraction · duration)`` of the run (default: the first
half of the run, but at least 2 s), then use the *last whole number of cycles* of what remains,
ending at the last sample.  At least ``min_cycles`` (default 3) whole cycles must remain, else
:class:`~identification.errors.UserError` names the run.  The transient of (13) decays like
``exp(-C t / 2)``; with the paper's C ≈ 4–7 1/s it is below 1e-3 of its initial size after 2 s.

Conventions: times ``t`` [s], frequencies ``frequency_hz`` [Hz], ``ω = 2π f`` [rad/s], angles
[rad].  A1 = A0 sin φ, A2 = A0 cos φ so that θ = A0 sin(ωt + φ) (16).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import UserError

#: Default minimum settling time discarded at the start of a run [s].
SETTLE_S = 2.0
#: Default fraction of the run discarded at the start [-].
SETTLE_FRACTION = 0.5
#: Default minimum number of whole steady-state cycles [-].
MIN_CYCLES = 3


@dataclass(frozen=True)
class SineFit:
    """Least-squares fit of ``y ≈ offset + A1 cos(ωt) + A2 sin(ωt)`` (14)–(15).

    Attributes
    ----------
    A1, A2 : float
        Cosine and sine coefficients [unit of y].
    offset : float
        Fitted constant term [unit of y].
    frequency_hz : float
        The frequency that was fitted [Hz].
    explained_fraction : float
        Fraction of the mean-removed energy of y explained by the fundamental,
        ``1 - Σ(residual²) / Σ((y - ȳ)²)`` [-]; 1 for a pure sinusoid.
    harmonic2_ratio, harmonic3_ratio : float
        Amplitude of the 2nd / 3rd harmonic relative to the fundamental [-], from a separate fit
        with harmonics 1–3 (friction distortion shows up mainly in the 3rd).
    n_samples : int
        Number of samples used.
    """

    A1: float
    A2: float
    offset: float
    frequency_hz: float
    explained_fraction: float
    harmonic2_ratio: float
    harmonic3_ratio: float
    n_samples: int

    @property
    def A0(self) -> float:
        """Amplitude ``sqrt(A1² + A2²)`` (16) [unit of y]."""
        return math.hypot(self.A1, self.A2)

    @property
    def phase(self) -> float:
        """Phase φ of ``A0 sin(ωt + φ)`` (16) [rad], ``atan2(A1, A2)``."""
        return math.atan2(self.A1, self.A2)


def fit_sine(t: np.ndarray, y: np.ndarray, frequency_hz: float) -> SineFit:
    """Fit ``y ≈ offset + A1 cos(ωt) + A2 sin(ωt)`` by linear least squares (15).

    Parameters
    ----------
    t : array [s]
        Sample times (all samples given are used; see :func:`steady_state_window`).
    y : array
        Samples.
    frequency_hz : float [Hz]
        Known frequency f, ω = 2πf.

    Returns
    -------
    SineFit
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    w = 2.0 * math.pi * frequency_hz
    cols = [np.ones_like(t)]
    for k in (1, 2, 3):
        cols += [np.cos(k * w * t), np.sin(k * w * t)]
    full = np.column_stack(cols)
    # (15) with a constant column: the fundamental-only fit gives A1, A2.
    coef1, *_ = np.linalg.lstsq(full[:, :3], y, rcond=None)
    offset, a1, a2 = (float(c) for c in coef1)
    resid = y - full[:, :3] @ coef1
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    explained = 1.0 - float(np.sum(resid**2)) / ss_tot if ss_tot > 0 else 0.0
    coef3, *_ = np.linalg.lstsq(full, y, rcond=None)
    amp = [math.hypot(coef3[2 * k - 1], coef3[2 * k]) for k in (1, 2, 3)]
    h2 = amp[1] / amp[0] if amp[0] > 0 else math.inf
    h3 = amp[2] / amp[0] if amp[0] > 0 else math.inf
    return SineFit(a1, a2, offset, float(frequency_hz), explained, h2, h3, int(t.size))


def steady_state_window(
    t: np.ndarray,
    frequency_hz: float,
    *,
    settle_s: float = SETTLE_S,
    settle_fraction: float = SETTLE_FRACTION,
    min_cycles: int = MIN_CYCLES,
    name: str = "run",
) -> tuple[slice, int]:
    """Choose the steady-state samples by the module's rule.

    Parameters
    ----------
    t : array [s]
        Uniformly spaced sample times.
    frequency_hz : float [Hz]
        Sine frequency.
    settle_s : float [s]
        Minimum time discarded at the start.
    settle_fraction : float [-]
        Fraction of the run discarded at the start (the larger of the two is used).
    min_cycles : int
        Minimum number of whole cycles required.
    name : str
        Run name for error messages.

    Returns
    -------
    window : slice
        Indices of the last whole number of cycles after the settling time.
    n_cycles : int
        Number of whole cycles in the window.

    Raises
    ------
    UserError
        Non-positive frequency or fewer than ``min_cycles`` whole cycles after settling.
    """
    t = np.asarray(t, dtype=float)
    if not (frequency_hz > 0 and math.isfinite(frequency_hz)):
        raise UserError(f"{name}: sine frequency_hz must be > 0, got {frequency_hz!r}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    duration = t[-1] - t[0] + dt  # each sample stands for one period dt
    start = t[0] + max(settle_s, settle_fraction * duration)
    available = t[-1] + dt - start
    period = 1.0 / frequency_hz
    n_cycles = int(math.floor(available / period + 1e-9))
    if n_cycles < min_cycles:
        raise UserError(
            f"{name}: only {max(n_cycles, 0)} whole steady-state cycle(s) of {frequency_hz:g} Hz after "
            f"discarding the first {start - t[0]:.3g} s of {duration:.3g} s (need >= {min_cycles}; "
            f"record a longer run)")
    n = int(round(n_cycles * period / dt))
    return slice(t.size - n, t.size), n_cycles


@dataclass(frozen=True)
class RunSineFit:
    """Steady-state sine fit of one run, referred to its reference.

    Attributes
    ----------
    name : str
        Run name.
    frequency_hz : float [Hz]
    amplitude_rad : float [rad]
        A_r from the run's metadata.
    A1, A2 : float [rad]
        Coefficients of (14) for a reference exactly ``A_r sin(ωt)``: the θ phasor divided by
        the measured reference phasor, times A_r.
    theta : SineFit
        Raw fit of θ (in the file's time origin).
    reference : SineFit
        Raw fit of r.
    n_cycles : int
        Whole cycles used.
    t_start, t_end : float [s]
        Time span used.
    """

    name: str
    frequency_hz: float
    amplitude_rad: float
    A1: float
    A2: float
    theta: SineFit
    reference: SineFit
    n_cycles: int
    t_start: float
    t_end: float

    @property
    def omega(self) -> float:
        """ω = 2πf [rad/s]."""
        return 2.0 * math.pi * self.frequency_hz


def fit_run(
    run,
    *,
    settle_s: float = SETTLE_S,
    settle_fraction: float = SETTLE_FRACTION,
    min_cycles: int = MIN_CYCLES,
) -> RunSineFit:
    """Fit (14)–(15) to the steady state of a sine run.

    θ and r are both fitted on the same window.  With phasors ``P = A2 + j A1`` (so that
    ``A1 cos + A2 sin = Im(P e^{jωt})``), the returned coefficients are
    ``A2 + j A1 = A_r · P_θ / P_r``: the response to a reference exactly ``A_r sin(ωt)``, which
    is what (18)–(20) assume.  For a file whose reference is exactly ``A_r sin(ωt)`` this equals
    (15) on θ directly.

    Parameters
    ----------
    run : identification.dataset.Run
        A run with ``kind == "sine"``.

    Raises
    ------
    UserError
        Too few steady-state cycles, non-positive amplitude, or a reference with no component
        at the sine frequency.
    """
    f = run.frequency_hz
    ar = run.amplitude_rad
    if not ar > 0:
        raise UserError(f"{run.name}: sine amplitude_rad must be > 0, got {ar!r}")
    win, n_cycles = steady_state_window(
        run.t, f, settle_s=settle_s, settle_fraction=settle_fraction, min_cycles=min_cycles,
        name=run.name)
    t = run.t[win]
    th = fit_sine(t, run.theta[win], f)
    rf = fit_sine(t, run.r[win], f)
    p_r = complex(rf.A2, rf.A1)
    if abs(p_r) < 1e-3 * ar:
        raise UserError(
            f"{run.name}: the reference r has no component at {f:g} Hz (fitted amplitude "
            f"{abs(p_r):.3g} rad, amplitude_rad {ar:g}); is frequency_hz right?")
    p = ar * complex(th.A2, th.A1) / p_r
    return RunSineFit(run.name, f, ar, p.imag, p.real, th, rf, n_cycles, float(t[0]), float(t[-1]))


def _fundamental_columns(t: np.ndarray, frequency_hz: float) -> np.ndarray:
    """The first three columns of :func:`fit_sine`'s design matrix, computed the same way
    (``[1, cos ωt, sin ωt]``), so a fit on them gives its fundamental bit for bit."""
    w = 2.0 * math.pi * frequency_hz
    return np.column_stack([np.ones_like(t), np.cos(1 * w * t), np.sin(1 * w * t)])


def fundamentals(run, thetas, **window) -> list[tuple[float, float]]:
    """``(A1, A2)`` of :func:`fit_run` for the run with each of ``thetas`` in place of its θ,
    the same numbers: the same window, the reference fitted once, the fundamental only (no
    harmonics, goodness of fit or record of the fits; what scoring model predictions needs).

    Raises
    ------
    UserError
        As :func:`fit_run`.
    """
    f = run.frequency_hz
    ar = run.amplitude_rad
    if not ar > 0:
        raise UserError(f"{run.name}: sine amplitude_rad must be > 0, got {ar!r}")
    win, _ = steady_state_window(run.t, f, name=run.name, **window)
    a = _fundamental_columns(np.asarray(run.t[win], dtype=float), f)
    rc, *_ = np.linalg.lstsq(a, np.asarray(run.r[win], dtype=float), rcond=None)
    p_r = complex(float(rc[2]), float(rc[1]))
    if abs(p_r) < 1e-3 * ar:
        raise UserError(
            f"{run.name}: the reference r has no component at {f:g} Hz (fitted amplitude "
            f"{abs(p_r):.3g} rad, amplitude_rad {ar:g}); is frequency_hz right?")
    out = []
    for theta in thetas:
        c, *_ = np.linalg.lstsq(a, np.asarray(theta[win], dtype=float), rcond=None)
        p = ar * complex(float(c[2]), float(c[1])) / p_r
        out.append((p.imag, p.real))
    return out

