"""``omni identify`` / ``omni fit-inertia`` end to end, including bad input through the CLI."""

import json
import math
from importlib import resources

import numpy as np
import pytest

from identification.identify import identify_dataset
from identification.dataset import write_run
from omni_app import commands
from omni_app.cli import main
from test_linear import simulate_sine_run


def _cli(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _assert_user_error(code, err, *needles):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), err
    for n in needles:
        assert n in lines[0], (n, lines[0])


def _own_inertia(g1, g2, ib, i1, i2, i3, goff):
    a = np.radians(g1)
    b = math.pi - a - np.radians(g2) - math.radians(goff)
    return ib + i1 * np.cos(a) ** 2 + i2 * np.cos(b) ** 2 + i3 * np.cos(a) * np.cos(b)


@pytest.fixture(scope="module")
def nine_pose_runs():
    """Table 1 poses (Table 3 actual angles) simulated with (13), hidden inertia truth."""
    truth = (1.4e-3, 2.9e-3, 0.94e-3, 3.16e-3, 9.9, 36.7)
    sets = [(s1, s2) for s1 in (25, 45, 65) for s2 in (70, 90, 115)]
    actual = [(21.54, 69.54), (20.55, 88.54), (19.31, 112.44), (40.68, 68.52), (39.83, 87.63),
              (39.16, 111.98), (60.68, 67.62), (60.08, 87.00), (59.56, 111.45)]
    runs, kp = [], 2.0
    for (s1, s2), (g1, g2) in zip(sets, actual):
        inert = _own_inertia(g1, g2, *truth[:5])
        C, beta = 1 / (truth[5] * inert), kp / inert
        for f in (2.0, 4.0):
            runs.append(simulate_sine_run(f"p{s1}_{s2}_f{f:g}", C, beta, f, 0.05, kp=kp, g1=g1, g2=g2,
                                          duration_s=6.0, set_angles=(s1, s2)))
    return truth, runs


def test_identify_dataset_recovers_hidden_truth(nine_pose_runs):
    truth, runs = nine_pose_runs
    params = identify_dataset(runs)
    assert len(params["poses"]) == 9 and params["alpha_model"] is None
    for pose in params["poses"]:
        inert = _own_inertia(pose["gamma1_deg"], pose["gamma2_deg"], *truth[:5])
        assert abs(pose["C_linear"] * truth[5] * inert - 1) < 0.005
        assert abs(pose["beta_tilde_linear"] * inert - 1) < 0.005
        assert pose["beta_linear"] == pytest.approx(2.0 * pose["beta_tilde_linear"])
        for fr in pose["frequencies"]:
            assert fr["used"] and {"frequency_hz", "A1", "A2", "C_data", "beta_data", "alpha"} <= set(fr)
    im = params["inertia_model"]
    assert im["C0_bar"] == pytest.approx(truth[5], rel=0.005)
    assert im["gamma_offs_deg"] == pytest.approx(truth[4], abs=0.5)
    for k, v in zip(("I_base", "I1", "I2", "I3"), truth):
        assert im[k] == pytest.approx(v, rel=0.02), k


def test_identify_cli_writes_outputs(nine_pose_runs, tmp_path, capsys):
    _, runs = nine_pose_runs
    data = tmp_path / "data"
    data.mkdir()
    for r in runs:
        write_run(data, r)
    out = tmp_path / "out"
    code, stdout, err = _cli(["identify", str(data), "--out", str(out)], capsys)
    assert code == 0, err
    params = json.loads((out / "params.json").read_text())
    assert set(params) >= {"poses", "inertia_model", "alpha_model"}
    assert (out / "report.md").read_text().startswith("# Identification report")
    assert (out / "inertia_fit.png").stat().st_size > 0 and (out / "local_linear.png").stat().st_size > 0
    # existing output needs --force
    code, _, err = _cli(["identify", str(data), "--out", str(out)], capsys)
    _assert_user_error(code, err, "--force")


#: The sample :func:`_jitter` stamps late: inside every run's steady-state window (the last
#: cycles of a 5 s run), so the identification's fits see it.
JITTERED_SAMPLE = 4000


def _hand_written_dataset(folder):
    """A real-device-like single pose: three sines written by hand as CSV + JSON text."""
    folder.mkdir()
    C, beta, ar, kp = 6.0, 450.0, 0.07, 2.0
    for f in (2.0, 3.0, 5.0):
        w = 2 * math.pi * f
        h = beta / (beta - w**2 + 1j * C * w)
        t = np.arange(5000) / 1000.0
        r = ar * np.sin(w * t)
        theta = ar * abs(h) * np.sin(w * t + np.angle(h)) + 0.001  # steady state + encoder offset
        v = kp * (r - theta)
        lines = ["t,r,theta,v"] + [f"{a:.3f},{b:.7f},{c:.7f},{d:.7f}" for a, b, c, d in zip(t, r, theta, v)]
        (folder / f"sine_{f:g}hz.csv").write_text("\n".join(lines) + "\n")
        (folder / f"sine_{f:g}hz.json").write_text(json.dumps(
            {"kind": "sine", "gamma1_deg": 60.1, "gamma2_deg": 87.0, "kp": kp, "frequency_hz": f,
             "amplitude_rad": ar, "source": "hand-written"}))
    return C, beta


def test_identify_single_pose_hand_written(tmp_path, capsys):
    data = tmp_path / "data"
    C, beta = _hand_written_dataset(data)
    out = tmp_path / "out"
    code, stdout, err = _cli(["identify", str(data), "--out", str(out)], capsys)
    assert code == 0, err
    params = json.loads((out / "params.json").read_text())
    assert params["inertia_model"] is None
    assert any("inertia model not fitted" in w for w in params["warnings"])
    (pose,) = params["poses"]
    assert pose["C_linear"] == pytest.approx(C, rel=0.005)
    assert pose["beta_linear"] == pytest.approx(beta, rel=0.005)
    assert "Not fitted" in (out / "report.md").read_text()
    assert not (out / "inertia_fit.png").exists()


@pytest.mark.parametrize("damage, needles", [
    (lambda d: _nan_line(d / "sine_3hz.csv"), ["sine_3hz.csv", "non-finite"]),
    (lambda d: _drop_column(d / "sine_2hz.csv"), ["sine_2hz.csv", "missing column"]),
    (lambda d: _drop_key(d / "sine_5hz.json", "kp"), ["sine_5hz.json", "kp"]),
    (lambda d: _truncate(d / "sine_2hz.csv", 2500), ["sine_2hz", "1 whole steady-state cycle"]),
    (lambda d: _gap(d / "sine_3hz.csv"), ["sine_3hz.csv", "gap of", "sample periods"]),
    (lambda d: _swap_times(d / "sine_3hz.csv"), ["sine_3hz.csv", "not strictly increasing"]),
    (lambda d: [(d / f"sine_{f}hz.{e}").unlink() for f in (3, 5) for e in ("csv", "json")],
     ["1 distinct sine frequency", "sine_2hz"]),
])
def test_identify_bad_input(tmp_path, capsys, damage, needles):
    data = tmp_path / "data"
    _hand_written_dataset(data)
    damage(data)
    out = tmp_path / "out"
    code, _, err = _cli(["identify", str(data), "--out", str(out)], capsys)
    _assert_user_error(code, err, *needles)
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name != "data"]  # no temporary folder left


def _lines(path):
    return path.read_text().splitlines()


def _nan_line(path):
    lines = _lines(path)
    parts = lines[3000].split(",")
    parts[2] = "nan"
    lines[3000] = ",".join(parts)
    path.write_text("\n".join(lines) + "\n")


def _drop_column(path):
    lines = [",".join(l.split(",")[:3]) for l in _lines(path)]
    path.write_text("\n".join(lines) + "\n")


def _drop_key(path, key):
    meta = json.loads(path.read_text())
    del meta[key]
    path.write_text(json.dumps(meta))


def _truncate(path, n):
    path.write_text("\n".join(_lines(path)[: n + 1]) + "\n")


def _jitter(path, k=JITTERED_SAMPLE):
    """Sample ``k`` stamped half a period late (its values kept): a jittered log."""
    lines = _lines(path)
    parts = lines[k + 1].split(",")
    parts[0] = f"{float(parts[0]) + 0.0005:.4f}"
    lines[k + 1] = ",".join(parts)
    path.write_text("\n".join(lines) + "\n")


def _gap(path):
    """Samples 100-129 lost: a 31-period gap (longer than the 10 periods a run may bridge)."""
    lines = _lines(path)
    path.write_text("\n".join(lines[:100] + lines[130:]) + "\n")


def _swap_times(path):
    lines = _lines(path)
    lines[100], lines[101] = lines[101], lines[100]
    path.write_text("\n".join(lines) + "\n")


def test_identify_resamples_a_jittered_log(tmp_path, capsys, monkeypatch):
    """Sample 4000 of a 1 kHz sine stamped half a period late makes a jittered log.  ``omni
    identify`` identifies it on the uniform grid of its median period (1 ms): the file's own
    samples where the grid meets them, and at the one grid time inside the late interval (4.000 s,
    between 3.999 s and 4.0005 s) the linear interpolation, 2/3 of the way from sample 3999 to
    the late one; ``resampled_from`` records the log's timing.  The coefficients are the clean
    data's within 1e-4 (measured 3.9e-6: one sample of ~2300 in the steady state of one run of
    three moved by a third of its step).

    Shown to fail with the resampler made the identity (the run reaches identification with its
    irregular times)."""
    clean, jittered = tmp_path / "clean", tmp_path / "jittered"
    _hand_written_dataset(clean)
    _hand_written_dataset(jittered)
    _jitter(jittered / "sine_3hz.csv")
    identified, got = {}, {}
    real = commands.identify_runs

    def spy(runs, *args, **kwargs):
        identified.update({r.name: r for r in runs})
        return real(runs, *args, **kwargs)

    monkeypatch.setattr(commands, "identify_runs", spy)
    for data in (clean, jittered):
        identified.clear()
        code, _, err = _cli(["identify", str(data), "--out", str(tmp_path / f"out_{data.name}")], capsys)
        assert code == 0, err
        got[data.name] = json.loads((tmp_path / f"out_{data.name}" / "params.json").read_text())["poses"][0]
    for key in ("C_linear", "beta_linear"):
        assert got["jittered"][key] == pytest.approx(got["clean"][key], rel=1e-4)
    assert sorted(identified) == ["sine_2hz", "sine_3hz", "sine_5hz"]
    assert "resampled_from" not in identified["sine_2hz"].meta  # uniform: kept as it is
    run = identified["sine_3hz"]
    logged = np.loadtxt(jittered / "sine_3hz.csv", delimiter=",", skiprows=1)
    assert logged[JITTERED_SAMPLE, 0] == 4.0005
    k = JITTERED_SAMPLE
    expected = logged.copy()
    expected[:, 0] = np.arange(len(logged)) / 1000.0
    expected[k, 1:] = logged[k - 1, 1:] + (logged[k, 1:] - logged[k - 1, 1:]) * (0.001 / 0.0015)
    # 1e-11: the grid is t0 + j * (the median spacing of the parsed times), 1 ms within a few
    # ulps, so within 5000 * 2e-16 s of the file's times (measured 4.4e-15 s), and the values
    # within that times their slope (< 3 rad/s); without resampling sample k keeps its time
    # 4.0005 s and its value, 4e-4 rad from the interpolated theta (a third of its 1 ms step)
    got_cols = np.column_stack([run.t, run.r, run.theta, run.v])
    np.testing.assert_allclose(got_cols, expected, rtol=0, atol=1e-11)
    assert run.meta["resampled_from"]["period_s"] == pytest.approx(0.001, rel=1e-9)
    assert run.meta["resampled_from"]["max_gap_s"] == pytest.approx(0.0015, rel=1e-9)


def test_fit_inertia_cli_on_table3(tmp_path, capsys):
    table = tmp_path / "t3.csv"
    with resources.files("identification").joinpath("data", "table3_linear_coefficients.csv").open() as fh:
        table.write_text(fh.read())
    out = tmp_path / "fit.json"
    code, stdout, err = _cli(["fit-inertia", str(table), "--out", str(out)], capsys)
    assert code == 0, err
    assert "C0_bar" in stdout and "poorly determined" in stdout
    res = json.loads(out.read_text())
    assert res["inertia_model"]["C0_bar"] == pytest.approx(36.38, abs=0.01)
    assert res["inertia_fit"]["C0_bar_regression"] == pytest.approx(36.726, abs=0.001)
    assert len(res["poses"]) == 9


@pytest.mark.parametrize("text, needles", [
    ("gamma1_deg,gamma2_deg,C_linear\n1,2,3\n", ["missing column", "beta_tilde_linear"]),
    ("gamma1_deg,gamma2_deg,C_linear,beta_tilde_linear\n1,2,x,4\n", ["line 2", "not a number"]),
    ("gamma1_deg,gamma2_deg,C_linear,beta_tilde_linear\n1,2,inf,4\n", ["non-finite"]),
    ("gamma1_deg,gamma2_deg,C_linear,beta_tilde_linear\n1,2,3,4\n2,3,4,5\n", ["2 pose", "needs >= 6"]),
])
def test_fit_inertia_bad_input(tmp_path, capsys, text, needles):
    table = tmp_path / "t.csv"
    table.write_text(text)
    out = tmp_path / "fit.json"
    code, _, err = _cli(["fit-inertia", str(table), "--out", str(out)], capsys)
    _assert_user_error(code, err, "t.csv", *needles)
    assert not out.exists()


def test_fit_inertia_missing_file(tmp_path, capsys):
    code, _, err = _cli(["fit-inertia", str(tmp_path / "nope.csv")], capsys)
    _assert_user_error(code, err, "nope.csv", "not found")
