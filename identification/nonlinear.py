"""The α-invariant nonlinear damping and torque-constant model, paper sections 2.3.3–2.3.5.

Model (37): θ'' + C(α, I)·θ' = β̃(α, I)·v, with

* damping C(α, I) tri-linear in α between breakpoints α0 < α1 < α2 < α3 (38)–(39), with the
  values at the breakpoints C_k(I) = 1/(C_k1·I) (40);
* torque constant β̃(α, I) linear in α through the values β̃_k(I) = 1/(β̃_k1·I) (42) at the
  predefined ᾱ0, ᾱ1 (41) (paper Table 6: 0 and 250); outside [ᾱ0, ᾱ1] held or extrapolated
  depending on the option ``beta_clamp`` (below).

Units as in the paper (β̄ = 1): C [1/s], β̃ [rad/(V·s²)] (β = kp·β̃ [1/s²]), α [V²/s²], I in the
paper's units so that β̃_linear = 1/I (7); C_k1 and β̃_k1 are then dimensionless ratios like C̄0.

Decisions (each also stated where it is implemented):

Outside [α0, α3]
    As printed, (38) multiplies each segment by a boxcar, so C would drop to zero below α0 and
    above α3 — zero damping for the highest-energy motion, which is unphysical.  Here the end
    values are held: C(α) = C0 for α < α0 and C3 for α > α3 (``numpy.interp`` semantics).  The
    instantaneous α of a transient can be negative (e.g. v = cosh t gives α = −1), which this
    also covers.
β̃ outside [ᾱ0, ᾱ1]
    (41) is a straight line through (ᾱ0, β̃0), (ᾱ1, β̃1).  With the option ``beta_clamp``
    β̃ is held at its end values outside [ᾱ0, ᾱ1], as C is outside [α0, α3]: the model does
    not extrapolate beyond the α range it was given.  :func:`fit_alpha_model` sets it by
    default (``beta_clamp=True``), so an *identified* model is clamped; an
    :class:`AlphaModel` built directly, including :func:`paper_alpha_model`, has
    ``beta_clamp=False`` unless its ``options`` say otherwise, and follows the line.
    Measured on the first (hard-stick) virtual Omni's paper campaign: with the line
    extrapolated, β̃ rose with α without bound, the simulated sine response near resonance
    jumped to the upper (resonant) branch and stayed there above resonance, and the sine-sweep
    phase p90 error was 43.9 deg; clamped, 17.9 deg (the global linear model: 14.2 deg).
    Unclamped, a falling line would reach zero and then reverse the actuator, so it is floored
    at ``beta_floor_fraction`` (default 0.1) times min(β̃0, β̃1) (clamped, the floor is
    inactive since β̃ stays between β̃0 and β̃1).
Constraints
    C_k ≥ 0 always, and by default C non-increasing in α (C0 ≥ C1 ≥ C2 ≥ C3), via the
    reparameterisation C_k = Σ_{j≥k} p_j, p ≥ 0, solved with :func:`scipy.optimize.nnls`.  An
    unconstrained fit gave negative segments on a MuJoCo joint and the iteration (44)–(46) then
    failed on 35–76 % of steps (project notes).  β̃0, β̃1 ≥ 0 likewise (plain NNLS).
Breakpoints
    One set shared by all poses (paper Table 7 has one set), chosen by exhaustive grid search
    over increasing 4-subsets of a candidate grid: by default {0} ∪ 10 log-spaced values from
    the smallest to the largest used α of the pooled data.  A subset is admissible when the
    pooled data identify all four values (hat-function design of full column rank).  The
    criterion is the sum of squared errors of the *final* global model C(α, I) over all used
    data points of all poses; ties go to the first subset in lexicographic order.
Across poses (2.3.5)
    ``method="two_stage"`` (default, the paper): fit C0..C3, β̃0, β̃1 per pose with I fixed
    (the "intermediate data"), then invert (40)/(42): C_k = (1/C_k1)·(1/I) is linear in
    1/C_k1, so 1/C_k1 is the ordinary least-squares slope through the origin of C_k on the
    regressor 1/I over poses, 1/C_k1 = Σ C_k,p/I_p / Σ 1/I_p² (same for β̃_k1).  This is a
    positive weighting of the per-pose values, so non-negativity and monotonicity carry over.
    ``method="pooled"`` fits 1/C_k1 directly to all data points at once (the model is linear
    in them); offered because per pose only ~4 frequencies lie below resonance.
Frequency selection
    ``use="up_to_resonance"`` (default) fits only frequencies f ≤ f_res of each pose; ``"all"``
    fits every frequency.  α(ω) rises up to resonance and falls above it (paper Fig. 8), so
    over the whole sweep the same α occurs twice with different C_data and C is not a function
    of α; on a MuJoCo joint C_data fell from ≈10 to ≈4.8 1/s below resonance and rose again to
    ≈17 above it, and fitting all frequencies gave sine magnitude p90 errors of 1.2–1.7 instead
    of 0.26–0.31 (project notes).  Frequencies with non-finite or non-positive C_data or
    β̃_data are always excluded (paper 2.2.4: physically impossible).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from . import paper
from .errors import UserError

__all__ = [
    "AlphaModel",
    "PoseFit",
    "hat_basis",
    "fit_pose",
    "fit_alpha_model",
    "default_alpha_grid",
    "pose_resonance_hz",
    "select_frequencies",
    "paper_alpha_model",
    "PAPER_ALPHA_BAR",
]

#: ᾱ0, ᾱ1 of the torque-constant model (41), paper Table 6 [V²/s²].
PAPER_ALPHA_BAR = tuple(r["alpha_bar"] for r in paper.table6())
_DEFAULT_OPTIONS = {"beta_floor_fraction": 0.1, "beta_clamp": False}


def _as_vec(x, n, name):
    a = np.asarray(x, dtype=float).reshape(-1)
    if a.shape != (n,):
        raise ValueError(f"{name} must have {n} values, got {a.size}")
    return a


@dataclass
class AlphaModel:
    """The identified α-invariant model C(α, I) (38)–(40) and β̃(α, I) (41)–(42).

    Attributes
    ----------
    alpha_breaks : ndarray, shape (4,) [V²/s²]
        α0 < α1 < α2 < α3 of (38)–(39).
    C_k1 : ndarray, shape (4,) [-]
        C_01..C_31 of (40): C_k(I) = 1/(C_k1·I).  ``inf`` means C_k = 0.
    alpha_bar : ndarray, shape (2,) [V²/s²]
        ᾱ0 < ᾱ1 of (41).
    beta_k1 : ndarray, shape (2,) [-]
        β̃_01, β̃_11 of (42): β̃_k(I) = 1/(β̃_k1·I).
    options : dict
        Settings: ``beta_floor_fraction`` (default 0.1) and ``beta_clamp`` (default False;
        :func:`fit_alpha_model` sets True), see the module docstring, and the fitting options
        that produced the model (kept for provenance).
    diagnostics : dict
        JSON-safe fit details (per-pose intermediate values, used-frequency masks, grid
        search); empty for a model not produced by :func:`fit_alpha_model`.
    """

    alpha_breaks: np.ndarray
    C_k1: np.ndarray
    alpha_bar: np.ndarray = field(default_factory=lambda: np.array(PAPER_ALPHA_BAR))
    beta_k1: np.ndarray = field(default_factory=lambda: np.ones(2))
    options: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)

    def __post_init__(self):
        self.alpha_breaks = _as_vec(self.alpha_breaks, 4, "alpha_breaks")
        self.C_k1 = _as_vec(self.C_k1, 4, "C_k1")
        self.alpha_bar = _as_vec(self.alpha_bar, 2, "alpha_bar")
        self.beta_k1 = _as_vec(self.beta_k1, 2, "beta_k1")
        self.options = {**_DEFAULT_OPTIONS, **dict(self.options)}
        if not (np.all(np.isfinite(self.alpha_breaks)) and np.all(np.diff(self.alpha_breaks) > 0)):
            raise ValueError(f"alpha_breaks must be finite and strictly increasing: {self.alpha_breaks}")
        if not (np.all(np.isfinite(self.alpha_bar)) and self.alpha_bar[1] > self.alpha_bar[0]):
            raise ValueError(f"alpha_bar must be finite and increasing: {self.alpha_bar}")
        if np.any(np.isnan(self.C_k1)) or np.any(self.C_k1 <= 0):
            raise ValueError(f"C_k1 must be positive (inf allowed): {self.C_k1}")
        if not (np.all(np.isfinite(self.beta_k1)) and np.all(self.beta_k1 > 0)):
            raise ValueError(f"beta_k1 must be finite and positive: {self.beta_k1}")

    # -- the model ----------------------------------------------------------------------------
    @property
    def C_inv(self) -> np.ndarray:
        """1/C_k1 (0 where C_k1 is inf): C_k(I) = C_inv[k]/I [-]."""
        with np.errstate(divide="ignore"):
            return 1.0 / self.C_k1

    @property
    def beta_inv(self) -> np.ndarray:
        """1/β̃_k1: β̃_k(I) = beta_inv[k]/I [-]."""
        return 1.0 / self.beta_k1

    def C_points(self, I):
        """C_0(I)..C_3(I) of (40) [1/s]; shape ``np.shape(I) + (4,)``."""
        return self.C_inv / np.asarray(I, dtype=float)[..., None]

    def beta_points(self, I):
        """β̃_0(I), β̃_1(I) of (42) [rad/(V·s²)]; shape ``np.shape(I) + (2,)``."""
        return self.beta_inv / np.asarray(I, dtype=float)[..., None]

    def C(self, alpha, I):
        """Damping C(α, I) of (38)–(40) [1/s], held at C0 / C3 outside [α0, α3].

        Parameters
        ----------
        alpha : array_like [V²/s²]
        I : array_like [paper units]
            Broadcast against ``alpha``.
        """
        return np.interp(alpha, self.alpha_breaks, self.C_inv) / np.asarray(I, dtype=float)

    def beta_tilde(self, alpha, I):
        """Torque constant β̃(α, I) of (41)–(42) [rad/(V·s²)].

        Linear in α on [ᾱ0, ᾱ1].  Outside it: held at β̃0 / β̃1 if ``options["beta_clamp"]``
        (the default of :func:`fit_alpha_model`), otherwise the line extrapolated (the default
        of a directly built model).  Either way floored at
        ``options["beta_floor_fraction"]``·min(β̃0, β̃1).
        """
        b0, b1 = self.beta_inv
        a0, a1 = self.alpha_bar
        alpha = np.asarray(alpha, dtype=float)
        if self.options.get("beta_clamp", False):
            alpha = np.clip(alpha, a0, a1)
        line = b0 + (b1 - b0) / (a1 - a0) * (alpha - a0)
        floor = self.options["beta_floor_fraction"] * min(b0, b1)
        return np.maximum(line, floor) / np.asarray(I, dtype=float)

    def C_fall(self, I) -> float:
        """The fall of C(α): C at the first breakpoint α0 over C at the last α3, at inertia
        ``I`` [-] (``inf`` when C3 = 0).  Table 10: 16.955 / 3.710 = 4.6 at γ1 = 65°, γ2 = 90°."""
        c = self.C(self.alpha_breaks, I)
        return float(c[0] / c[-1]) if c[-1] > 0 else math.inf

    # -- serialisation ------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-safe dict (``inf`` in C_k1 is written as ``null``)."""
        return {
            "alpha_breaks": [float(x) for x in self.alpha_breaks],
            "C_k1": [None if math.isinf(x) else float(x) for x in self.C_k1],
            "alpha_bar": [float(x) for x in self.alpha_bar],
            "beta_k1": [float(x) for x in self.beta_k1],
            "options": _json_safe(self.options),
            "diagnostics": _json_safe(self.diagnostics),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "AlphaModel":
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        UserError
            Missing keys or invalid values (the dict usually comes from a user's file).
        """
        if not isinstance(d, Mapping):
            raise UserError("alpha_model must be a JSON object")
        missing = [k for k in ("alpha_breaks", "C_k1", "alpha_bar", "beta_k1") if k not in d]
        if missing:
            raise UserError(f"alpha_model: missing key(s): {', '.join(missing)}")
        try:
            C_k1 = [math.inf if x is None else float(x) for x in d["C_k1"]]
            return cls(
                alpha_breaks=np.asarray(d["alpha_breaks"], dtype=float),
                C_k1=np.asarray(C_k1, dtype=float),
                alpha_bar=np.asarray(d["alpha_bar"], dtype=float),
                beta_k1=np.asarray(d["beta_k1"], dtype=float),
                options=dict(d.get("options", {})),
                diagnostics=dict(d.get("diagnostics", {})),
            )
        except (TypeError, ValueError) as exc:
            raise UserError(f"alpha_model: {exc}") from None


def _json_safe(x):
    if isinstance(x, Mapping):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_json_safe(v) for v in (x.tolist() if isinstance(x, np.ndarray) else x)]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x


def paper_alpha_model(as_printed: bool = False) -> AlphaModel:
    """The paper's model, Tables 6 and 7 (read from :mod:`identification.paper`).

    As printed, Table 7 assigns C_01 = 61.733 to α0 = 0 and C_31 = 13.509 to α3 = 250, which
    makes the damping *rise* with α, and Table 6 makes β̃ rise with α; the text (2.3.3, 2.3.4)
    says both fall with α, and Table 10 (γ1 = 65°, γ2 = 90°) lists C0..C3 = 16.955, 10.619,
    6.486, 3.710 and β̃0, β̃1 = 267.6, 170.9, which are exactly 1/(C_k1·I), 1/(β̃_k1·I) with
    I = 0.004366 (Table 10's first value, = 1/229.04, the modelled β̃_linear of Table 5, 229.0
    in Table 9) and the C_k1, β̃_k1 in *reverse* order (``identification/data/README.md``).
    By default the values are therefore assigned in reverse (falling C and β̃ in α, agreeing
    with the text and Table 10); ``as_printed=True`` gives the tables' literal assignment.
    Breakpoints α0..α3 and ᾱ0, ᾱ1 are the tables' α columns.  ``options`` has no
    ``beta_clamp``, so β̃ follows the line (41) outside [ᾱ0, ᾱ1] (module docstring).
    """
    t6, t7 = paper.table6(), paper.table7()
    C_k1 = np.array([r["value"] for r in t7])
    beta_k1 = np.array([r["value"] for r in t6])
    if not as_printed:
        C_k1, beta_k1 = C_k1[::-1], beta_k1[::-1]
    return AlphaModel(
        alpha_breaks=np.array([r["alpha"] for r in t7]),
        C_k1=C_k1,
        alpha_bar=np.array([r["alpha_bar"] for r in t6]),
        beta_k1=beta_k1,
        options={"source": "paper Tables 6-7" + (" as printed" if as_printed else ", order as Table 10")},
    )


# -- per-pose fit (the "intermediate data" of 2.3.5) ----------------------------------------------
def hat_basis(alpha, breaks) -> np.ndarray:
    """Design matrix of the clamped piecewise-linear model (38): C(α) = basis @ [C0..C3].

    Column k is the hat function that is 1 at ``breaks[k]`` and 0 at the other breakpoints,
    held constant outside [breaks[0], breaks[-1]].  Shape ``(len(alpha), len(breaks))``.
    """
    alpha = np.asarray(alpha, dtype=float).reshape(-1)
    eye = np.eye(len(breaks))
    return np.column_stack([np.interp(alpha, breaks, eye[k]) for k in range(len(breaks))])


def _beta_basis(alpha, alpha_bar):
    s = (np.asarray(alpha, dtype=float).reshape(-1) - alpha_bar[0]) / (alpha_bar[1] - alpha_bar[0])
    return np.column_stack([1.0 - s, s])


def _nnls_values(A, y, monotone):
    """Least squares for breakpoint values with C >= 0 (and non-increasing if ``monotone``)."""
    from scipy.optimize import nnls  # here: the model's classes load without scipy

    if A.shape[0] == 0:
        return np.zeros(A.shape[1])
    if monotone:
        T = np.triu(np.ones((A.shape[1], A.shape[1])))
        p, _ = nnls(A @ T, y)
        return T @ p
    x, _ = nnls(A, y)
    return x


@dataclass
class PoseFit:
    """Per-pose values (I fixed), the intermediate data of 2.3.5.

    Attributes
    ----------
    C_k : ndarray (4,) [1/s]
        C0..C3 at the breakpoints.
    beta_k : ndarray (2,) [rad/(V·s²)]
        β̃0, β̃1 at ᾱ0, ᾱ1.
    sse_C : float [1/s²]
        Sum of squared residuals of C over the fitted points.
    sse_beta : float
        Same for β̃.
    n_points : int
        Number of fitted frequencies.
    """

    C_k: np.ndarray
    beta_k: np.ndarray
    sse_C: float
    sse_beta: float
    n_points: int


def fit_pose(alpha, C_data, beta_tilde_data, alpha_breaks, alpha_bar=PAPER_ALPHA_BAR,
             monotone=True) -> PoseFit:
    """Fit C0..C3 (38)–(39) and β̃0, β̃1 (41) to one pose's data, I fixed.

    Parameters
    ----------
    alpha : array_like [V²/s²]
        α per frequency (36).
    C_data : array_like [1/s]
        C_data(ω) (19) at those frequencies.
    beta_tilde_data : array_like [rad/(V·s²)]
        β_data(ω)/kp (20).
    alpha_breaks : array_like (4,) [V²/s²]
    alpha_bar : array_like (2,) [V²/s²]
    monotone : bool
        Constrain C non-increasing in α (C ≥ 0 always).

    Returns
    -------
    PoseFit
    """
    alpha = np.asarray(alpha, dtype=float).reshape(-1)
    C_data = np.asarray(C_data, dtype=float).reshape(-1)
    b_data = np.asarray(beta_tilde_data, dtype=float).reshape(-1)
    breaks = _as_vec(alpha_breaks, 4, "alpha_breaks")
    abar = _as_vec(alpha_bar, 2, "alpha_bar")
    A = hat_basis(alpha, breaks)
    C_k = _nnls_values(A, C_data, monotone)
    B = _beta_basis(alpha, abar)
    beta_k = _nnls_values(B, b_data, False)
    return PoseFit(
        C_k=C_k,
        beta_k=beta_k,
        sse_C=float(np.sum((A @ C_k - C_data) ** 2)),
        sse_beta=float(np.sum((B @ beta_k - b_data) ** 2)),
        n_points=int(alpha.size),
    )


# -- frequency selection ----------------------------------------------------------------------
def _get(pose, key, default=None):
    if isinstance(pose, Mapping):
        return pose.get(key, default)
    return getattr(pose, key, default)


def pose_resonance_hz(pose) -> float:
    """Resonance frequency [Hz] of one pose, used by ``use="up_to_resonance"``.

    In order of preference: the pose's ``resonance_hz``; √β_linear/(2π) from ``beta_linear``
    [1/s²]; √(kp/I)/(2π) from ``kp`` [V/rad] (β_linear = kp·β̃_linear = kp/I by (7)); the
    frequency of the largest ``amplitude`` (A0 per frequency [rad]).  √β/(2π) is the undamped
    natural frequency; the amplitude peak lies within 2 % of it for C ≈ 6 1/s, β ≈ 445 1/s².

    Raises
    ------
    ValueError
        None of these keys is present.
    """
    f = _get(pose, "resonance_hz")
    if f is not None:
        return float(f)
    b = _get(pose, "beta_linear")
    if b is not None:
        return math.sqrt(float(b)) / (2 * math.pi)
    kp = _get(pose, "kp")
    if kp is not None:
        return math.sqrt(float(kp) / float(_get(pose, "I"))) / (2 * math.pi)
    amp = _get(pose, "amplitude")
    if amp is not None:
        freq = np.asarray(_get(pose, "frequency_hz"), dtype=float)
        return float(freq[int(np.argmax(np.asarray(amp, dtype=float)))])
    raise ValueError(
        "use='up_to_resonance' needs one of resonance_hz, beta_linear, kp or amplitude per pose"
    )


def select_frequencies(pose, use="up_to_resonance") -> np.ndarray:
    """Boolean mask of the frequencies of ``pose`` that enter the fit.

    A frequency is used when C_data and β̃_data are finite and positive (paper 2.2.4) and,
    for ``use="up_to_resonance"``, f ≤ :func:`pose_resonance_hz` (see module docstring).
    """
    if use not in ("up_to_resonance", "all"):
        raise ValueError(f"use must be 'up_to_resonance' or 'all', got {use!r}")
    C = np.asarray(_get(pose, "C_data"), dtype=float).reshape(-1)
    b = np.asarray(_get(pose, "beta_tilde_data"), dtype=float).reshape(-1)
    a = np.asarray(_get(pose, "alpha"), dtype=float).reshape(-1)
    ok = np.isfinite(C) & np.isfinite(b) & np.isfinite(a) & (C > 0) & (b > 0)
    if use == "up_to_resonance":
        f = np.asarray(_get(pose, "frequency_hz"), dtype=float).reshape(-1)
        ok &= f <= pose_resonance_hz(pose) * (1 + 1e-12)
    return ok


def default_alpha_grid(alpha_used, n_grid=10) -> np.ndarray:
    """Candidate breakpoints: 0 and ``n_grid`` log-spaced values over the used α range."""
    a = np.asarray(alpha_used, dtype=float)
    a = a[a > 0]
    if a.size == 0:
        raise UserError("no usable frequency with positive alpha to fit the alpha model")
    lo, hi = a.min(), a.max()
    if hi <= lo * (1 + 1e-9):
        hi = lo * 2.0
    return np.unique(np.concatenate([[0.0], np.geomspace(lo, hi, n_grid)]))


# -- across poses -----------------------------------------------------------------------------
def _invert(values_per_pose, I):
    """OLS through the origin of values (P, K) on regressor 1/I (P,): returns 1/C_k1 (K,)."""
    w = 1.0 / I
    return (w @ values_per_pose) / (w @ w)


def _fit_given_breaks(data, breaks, alpha_bar, monotone, method):
    """Fit for fixed breakpoints. Returns (C_inv (4,), beta_inv (2,), pose_fits, sse_C)."""
    I = np.array([d["I"] for d in data])
    if method == "two_stage":
        fits = [fit_pose(d["alpha"], d["C"], d["b"], breaks, alpha_bar, monotone) for d in data]
        C_inv = _invert(np.array([f.C_k for f in fits]), I)
        beta_inv = _invert(np.array([f.beta_k for f in fits]), I)
    else:
        A = np.vstack([hat_basis(d["alpha"], breaks) / d["I"] for d in data])
        C_inv = _nnls_values(A, np.concatenate([d["C"] for d in data]), monotone)
        B = np.vstack([_beta_basis(d["alpha"], alpha_bar) / d["I"] for d in data])
        beta_inv = _nnls_values(B, np.concatenate([d["b"] for d in data]), False)
        fits = None
    sse = 0.0
    for d in data:
        sse += float(np.sum((np.interp(d["alpha"], breaks, C_inv) / d["I"] - d["C"]) ** 2))
    return C_inv, beta_inv, fits, sse


def fit_alpha_model(poses: Sequence, *, use="up_to_resonance", monotone=True, method="two_stage",
                    alpha_breaks=None, alpha_grid=None, n_grid=10, alpha_bar=PAPER_ALPHA_BAR,
                    beta_floor_fraction=0.1, beta_clamp=True) -> AlphaModel:
    """Identify the α-invariant model (38)–(42) from several poses (2.3.5).

    Parameters
    ----------
    poses : sequence of mapping or object
        Per pose: ``I`` [paper units] (modelled inertia, β̃_linear ≈ 1/I); ``alpha``
        [V²/s²], ``C_data`` [1/s], ``beta_tilde_data`` [rad/(V·s²)], ``frequency_hz`` [Hz]
        (arrays, one value per frequency); for ``use="up_to_resonance"`` also one of
        ``resonance_hz``, ``beta_linear``, ``kp``, ``amplitude`` (see
        :func:`pose_resonance_hz`).
    use : {"up_to_resonance", "all"}
        Frequencies fitted (module docstring explains the default).
    monotone : bool
        Constrain C non-increasing in α (C ≥ 0 always).
    method : {"two_stage", "pooled"}
        Per-pose fit then OLS inversion (paper), or one pooled least-squares fit.
    alpha_breaks : array_like (4,), optional
        Fixed breakpoints [V²/s²]; skips the grid search.
    alpha_grid : array_like, optional
        Candidate breakpoints for the grid search; default :func:`default_alpha_grid`.
    n_grid : int
        Size of the default grid's log-spaced part.
    alpha_bar : array_like (2,) [V²/s²]
        ᾱ0, ᾱ1 of (41).
    beta_floor_fraction : float
        Floor of the β̃ extrapolation (see :class:`AlphaModel`).
    beta_clamp : bool
        Hold β̃ at its end values outside [ᾱ0, ᾱ1] (module docstring).

    Returns
    -------
    AlphaModel
        With ``diagnostics``: ``poses`` (per pose: ``I``, ``used`` mask and, for
        ``two_stage``, ``C_k``, ``beta_k``, ``sse_C``, ``sse_beta``), ``sse_C`` of the global
        model, ``alpha_grid`` (the candidates) and ``n_candidates`` (admissible subsets tried).

    Raises
    ------
    UserError
        No pose has a usable frequency, or no admissible breakpoint set exists.
    """
    if method not in ("two_stage", "pooled"):
        raise ValueError(f"method must be 'two_stage' or 'pooled', got {method!r}")
    alpha_bar = _as_vec(alpha_bar, 2, "alpha_bar")
    masks, data = _usable_data(poses, use)
    grid, breaks, (C_inv, beta_inv, fits, sse), n_tried = _search_breaks(
        data, alpha_breaks, alpha_grid, n_grid, alpha_bar, monotone, method)
    if np.any(beta_inv <= 0):
        raise UserError(
            f"the fitted torque constant is zero at alpha_bar = {alpha_bar.tolist()} "
            f"(values {beta_inv.tolist()}); the beta_data do not support the linear model (41)"
        )
    with np.errstate(divide="ignore"):
        C_k1 = 1.0 / C_inv
    diag_poses = []
    fit_iter = iter(fits) if fits is not None else None
    for pose, m in zip(poses, masks):
        entry = {"I": float(_get(pose, "I")), "used": m.tolist()}
        if fit_iter is not None and m.any():
            f = next(fit_iter)
            entry.update(C_k=f.C_k.tolist(), beta_k=f.beta_k.tolist(), sse_C=f.sse_C,
                         sse_beta=f.sse_beta)
        diag_poses.append(entry)
    options = {"use": use, "monotone": monotone, "method": method,
               "beta_floor_fraction": beta_floor_fraction, "beta_clamp": bool(beta_clamp),
               "breaks_from": "given" if alpha_breaks is not None else "grid search"}
    diagnostics = {"poses": diag_poses, "sse_C": sse, "n_candidates": n_tried,
                   "alpha_grid": grid.tolist()}
    return AlphaModel(alpha_breaks=breaks, C_k1=C_k1, alpha_bar=alpha_bar,
                      beta_k1=1.0 / beta_inv, options=options, diagnostics=diagnostics)


def _usable_data(poses, use):
    """Per pose the mask of the frequencies fitted (:func:`select_frequencies`), and for the
    poses with any, their ``I`` and the used ``alpha``, ``C`` (C_data) and ``b``
    (beta_tilde_data)."""
    masks, data = [], []
    for pose in poses:
        m = select_frequencies(pose, use)
        masks.append(m)
        I = float(_get(pose, "I"))
        if not (math.isfinite(I) and I > 0):
            raise UserError(f"pose inertia I must be finite and positive, got {I}")
        if m.any():
            data.append({
                "I": I,
                "alpha": np.asarray(_get(pose, "alpha"), dtype=float).reshape(-1)[m],
                "C": np.asarray(_get(pose, "C_data"), dtype=float).reshape(-1)[m],
                "b": np.asarray(_get(pose, "beta_tilde_data"), dtype=float).reshape(-1)[m],
            })
    if not data:
        raise UserError("no pose has a usable frequency (positive C_data and beta_data) to fit")
    return masks, data


def _search_breaks(data, alpha_breaks, alpha_grid, n_grid, alpha_bar, monotone, method):
    """The breakpoints: given, or the admissible 4-subset of the grid with the least SSE of C
    (ties within 1e-15 relative keep the first).  Returns ``(grid, breaks, fit, n_tried)``
    with ``fit`` = :func:`_fit_given_breaks`'s ``(C_inv, beta_inv, fits, sse)``."""
    all_alpha = np.concatenate([d["alpha"] for d in data])
    if alpha_breaks is not None:
        grid = _as_vec(alpha_breaks, 4, "alpha_breaks")
        candidates = [grid]
    else:
        grid = default_alpha_grid(all_alpha, n_grid) if alpha_grid is None else np.unique(
            np.asarray(alpha_grid, dtype=float))
        candidates = [np.array(c) for c in itertools.combinations(grid, 4)]
    best = None
    n_tried = 0
    for breaks in candidates:
        if alpha_breaks is None and np.linalg.matrix_rank(hat_basis(all_alpha, breaks)) < 4:
            continue
        n_tried += 1
        res = _fit_given_breaks(data, breaks, alpha_bar, monotone, method)
        if best is None or res[3] < best[1][3] - 1e-15 * max(1.0, best[1][3]):
            best = (breaks, res)
    if best is None:
        raise UserError(
            f"no breakpoint set is identified by the data ({all_alpha.size} usable points over "
            f"{len(data)} poses); at least 4 distinct alpha values spread over the grid are needed"
        )
    breaks, fit = best
    return grid, breaks, fit, n_tried
