"""The fidelity screen (omni_studies/fidelity_screen.py, omni_app/fidelity_screen_report.py): its
configurations are valid library effects inside their bounds, and what it writes never holds an
alpha-model key (the pipeline is replaced by a stub)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from omni_app import fidelity_screen_report as writer
from omni_studies import fidelity_screen


@pytest.fixture(scope="module")
def screen():
    return fidelity_screen


def _keys(x):
    if isinstance(x, dict):
        for k, v in x.items():
            yield k
            yield from _keys(v)
    elif isinstance(x, list):
        for v in x:
            yield from _keys(v)


def test_configurations_are_library_effects_inside_their_bounds(screen):
    from discrepancy import effects

    ids = [c["id"] for c in screen.CONFIGURATIONS]
    assert len(ids) == len(set(ids)) and len(ids) <= 45
    for c in screen.CONFIGURATIONS:
        assert c["base"] in screen.BASES and c["provenance"]
        if c["effect"] is None:
            continue
        lo, hi = effects.get(c["effect"]).bounds()
        v = np.asarray(c["values"])
        assert v.shape == lo.shape and np.all(v >= lo) and np.all(v <= hi), c["id"]


def test_a_configuration_compiles_with_its_effect(screen):
    cfg = next(c for c in screen.CONFIGURATIONS if c["id"] == "lugre/time_delay/5ms")
    import mujoco

    m = screen.build_model(cfg)
    a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "yaw_motor")
    assert m.actuator_delay[a] == pytest.approx(0.005)


def test_strip_alpha_drops_nested_keys(screen):
    d = {"a": 1, "alpha_model": 2, "x": [{"median_abs_error_alpha_rad": 3, "b": {"C_alpha": 4, "c": 5}}]}
    assert screen.strip_alpha(d) == {"a": 1, "x": [{"b": {"c": 5}}]}


def test_written_files_hold_no_alpha_key(screen, tmp_path, monkeypatch):
    """A stubbed pipeline that returns alpha scores: none reaches the JSON or the page."""
    def fake_measure(model, jobs=None):
        rows = [{"set_deg": [0, 90], "median_linear_rad": 0.004, "p90_linear_rad": 0.01}]
        return {"ok": True, "warnings": [], "resonance_hz_65_90": 3.4,
                "median_abs_error_alpha_rad": 0.001, "alpha_better_poses": 25,
                "table3": {"n_poses": 9, "C_linear_worst_rel_error": -0.1,
                           "beta_tilde_linear_worst_rel_error": 0.05, "angle_worst_error_deg": -1.1,
                           "C_alpha_fall": 3.0, "poses": []},
                "step_linear": {**screen.summarise_steps(rows), "ratio_of_medians_alpha": 3.0}}

    monkeypatch.setattr(screen, "measure_model", fake_measure)
    out = tmp_path / "screen.json"
    writer.run_screen(out, ["lugre/none/base", "lugre/armature/2e-4"], rerun=True)
    doc = json.loads(out.read_text())
    assert [r["id"] for r in doc["configurations"]] == ["lugre/none/base", "lugre/armature/2e-4"]
    assert not [k for k in _keys(doc) if "alpha" in k.lower()]
    assert doc["configurations"][0]["step_linear"]["poses_within_40pct"] in (0, 1)
    page = (tmp_path / "screen.md").read_text()
    assert "alpha model was not computed" in page and "| lugre | armature | 2e-4 | 4.00 / 10.00 |" in page
    assert (tmp_path / "screen.png").stat().st_size > 1000
    # --merge keeps what is there and runs only the missing ones
    calls = []
    monkeypatch.setattr(screen, "measure_model", lambda m, jobs=None: calls.append(1) or fake_measure(m))
    writer.run_screen(out, ["lugre/none/base", "lugre/armature/5e-5"], merge=True, rerun=True)
    assert len(calls) == 2  # --only re-runs what it names
    doc = json.loads(out.read_text())
    assert len(doc["configurations"]) == 3
    calls.clear()
    writer.run_screen(out, ["lugre/none/base", "lugre/armature/5e-5", "lugre/backlash/1count"],
                      merge=True)
    assert len(calls) == 1  # without --only: only the missing one
