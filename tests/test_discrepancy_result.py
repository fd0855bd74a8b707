"""discrepancy.result: the workflow's result reads its typed verdict from report.json's own
numbers (a committed report, written by the command, is the independent record), and is frozen."""

import dataclasses
import json
from pathlib import Path

import pytest

from discrepancy import Correction, DiscrepancyResult, NamedEffect
from discrepancy.workflow import Outcome

ROOT = Path(__file__).resolve().parents[1]
#: Two committed reports: one names an effect (the demo), one names none after corrections
#: (the real servo).
DEMO = ROOT / "docs" / "studies" / "discrepancy" / "example" / "report.json"
REAL = ROOT / "examples" / "real_servo" / "report" / "report.json"


def _result(path: Path) -> DiscrepancyResult:
    return DiscrepancyResult(json.loads(path.read_text()), None, [], [], [])


def test_named_effects_are_the_reports_entries():
    rep = json.loads(DEMO.read_text())
    res = _result(DEMO)
    named = [e for e in rep["effects"] if e["name"] != "none"]
    assert named and [e.name for e in res.named] == [e["name"] for e in named]
    for e, j in zip(res.named, named):
        assert isinstance(e, NamedEffect)
        assert dict(e.parameters) == j["parameters"] and dict(e.uncertainty) == j["uncertainty"]
        assert dict(e.units) == j["units"] and e.confidence == j["confidence"]
        assert e.runner_up == j["runner_up"] and e.margin == j["margin"]
        with pytest.raises(TypeError):
            e.parameters["x"] = 1.0  # read-only
    assert res.gap_before == rep["gap_before"] and res.gap_after == rep["gap_after"]
    assert res.shrink_factor == rep["shrink_factor"] and res.noise_floor_rad == rep["noise_floor_rad"]
    assert res.unexplained is rep["unexplained"] and res.to_json() is res.report


def test_corrections_and_nothing_named():
    rep = json.loads(REAL.read_text())
    res = _result(REAL)
    assert res.named == () and rep["effects"][0]["name"] == "none"
    assert len(res.corrections) == len(rep["corrections"]) > 0
    for c, j in zip(res.corrections, rep["corrections"]):
        assert isinstance(c, Correction)
        assert (c.effect, c.parameter, c.unit, c.nominal, c.fitted) == (
            j["effect"], j["parameter"], j["unit"], j["nominal"], j["fitted"])
        assert c.plausible is bool(j["plausible"])
    assert res.unexplained is True
    # a correction confounded with a named law (report.json's form, discrepancy/report.py)
    entry = dict(rep["corrections"][0], confounded_with=[
        {"effect": "load_friction", "parameter": "mu_back", "correlation": -0.93}])
    assert Correction.from_json(entry).confounded_with == (("load_friction", "mu_back", -0.93),)


def test_frozen_and_the_former_name():
    res = _result(DEMO)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.report = {}
    assert Outcome is DiscrepancyResult
