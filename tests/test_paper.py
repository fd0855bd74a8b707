"""identification.paper: the stored tables checked against each other and against the paper's
own summary rows and model equations (independent checks of the transcription).

Tolerances are the printed rounding: a value printed with d decimals is within 0.5·10^-d of
the true one.
"""

import math

import numpy as np
import pytest

from identification import paper


def _col(rows, key):
    return np.array([r[key] for r in rows])


def test_shapes_and_poses():
    assert len(paper.table3()) == 9 and len(paper.table5()) == 9 and len(paper.table8()) == 9
    assert len(paper.table11()) == 25
    table1 = {(g1, g2) for g1 in (25, 45, 65) for g2 in (70, 90, 115)}
    table2 = {(g1, g2) for g1 in (25, 35, 45, 55, 65) for g2 in (60, 70, 90, 110, 115)}
    for t in (paper.table3(), paper.table5(), paper.table8()):
        assert set(paper.by_set_pose(t)) == table1
    assert set(paper.by_set_pose(paper.table11())) == table2
    assert [r["quantity"] for r in paper.table7()] == ["C_01", "C_11", "C_21", "C_31"]
    assert [r["quantity"] for r in paper.table6()] == ["beta_tilde_01", "beta_tilde_11"]
    assert list(paper.table10()) == ["I", "C0", "C1", "C2", "C3", "beta_tilde_0", "beta_tilde_1"]


def test_table5_fitted_columns_are_table3():
    t3, t5 = paper.by_set_pose(paper.table3()), paper.by_set_pose(paper.table5())
    for pose, r3 in t3.items():
        r5 = t5[pose]
        assert (r5["gamma1_deg"], r5["gamma2_deg"]) == (r3["gamma1_deg"], r3["gamma2_deg"]), pose
        assert r5["C_linear_fitted"] == r3["C_linear"], pose
        assert r5["beta_tilde_linear_fitted"] == r3["beta_tilde_linear"], pose


def test_table9_beta_is_kp_times_beta_tilde():
    """Table 9: β_linear = kp·β̃_linear with kp = 2 V/rad, in both columns (exact as printed)."""
    t9 = paper.table9()
    assert paper.kp() == 2.0
    for col in ("fitted", "modelled"):
        assert t9["beta_linear"][col] == 2 * t9["beta_tilde_linear"][col], col


def test_table9_is_the_65_90_row_of_tables_3_and_5():
    t9 = paper.table9()
    r3 = paper.by_set_pose(paper.table3())[paper.TABLE9_10_SET_POSE]
    r5 = paper.by_set_pose(paper.table5())[paper.TABLE9_10_SET_POSE]
    assert t9["C_linear"]["fitted"] == r3["C_linear"]
    assert t9["C_linear"]["modelled"] == r5["C_linear_modelled"]
    # Table 9 prints β̃ with one decimal, Tables 3 and 5 with two
    assert abs(t9["beta_tilde_linear"]["fitted"] - r3["beta_tilde_linear"]) <= 0.05
    assert abs(t9["beta_tilde_linear"]["modelled"] - r5["beta_tilde_linear_modelled"]) <= 0.05


def test_table11_medians_row_is_the_column_means():
    rows, printed = paper.table11(), paper.table11_medians_row()
    for key, value in printed.items():
        assert abs(_col(rows, key).mean() - value) <= 0.5e-4, key
    # ... and not the column medians (their linear / α medians differ by more than rounding)
    assert abs(np.median(_col(rows, "median_alpha_rad")) - printed["median_alpha_rad"]) > 0.5e-4


def test_paper_step_ratio_is_the_medians_row_ratio():
    printed = paper.table11_medians_row()
    assert round(printed["median_linear_rad"] / printed["median_alpha_rad"], 1) == paper.PAPER_STEP_RATIO


def test_table8_average_row_is_the_column_means():
    rows, printed = paper.table8(), paper.table8_average()
    assert set(printed) == set(rows[0]) - {"gamma1_set_deg", "gamma2_set_deg"}
    for key, value in printed.items():
        assert abs(_col(rows, key).mean() - value) <= 0.5e-4, key


def test_table7_ratio_column_is_value_over_table4_C0_bar():
    """"Ratio to Identified C̄0" = C_k1 / 36.693 (Table 4), not / 36.727 (Table 3's regression)."""
    C0_bar = paper.table4()["C0_bar"]
    for r in paper.table7():
        # rounding: C_k1 (3 decimals), ratio (5 decimals), C̄0 (3 decimals)
        bound = r["value"] / r["ratio_to_C0_bar"] * (0.5e-3 / r["value"] + 0.5e-5 / r["ratio_to_C0_bar"]) + 0.5e-3
        assert abs(r["value"] / r["ratio_to_C0_bar"] - C0_bar) <= bound, r["quantity"]
        assert abs(r["value"] / r["ratio_to_C0_bar"] - 36.727) > bound, r["quantity"]


def test_table10_is_tables_6_7_at_the_inertia_of_table_5():
    """The inferred rows of Table 10 (data/README.md): I = 1/β̃_modelled(65, 90), and C0..C3,
    β̃0, β̃1 = 1/(value·I) with Tables 7 and 6 in reverse order."""
    t10 = paper.table10()
    r5 = paper.by_set_pose(paper.table5())[paper.TABLE9_10_SET_POSE]
    I = t10["I"]
    assert abs(1 / r5["beta_tilde_linear_modelled"] - I) <= 0.5e-6
    C = [t10[f"C{k}"] for k in range(4)]
    from_t7 = [1 / (r["value"] * I) for r in reversed(paper.table7())]
    np.testing.assert_allclose(C, from_t7, rtol=3e-4)   # I has 4 significant digits (1.2e-4)
    b = [t10["beta_tilde_0"], t10["beta_tilde_1"]]
    from_t6 = [1 / (r["value"] * I) for r in reversed(paper.table6())]
    np.testing.assert_allclose(b, from_t6, rtol=3e-4)
    # in the printed order instead, the values would be far off
    assert abs(C[0] / (1 / (paper.table7()[0]["value"] * I)) - 1) > 1


def test_table6_7_alpha_columns():
    """Table 6's ᾱ are Table 7's end breakpoints; the breakpoints increase (39)."""
    a7 = _col(paper.table7(), "alpha")
    assert np.all(np.diff(a7) > 0)
    assert list(_col(paper.table6(), "alpha_bar")) == [a7[0], a7[-1]]


def test_accessors_return_copies():
    t = paper.table3()
    t[0]["C_linear"] = math.nan
    assert paper.table3()[0]["C_linear"] == 5.890
    d = paper.table10()
    d["I"] = 0.0
    assert paper.table10()["I"] == 0.004366


def test_no_code_reads_paper_csvs_directly():
    """Only identification/paper.py names the data files (one home for the paper's numbers)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    offenders = []
    for pkg in ("identification", "omni_sim", "omni_studies", "omni_app", "scripts"):
        for path in (root / pkg).rglob("*.py"):
            if path.name == "paper.py" and path.parent.name == "identification":
                continue
            if "table3_linear_coefficients" in path.read_text() or "_errors.csv" in path.read_text():
                offenders.append(str(path.relative_to(root)))
    assert not offenders, offenders
