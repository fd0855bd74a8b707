"""Scores of the linear and α-invariant models, as the paper's Tables 8 and 11.

Sine sweep (Table 8)
    Per frequency, the fundamental of the steady-state output θ = A1·cos ωt + A2·sin ωt (14)
    in polar form θ = A0·sin(ωt + φ) (16), A0 = √(A1² + A2²), φ = atan2(A1, A2).  The
    magnitude is A0/Ar [-] and the magnitude error |A0_model/Ar − A0_data/Ar| (the paper:
    "absolute difference in response magnitude"); the phase error is φ_model − φ_data in
    degrees wrapped to (−180°, 180°].  Per pose the score is the 90th percentile of the
    absolute errors over the frequencies; the summary row is the mean over poses (Table 8's
    "Average" row).
Step responses (Table 11)
    |θ_model − θ_data| [rad] per sample, reduced to the median and the 90th percentile, per run,
    over two labelled windows: ``whole_record`` (every sample) and ``after_edges`` (the samples
    within ``window_s`` = 1 s after each edge of the square wave, t = 0 included: the paper's
    Fig. 14 shows "the first second" of a transition).  The project notes found the window
    changes the linear/α ratio of medians more than the model does (1.1–1.4× over whole 8 s
    records, 2.2–2.7× after edges, on MuJoCo), so both are always reported.  The summary gives
    the median over runs of each column with the ratio of those medians, linear / α, and also
    the mean over runs with the ratio of means: Table 11's row labelled "Medians" (0.0113,
    0.0256, 0.0043, 0.0115) is, to its 4 decimals, the column *means* of its 25 rows (0.01131,
    0.02555, 0.00430, 0.01152); the column medians are 0.0112, 0.0259, 0.0037, 0.0111.  The
    paper's "2.6 times" is therefore the ratio of means (2.63); the ratio of medians over runs
    is 3.03 (both checked in the tests).

Percentiles are ``numpy.percentile`` with its default ``method="linear"`` (linear
interpolation between order statistics, Hyndman–Fan type 7): the 90th percentile of n values
sorted x_(0) ≤ … ≤ x_(n−1) is x at fractional index 0.9·(n − 1).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

__all__ = [
    "magnitude_phase",
    "wrap_deg",
    "sine_errors",
    "sine_pose_scores",
    "sine_summary",
    "edge_times",
    "abs_error_stats",
    "step_scores",
    "step_summary",
    "STEP_WINDOWS",
]

#: Labels of the two step-scoring windows.
STEP_WINDOWS = ("whole_record", "after_edges")


def wrap_deg(x):
    """Wrap angles [deg] to (−180, 180]."""
    x = np.asarray(x, dtype=float)
    return x - 360.0 * np.ceil((x - 180.0) / 360.0)


def magnitude_phase(A1, A2, Ar):
    """Magnitude A0/Ar [-] and phase φ = atan2(A1, A2) [deg] of (14)/(16)."""
    A1 = np.asarray(A1, dtype=float)
    A2 = np.asarray(A2, dtype=float)
    return np.hypot(A1, A2) / np.asarray(Ar, dtype=float), np.degrees(np.arctan2(A1, A2))


def sine_errors(A1_data, A2_data, A1_model, A2_model, Ar):
    """Per-frequency magnitude and phase errors of a model against data.

    Parameters
    ----------
    A1_data, A2_data, A1_model, A2_model : array_like [rad]
        Fundamentals (14) of the measured and simulated steady-state outputs.
    Ar : float or array_like [rad]
        Reference amplitude.

    Returns
    -------
    magnitude_error : ndarray [-]
        |A0_model − A0_data|/Ar.
    phase_error_deg : ndarray [deg]
        φ_model − φ_data wrapped to (−180, 180] (signed).
    """
    m_d, p_d = magnitude_phase(A1_data, A2_data, Ar)
    m_m, p_m = magnitude_phase(A1_model, A2_model, Ar)
    return np.abs(m_m - m_d), wrap_deg(p_m - p_d)


def sine_pose_scores(A1_data, A2_data, A1_model, A2_model, Ar) -> dict:
    """One pose's Table 8 entries: 90th percentiles of the absolute errors over frequencies.

    Returns
    -------
    dict
        ``magnitude_p90`` [-], ``phase_p90_deg`` [deg], ``n_frequencies``.
    """
    mag, ph = sine_errors(A1_data, A2_data, A1_model, A2_model, Ar)
    return {
        "magnitude_p90": float(np.percentile(mag, 90)),
        "phase_p90_deg": float(np.percentile(np.abs(ph), 90)),
        "n_frequencies": int(mag.size),
    }


def sine_summary(per_pose: Sequence[Mapping[str, float]]) -> dict:
    """Table 8's "Average" row: the mean over poses of each numeric score."""
    keys = [k for k in per_pose[0] if k != "n_frequencies"]
    return {k: float(np.mean([p[k] for p in per_pose])) for k in keys}


def edge_times(t, r):
    """Times of the square-wave edges [s]: t[0] and every sample where r changes."""
    t = np.asarray(t, dtype=float)
    r = np.asarray(r, dtype=float)
    return np.concatenate([t[:1], t[1:][np.diff(r) != 0]])


def abs_error_stats(theta_data, theta_model, mask=None) -> dict:
    """Median and 90th percentile of |θ_model − θ_data| [rad] over ``mask`` (default all)."""
    e = np.abs(np.asarray(theta_model, dtype=float) - np.asarray(theta_data, dtype=float))
    if mask is not None:
        e = e[mask]
    if e.size == 0:
        raise ValueError("empty scoring window")
    return {
        "median_abs_error_rad": float(np.median(e)),
        "p90_abs_error_rad": float(np.percentile(e, 90)),
        "n_samples": int(e.size),
    }


def step_scores(t, theta_data, theta_linear, theta_alpha, r=None, edges_s=None,
                window_s=1.0) -> dict:
    """One step run's Table 11 entries, for both windows (labelled).

    Parameters
    ----------
    t : array_like [s]
    theta_data, theta_linear, theta_alpha : array_like [rad]
        Measured and simulated angles at ``t``.
    r : array_like [rad], optional
        Reference; its edges (and t[0]) start the ``after_edges`` windows.
    edges_s : array_like [s], optional
        Edge times, instead of ``r``.
    window_s : float [s]
        Length of each after-edge window.

    Returns
    -------
    dict
        ``{"whole_record": W, "after_edges": W}`` with
        ``W = {"linear": stats, "alpha": stats, "ratio_of_medians": linear/alpha}``, stats from
        :func:`abs_error_stats`; ``after_edges`` also has ``window_s`` and ``edges_s``.
    """
    t = np.asarray(t, dtype=float)
    if edges_s is None:
        if r is None:
            raise ValueError("step_scores needs r or edges_s for the after-edges window")
        edges_s = edge_times(t, r)
    edges_s = np.asarray(edges_s, dtype=float)
    after = np.zeros(t.shape, dtype=bool)
    for e in edges_s:
        after |= (t >= e) & (t < e + window_s)

    def window(mask):
        lin = abs_error_stats(theta_data, theta_linear, mask)
        alp = abs_error_stats(theta_data, theta_alpha, mask)
        ratio = lin["median_abs_error_rad"] / alp["median_abs_error_rad"] if alp[
            "median_abs_error_rad"] > 0 else float("inf")
        return {"linear": lin, "alpha": alp, "ratio_of_medians": ratio}

    out = {"whole_record": window(None), "after_edges": window(after)}
    out["after_edges"].update(window_s=float(window_s), edges_s=edges_s.tolist())
    return out


def step_summary(per_run: Sequence[Mapping]) -> dict:
    """Table 11's summary row, per window, over runs scored by :func:`step_scores`.

    Returns
    -------
    dict
        Per window label: ``median_abs_error_linear_rad``, ``median_abs_error_alpha_rad``,
        ``p90_abs_error_linear_rad``, ``p90_abs_error_alpha_rad`` (medians over runs of the
        per-run values) and ``ratio_of_medians`` (linear/α of those medians); the same four with
        ``mean_`` prefixed (means over runs, which is what the paper's "Medians" row holds, see
        the module docstring) and ``ratio_of_means``; ``alpha_better_poses`` (runs whose α
        median error is below the linear one), ``alpha_better_poses_p90`` (the same for the
        90th percentile) and ``n_poses``.
    """
    out = {}
    for w in STEP_WINDOWS:
        rows = [p[w] for p in per_run]
        s = {}
        for model in ("linear", "alpha"):
            for stat in ("median", "p90"):
                vals = [x[model][f"{stat}_abs_error_rad"] for x in rows]
                s[f"{stat}_abs_error_{model}_rad"] = float(np.median(vals))
                s[f"mean_{stat}_abs_error_{model}_rad"] = float(np.mean(vals))
        for kind, prefix in (("medians", ""), ("means", "mean_")):
            a = s[f"{prefix}median_abs_error_alpha_rad"]
            s[f"ratio_of_{kind}"] = (s[f"{prefix}median_abs_error_linear_rad"] / a
                                     if a > 0 else float("inf"))
        s["alpha_better_poses"] = int(sum(
            x["alpha"]["median_abs_error_rad"] < x["linear"]["median_abs_error_rad"] for x in rows))
        s["alpha_better_poses_p90"] = int(sum(
            x["alpha"]["p90_abs_error_rad"] < x["linear"]["p90_abs_error_rad"] for x in rows))
        s["n_poses"] = len(rows)
        out[w] = s
    return out
