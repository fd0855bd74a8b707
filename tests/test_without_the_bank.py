"""The library without its validation bank, as a regular ``pip install .`` has it: the bank
(``bank/``, a distribution of its own) is hidden from imports here (``sys.modules[name] = None``
makes ``import bank`` fail as a missing package does).  The commands that run the bank's cases
refuse at once, in one ``error:`` line naming the fix, exit 2, before any computation; the
others, the demo among them, run."""

from __future__ import annotations

import json
import sys

import pytest

from identification.errors import UserError
from omni_app.cli import main

FIX = "pip install -e ./bank"


@pytest.fixture
def no_bank(monkeypatch):
    """Every import of the bank fails with ModuleNotFoundError, as without the distribution."""
    for name in [m for m in sys.modules if m == "bank" or m.startswith("bank.")] + ["bank"]:
        monkeypatch.setitem(sys.modules, name, None)


@pytest.fixture
def nothing_runs(monkeypatch):
    """Any simulation or workflow run fails the test (the refusal comes first)."""
    import discrepancy.workflow
    from omni_sim import experiments as ex

    def boom(*a, **k):
        raise AssertionError("a computation started before the refusal")

    monkeypatch.setattr(ex, "simulate", boom)
    monkeypatch.setattr(discrepancy.workflow, "run_discrepancy", boom)
    import omni_studies.bench
    monkeypatch.setattr(omni_studies.bench, "_bench_discrepancy_servo", boom)


def _one_error_line(capsys, *words) -> str:
    err = capsys.readouterr().err
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
    for w in (FIX,) + words:
        assert w in err, (w, err)
    return err


def test_the_hidden_bank_is_missing(no_bank):
    """The fixture does hide it (the tests below would pass trivially otherwise)."""
    with pytest.raises(ModuleNotFoundError):
        import bank.hidden  # noqa: F401


def test_the_door_names_the_fix(no_bank):
    from omni_studies import bank_link
    with pytest.raises(UserError) as e:
        bank_link.load("this test")
    assert str(e.value).startswith("this test runs cases of the validation bank, which is not installed")
    assert FIX in str(e.value)


def test_the_door_opens_with_the_bank():
    from omni_studies import bank_link
    bank = bank_link.load("this test")
    assert bank.hidden.case("time_delay").effects == (("time_delay", (0.004,)),)
    assert bank.servo_truth.JOINT == "pivot"


@pytest.mark.parametrize("argv", [["bench", "--only", "discrepancy_servo"], ["bench"],
                                  ["bench", "--discrepancy-campaign"]])
def test_bench_refuses_without_the_bank(no_bank, nothing_runs, capsys, tmp_path, argv):
    out = tmp_path / "figures.json"
    assert main(argv + ["--out", str(out)]) == 2
    _one_error_line(capsys, "omni bench")
    assert not out.exists()


def test_bench_campaign_refuses_without_the_bank(no_bank, nothing_runs):
    from omni_studies.bench import bench_discrepancy_campaign
    with pytest.raises(UserError, match="pip install -e ./bank"):
        bench_discrepancy_campaign()


def test_sweep_discrepancy_refuses_without_the_bank(no_bank, nothing_runs, capsys, tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text('[base]\nfriction = "lugre"\n[pipeline]\nname = "discrepancy"\nhidden = "armature"\n'
                    '[grid]\nkp = [1.0, 2.0]\n')
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out)]) == 2
    _one_error_line(capsys, f"{spec}: pipeline: ", "omni sweep's discrepancy pipeline")
    assert not out.exists()  # nothing started


def test_sweep_without_the_bank_runs_other_pipelines(no_bank, tmp_path):
    """Only the discrepancy pipeline needs the bank: a simulate study parses."""
    from omni_studies import sweep as sw
    study = sw.parse_study('[base]\nfriction = "lugre"\n[pipeline]\nname = "simulate"\n[grid]\nkp = [1.0]\n',
                           "s.toml", tmp_path)
    assert study.pipeline["name"] == "simulate"


@pytest.mark.slow
def test_demo_runs_without_the_bank(no_bank, tmp_path, capsys):
    """``omni discrepancy --demo`` hides its delay and finds it with the library alone (~1 min;
    its output is docs/studies/discrepancy/example's, but for timings: tests/test_demo.py checks
    its truth and runs are the bank's case's)."""
    out = tmp_path / "demo"
    assert main(["discrepancy", "--demo", "--out", str(out)]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert [(e["name"], e["confidence"]) for e in rep["effects"]] == [("time_delay", "high")]
    assert rep["hidden"]["effects"] == {"time_delay": [0.004]}
    assert len(list((out / "measured").glob("*.csv"))) == 16
    assert "bank" not in sys.modules or sys.modules["bank"] is None
