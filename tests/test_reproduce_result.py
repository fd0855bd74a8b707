"""The reproduce study's results as objects (:mod:`omni_studies.reproduce`): frozen, and their
JSON is the committed records' (``summary.json``), key for key and byte for byte."""

import dataclasses
import json
from pathlib import Path

import pytest

from omni_studies import reproduce as rp

DOCS = Path(__file__).resolve().parents[1] / "docs" / "studies"
#: Every committed ``summary.json`` of ``omni reproduce`` (the paper's run and each friction family's).
RECORDS = sorted([DOCS / "reproduce" / "summary.json", *(DOCS / "friction").glob("*/summary.json")])
#: The writer's wall times: in summary.json, never in the result.
WRITER_KEYS = {"wall_s_total", "real_time_factor"}

#: A small campaign (6 Table 1 poses, enough for the inertia model; one step run): seconds.
CAMPAIGN = """
[sine]
poses_deg = [[25, 70], [25, 115], [45, 90], [65, 70], [65, 90], [65, 115]]
frequencies_hz = [2.5, 3.0, 3.5, 5.0]
amplitude_rad = 0.05
settle_s = 2.0
record_s = 1.2

[step]
poses_deg = [[65, 90]]
frequency_hz = 0.5
amplitude_rad = 0.07
duration_s = 4.0
"""


def _paths(d, prefix=()):
    """Every key path of a JSON object (a list's rows: the first one's paths)."""
    out = set()
    for k, v in d.items():
        out.add(prefix + (k,))
        if isinstance(v, dict):
            out |= _paths(v, prefix + (k,))
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            out |= _paths(v[0], prefix + (k, "[]"))
    return out


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """One reproduction of :data:`CAMPAIGN`, its first stage kept: ``(sim, result)``."""
    from omni_sim.device import Device

    camp = tmp_path_factory.mktemp("camp") / "camp.toml"
    camp.write_text(CAMPAIGN)
    sim = rp.simulate_campaign(Device.load(friction="lugre"), jobs=1, campaign=str(camp))
    return sim, rp.analyse(sim)


@pytest.mark.parametrize("record", RECORDS, ids=lambda p: p.parent.name)
def test_summary_round_trips_the_committed_record(record):
    """A committed summary.json read into a :class:`ReproduceSummary` and written back, with
    the record's own total wall time, is the same text byte for byte (keys, their order,
    values, the real-time factor recomputed)."""
    text = record.read_text()
    d = json.loads(text)
    summary = rp.ReproduceSummary.from_json(d)
    assert json.dumps(summary.to_json(d["run"]["wall_s_total"]), indent=2) + "\n" == text
    assert summary.run.real_time_factor(d["run"]["wall_s_total"]) == d["run"]["real_time_factor"]


def test_a_result_writes_the_committed_records_keys(small):
    """The JSON of a result computed now has exactly the key paths of the committed record
    (the writer's wall times only when it passes its own)."""
    _, res = small
    committed = _paths(json.loads((DOCS / "reproduce" / "summary.json").read_text()))
    assert _paths(res.summary.to_json(2.5)) == committed
    assert _paths(res.summary.to_json()) == {p for p in committed if p[-1] not in WRITER_KEYS}
    scores = res.to_json(2.5)
    assert list(scores) == ["summary", "sine", "step"] and scores["summary"] == res.summary.to_json(2.5)
    assert len(scores["sine"]) == 6 and len(scores["step"]) == 1
    run = scores["summary"]["run"]
    assert run["real_time_factor"] == run["simulated_time_s"] / 2.5


def test_results_are_frozen(small):
    """Nothing downstream can change a result or the first stage's state: assignment raises."""
    sim, res = small
    section = res.summary.step.windows.whole_record
    for obj, field in ((res, "summary"), (res, "ident"), (sim, "runs"), (res.summary, "run"),
                       (res.summary.run, "wall_s_before_writing"), (res.summary.inertia, "max_rel_error"),
                       (res.summary.inertia.poses[0], "rel_error"), (res.summary.sine, "n_poses"),
                       (section, "ratio_of_medians"), (res.summary.alpha_simulation, "steps")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, field, None)
    assert isinstance(sim.runs, tuple) and isinstance(res.runs, tuple)
    assert isinstance(res.summary.inertia.poses, tuple)


def test_analyse_leaves_its_input_alone(small):
    """A second analysis of the same first stage gives the same figures (nothing of the first
    was stored in ``sim``), in a new object; only the measured wall time differs."""
    sim, res = small
    before = [f.name for f in dataclasses.fields(sim)], sim.runs, sim.started
    again = rp.analyse(sim)
    assert ([f.name for f in dataclasses.fields(sim)], sim.runs, sim.started) == before
    assert again is not res and again.runs is sim.runs
    first, second = res.to_json(), again.to_json()
    for d in (first, second):
        d["summary"]["run"].pop("wall_s_before_writing")
    assert json.dumps(first) == json.dumps(second)
