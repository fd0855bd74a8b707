"""The table-level targets (omni_sim.calibration, targets="tables"): the published tables that
describe the real Omni -- Table 3, Table 9's resonance, Table 10, section 2.3 and Table 11's
*linear* column -- and never the paper's validation of the alpha model (Tables 8 and 11's alpha
columns).  The guard is behavioural: the alpha model's simulators are made to fail, and the
alpha columns of Tables 8 and 11 are replaced by nonsense; the residuals must not change.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from identification import paper
from identification import simulate as sim
from identification import validation
from omni_sim import calibration as cal
from omni_sim import model as om

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from scripts.fidelity_search import N_RESIDUALS  # noqa: E402


def _forbidden(*args, **kwargs):
    raise AssertionError("an alpha-model simulation ran while computing calibration residuals")


@pytest.fixture(scope="module")
def evaluation():
    fig = cal.evaluate(om.load_model(), cal.ex.SINE_AMPLITUDE_RAD, steps=True)
    return fig


def test_residual_sets(evaluation):
    """'calibration' = Table 3 (4 x 9), Table 10 (3 + the fall), section 2.3 (1); 'tables' adds
    Table 9's resonance and Table 11's linear median and p90 at its 25 poses."""
    cal_terms = cal.residual_terms(evaluation, "calibration")
    tab_terms = cal.residual_terms(evaluation, "tables")
    assert len(cal_terms) == 36 + 4 + 1
    assert tab_terms[:len(cal_terms)] == cal_terms
    extra = [label for label, _ in tab_terms[len(cal_terms):]]
    assert extra[0] == "table9 resonance"
    assert len(extra) == 1 + 2 * len(paper.table11()) == 51
    assert len(tab_terms) == N_RESIDUALS  # what the search returns for a failed candidate
    assert all(label.startswith(("table3", "table10", "section2.3", "table9", "table11 linear"))
               for label, _ in tab_terms)
    assert np.array_equal(cal.residuals(evaluation), np.array([v for _, v in cal_terms]))
    with pytest.raises(cal.UserError):
        cal.residual_terms(evaluation, "table8")


def test_table11_residuals_are_the_log_ratios(evaluation):
    """Each step residual is log(virtual / real) over half the 40 % band, per pose."""
    steps = evaluation["steps"]
    by_label = dict(cal.residual_terms(evaluation, "tables"))
    rows = paper.by_set_pose(paper.table11())
    for s in steps["poses"]:
        real = rows[tuple(s["set"])]
        key = f"{s['set'][0]}/{s['set'][1]}"
        assert by_label[f"table11 linear median {key}"] == pytest.approx(
            math.log(s["median_rad"] / real["median_linear_rad"]) / (math.log(1.4) / 2), rel=1e-12)
        assert s["paper_p90_rad"] == real["p90_linear_rad"]
    assert len(steps["poses"]) == 25


def test_no_alpha_model_output_enters_any_residual(evaluation, monkeypatch):
    """With the alpha model's simulators failing and Tables 8 and 11's alpha columns replaced by
    nonsense, the table-level evaluation runs and gives the same residuals, bit for bit."""
    for mod in (sim, validation):
        for name in ("simulate_alpha", "simulate_alpha_batch", "simulate_runs", "validate_runs"):
            if hasattr(mod, name):
                monkeypatch.setattr(mod, name, _forbidden)
    t11 = paper.table11()
    t8 = paper.table8()
    monkeypatch.setattr(paper, "table11", lambda: [
        {**r, "median_alpha_rad": 1e3 * (i + 1), "p90_alpha_rad": -1.0} for i, r in enumerate(t11)])
    monkeypatch.setattr(paper, "table8", lambda: [
        {**r, "magnitude_p90_alpha": 1e9, "phase_p90_alpha_deg": -1e9} for r in t8])
    again = cal.evaluate(om.load_model(), cal.ex.SINE_AMPLITUDE_RAD, steps=True)
    assert np.array_equal(cal.residuals(again, "tables"), cal.residuals(evaluation, "tables"))


def test_step_figures_match_the_reproduction(evaluation):
    """The calibration's Table 11 linear column is the reproduction's: the default scene's
    median over poses is the committed comparison's (docs/friction/comparison.json: 3.10 mrad),
    here re-measured; the linear model is 3-4x more accurate on the virtual Omni than on the
    real one (11.2 mrad), which is what the table-level search is about."""
    med = evaluation["steps"]["median_over_poses_rad"]
    real = float(np.median([r["median_linear_rad"] for r in paper.table11()]))
    assert real == pytest.approx(0.0112, abs=5e-5)
    assert 2.5 < real / med < 4.5, med


# -- the matched scene ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def matched():
    import json

    record = json.loads((om.MODELS_DIR / "calibration_matched.json").read_text())
    fig = cal.evaluate(om.load_model(friction="matched"), cal.ex.SINE_AMPLITUDE_RAD, steps=True)
    return record, fig


def test_matched_scene_is_both_families_on_the_shared_robot():
    """scene_matched.xml: the LuGre drive *and* a hard stick, on the robot every family shares
    (same masses, inertias, servo gains as the lugre scene)."""
    from omni_sim.device import Device

    m, lug = om.load_model(friction="matched"), om.load_model(friction="lugre")
    f = Device(m).friction()
    assert f["frictionloss"] > 0 and f["lugre_Fc"] > 0
    for field in ("body_mass", "body_inertia", "actuator_gainprm", "dof_armature"):
        assert np.array_equal(getattr(m, field)[:len(getattr(lug, field))], getattr(lug, field)), field
    assert "matched" in om.FRICTION_FAMILIES and om.builtin_family(om.scene_path("matched")) == "matched"


def test_matched_scene_meets_its_record(matched):
    """The matched scene, re-measured here with the table-level targets, gives its record's
    figures (tolerance: 1 % of each figure or 0.2 mrad; the record was measured on one CPU, and
    stick-slip amplifies last-bit differences of other CPUs), and keeps the published tables it
    met: Table 11's linear column (median within 25 % of 11.2 mrad, >= 20 of 25 poses within
    40 %), Table 9's resonance, the angles, Table 10's fall >= 3x, section 2.3."""
    record, fig = matched
    rec = record["achieved"]
    steps = fig["steps"]
    assert steps["median_over_poses_rad"] == pytest.approx(rec["step_median_rad"], rel=0.01, abs=2e-4)
    assert abs(steps["within_40pct"] - rec["poses_within_40pct"]) <= 1
    assert abs(steps["median_over_poses_rad"] / 0.0112 - 1) <= 0.25
    assert steps["within_40pct"] >= 20
    worst_c = max((p["C_linear"] / p["C_paper"] - 1 for p in fig["poses"]), key=abs)
    assert worst_c == pytest.approx(rec["table3_C_worst_rel"], abs=0.01)
    assert abs(fig["detail"]["resonance_hz"] - cal.TABLE9_RESONANCE_HZ) <= 0.3
    assert fig["C_alpha_fall"] >= 3.0 and cal.min_margin(fig) <= cal.MARGIN_TARGET
    assert 0.5 * float(cal.residuals(fig, "tables") @ cal.residuals(fig, "tables")) == pytest.approx(
        record["cost"], rel=0.05)
    tried = {c["id"] for c in record["candidates_tried"]}
    assert record["from_candidate"] in tried and len(tried) >= 30
