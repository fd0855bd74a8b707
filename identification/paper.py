"""The paper's published numbers, read from ``identification/data/*.csv`` (one home for them).

Every table the code uses (Tables 3–11) is stored as printed, one CSV per table (plus the printed
summary rows of Tables 8 and 11 in their own files); provenance, and which rows of Table 10 are
inferred and why, are in ``data/README.md``; what is inconsistent between the tables is in
``data/README.md`` and ``data/REPRODUCTION.md``.  Nothing else in the project writes the paper's
numbers again: other modules call the accessors below.

Accessors return fresh containers (callers may modify them); numbers are ``float``, labels
``str``.  ``(γ1, γ2)`` set-point keys are ``int`` degrees.
"""

from __future__ import annotations

import csv
import statistics
from functools import lru_cache
from importlib import resources

__all__ = [
    "PAPER_STEP_RATIO",
    "TABLE9_10_SET_POSE",
    "table",
    "by_set_pose",
    "table3",
    "table4",
    "table5",
    "table6",
    "table7",
    "table8",
    "table8_average",
    "table9",
    "table10",
    "table11",
    "table11_medians_row",
    "table11_summary",
    "kp",
]

#: Section 3.4: "The median of each non-linear response is 2.6 times more accurate than the
#: linear predicted response" — the ratio of Table 11's "Medians" row (0.0113 / 0.0043 = 2.63),
#: which is a row of column means (see data/README.md), so a ratio of means.
PAPER_STEP_RATIO = 2.6

#: The set point (γ1, γ2) [deg] of Tables 9 and 10 (their titles) and of Figs. 9–14.
TABLE9_10_SET_POSE = (65, 90)


@lru_cache(maxsize=None)
def _rows(name: str) -> tuple[dict, ...]:
    text = resources.files("identification").joinpath("data", name).read_text()
    out = []
    for row in csv.DictReader(text.splitlines()):
        rec = {}
        for k, v in row.items():
            try:
                rec[k] = float(v)
            except ValueError:
                rec[k] = v
        out.append(rec)
    return tuple(out)


def table(name: str) -> list[dict]:
    """Rows of ``identification/data/<name>`` as dicts (numbers as float, labels as str)."""
    return [dict(r) for r in _rows(name)]


def by_set_pose(rows) -> dict[tuple[int, int], dict]:
    """Rows keyed by their set point ``(gamma1_set_deg, gamma2_set_deg)`` as ints [deg]."""
    return {(int(r["gamma1_set_deg"]), int(r["gamma2_set_deg"])): r for r in rows}


def _by_quantity(name: str, column: str = "value") -> dict[str, float]:
    return {r["quantity"]: r[column] for r in _rows(name)}


def table3() -> list[dict]:
    """Table 3, the global linear model per Table 1 pose (9 rows).

    Keys: ``gamma1_set_deg, gamma2_set_deg`` (set angles), ``gamma1_deg, gamma2_deg`` (true
    angles) [deg], ``C_linear`` [1/s], ``beta_tilde_linear`` [rad/(V s²)].
    """
    return table("table3_linear_coefficients.csv")


def table4() -> dict[str, float]:
    """Table 4, inertia model (6) and damping ratio, as printed (its rows look shifted:
    data/REPRODUCTION.md §2).  Keys: ``I_base, I1, I2, I3`` [paper units, β̄ = 1],
    ``gamma_offs_deg`` [deg], ``C0_bar`` [-]."""
    return _by_quantity("table4_inertia_parameters.csv")


def table5() -> list[dict]:
    """Table 5: Table 3's columns as ``*_fitted`` plus the paper's ``*_modelled`` C_linear,
    β̃_linear, and the set and true angles (9 rows)."""
    return table("table5_modelled_coefficients.csv")


def table6() -> list[dict]:
    """Table 6, the non-linear β̃ model (42) as printed: rows ``quantity`` (``beta_tilde_01``,
    ``beta_tilde_11``), ``alpha_bar`` [V²/s²] (ᾱ0, ᾱ1 of (41)), ``value`` [-] (β̃_k1)."""
    return table("table6_nonlinear_beta.csv")


def table7() -> list[dict]:
    """Table 7, the non-linear C model (40) as printed: rows ``quantity`` (``C_01``..``C_31``),
    ``value`` [-] (C_k1), ``alpha`` [V²/s²] (the breakpoints α0..α3 of (39)),
    ``ratio_to_C0_bar`` [-] (C_k1 / C̄0)."""
    return table("table7_nonlinear_C.csv")


def table8() -> list[dict]:
    """Table 8, sine-sweep p90 errors per Table 1 pose (9 rows): ``magnitude_p90_linear``,
    ``phase_p90_linear_deg``, ``magnitude_p90_alpha``, ``phase_p90_alpha_deg``."""
    return table("table8_sine_errors.csv")


def table8_average() -> dict[str, float]:
    """Table 8's printed "Average" row (the column means), keys as :func:`table8`'s."""
    return dict(_rows("table8_sine_errors_average.csv")[0])


def table9() -> dict[str, dict[str, float]]:
    """Table 9, global linear model at γ1 = 65°, γ2 = 90°: ``{quantity: {"fitted", "modelled"}}``
    for ``C_linear`` [1/s], ``beta_linear`` [1/s²], ``beta_tilde_linear`` [rad/(V s²)]."""
    return {r["quantity"]: {"fitted": r["fitted"], "modelled": r["modelled"]}
            for r in _rows("table9_linear_65_90.csv")}


def table10() -> dict[str, float]:
    """Table 10, the α model at γ1 = 65°, γ2 = 90°, by *inferred* quantity (the printed table
    lost its first column; inference in data/README.md): ``I`` [paper units], ``C0``..``C3``
    [1/s] at α0..α3, ``beta_tilde_0``, ``beta_tilde_1`` [rad/(V s²)] at ᾱ0, ᾱ1."""
    return _by_quantity("table10_model_65_90.csv")


def table11() -> list[dict]:
    """Table 11, step-response absolute angle errors per Table 2 pose (25 rows) [rad]:
    ``median_linear_rad``, ``p90_linear_rad``, ``median_alpha_rad``, ``p90_alpha_rad``."""
    return table("table11_step_errors.csv")


def table11_medians_row() -> dict[str, float]:
    """Table 11's printed "Medians" row, keys as :func:`table11`'s.  It equals the column
    *means*, not medians (data/README.md)."""
    return dict(_rows("table11_step_errors_medians.csv")[0])


def table11_summary() -> dict:
    """Table 11 reduced over its 25 poses with the statistics the project's step summary uses
    (:func:`identification.scoring.step_summary`, whole record), so that ours and the paper's
    are compared like for like: ``median_*`` / ``mean_*`` of each column over poses (keys as
    the step summary's: ``median_abs_error_linear_rad``, ``mean_median_abs_error_linear_rad``,
    ``p90_abs_error_linear_rad``, ``mean_p90_abs_error_linear_rad``, same for ``alpha``),
    ``ratio_of_medians`` (3.03) and ``ratio_of_means`` (2.63: the printed "Medians" row is the
    column means, so the paper's "2.6 times" is this one), ``alpha_better_poses`` (α median
    below the linear one) and ``alpha_better_poses_p90`` (the same for the p90), ``n_poses``.
    The paper does not state its scoring window."""
    rows = table11()
    out: dict = {}
    for model in ("linear", "alpha"):
        for stat in ("median", "p90"):
            col = [r[f"{stat}_{model}_rad"] for r in rows]
            out[f"{stat}_abs_error_{model}_rad"] = float(statistics.median(col))
            out[f"mean_{stat}_abs_error_{model}_rad"] = sum(col) / len(col)
    out["ratio_of_medians"] = out["median_abs_error_linear_rad"] / out["median_abs_error_alpha_rad"]
    out["ratio_of_means"] = (out["mean_median_abs_error_linear_rad"]
                             / out["mean_median_abs_error_alpha_rad"])
    out["alpha_better_poses"] = sum(r["median_alpha_rad"] < r["median_linear_rad"] for r in rows)
    out["alpha_better_poses_p90"] = sum(r["p90_alpha_rad"] < r["p90_linear_rad"] for r in rows)
    out["n_poses"] = len(rows)
    return out


def kp() -> float:
    """The yaw P gain kp [V/rad] implied by Table 9: β_linear / β̃_linear (fitted) = 2."""
    t9 = table9()
    return t9["beta_linear"]["fitted"] / t9["beta_tilde_linear"]["fitted"]
