"""Tests of identification.scoring against hand-computed cases (Tables 8 and 11)."""

import numpy as np
import pytest

from identification.scoring import (
    abs_error_stats,
    edge_times,
    magnitude_phase,
    sine_errors,
    sine_pose_scores,
    sine_summary,
    step_scores,
    step_summary,
    wrap_deg,
)


def test_wrap_deg_half_open_interval():
    np.testing.assert_allclose(wrap_deg([0, 180, -180, 190, -190, 540, 359, -360]),
                               [0, 180, 180, -170, 170, 180, -1, 0])


def test_magnitude_phase_polar_form_16():
    # θ = A0 sin(ωt + φ) with A0 = 0.05, φ = 30°: A1 = A0 sin φ = 0.025, A2 = A0 cos φ
    mag, ph = magnitude_phase(0.025, 0.05 * np.cos(np.pi / 6), 0.1)
    assert mag == pytest.approx(0.5) and ph == pytest.approx(30.0)


def test_sine_errors_and_p90_hand_case():
    Ar = 0.1
    # data: magnitudes 1.0 at phases 0, -90, -170 deg; model: 1.2, 0.9, 1.0 at 10, -80, 175 deg
    def ab(mag, deg):
        return mag * Ar * np.sin(np.radians(deg)), mag * Ar * np.cos(np.radians(deg))
    d = [ab(1.0, p) for p in (0, -90, -170)]
    m = [ab(1.2, 10), ab(0.9, -80), ab(1.0, 175)]
    A1d, A2d = np.array(d).T
    A1m, A2m = np.array(m).T
    mag, ph = sine_errors(A1d, A2d, A1m, A2m, Ar)
    np.testing.assert_allclose(mag, [0.2, 0.1, 0.0], atol=1e-12)
    np.testing.assert_allclose(ph, [10, 10, -15], atol=1e-9)  # 175 − (−170) = 345 → −15
    s = sine_pose_scores(A1d, A2d, A1m, A2m, Ar)
    # 90th percentile, linear interpolation at index 0.9·2 = 1.8 of the sorted values
    assert s["magnitude_p90"] == pytest.approx(0.1 + 0.8 * 0.1)          # sorted 0, .1, .2
    assert s["phase_p90_deg"] == pytest.approx(10 + 0.8 * 5)             # sorted 10, 10, 15
    assert s["n_frequencies"] == 3
    avg = sine_summary([s, {"magnitude_p90": 0.0, "phase_p90_deg": 0.0, "n_frequencies": 1}])
    assert avg == pytest.approx({"magnitude_p90": 0.09, "phase_p90_deg": 7.0})


def test_table8_average_row():
    """Mean of Table 8's linear magnitude column reproduces its "Average" row."""
    lin = [0.6410, 0.4776, 0.4737, 0.5002, 0.3675, 0.5762, 0.3939, 0.4312, 0.3403]
    rows = [{"magnitude_p90": x, "phase_p90_deg": 0.0} for x in lin]
    assert sine_summary(rows)["magnitude_p90"] == pytest.approx(0.4668, abs=5e-5)


def test_edge_times_and_abs_error_stats():
    t = np.arange(8) * 0.5
    r = np.array([1, 1, 1, -1, -1, 1, 1, 1.0])
    np.testing.assert_allclose(edge_times(t, r), [0.0, 1.5, 2.5])
    s = abs_error_stats([0, 0, 0, 0, 0], [1, -2, 3, -4, 5])
    assert s["median_abs_error_rad"] == 3 and s["p90_abs_error_rad"] == pytest.approx(4.6)


def test_step_scores_windows_hand_case():
    t = np.arange(10) * 0.5          # edges at 0 and 2.5 s; window 1 s → samples 0,1 and 5,6
    r = np.where(t < 2.5, 0.07, -0.07)
    data = np.zeros(10)
    lin = np.array([4, 4, 1, 1, 1, 4, 4, 1, 1, 1.0]) * 1e-3
    alp = np.array([1, 1, 1, 1, 1, 1, 1, 1, 1, 1.0]) * 1e-3
    s = step_scores(t, data, lin, alp, r=r, window_s=1.0)
    assert s["whole_record"]["linear"]["median_abs_error_rad"] == pytest.approx(1e-3)
    assert s["whole_record"]["ratio_of_medians"] == pytest.approx(1.0)
    assert s["after_edges"]["linear"]["median_abs_error_rad"] == pytest.approx(4e-3)
    assert s["after_edges"]["linear"]["n_samples"] == 4
    assert s["after_edges"]["ratio_of_medians"] == pytest.approx(4.0)
    assert s["after_edges"]["edges_s"] == [0.0, 2.5]
    # p90 over 10 samples (six 1e-3, four 4e-3): index 8.1 → 4e-3
    assert s["whole_record"]["linear"]["p90_abs_error_rad"] == pytest.approx(4e-3)
    with pytest.raises(ValueError):
        step_scores(t, data, lin, alp)


TABLE11 = np.array([  # γ1 γ2 | linear median, p90 | α-invariant median, p90  [rad]
    [25, 60, 0.0083, 0.0207, 0.0036, 0.0123], [25, 70, 0.0098, 0.0230, 0.0045, 0.0138],
    [25, 90, 0.0120, 0.0276, 0.0067, 0.0157], [25, 110, 0.0138, 0.0314, 0.0082, 0.0160],
    [25, 115, 0.0145, 0.0320, 0.0087, 0.0167], [35, 60, 0.0075, 0.0217, 0.0021, 0.0068],
    [35, 70, 0.0099, 0.0230, 0.0029, 0.0078], [35, 90, 0.0140, 0.0270, 0.0036, 0.0088],
    [35, 110, 0.0167, 0.0293, 0.0041, 0.0100], [35, 115, 0.0175, 0.0298, 0.0043, 0.0096],
    [45, 60, 0.0087, 0.0206, 0.0030, 0.0109], [45, 70, 0.0097, 0.0230, 0.0036, 0.0119],
    [45, 90, 0.0118, 0.0270, 0.0058, 0.0138], [45, 110, 0.0133, 0.0298, 0.0073, 0.0150],
    [45, 115, 0.0137, 0.0303, 0.0076, 0.0156], [55, 60, 0.0070, 0.0265, 0.0020, 0.0092],
    [55, 70, 0.0088, 0.0259, 0.0025, 0.0093], [55, 90, 0.0120, 0.0256, 0.0037, 0.0090],
    [55, 110, 0.0137, 0.0270, 0.0037, 0.0091], [55, 115, 0.0139, 0.0271, 0.0036, 0.0093],
    [65, 60, 0.0066, 0.0192, 0.0023, 0.0089], [65, 70, 0.0078, 0.0209, 0.0024, 0.0111],
    [65, 90, 0.0097, 0.0231, 0.0034, 0.0118], [65, 110, 0.0108, 0.0235, 0.0037, 0.0126],
    [65, 115, 0.0112, 0.0238, 0.0041, 0.0129],
])
TABLE11_ROW = [0.0113, 0.0256, 0.0043, 0.0115]  # the row labelled "Medians"


def test_step_summary_on_table11():
    """Table 11's "Medians" row is the column means (to 4 decimals), not the medians."""
    runs = []
    for _, _, lm, lp, am, ap in TABLE11:
        w = {"linear": {"median_abs_error_rad": lm, "p90_abs_error_rad": lp},
             "alpha": {"median_abs_error_rad": am, "p90_abs_error_rad": ap}}
        runs.append({"whole_record": w, "after_edges": w})
    s = step_summary(runs)["whole_record"]
    means = [s["mean_median_abs_error_linear_rad"], s["mean_p90_abs_error_linear_rad"],
             s["mean_median_abs_error_alpha_rad"], s["mean_p90_abs_error_alpha_rad"]]
    np.testing.assert_allclose(means, TABLE11_ROW, atol=5e-5)
    medians = [s["median_abs_error_linear_rad"], s["p90_abs_error_linear_rad"],
               s["median_abs_error_alpha_rad"], s["p90_abs_error_alpha_rad"]]
    np.testing.assert_allclose(medians, [0.0112, 0.0259, 0.0037, 0.0111], atol=1e-12)
    assert s["ratio_of_means"] == pytest.approx(2.63, abs=0.005)      # the paper's "2.6 times"
    assert s["ratio_of_medians"] == pytest.approx(0.0112 / 0.0037)    # 3.03
    assert s["alpha_better_poses"] == 25 and s["n_poses"] == 25
