"""The validation's results as objects (:mod:`identification.validation`): frozen, their JSON
is the committed records' sections (``summary.json``'s ``sine``, ``step``, ``alpha_simulation``)
key for key and byte for byte, and ``scores, predictions = validate_runs(...)`` unpacks as it
did when the function returned that pair."""

import dataclasses
import json

import pytest

from identification.validation import Params, StepSummary, Validation, ValidationSummary, validate_runs
from test_reproduce_result import CAMPAIGN, DOCS, RECORDS, _paths

#: The sections of a reproduction's summary.json that are the validation's.
SECTIONS = ("sine", "step", "alpha_simulation")


@pytest.fixture(scope="module")
def validated(tmp_path_factory):
    """The runs of :data:`CAMPAIGN` validated with their own identification, with its α model
    and without: ``(runs, with_alpha, linear_only)``."""
    from identification.identify import identify_runs
    from omni_sim.device import Device
    from omni_studies.reproduce import simulate_campaign

    camp = tmp_path_factory.mktemp("camp") / "camp.toml"
    camp.write_text(CAMPAIGN)
    runs = list(simulate_campaign(Device.load(friction="lugre"), jobs=1, campaign=str(camp)).runs)
    ident = identify_runs(runs)
    poses = ident.to_params()["poses"]
    with_alpha = validate_runs(runs, Params(ident.inertia.params, ident.alpha_model, poses))
    linear = validate_runs(runs, Params(ident.inertia.params, None, poses, "params has no alpha_model"))
    return runs, with_alpha, linear


@pytest.mark.parametrize("record", RECORDS, ids=lambda p: p.parent.name)
def test_sections_round_trip_the_committed_record(record):
    """A committed summary.json's validation sections read into a :class:`ValidationSummary`
    and written back are the same text (keys, their order, values); ``inertia`` is null."""
    d = json.loads(record.read_text())
    out = ValidationSummary.from_json(d).to_json()
    assert list(out) == ["inertia", *SECTIONS] and out["inertia"] is None
    for key in SECTIONS:
        assert json.dumps(out[key], indent=2) == json.dumps(d[key], indent=2), key


def test_a_validation_writes_the_committed_records_keys(validated):
    """validate's summary computed now has exactly the key paths of the committed record's
    sections (the record's inertia and run are omni reproduce's own); scores.json is the
    summary and the rows."""
    runs, val, _ = validated
    committed = _paths(json.loads((DOCS / "reproduce" / "summary.json").read_text()))
    mine = {p for p in committed if p[0] in SECTIONS} | {("inertia",)}
    assert _paths(val.summary.to_json()) == mine
    scores = val.to_json()
    assert list(scores) == ["summary", "sine", "step"] and scores["summary"] == val.summary.to_json()
    assert len(scores["sine"]) == 6 and len(scores["step"]) == 1
    assert set(val.predictions) == {r.name for r in runs}
    assert val.summary.alpha_simulation.steps == sum(len(r.t) for r in runs)


def test_the_linear_model_alone(validated):
    """Without an α model (README: α scores null, the reason in ``alpha_not_scored``): every α
    figure and ratio of the step section is None, the reason is the summary's last key, and
    the linear figures are the ones scored beside an α model."""
    _, both, linear = validated
    d = linear.summary.to_json()
    assert list(d)[-1] == "alpha_not_scored" and d["alpha_not_scored"] == "params has no alpha_model"
    assert "alpha_not_scored" not in both.summary.to_json()
    assert linear.summary.alpha_simulation is None and linear.summary.sine.magnitude_p90_alpha is None
    for section in (d["step"], *d["step"]["windows"].values()):
        nulls = {k for k, v in section.items() if v is None}
        assert nulls == {k for k in section if "alpha" in k or k.startswith("ratio_")}, nulls
    assert linear.summary.step.median_abs_error_linear_rad == both.summary.step.median_abs_error_linear_rad
    assert ValidationSummary.from_json(d) == linear.summary


def test_it_unpacks_as_the_pair_it_was(validated):
    """``scores, predictions = validate_runs(...)``: scores.json's dict (a new one each time)
    and the predictions."""
    _, val, _ = validated
    scores, predictions = val
    assert scores == val.to_json() and scores is not val.to_json()
    assert predictions is val.predictions
    assert scores["summary"]["step"]["median_abs_error_linear_rad"] == val.summary.step.median_abs_error_linear_rad


def test_validations_are_frozen(validated):
    """Nothing downstream can change a validation: assignment raises, nested sections too."""
    _, val, _ = validated
    s = val.summary
    for obj, field in ((val, "summary"), (val, "sine_rows"), (s, "step"), (s, "alpha_not_scored"),
                       (s.sine, "n_poses"), (s.step, "ratio_of_medians"), (s.step.windows, "after_edges"),
                       (s.step.windows.whole_record, "n_runs"), (s.alpha_simulation, "steps")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, field, None)
    assert isinstance(val, Validation) and isinstance(s.step, StepSummary)
    assert isinstance(val.sine_rows, tuple) and isinstance(val.step_rows, tuple)
