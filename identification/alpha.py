"""The α-invariant, paper section 2.3.1–2.3.2, equations (33)–(36).

For a command voltage v(t) [V] the instantaneous α-invariant is (33)

    α = v̇² − v·v̈        [V²/s²]

For any pure sine v = A·sin(ωt + φ) it is constant, α = A²ω² (the squared semi-axis of the
phase-portrait ellipse (30)–(32)).  For other periodic waveforms it varies within a cycle and the
cycle average (34) is used instead.  For the sinusoidal steady state of the P-controlled yaw
axis, v = kp·(−A1·cos ωt + (Ar − A2)·sin ωt) (35) and (36) gives the closed form
α = kp²·ω²·(A1² + (Ar − A2)²).

Conventions: times in [s], angles in [rad], voltages in [V], angular frequency ω in [rad/s],
α in [V²/s²].  Arrays are 1-D and uniformly sampled unless stated otherwise.

This module is the single implementation of (33)–(36).  The identification pipeline uses
:func:`alpha_sine` (36) for every sine frequency (through :func:`identification.linear.alpha_sine`,
which only reorders the arguments).  :func:`alpha_invariant`, :func:`alpha_from_samples` and
:func:`alpha_cycle_average` are public tools for users with measured command-voltage records
(a real device's log, or a non-sinusoidal input where α varies within a cycle); the pipeline
itself does not need them, since it knows the steady-state sine coefficients.  The quasilinear
simulation (:mod:`identification.simulate`) evaluates (33) inline inside its vectorised
per-step iteration (44).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "DEFAULT_WINDOW_S",
    "DEFAULT_POLYORDER",
    "alpha_invariant",
    "alpha_sine",
    "sine_command",
    "derivatives_from_samples",
    "alpha_from_samples",
    "alpha_cycle_average",
]

#: Default Savitzky–Golay window [s] for measured data.  40 ms is 41 samples at 1 kHz: long
#: enough to average encoder quantisation (4.19e-4 rad → 8.4e-4 V at kp = 2 V/rad) over many
#: samples, short enough that a degree-4 local polynomial follows the fastest sine of the paper's
#: sweep (7 Hz, period 143 ms).  Measured bias on α for a pure 7 Hz sine: 0.25 % away from the
#: record ends, 1.8 % within half a window of them (tested); at 1.5 Hz, 6e-6 and 3e-4.
DEFAULT_WINDOW_S = 0.04
#: Default polynomial order of the Savitzky–Golay differentiator (must exceed 2, the highest
#: derivative taken).
DEFAULT_POLYORDER = 4


def alpha_invariant(v, v_dot, v_ddot):
    """Instantaneous α-invariant (33): α = v̇² − v·v̈.

    Parameters
    ----------
    v : array_like [V]
        Command voltage.
    v_dot : array_like [V/s]
        Its first time derivative.
    v_ddot : array_like [V/s²]
        Its second time derivative.

    Returns
    -------
    alpha : ndarray [V²/s²]
        Broadcast over the inputs.
    """
    v = np.asarray(v, dtype=float)
    return np.asarray(v_dot, dtype=float) ** 2 - v * np.asarray(v_ddot, dtype=float)


def alpha_sine(kp, omega, A1, A2, Ar):
    """Closed-form α of the sinusoidal steady state (36).

    α = kp²·ω²·(A1² + (Ar − A2)²), for the output θ = A1·cos ωt + A2·sin ωt (14) of the
    reference r = Ar·sin ωt under v = kp·(r − θ) (35).

    Parameters
    ----------
    kp : float [V/rad]
        Proportional gain.
    omega : array_like [rad/s]
        Angular frequency.
    A1, A2 : array_like [rad]
        Cosine and sine coefficients of the steady-state output (14).
    Ar : array_like [rad]
        Reference amplitude.

    Returns
    -------
    alpha : ndarray [V²/s²]
    """
    omega = np.asarray(omega, dtype=float)
    A1 = np.asarray(A1, dtype=float)
    A2 = np.asarray(A2, dtype=float)
    return kp**2 * omega**2 * (A1**2 + (np.asarray(Ar, dtype=float) - A2) ** 2)


def sine_command(t, kp, omega, A1, A2, Ar):
    """The command voltage (35) of the sinusoidal steady state and its exact derivatives.

    v = kp·(−A1·cos ωt + (Ar − A2)·sin ωt).

    Parameters
    ----------
    t : array_like [s]
    kp : float [V/rad]
    omega : float [rad/s]
    A1, A2, Ar : float [rad]
        As in :func:`alpha_sine`.

    Returns
    -------
    v, v_dot, v_ddot : ndarray [V], [V/s], [V/s²]
    """
    t = np.asarray(t, dtype=float)
    c, s = np.cos(omega * t), np.sin(omega * t)
    a, b = -kp * A1, kp * (Ar - A2)
    v = a * c + b * s
    v_dot = omega * (-a * s + b * c)
    v_ddot = -(omega**2) * v
    return v, v_dot, v_ddot


def _window_samples(dt, window_s, polyorder, n):
    w = int(round(window_s / dt))
    if w % 2 == 0:
        w += 1
    w_min = polyorder + 1 if polyorder % 2 == 0 else polyorder + 2
    w = max(w, w_min)
    if w > n:
        raise ValueError(
            f"Savitzky-Golay window of {w} samples ({window_s} s at dt={dt} s) is longer than the "
            f"signal ({n} samples)"
        )
    return w


def derivatives_from_samples(t, v, window_s=DEFAULT_WINDOW_S, polyorder=DEFAULT_POLYORDER):
    """Smoothed signal and first two derivatives of a uniformly sampled signal.

    A Savitzky–Golay differentiator (:func:`scipy.signal.savgol_filter`): a least-squares
    polynomial of degree ``polyorder`` over a centred window of ``window_s`` seconds (rounded to
    an odd number of samples), differentiated analytically at the window centre.  The ends use
    ``mode="interp"`` (the polynomial fitted to the first/last window), so the output has the
    input's length and no padding artefacts.

    Parameters
    ----------
    t : array_like [s]
        Uniform sample times.
    v : array_like
        The signal (any unit X).
    window_s : float [s]
        Window length.  See :data:`DEFAULT_WINDOW_S` for why 40 ms.
    polyorder : int
        Polynomial degree, at least 3.

    Returns
    -------
    v_s, v_dot, v_ddot : ndarray [X], [X/s], [X/s²]
    """
    from scipy.signal import savgol_filter  # here: scipy.signal takes ~1 s to import

    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    if t.ndim != 1 or v.shape != t.shape or t.size < 3:
        raise ValueError("t and v must be 1-D arrays of the same length (at least 3 samples)")
    if polyorder < 3:
        raise ValueError(f"polyorder must be at least 3 (a second derivative is taken), got {polyorder}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    w = _window_samples(dt, window_s, polyorder, t.size)
    kw = dict(window_length=w, polyorder=polyorder, delta=dt, mode="interp")
    return (
        savgol_filter(v, deriv=0, **kw),
        savgol_filter(v, deriv=1, **kw),
        savgol_filter(v, deriv=2, **kw),
    )


def alpha_from_samples(t, v, window_s=DEFAULT_WINDOW_S, polyorder=DEFAULT_POLYORDER):
    """Instantaneous α (33) of a measured (sampled, noisy) command voltage.

    The derivatives come from :func:`derivatives_from_samples` (Savitzky–Golay, window
    ``window_s``, degree ``polyorder``); α is (33) applied to the smoothed signal and its
    derivatives.

    Parameters
    ----------
    t : array_like [s]
        Uniform sample times.
    v : array_like [V]
        Command voltage.
    window_s : float [s]
    polyorder : int

    Returns
    -------
    alpha : ndarray [V²/s²]
        One value per sample.
    """
    v_s, v_dot, v_ddot = derivatives_from_samples(t, v, window_s, polyorder)
    return alpha_invariant(v_s, v_dot, v_ddot)


def alpha_cycle_average(t, v, period_s, n_cycles=1, v_dot=None, window_s=DEFAULT_WINDOW_S,
                        polyorder=DEFAULT_POLYORDER):
    """Cycle-average α-invariant (34) over the last ``n_cycles`` periods of the record.

    (34) is α ≈ (1/T)·∫ (v̇² − v·v̈) dt over one period T ending at t0 (here the last sample).
    It is evaluated after integrating the v·v̈ term by parts, which is an identity for any
    interval [a, b]:

        ∫_a^b (v̇² − v·v̈) dt = 2·∫_a^b v̇² dt − [v·v̇]_a^b,

    so only the first derivative is needed (the second derivative of measured data is the
    noisiest quantity) and the form is valid for C⁰ waveforms whose derivative is piecewise
    defined, as the paper states for (34).  The integral is the trapezoid rule over the last
    ``round(n_cycles·T/dt)`` sample intervals, and it is divided by that interval's actual length.

    Parameters
    ----------
    t : array_like [s]
        Uniform sample times.
    v : array_like [V]
        Command voltage.
    period_s : float [s]
        The period T.
    n_cycles : int
        Number of whole periods averaged (ending at the last sample).
    v_dot : array_like [V/s], optional
        Exact derivative, if known; otherwise :func:`derivatives_from_samples` is used (and the
        smoothed v with it).
    window_s, polyorder :
        Differentiator settings (see :func:`derivatives_from_samples`).

    Returns
    -------
    alpha : float [V²/s²]
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    if period_s <= 0 or n_cycles < 1:
        raise ValueError(f"period_s must be > 0 and n_cycles >= 1, got {period_s}, {n_cycles}")
    if v_dot is None:
        v, v_dot, _ = derivatives_from_samples(t, v, window_s, polyorder)
    else:
        v_dot = np.asarray(v_dot, dtype=float)
    dt = (t[-1] - t[0]) / (t.size - 1)
    n = int(round(n_cycles * period_s / dt))
    if n < 2 or n > t.size - 1:
        raise ValueError(
            f"{n_cycles} period(s) of {period_s} s need {n} sample intervals; the record has "
            f"{t.size - 1}"
        )
    sl = slice(t.size - 1 - n, t.size)
    ts, vs, vds = t[sl], v[sl], v_dot[sl]
    integral = 2.0 * np.trapezoid(vds**2, ts) - (vs[-1] * vds[-1] - vs[0] * vds[0])
    return float(integral / (ts[-1] - ts[0]))
