"""Local and global linear models, paper equations (18)–(22) and the sine α-invariant (36).

Closed loop (13): ``θ'' + C θ' + β θ = β r`` with ``r = A_r sin(ωt)`` and the steady state
``θ = A1 cos(ωt) + A2 sin(ωt)`` (14).  Equating cosine and sine coefficients gives

    cos:  -ω² A1 + ω A2 C + A1 β        = 0
    sin:  -ω² A2 - ω A1 C + (A2 - A_r) β = 0                                   (18)

Note the sign of the ``ω A1 C`` term: the paper prints ``+ω A1 C`` in (18) and ``ω∘A1`` in the
second block row of (22), but its own solution (19)–(20) is the solution of the system above
(with ``-ω A1 C``), which is also what substituting (14) into (13) gives
(``C θ'`` contributes ``-C ω A1`` to the sine coefficient).  This module uses the derived sign
everywhere; with the printed sign, (22) would not return the C, β of a linear system.

Solving (18) gives the local ("data") coefficients (19)–(20):

    C_data(ω) = -ω A_r A1 / D,   β_data(ω) = ω² (A1² + A2²) / D,   D = A1² + A2 (A2 - A_r)

and ``β̃_data = β_data / k_p``.  When ``A_r A2 > A1² + A2²`` (D < 0) they are negative: the
paper excludes such frequencies from the α-invariant model (section 2.2.4); here they are kept
in the output with ``used = False`` and a warning.  The global linear model (22) stacks (18)
for all frequencies of one pose and solves for C_linear, β_linear by least squares; following
section 2.2.5 it uses *all* frequencies of the pose (``used`` only selects the α-model input).
Section 3.3 mentions that the paper's Table 9 used 3–4.5 Hz; that choice is not the default.

The α-invariant of the sine input voltage ``v = k_p (r - θ)`` (35) is (36)

    α = k_p² ω² (A1² + (A_r - A2)²)     [V²/s²], with ω in rad/s,

computed by :mod:`identification.alpha` (:func:`alpha_sine` here only reorders its arguments).

Units: ω [rad/s], A1, A2, A_r [rad], C [1/s], β [1/s²], k_p [V/rad], β̃ = β/k_p [rad/(V·s²)].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import alpha as _alpha
from .errors import UserError
from .sine_fit import RunSineFit

#: Minimum number of frequencies for the per-pose global linear model (22).  One frequency
#: already determines (C, β) exactly (2 equations, 2 unknowns); two give a least-squares fit
#: with a residual that shows whether the linear model fits.
MIN_FREQUENCIES = 2


def local_coefficients(A1, A2, amplitude_rad, omega):
    """Local linear model (19)–(20) from one frequency's sine coefficients.

    Parameters
    ----------
    A1, A2 : float or array [rad]
        Steady-state coefficients (14).
    amplitude_rad : float or array [rad]
        Reference amplitude A_r.
    omega : float or array [rad/s]
        Angular frequency ω.

    Returns
    -------
    C_data : float or array [1/s]
        (19).
    beta_data : float or array [1/s²]
        (20).
    """
    A1, A2, ar, w = (np.asarray(x, dtype=float) for x in (A1, A2, amplitude_rad, omega))
    with np.errstate(divide="ignore", invalid="ignore"):
        d = A1**2 + A2 * (A2 - ar)
        c = -w * ar * A1 / d
        b = w**2 * (A1**2 + A2**2) / d
    if c.ndim == 0:
        return float(c), float(b)
    return c, b


def alpha_sine(A1, A2, amplitude_rad, omega, kp):
    """α-invariant of the sine input voltage (36): ``k_p² ω² (A1² + (A_r − A2)²)``.

    The formula is :func:`identification.alpha.alpha_sine` (the single implementation of
    (33)–(36)); this wrapper takes the arguments in this module's order and returns a ``float``
    for scalar input.

    Parameters
    ----------
    A1, A2, amplitude_rad : float or array [rad]
    omega : float or array [rad/s]
    kp : float or array [V/rad]

    Returns
    -------
    alpha : float or array [V²/s²]
    """
    a = np.asarray(_alpha.alpha_sine(np.asarray(kp, dtype=float), omega, A1, A2, amplitude_rad))
    return float(a) if a.ndim == 0 else a


def global_coefficients(A1, A2, amplitude_rad, omega):
    """Global linear model (22): least-squares C_linear, β_linear over all frequencies.

    Solves ``[[ω∘A2, A1], [−ω∘A1, A2 − A_r]] [C, β]ᵀ = [A1∘ω², A2∘ω²]`` (sign of ``ω∘A1``
    as derived in the module docstring).

    Parameters
    ----------
    A1, A2 : array [rad]
    amplitude_rad : float or array [rad]
    omega : array [rad/s]

    Returns
    -------
    C_linear : float [1/s]
    beta_linear : float [1/s²]
    """
    A1, A2, w = (np.atleast_1d(np.asarray(x, dtype=float)) for x in (A1, A2, omega))
    ar = np.broadcast_to(np.asarray(amplitude_rad, dtype=float), A1.shape)
    m = np.block([[(w * A2)[:, None], A1[:, None]], [(-w * A1)[:, None], (A2 - ar)[:, None]]])
    rhs = np.concatenate([A1 * w**2, A2 * w**2])
    (c, b), *_ = np.linalg.lstsq(m, rhs, rcond=None)
    return float(c), float(b)


@dataclass
class FrequencyPoint:
    """One frequency of one pose: sine fit and local model (19)–(20), (36).

    Attributes
    ----------
    run : str
        Run name.
    frequency_hz : float [Hz]
    amplitude_rad : float [rad]
    A1, A2 : float [rad]
    C_data : float [1/s]
    beta_data : float [1/s²]
    beta_tilde_data : float [rad/(V·s²)]
    alpha : float [V²/s²]
    used : bool
        False when C_data or β_data is negative or not finite (excluded from the α model).
    explained_fraction, harmonic3_ratio : float [-]
        Goodness of the sine fit of θ (see :class:`identification.sine_fit.SineFit`).
    n_cycles : int
    """

    run: str
    frequency_hz: float
    amplitude_rad: float
    A1: float
    A2: float
    C_data: float
    beta_data: float
    beta_tilde_data: float
    alpha: float
    used: bool
    explained_fraction: float
    harmonic3_ratio: float
    n_cycles: int

    def to_dict(self) -> dict:
        return {
            "run": self.run,
            "frequency_hz": self.frequency_hz,
            "amplitude_rad": self.amplitude_rad,
            "A1": self.A1,
            "A2": self.A2,
            "C_data": _finite_or_none(self.C_data),
            "beta_data": _finite_or_none(self.beta_data),
            "beta_tilde_data": _finite_or_none(self.beta_tilde_data),
            "alpha": self.alpha,
            "used": self.used,
            "explained_fraction": self.explained_fraction,
            "harmonic3_ratio": self.harmonic3_ratio,
            "n_cycles": self.n_cycles,
        }


def _finite_or_none(x: float):
    return float(x) if math.isfinite(x) else None


@dataclass
class PoseLinearModel:
    """Local (19)–(20) and global (22) linear models of one pose.

    Attributes
    ----------
    label : str
        Human name of the pose (set point or actual angles).
    gamma1_deg, gamma2_deg : float [deg]
        Actual arm angles (mean over the pose's runs).
    gamma1_set_deg, gamma2_set_deg : float or None [deg]
    kp : float [V/rad]
    frequencies : list of FrequencyPoint
        Sorted by frequency.
    C_linear : float [1/s]
    beta_linear : float [1/s²]
    beta_tilde_linear : float [rad/(V·s²)]
        ``β_linear / k_p``.
    warnings : list of str
    """

    label: str
    gamma1_deg: float
    gamma2_deg: float
    gamma1_set_deg: float | None
    gamma2_set_deg: float | None
    kp: float
    frequencies: list
    C_linear: float
    beta_linear: float
    beta_tilde_linear: float
    warnings: list = field(default_factory=list)

    @property
    def physical(self) -> bool:
        """True when C_linear > 0 and β_linear > 0 (usable by the inertia model)."""
        return self.C_linear > 0 and self.beta_linear > 0

    def to_dict(self) -> dict:
        d = {
            "gamma1_deg": self.gamma1_deg,
            "gamma2_deg": self.gamma2_deg,
            "C_linear": self.C_linear,
            "beta_linear": self.beta_linear,
            "beta_tilde_linear": self.beta_tilde_linear,
            "kp": self.kp,
            "frequencies": [f.to_dict() for f in self.frequencies],
        }
        if self.gamma1_set_deg is not None:
            d["gamma1_set_deg"] = self.gamma1_set_deg
            d["gamma2_set_deg"] = self.gamma2_set_deg
        return d


def frequency_point(fit: RunSineFit, kp: float) -> tuple[FrequencyPoint, str | None]:
    """Local model (19)–(20) and α (36) for one run's sine fit; returns the point and a warning."""
    w = fit.omega
    c, b = local_coefficients(fit.A1, fit.A2, fit.amplitude_rad, w)
    alpha = alpha_sine(fit.A1, fit.A2, fit.amplitude_rad, w, kp)
    used = math.isfinite(c) and math.isfinite(b) and c > 0 and b > 0
    warning = None
    if not used:
        warning = (f"{fit.name}: {fit.frequency_hz:g} Hz gives non-physical local coefficients "
                   f"C_data={c:.4g} 1/s, beta_data={b:.4g} 1/s^2 (A_r*A2 > A1^2+A2^2); "
                   f"excluded from the alpha model (used=false)")
    pt = FrequencyPoint(fit.name, fit.frequency_hz, fit.amplitude_rad, fit.A1, fit.A2, c, b,
                        b / kp, alpha, used, fit.theta.explained_fraction,
                        fit.theta.harmonic3_ratio, fit.n_cycles)
    return pt, warning


def fit_pose(
    fits: list[RunSineFit],
    kp: float,
    gamma1_deg: float,
    gamma2_deg: float,
    *,
    label: str,
    gamma1_set_deg: float | None = None,
    gamma2_set_deg: float | None = None,
    min_frequencies: int = MIN_FREQUENCIES,
) -> PoseLinearModel:
    """Local models of every frequency and the global linear model (22) of one pose.

    Parameters
    ----------
    fits : list of RunSineFit
        The pose's sine fits (any order; repeated frequencies are allowed).
    kp : float [V/rad]
        Proportional gain (the same for all runs of the pose).
    gamma1_deg, gamma2_deg : float [deg]
        Actual arm angles.
    label : str
        Name of the pose for messages.

    Raises
    ------
    UserError
        Fewer than ``min_frequencies`` distinct frequencies.
    """
    fits = sorted(fits, key=lambda f: (f.frequency_hz, f.name))
    n_freq = len({f.frequency_hz for f in fits})
    if n_freq < min_frequencies:
        names = ", ".join(f.name for f in fits)
        raise UserError(
            f"pose {label}: {n_freq} distinct sine frequency(ies) (runs: {names}); the global "
            f"linear model (22) needs >= {min_frequencies}")
    points, warnings = [], []
    for f in fits:
        pt, w = frequency_point(f, kp)
        points.append(pt)
        if w:
            warnings.append(w)
    c, b = global_coefficients([p.A1 for p in points], [p.A2 for p in points],
                               [p.amplitude_rad for p in points],
                               [2 * math.pi * p.frequency_hz for p in points])
    model = PoseLinearModel(label, gamma1_deg, gamma2_deg, gamma1_set_deg, gamma2_set_deg, kp,
                            points, c, b, b / kp, warnings)
    if not model.physical:
        warnings.append(f"pose {label}: global linear model is non-physical (C_linear={c:.4g} 1/s, "
                        f"beta_linear={b:.4g} 1/s^2); the pose is left out of the inertia model")
    return model
