"""The test halves' ``make.py`` checks, shared by tests/test_bank_test_half*.py: a folder's
bytes by file (:func:`digest`), and a half's make run twice with its seed and once with another,
its runs read back through the dataset contract (:func:`check_make_keeps_the_contract`: the
second, third and fourth halves)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from bank.test_half import truths as tr


def digest(folder: Path) -> dict:
    """Each file under ``folder`` (its path relative to it) -> the SHA-256 of its bytes."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def check_make_keeps_the_contract(make, tmp_path: Path, cases: tuple[str, str], seed: int) -> None:
    """``make`` of a half on ``cases`` (quick): the same seed gives the same bytes and another
    seed other bytes; the runs read back through the dataset contract with their metadata,
    jittered log intervals and encoder counts; cases.json holds each case's law, source,
    equation, plant factors and expectation; the default seed is ``seed``."""
    from identification.dataset import read_dataset
    args = ["--only", ",".join(cases), "--quick"]
    assert make.main(["--out", str(tmp_path / "a"), *args]) == 0
    assert make.main(["--out", str(tmp_path / "b"), *args]) == 0
    assert make.main(["--out", str(tmp_path / "c"), "--seed", "7", *args]) == 0
    a, b, c = (digest(tmp_path / x) for x in "abc")
    assert a == b and len(a) == 2 * 4 + 1
    assert a["j_null/lift_and_drop.csv"] != c["j_null/lift_and_drop.csv"]
    for case in cases:
        runs = read_dataset(tmp_path / "a" / case, purpose="discrepancy")
        assert len(runs) == 2
        for r in runs:
            assert {"kind", "kp", "command_limit", "control_period_s", "encoder_step_rad", "units"} <= set(r.meta)
            assert r.meta["kp"] == 30.0 and r.meta["command_limit"] == 12.0
            assert r.meta["control_period_s"] == 0.001
            dt = np.diff(r.t)
            assert dt.min() >= 3.5e-3 - 1e-12 and dt.max() <= 6.5e-3 + 1e-12 and np.ptp(dt) > 1e-3
            assert np.allclose(np.round(r.theta / tr.ENCODER_STEP_RAD) * tr.ENCODER_STEP_RAD, r.theta)
            assert np.all(np.isfinite(r.theta)) and np.all(np.abs(r.v) <= 12.0)
    doc = json.loads((tmp_path / "a" / "cases.json").read_text())
    assert doc["seed"] == make.DEFAULT_SEED == seed and [x["name"] for x in doc["cases"]] == list(cases)
    for case in doc["cases"]:
        assert {"law", "source", "equation", "params", "plant", "plant_factors", "expected",
                "model", "joint", "actuator"} <= set(case)
        assert all(0.85 <= f <= 1.15 and abs(f - 1) >= 0.05 - 1e-12 for f in case["plant_factors"].values())
