"""mujoco.sysid beside the discrepancy fit (bank/studies/sysid_compare.py, its page
bank/writers/sysid_report.py, scripts/sysid_compare.py).  The page is the record rendered; the record
holds every case and method with figures that agree with each other, with the models (truths,
bounds, start) and with a replay of two of its estimates; mujoco.sysid stays out of the project's
dependencies.  The study itself (minutes of fits, and mujoco.sysid's extra) is not rerun here."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from bank.writers import sysid_report as sr
from bank import servo_truth
from discrepancy.replay import Replayer
from bank.studies import sysid_compare as sc

ROOT = Path(__file__).resolve().parents[1]
RECORD = json.loads((ROOT / "docs/studies/discrepancy" / sr.JSON_NAME).read_text())
PAGE = (ROOT / "docs/studies/discrepancy" / sr.MD_NAME).read_text()
CASES = {c["id"]: c for c in RECORD["cases"]}
METHODS = ("ours", "ours_workflow", "sysid_open", "sysid_closed", "sysid_closed_scaled")


def test_the_page_is_the_record_rendered():
    assert PAGE == sr.render(RECORD)


def test_the_record_holds_every_case_and_method():
    assert list(CASES) == list(sc.CASES)
    assert re.fullmatch(r"[0-9a-f]{40}", RECORD["code_commit"])
    assert all(c["code_commit"] == RECORD["code_commit"] for c in RECORD["cases"])
    assert RECORD["uncommitted_code"] == []  # the study ran the committed code
    assert RECORD["mujoco"] == mujoco.__version__
    for c in RECORD["cases"]:
        assert set(c["methods"]) == set(METHODS), c["id"]


def test_truths_are_the_models():
    """servo_off's truths are models/servo_pendulum/servo_pendulum.xml's constants; servo_load's the hidden
    law's coefficients; the other two cases have none."""
    m = mujoco.MjModel.from_xml_path(str(servo_truth.model_path()))
    dof = int(m.jnt_dofadr[m.joint(servo_truth.JOINT).id])
    a = m.actuator(servo_truth.ACTUATOR).id
    want = [m.dof_armature[dof], m.dof_damping[dof], m.dof_frictionloss[dof], m.actuator_gear[a, 0]]
    assert [p["truth"] for p in CASES["servo_off"]["parameters"]] == pytest.approx(want, rel=1e-12)
    assert [p["truth"] for p in CASES["servo_load"]["parameters"]] == [servo_truth.MU_DRIVE, servo_truth.MU_BACK]
    assert [p["name"] for p in CASES["servo_load"]["parameters"]] == ["load_friction.mu_drive",
                                                                       "load_friction.mu_back"]
    for cid in ("servo_load_mjcf", "feetech"):
        assert all(p["truth"] is None for p in CASES[cid]["parameters"])
        assert [p["name"].split(".")[0] for p in CASES[cid]["parameters"]] == list(sc.MJCF_SET)


def test_start_is_the_nominal_moved_off_the_bounds():
    for c in RECORD["cases"]:
        P = c["parameters"]
        lo, hi = np.array([p["lower"] for p in P]), np.array([p["upper"] for p in P])
        start = sc.off_bounds([p["nominal"] for p in P], lo, hi)
        assert [p["start"] for p in P] == pytest.approx(start.tolist(), rel=1e-12), c["id"]
        assert np.all((start > lo) & (start < hi))


@pytest.mark.parametrize("cid", sc.CASES)
def test_figures_agree(cid):
    """Every estimate inside the bounds with a non-negative interval per parameter, positive wall
    times and steps, a closed-loop gap; sysid's open loop holds no engine law (servo_load) and
    says why; the batched residual is sysid's own to rounding."""
    c = CASES[cid]
    P = c["parameters"]
    for key, m in c["methods"].items():
        if key == "sysid_open" and cid == "servo_load":
            assert m["represents"] is False and "control period" in m["reason"]
            continue
        assert "failed" not in m, (key, m.get("failed"))
        assert len(m["x"]) == len(m["half_width_95"]) == len(P), key
        for x, h, p in zip(m["x"], m["half_width_95"], P):
            assert p["lower"] <= x <= p["upper"], (key, p["name"])
            assert h >= 0, (key, p["name"])
        assert m["wall_s"] > 0 and m["physics_steps"] > 0, key
        assert m["gap_closed_loop_rad"] > 0, key
    assert c["hook_check"]["max_abs_difference"] < 1e-12
    if "drift" in c:
        assert c["drift"]["open_loop_truth_gap_rad"] > c["drift"]["closed_loop_truth_gap_rad"] > 0


def test_the_verdict_follows_its_rule():
    """judge: gap within GAP_TOL of ours and at least as many truths inside; the page's
    statements follow from the record (a changed figure changes them)."""
    v = sr.judge(CASES["servo_off"])
    for key, j in v.items():
        m = CASES["servo_off"]["methods"][key]
        ratio = m["gap_closed_loop_rad"] / CASES["servo_off"]["methods"]["ours"]["gap_closed_loop_rad"]
        truth = [p["truth"] for p in CASES["servo_off"]["parameters"]]
        n_in = sum(abs(x - t) <= h for x, h, t in zip(m["x"], m["half_width_95"], truth))
        assert j["same_job"] == (ratio <= 1 + sr.GAP_TOL and n_in >= v["ours"]["inside"]), key
    worse = copy.deepcopy(RECORD)
    case = next(c for c in worse["cases"] if c["id"] == "servo_off")
    case["methods"]["sysid_closed"]["gap_closed_loop_rad"] *= 2
    assert sr.judge(case)["sysid_closed"]["same_job"] is False
    assert sr.render(worse) != PAGE


def test_two_estimates_replay_to_their_recorded_gaps():
    """The closed-loop gaps of ours and sysid's open-loop estimate on servo_off, replayed here
    from the record's values (the same data, seed and model)."""
    case = sc.make_case("servo_off", None)
    with Replayer(1, case.target, case.period) as rep:
        for key in ("ours", "sysid_open"):
            m = CASES["servo_off"]["methods"][key]
            assert sc.closed_gap(case, rep, np.array(m["x"])) == pytest.approx(m["gap_closed_loop_rad"], rel=1e-6)


def test_sysid_is_not_a_dependency():
    text = (ROOT / "pyproject.toml").read_text()
    assert "sysid" not in text


def test_the_discrepancy_page_quotes_the_record():
    """docs/method/discrepancy.md's summary of the comparison: the closed-loop variants' physics steps
    against ours, over the cases, are the record's."""
    text = " ".join((ROOT / "docs/method/discrepancy.md").read_text().split())

    def ends(k):
        r = [c["methods"][k]["physics_steps"] / c["methods"]["ours"]["physics_steps"] for c in RECORD["cases"]]
        return sr.g(min(r), 2), sr.g(max(r), 2)

    a, b = ends("sysid_closed")
    c, d = ends("sysid_closed_scaled")
    assert f"at {a} to {b} times our physics steps (scaled as ours: {c} to {d} times)" in text
