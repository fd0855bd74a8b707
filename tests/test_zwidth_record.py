"""The Z-width map's results as objects (:mod:`omni_studies.zwidth`): :func:`passivity_map`
returns a frozen :class:`PassivityMap`, ``zwidth.json`` is a frozen :class:`MapRecord` whose
JSON is the committed records', key for key and byte for byte."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import omni_studies.zwidth as zw
from test_reproduce_result import _paths

HAPTICS = Path(__file__).resolve().parents[1] / "docs" / "studies" / "haptics"
#: Every committed record of ``omni zwidth`` (the default, ideal and exact-encoder maps).
RECORDS = sorted(HAPTICS.glob("zwidth_*.json"))


@pytest.fixture(scope="module")
def small():
    """A 2 x 4 map of the ideal device, as ``omni zwidth --ideal`` runs it: ``(res, record)``."""
    dev, tlim = zw.map_device(ideal=True)
    K, B = np.linspace(0.0, 20.0, 4).tolist(), [0.0, 0.003]
    res = zw.passivity_map(dev, K, B, torque_limit=tlim, duration_s=0.5)
    settings = zw.MapSettings(model=None, friction="ideal", ideal=True, quantize=False, delay_periods=0,
                              physics_substeps=dev.substeps, probe_speed=zw.PROBE_SPEED,
                              probe_periods=zw.PROBE_PERIODS, start_penetration_rad=zw.START_PENETRATION,
                              duration_s=0.5, settle_fraction=zw.SETTLE_FRACTION, tolerance=zw.TOL,
                              torque_limit=tlim, encoder_step_rad=4e-4, elapsed_s=1.0)
    return res, zw.map_record(dev, K, B, res, settings)


#: Keys that ``omni zwidth`` added after the ideal and exact-encoder maps were committed.
LATER_KEYS = {"beyond_boundary", "probe_amplitude_counts", "notes", "settings.encoder_step_rad"}


def _keys(d: dict) -> set:
    return set(d) | {f"settings.{k}" for k in d["settings"]}


def test_the_committed_records_and_their_format():
    """The default map has every key a record has now; the two older maps lack exactly the
    keys added since (they are read as they are by the docs' checks, not as records)."""
    now = {f.name for f in dataclasses.fields(zw.MapRecord)} | {
        f"settings.{f.name}" for f in dataclasses.fields(zw.MapSettings)} | {"settings"}
    found = {p.stem: _keys(json.loads(p.read_text())) for p in RECORDS}
    assert found == {"zwidth_default": now, "zwidth_ideal": now - LATER_KEYS,
                     "zwidth_lugre_exact": now - LATER_KEYS}


def test_the_committed_record_round_trips():
    """The committed default zwidth.json read into a :class:`MapRecord` and written as ``omni
    zwidth`` writes it is the same text byte for byte (keys, their order, values), and its
    notes are the tool's own."""
    text = (HAPTICS / "zwidth_default.json").read_text()
    rec = zw.MapRecord.from_json(json.loads(text))
    assert json.dumps(rec.to_json(), indent=1) + "\n" == text
    assert list(rec.notes) == zw.map_notes(rec.to_json()) and len(rec.notes) == 2


def test_a_map_writes_the_committed_records_keys(small):
    """The record of a map computed now has exactly the key paths of the committed default
    map (settings and the per-probe keys included); its cells are the map's."""
    res, rec = small
    committed = json.loads((HAPTICS / "zwidth_default.json").read_text())
    d = rec.to_json()
    assert _paths(d) == _paths(committed) and list(d) == list(committed)
    assert d["passive"] == res.passive.tolist() and list(d["energy_index_per_probe"]) == ["1", "4", "16"]
    assert d["colgate_stiffness"] == zw.colgate_limit(rec.physical_damping, [0.0, 0.003], 1e-3).tolist()
    assert zw.MapRecord.from_json(d) == rec


def test_map_results_are_frozen(small):
    """Nothing downstream can change a map or its record: assignment raises, nested too."""
    res, rec = small
    for obj, field in ((res, "passive"), (res, "index"), (rec, "passive"), (rec, "notes"),
                       (rec, "settings"), (rec.settings, "elapsed_s")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, field, None)
    assert isinstance(rec.passive, tuple) and isinstance(rec.passive[0], tuple)
    assert isinstance(res.probe_periods, tuple) and res.trace is None
