"""Friction families on the command line, in the environment, the comparison and the study."""

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from identification.dataset import read_dataset
from omni_app import friction_study_report as friction_report
from omni_app import reproduce as rp
from omni_app.cli import main
from omni_sim import model as om
from omni_sim.device import Device
from omni_studies import friction_study
from omni_studies import reproduce as study_rp

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "identification" / "data"

# six sine poses (>= the inertia model's 6), the 65/90 detail pose in both halves
TINY = """
[sine]
poses_deg = [[25, 70], [25, 115], [45, 90], [65, 70], [65, 90], [65, 115]]
frequencies_hz = [2.0, 2.5, 3.0, 3.5, 4.0, 5.0]
amplitude_rad = 0.05
settle_s = 2.0
record_s = 2.0

[step]
poses_deg = [[45, 90], [65, 90]]
frequency_hz = 0.5
amplitude_rad = 0.07
duration_s = 2.0
"""

ONE_STEP = """
[step]
poses_deg = [[65, 90]]
frequency_hz = 1.0
amplitude_rad = 0.07
duration_s = 1.0
"""


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    d = tmp_path_factory.mktemp("campaigns")
    (d / "tiny.toml").write_text(TINY)
    (d / "one_step.toml").write_text(ONE_STEP)
    return d


def _cli(args, cwd):
    return subprocess.run([sys.executable, "-m", "omni_app", *args], cwd=cwd, capture_output=True,
                          text=True)


def _one_line_error(res):
    assert res.returncode == 2, res.stderr
    assert res.stderr.startswith("error:") and len(res.stderr.strip().splitlines()) == 1, res.stderr


class _Result:
    def __init__(self, returncode, stderr):
        self.returncode, self.stderr = returncode, stderr


def _main(args, capsys):
    """``omni ARGS`` in this process: (exit status, stderr) as a subprocess would give them."""
    capsys.readouterr()
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's errors
        code = exc.code
    return _Result(code, capsys.readouterr().err)


# -- omni generate ------------------------------------------------------------------------------
def test_generate_friction_metadata_and_physics(campaigns, tmp_path):
    camp = str(campaigns / "one_step.toml")
    runs = {}
    for label, extra in (("default", []), ("lugre", ["--friction", "lugre"]),
                         ("coulomb", ["--friction", "coulomb"]),
                         ("coulomb_file", ["--model", str(om.scene_path("coulomb"))])):
        assert main(["generate", "--campaign", camp, "--out", str(tmp_path / label), *extra]) == 0
        runs[label] = read_dataset(tmp_path / label)[0]
    assert runs["default"].meta["friction"] == "lugre"
    assert runs["lugre"].meta["friction"] == "lugre"
    assert runs["lugre"].meta["model"] == "scene_lugre.xml"
    assert runs["coulomb"].meta["friction"] == "coulomb"
    assert runs["coulomb"].meta["model"] == "scene_coulomb.xml"
    assert runs["coulomb_file"].meta["friction"] == "coulomb"
    # the default scene is the lugre family: same physics; coulomb is another
    np.testing.assert_array_equal(runs["default"].theta, runs["lugre"].theta)
    np.testing.assert_array_equal(runs["coulomb"].theta, runs["coulomb_file"].theta)
    assert np.max(np.abs(runs["coulomb"].theta - runs["lugre"].theta)) > 1e-3


def test_friction_family_of_user_and_in_memory_models():
    lugre, coulomb = om.load_model(friction="lugre"), om.load_model(friction="coulomb")
    assert Device(coulomb).friction_family() == "coulomb"      # compiled model: what its yaw carries
    assert Device(lugre).friction_family() == "lugre"
    Device(coulomb).scale_friction(0.0)
    assert Device(coulomb).friction_family() == "none"
    assert Device(lugre).friction_family(om.DEFAULT_SCENE) == "lugre"
    assert Device(coulomb).friction_family(om.scene_path("coulomb")) == "coulomb"  # the file's family


@pytest.mark.parametrize("command", [
    ["generate", "--campaign", "step"],
    ["reproduce"],
    ["discrepancy", "--measured", "nowhere"],
])
def test_friction_with_model_is_an_error(command, tmp_path, capsys):
    out = tmp_path / "out"
    res = _main([*command, "--out", str(out), "--friction", "coulomb", "--model",
                 str(om.scene_path("lugre"))], capsys)
    _one_line_error(res)
    assert "not both" in res.stderr
    assert not out.exists()


def test_reproduce_all_with_model_is_an_error(tmp_path, capsys):
    out = tmp_path / "out"
    res = _main(["reproduce", "--friction", "all", "--model", str(om.DEFAULT_SCENE), "--out", str(out)],
                capsys)
    _one_line_error(res)
    assert not out.exists()


@pytest.mark.parametrize("command", [["generate"], ["reproduce"], ["discrepancy", "--demo"],
                                     ["bench"]])
@pytest.mark.parametrize("value", ["viscous", "LUGRE", ""])
def test_bad_friction_value(command, value, tmp_path, capsys):
    res = _main([*command, "--friction", value, "--out", str(tmp_path / "out")], capsys)
    _one_line_error(res)
    assert "--friction" in res.stderr
    assert not (tmp_path / "out").exists()


def test_all_only_for_reproduce(tmp_path, capsys):
    for command in (["generate"], ["bench"], ["discrepancy", "--measured", "x"]):
        _one_line_error(_main([*command, "--friction", "all", "--out", str(tmp_path / "out")], capsys))
    assert not (tmp_path / "out").exists()


def test_friction_with_model_subprocess(tmp_path):
    """The same error from the installed command: one line, status 2, nothing written."""
    out = tmp_path / "out"
    res = _cli(["generate", "--friction", "lugre", "--model", str(om.DEFAULT_SCENE), "--out", str(out)],
               tmp_path)
    _one_line_error(res)
    assert not out.exists()


# -- omni discrepancy / omni bench ----------------------------------------------------------------
def test_discrepancy_friction_resolves_the_nominal_model(campaigns, tmp_path, monkeypatch):
    import omni_app.discrepancy as dc

    data = tmp_path / "measured"
    assert main(["generate", "--campaign", str(campaigns / "one_step.toml"), "--out", str(data)]) == 0
    seen = {}

    class Stop(Exception):
        pass

    def fake(runs, model_path=None, *, device=None, **kw):
        seen["model"], seen["device"] = model_path, device
        raise Stop

    monkeypatch.setattr(dc, "run_discrepancy", fake)
    with pytest.raises(Stop):
        main(["discrepancy", "--measured", str(data), "--friction", "coulomb", "--out", str(tmp_path / "d")])
    # the command compiles the nominal once and hands the workflow that device, not a path
    assert seen["model"] is None and Path(seen["device"].file).resolve() == om.scene_path("coulomb").resolve()
    with pytest.raises(Stop):
        main(["discrepancy", "--measured", str(data), "--out", str(tmp_path / "d")])
    assert seen["model"] is None and seen["device"].file is None  # no option: the built-in scene.xml
    assert main(["discrepancy", "--demo", "--friction", "lugre", "--out", str(tmp_path / "e")]) == 2
    assert not (tmp_path / "e").exists()


def test_bench_friction(campaigns, monkeypatch):
    import omni_studies.bench as bench
    from omni_sim import experiments as ex

    loaded = []
    real_load = bench.om.load_model

    def load(path=None, friction=None):
        m = real_load(path, friction)
        loaded.append(Device(m).friction())
        return m

    monkeypatch.setattr(bench.om, "load_model", load)
    tiny = ex.campaign(campaigns / "one_step.toml")
    monkeypatch.setattr(bench.ex, "campaign", lambda name: tiny)
    figs = bench.run_bench(jobs=1, repeats=1, extended=False, friction="coulomb")
    assert figs["friction"] == "coulomb"
    assert loaded[-1]["frictionloss"] > 0 and loaded[-1]["lugre_Fc"] == 0
    figs = bench.run_bench(jobs=1, repeats=1, extended=False)
    assert figs["friction"] == "lugre"
    assert loaded[-1]["frictionloss"] == 0 and loaded[-1]["lugre_Fc"] > 0

    seen = {}

    def fake_bench(jobs=None, friction=None, discrepancy_campaign=False, only=None):
        seen["friction"] = friction
        seen["discrepancy_campaign"] = discrepancy_campaign
        return {}

    monkeypatch.setattr(bench, "run_bench", fake_bench)
    assert main(["bench", "--friction", "coulomb"]) == 0
    assert seen == {"friction": "coulomb", "discrepancy_campaign": False}
    assert main(["bench", "--discrepancy-campaign"]) == 0
    assert seen == {"friction": None, "discrepancy_campaign": True}


# -- gymnasium ------------------------------------------------------------------------------------
def test_env_friction_option():
    import gymnasium as gym

    from omni_sim.env import InvalidOptionError

    env = gym.make("omni_sim/OmniYaw-v0", friction="coulomb", duration_s=0.2)
    m = env.unwrapped.model
    assert env.unwrapped.friction == "coulomb"
    assert Device(m).friction()["frictionloss"] > 0 and not Device(m).lugre_actuators()
    env.reset(seed=0)
    env.close()
    env = gym.make("omni_sim/OmniYaw-v0")
    assert env.unwrapped.friction == "lugre" and Device(env.unwrapped.model).lugre_actuators()
    with pytest.raises(InvalidOptionError, match="can only be given when"):
        env.reset(options={"friction": "coulomb"})
    env.close()
    for bad in ("dry", 3, "Coulomb"):
        with pytest.raises(InvalidOptionError, match="unknown friction family"):
            gym.make("omni_sim/OmniYaw-v0", friction=bad)
    with pytest.raises(InvalidOptionError, match="not both"):
        gym.make("omni_sim/OmniYaw-v0", friction="lugre", model_path=om.DEFAULT_SCENE)


# -- reproduce --friction all: comparison ---------------------------------------------------------
@pytest.fixture(scope="module")
def compared(campaigns, tmp_path_factory):
    out = tmp_path_factory.mktemp("all") / "cmp"
    assert rp.reproduce_all(out, jobs=1, campaign=str(campaigns / "tiny.toml")) == 0
    return out


def _csv(name):
    with open(DATA / name) as fh:
        return {(int(r["gamma1_set_deg"]), int(r["gamma2_set_deg"])): {k: float(v) for k, v in r.items()}
                for r in csv.DictReader(fh)}


@pytest.mark.slow  # > 10 s (the default suite's time, 2 cores)
def test_comparison_layout_and_shape(compared):
    names = {p.name for p in compared.iterdir()}
    assert {"coulomb", "lugre", "comparison.json", "comparison.md", "comparison_C_alpha.png",
            "comparison_bode.png", "comparison_step.png"} <= names
    for fam in om.FRICTION_FAMILIES:
        inner = {p.name for p in (compared / fam).iterdir()}
        assert {"summary.json", "report.md", "params.json", "dataset", "predictions",
                "fig11_12_bode.png"} <= inner
        assert json.loads((compared / fam / "summary.json").read_text())["run"]["friction"] == fam
    comp = json.loads((compared / "comparison.json").read_text())
    assert set(comp["families"]) == set(om.FRICTION_FAMILIES)
    for fam, c in comp["families"].items():
        assert c["friction"] == fam
        for key in ("table3", "resonance_hz_65_90", "C_alpha_fall", "inertia", "step", "sine",
                    "step_linear_vs_table11"):
            assert key in c, key
        assert set(c["step"]) >= {"ratio_of_medians_whole_record", "ratio_of_medians_after_edges"}
        assert set(c["sine"]) == {"phase_p90_linear_deg", "phase_p90_alpha_deg",
                                  "magnitude_p90_linear", "magnitude_p90_alpha"}
    md = (compared / "comparison.md").read_text()
    assert "| figure | paper | coulomb | lugre |" in md
    assert "not a calibration target" in md


@pytest.mark.parametrize("fam", om.FRICTION_FAMILIES)
@pytest.mark.slow  # > 10 s (the default suite's time, 2 cores)
def test_comparison_figures_recomputed_independently(compared, fam):
    c = json.loads((compared / "comparison.json").read_text())["families"][fam]
    params = json.loads((compared / fam / "params.json").read_text())
    summary = json.loads((compared / fam / "summary.json").read_text())
    t3 = _csv("table3_linear_coefficients.csv")
    errs_C, errs_b, errs_g = [], [], []
    for p in params["poses"]:
        t = t3[(round(p["gamma1_set_deg"]), round(p["gamma2_set_deg"]))]
        errs_C.append(p["C_linear"] / t["C_linear"] - 1)
        errs_b.append(p["beta_tilde_linear"] / t["beta_tilde_linear"] - 1)
        errs_g += [p["gamma1_deg"] - t["gamma1_deg"], p["gamma2_deg"] - t["gamma2_deg"]]
    assert c["table3"]["n_poses"] == len(params["poses"]) == 6
    assert c["table3"]["C_linear_worst_rel_error"] == pytest.approx(max(errs_C, key=abs), rel=1e-12)
    assert c["table3"]["beta_tilde_linear_worst_rel_error"] == pytest.approx(max(errs_b, key=abs), rel=1e-12)
    assert c["table3"]["angle_worst_error_deg"] == pytest.approx(max(errs_g, key=abs), rel=1e-12)
    p6590 = next(p for p in params["poses"] if (p["gamma1_set_deg"], p["gamma2_set_deg"]) == (65, 90))
    assert c["resonance_hz_65_90"] == pytest.approx(math.sqrt(p6590["beta_linear"]) / (2 * math.pi), rel=1e-12)
    # C(alpha, I) = 1/(C_k1 I): the fall C0/C3 is C_31/C_01 at any inertia
    ck1 = params["alpha_model"]["C_k1"]
    assert c["C_alpha_fall"] == pytest.approx(ck1[3] / ck1[0], rel=1e-12)
    errs_I = [r["rel_error"] for r in summary["inertia"]["poses"]]
    assert c["inertia"]["max_rel_error"] == pytest.approx(max(map(abs, errs_I)), rel=1e-12)
    assert c["inertia"]["worst_signed_rel_error"] == pytest.approx(max(errs_I, key=abs), rel=1e-12)
    # step ratio of medians from the predictions and the dataset
    med_lin, med_alp = [], []
    for run in read_dataset(compared / fam / "dataset"):
        if run.kind != "step":
            continue
        pred = np.genfromtxt(compared / fam / "predictions" / f"{run.name}.csv", delimiter=",", names=True)
        med_lin.append(np.median(np.abs(pred["theta_linear"] - run.theta)))
        med_alp.append(np.median(np.abs(pred["theta_alpha"] - run.theta)))
    assert c["step"]["ratio_of_medians_whole_record"] == pytest.approx(
        np.median(med_lin) / np.median(med_alp), rel=1e-9)
    t11 = _csv("table11_step_errors.csv")
    rows = c["step_linear_vs_table11"]["poses"]
    assert sorted(r["median_linear_rad"] for r in rows) == pytest.approx(sorted(med_lin), rel=1e-9)
    for r in rows:
        assert r["paper_median_linear_rad"] == t11[tuple(r["set_deg"])]["median_linear_rad"]
        assert r["paper_p90_linear_rad"] == t11[tuple(r["set_deg"])]["p90_linear_rad"]


def test_comparison_paper_column():
    from omni_studies.comparison import paper_figures

    p = paper_figures()
    with open(DATA / "table10_model_65_90.csv") as fh:
        t10 = {r["quantity"]: float(r["value"]) for r in csv.DictReader(fh)}
    assert p["C_alpha_fall"] == pytest.approx(t10["C0"] / t10["C3"], rel=1e-12)
    assert p["resonance_hz_65_90"] == pytest.approx(3.4, abs=0.05)  # Table 9 / the paper's text


def test_reproduce_all_refuses_a_non_empty_folder(tmp_path):
    out = tmp_path / "cmp"
    out.mkdir()
    (out / "comparison.json").write_text("{}")  # what a finished run leaves there, and no more
    res = _cli(["reproduce", "--friction", "all", "--out", str(out)], tmp_path)
    _one_line_error(res)
    assert [p.name for p in out.iterdir()] == ["comparison.json"]
    assert (out / "comparison.json").read_text() == "{}"


@pytest.mark.slow
def test_reproduce_all_cli(tmp_path):
    out = tmp_path / "all"
    assert main(["reproduce", "--friction", "all", "--out", str(out)]) == 0
    comp = json.loads((out / "comparison.json").read_text())
    for fam in om.FRICTION_FAMILIES:
        assert comp["families"][fam]["table3"]["n_poses"] == 9
        assert comp["families"][fam]["step"]["n_poses"] == 25
        assert len(list((out / fam / "predictions").glob("*.csv"))) == 106


# -- the friction study ---------------------------------------------------------------------------
@pytest.mark.slow  # 14 s CPU: three reproductions of the tiny campaign (the study end to end)
def test_friction_study_two_levels(campaigns, tmp_path):
    out = tmp_path / "study"
    friction_report.write_outputs(out, friction_study.study(["lugre"], [0.0, 1.0],
                                                            str(campaigns / "tiny.toml"), 1))
    res = json.loads((out / "friction_study.json").read_text())
    assert (out / "friction_study.png").stat().st_size > 10_000
    rows = res["families"]["lugre"]["levels"]
    assert [r["scale"] for r in rows] == [0.0, 1.0]
    cal = res["families"]["lugre"]["calibrated_dry_friction"]
    assert rows[0]["dry_friction"]["lugre_Fc"] == 0 and rows[0]["dry_friction"]["lugre_Fs"] == 0
    assert rows[1]["dry_friction"] == cal
    for r in rows:
        if r["ok"]:
            assert set(r) >= {"step_ratio_of_medians_whole_record", "step_ratio_of_medians_after_edges",
                              "sine_phase_p90_linear_deg", "sine_phase_p90_alpha_deg",
                              "sine_magnitude_p90_linear", "sine_magnitude_p90_alpha",
                              "inertia_max_rel_error", "inertia_worst_signed_rel_error"}
            assert abs(r["inertia_worst_signed_rel_error"]) == pytest.approx(r["inertia_max_rel_error"])
        else:
            assert r["reason"]
    # the scale-1 level is the family's own reproduction on the same campaign (the one
    # `reproduce --friction all` runs for it, on the unscaled built-in device)
    own = study_rp.run_reproduce(Device.load(friction="lugre"), 1, str(campaigns / "tiny.toml")).summary
    assert rows[1]["ok"]
    assert rows[1]["step_ratio_of_medians_whole_record"] == pytest.approx(own.step.ratio_of_medians, rel=1e-12)
    assert rows[1]["inertia_max_rel_error"] == pytest.approx(own.inertia.max_rel_error, rel=1e-12)
    # dry friction matters: without it the identified sines are far closer to linear
    assert rows[0]["sine_phase_p90_linear_deg"] < rows[1]["sine_phase_p90_linear_deg"]


def test_friction_study_records_failures(tmp_path, monkeypatch):
    study = friction_study
    from identification.errors import UserError

    def fail(*a, **kw):
        raise UserError("identification failed on the generated campaign: sine_a: 2 Hz gives "
                        "non-physical local coefficients C_data=-1; sine_b: 1.5 Hz gives non-physical "
                        "local coefficients C_data=-2; alpha-invariant model not fitted: no pose has a "
                        "usable frequency")

    monkeypatch.setattr(study_rp, "run_reproduce", fail)
    row = study.run_level(Device.load(friction="coulomb"), 0.0, "paper", 1)
    assert row["ok"] is False
    assert row["reason"].startswith("alpha-invariant model not fitted: no pose has a usable frequency")
    assert "(2 sine run(s) with non-physical" in row["reason"]

    def diverge(*a, **kw):
        raise RuntimeError("sine_a: simulation diverged")

    monkeypatch.setattr(study_rp, "run_reproduce", diverge)
    row = study.run_level(Device.load(friction="coulomb"), 3.0, "paper", 1)
    assert row == {**row, "ok": False, "reason": "RuntimeError: sine_a: simulation diverged"}


@pytest.mark.parametrize("args, match", [
    (["--levels", "0,x"], "--levels"),
    (["--levels=-1,1"], ">= 0"),
    (["--levels", "1,1"], "repeated"),
    (["--levels", "nan"], ">= 0"),
    (["--families", "viscous"], "unknown friction family"),
    (["--campaign", "nowhere.toml"], "nowhere"),
])
def test_friction_study_bad_input(args, match, tmp_path):
    out = tmp_path / "s"
    res = subprocess.run([sys.executable, str(ROOT / "scripts" / "friction_study.py"), "--out", str(out),
                          *args], capture_output=True, text=True, cwd=tmp_path)
    _one_line_error(res)
    assert match in res.stderr
    assert not out.exists()


def test_friction_study_help():
    res = subprocess.run([sys.executable, str(ROOT / "scripts" / "friction_study.py"), "--help"],
                         capture_output=True, text=True)
    assert res.returncode == 0 and "--levels" in res.stdout and "--out" in res.stdout
