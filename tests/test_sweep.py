"""``omni sweep``: study files, expansion, Dask execution (local and an external cluster),
resume, failed variants, and the reproduce pipeline against ``run_reproduce``."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from identification.errors import UserError
from omni_app import sweep as sweep_app
from omni_studies import sweep as sw
from omni_app.cli import main

# one short step run: the `simulate` pipeline costs ~0.1 s a variant
ONE_STEP = """
[[pipeline.campaign.step]]
poses_deg = [[65, 90]]
frequency_hz = 1.0
amplitude_rad = 0.07
duration_s = 1.0
"""


def _spec(vary: str, pipeline: str = 'name = "simulate"', extra: str = "") -> str:
    return (f'seed = 3\n{extra}\n[base]\nfriction = "lugre"\n\n[pipeline]\n{pipeline}\n'
            f'{ONE_STEP if "simulate" in pipeline else ""}\n{vary}\n')


GRID = _spec('[grid]\n"joint.yaw.damping" = [0.004, 0.008]\nnoise_rad = [0.0, 1e-4]\n')


def _table(out: Path) -> list[dict]:
    rows = list(csv.DictReader((out / "results.csv").open()))
    for r in rows:
        for k in sw.TIMING_COLUMNS:
            r.pop(k)
    return rows


def _write(tmp_path: Path, text: str, name: str = "study.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


# -- study files ---------------------------------------------------------------------------
@pytest.mark.parametrize("vary, key", [
    ('[grid]\n"joint.nope.damping" = [1.0]', "grid.joint.nope.damping"),
    ('[grid]\n"joint.yaw.colour" = [1.0]', "grid.joint.yaw.colour"),
    ('[grid]\n"joint.yaw.damping[7]" = [1.0]', "grid.joint.yaw.damping[7]"),
    ('[grid]\nwibble = [1.0]', "grid.wibble"),
    ('[grid]\nkp = []', "grid.kp"),
    ('[grid]\nkp = [1, "a"]', "grid.kp[1]"),
    ('[grid]\nquantize = [0, 2]', "grid.quantize[1]"),
    ('[list]\nparams = ["kp"]\nrows = [[1.0, 2.0]]', "list.rows[0]"),
    ('[random]\nn = 3\nseed = 1\nkp = {uniform = [2.0, 1.0]}', "random.kp.uniform"),
    ('[random]\nn = 3\nseed = 1\nkp = {log_uniform = [0.0, 1.0]}', "random.kp.log_uniform"),
    ('[random]\nn = 0\nseed = 1\nkp = {uniform = [1.0, 2.0]}', "random.n"),
    ('[random]\nseed = 1\nkp = {uniform = [1.0, 2.0]}', "random.n"),
    ("", "grid"),
])
def test_bad_spec_names_the_key(tmp_path, vary, key):
    with pytest.raises(UserError) as e:
        sw.parse_study(_spec(vary), "s.toml", tmp_path)
    assert str(e.value).startswith(f"s.toml: {key}: "), str(e.value)


@pytest.mark.parametrize("text, key", [
    ('[base]\nfriction = "lugre"\n[grid]\nkp = [1.0]', "pipeline"),
    ('[base]\nfriction = "lugre"\n[pipeline]\nname = "x"\n[grid]\nkp = [1.0]', "pipeline.name"),
    ('[base]\nfriction = "nope"\n[pipeline]\nname = "simulate"\n[grid]\nkp = [1.0]', "base.friction"),
    ('[base]\nmodel = "missing.xml"\n[pipeline]\nname = "simulate"\n[grid]\nkp = [1.0]', "base.model"),
    ('[pipeline]\nname = "simulate"\ncampaign = "none.toml"\n[grid]\nkp = [1.0]', "pipeline.campaign"),
    ('[pipeline]\nname = "discrepancy"\nhidden = "gremlins"\n[grid]\nkp = [1.0]', "pipeline.hidden"),
    ('[pipeline]\nname = "simulate"\n[fixed]\nkp = 1.0\n[grid]\nkp = [1.0]', "grid.kp"),
    ('colour = 1\n[pipeline]\nname = "simulate"\n[grid]\nkp = [1.0]', "colour"),
])
def test_bad_spec_sections(tmp_path, text, key):
    with pytest.raises(UserError) as e:
        sw.parse_study(text, "s.toml", tmp_path)
    assert str(e.value).startswith(f"s.toml: {key}: "), str(e.value)


def test_cli_bad_spec_one_line_exit_2(tmp_path, capsys):
    p = _write(tmp_path, _spec('[grid]\n"body.upper_arm.nass" = [1.0]'))
    out = tmp_path / "out"
    assert main(["sweep", str(p), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {p}: grid.body.upper_arm.nass: ") and len(err.strip().splitlines()) == 1
    assert not out.exists()  # nothing started


def test_grid_list_random_expansion(tmp_path):
    g = sw.parse_study(GRID, "s", tmp_path)
    assert [v for v, _ in g.variants] == ["v0000", "v0001", "v0002", "v0003"]
    assert [d for _, d in g.variants] == [
        {"joint.yaw.damping": 0.004, "noise_rad": 0.0}, {"joint.yaw.damping": 0.004, "noise_rad": 1e-4},
        {"joint.yaw.damping": 0.008, "noise_rad": 0.0}, {"joint.yaw.damping": 0.008, "noise_rad": 1e-4}]
    lst = sw.parse_study(_spec('[list]\nparams = ["kp", "quantize"]\nrows = [[1.5, 1], [2.5, false]]'), "s", tmp_path)
    assert [d for _, d in lst.variants] == [{"kp": 1.5, "quantize": 1.0}, {"kp": 2.5, "quantize": 0.0}]
    rnd = _spec('[random]\nn = 50\nseed = 7\nkp = {uniform = [1.0, 3.0]}\n'
                '"actuator.yaw_friction.lugre_Fc" = {log_uniform = [1e-3, 1e-1]}')
    r1, r2 = sw.parse_study(rnd, "s", tmp_path), sw.parse_study(rnd, "s", tmp_path)
    assert r1.variants == r2.variants and len(r1.variants) == 50
    kp = [d["kp"] for _, d in r1.variants]
    fc = [d["actuator.yaw_friction.lugre_Fc"] for _, d in r1.variants]
    assert 1.0 <= min(kp) and max(kp) <= 3.0 and len(set(kp)) == 50
    assert 1e-3 <= min(fc) and max(fc) <= 1e-1
    assert sum(f < 1e-2 for f in fc) > 12  # log-uniform: about half below the geometric middle
    r3 = sw.parse_study(rnd.replace("seed = 7", "seed = 8"), "s", tmp_path)
    assert r3.variants != r1.variants
    # seeds derive from the study seed and the id only
    assert [j["seed"] for j in g.jobs()] == [sw.variant_seed(3, f"v{i:04d}") for i in range(4)]


def test_variant_attributes_reach_the_model():
    from omni_sim import model as om
    from omni_sim import variants as va
    from omni_sim.device import Device

    spec = va.base_spec(friction="lugre")
    base = spec.compile()
    _, m = va.build(spec, {"joint.yaw.damping": 0.02, "body.upper_arm.mass": 0.1,
                           "actuator.yaw_motor.gear": 0.4, "actuator.yaw_friction.lugre_sigma0": 5.0,
                           "friction_scale": 2.0, "kp": 9.0})
    ix = om.index(m)
    assert m.dof_damping[ix.yaw_dof] == 0.02
    assert Device(m).torque_constant == 0.4
    assert m.body_mass[m.body("upper_arm").id] == 0.1
    f0, f = Device(base).friction(), Device(m).friction()
    assert f["lugre_sigma0"] == 5.0 and f["lugre_Fc"] == pytest.approx(2 * f0["lugre_Fc"])
    assert f["lugre_Fs"] == pytest.approx(2 * f0["lugre_Fs"])
    assert spec.compile().dof_damping[ix.yaw_dof] == base.dof_damping[ix.yaw_dof]  # base untouched


# -- running -------------------------------------------------------------------------------
@pytest.mark.slow  # 29 s CPU: 16 variant runs on Dask clusters of one and two workers (end to end)
def test_one_vs_two_workers_resume_and_failed_variant(tmp_path):
    text = GRID.replace('noise_rad = [0.0, 1e-4]', 'noise_rad = [0.0, 1e-4]\n"body.upper_arm.mass" = [0.07, -1.0]')
    study = sw.parse_study(text, "s", tmp_path)
    assert len(study.variants) == 8
    r1 = sw.run_sweep(study, tmp_path / "w1", workers=1, progress=False)
    r2 = sw.run_sweep(study, tmp_path / "w2", workers=2, progress=False)
    assert r1.failed == r2.failed == 4 and r1.ran == 8
    t1, t2 = _table(tmp_path / "w1"), _table(tmp_path / "w2")
    assert t1 == t2
    assert [r["id"] for r in t1] == [f"v{i:04d}" for i in range(8)]
    for r in t1:
        if r["body.upper_arm.mass"] == "-1.0":
            assert r["status"] == "failed" and "mass and inertia" in r["error"] and r["rms_error_rad"] == ""
        else:
            assert r["status"] == "ok" and float(r["rms_error_rad"]) > 0 and r["error"] == ""
    # noise changes the result (seeded per variant), damping too
    ok = {(r["joint.yaw.damping"], r["noise_rad"]): r["rms_error_rad"] for r in t1 if r["status"] == "ok"}
    assert len(set(ok.values())) == 4
    # resume: delete some variants' outputs, rerun, same table; only those ran
    for v in ("v0001", "v0006"):
        shutil.rmtree(tmp_path / "w1" / "variants" / v)
    (tmp_path / "w1" / "results.csv").unlink()
    r3 = sw.run_sweep(study, tmp_path / "w1", workers=2, progress=False)
    assert (r3.ran, r3.skipped) == (2, 6)
    assert _table(tmp_path / "w1") == t1
    # a finished study: nothing to run, no cluster started
    assert sw.run_sweep(study, tmp_path / "w1", progress=False).ran == 0
    # resume with another spec: a user error
    other = sw.parse_study(GRID, "s", tmp_path)
    with pytest.raises(UserError, match="different spec"):
        sw.run_sweep(other, tmp_path / "w1", progress=False)
    # plots: one PNG per varied parameter
    pngs = sweep_app.plot(tmp_path / "w1")
    assert sorted(p.name for p in pngs) == ["sweep_body.upper_arm.mass.png", "sweep_joint.yaw.damping.png",
                                             "sweep_noise_rad.png"]
    assert all(p.stat().st_size > 10_000 for p in pngs)


def test_reproduce_pipeline_matches_run_reproduce(tmp_path):
    """The reproduce pipeline at default settings gives run_reproduce's summary figures."""
    from omni_sim.device import Device
    from omni_studies.reproduce import run_reproduce

    from test_reproduce_result import CAMPAIGN  # 6 Table 1 poses and one step run: seconds

    _write(tmp_path, CAMPAIGN, "camp.toml")
    study = sw.parse_study(_spec('[list]\nparams = ["friction_scale"]\nrows = [[1.0]]',
                                 'name = "reproduce"\ncampaign = "camp.toml"'), "s", tmp_path)
    res = sw.run_variant(study.jobs()[0])
    assert res.result.status == "ok", res.result.error
    ref = run_reproduce(Device.load(friction="lugre"), jobs=1, campaign=str(tmp_path / "camp.toml"))
    s = ref.summary
    fig = res.result.figures
    assert fig.inertia_max_rel_error == pytest.approx(s.inertia.max_rel_error, rel=1e-9)
    assert fig.step_ratio_of_medians_whole_record == pytest.approx(
        s.step.windows.whole_record.ratio_of_medians, rel=1e-9)
    assert fig.step_ratio_of_medians_after_edges == pytest.approx(
        s.step.windows.after_edges.ratio_of_medians, rel=1e-9)
    for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg", "magnitude_p90_linear", "magnitude_p90_alpha"):
        assert getattr(fig, f"sine_{k}") == pytest.approx(getattr(s.sine, k), rel=1e-9)
    assert json.loads(res.files["summary.json"])["inertia"]["n_poses"] == 25


# -- an external cluster ---------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_workers(address: str, n: int, timeout: float = 60) -> None:
    from distributed import Client

    with Client(address, timeout="30s") as c:
        c.wait_for_workers(n, timeout=timeout)


@pytest.mark.slow
def test_external_scheduler_and_two_workers(tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--no-dashboard"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--host", "127.0.0.1",
                 "--nthreads", "1", "--nworkers", "1", "--no-dashboard"], env=env,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        _wait_workers(address, 2)
        p = _write(tmp_path, GRID)
        assert main(["sweep", str(p), "--out", str(tmp_path / "remote"), "--scheduler", address]) == 0
        remote = _table(tmp_path / "remote")
        assert [r["id"] for r in remote] == ["v0000", "v0001", "v0002", "v0003"]
        assert all(r["status"] == "ok" for r in remote)
        # the same figures as the variants run in this process
        for job, row in zip(sw.parse_study(GRID, "s", tmp_path).jobs(), remote):
            assert row["rms_error_rad"] == repr(sw.run_variant(job).result.figures.rms_error_rad)
    finally:
        for pr in reversed(procs):
            pr.terminate()
        for pr in procs:
            try:
                pr.wait(timeout=20)
            except subprocess.TimeoutExpired:
                pr.kill()
                pr.wait()


def test_unreachable_scheduler_is_a_user_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sw, "CONNECT_TIMEOUT_S", 1)
    p = _write(tmp_path, GRID)
    code = main(["sweep", str(p), "--out", str(tmp_path / "o"), "--scheduler", f"tcp://127.0.0.1:{_free_port()}"])
    assert code == 2 and capsys.readouterr().err.startswith("error: --scheduler")


# -- kill -9 and rerun --------------------------------------------------------------------------
@pytest.mark.slow
def test_kill_9_then_rerun_gives_the_same_table(tmp_path):
    """A study killed with SIGKILL after its first variant finished completes on a rerun, with the
    table of an uninterrupted run."""
    p = _write(tmp_path, _spec('[grid]\n"joint.yaw.damping" = [0.004, 0.006, 0.008, 0.01]\n'
                               'noise_rad = [0.0, 1e-4, 2e-4]\n').replace("duration_s = 1.0", "duration_s = 4.0"))
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "omni_app", "sweep", str(p), "--out", str(out),
                             "--workers", "1"], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.time()
    while not sw.finished(out) and time.time() - t0 < 120:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its cluster's worker processes
    proc.wait()
    n_before = len(sw.finished(out))
    assert 1 <= n_before < 12 and not (out / "results.csv").exists()
    assert main(["sweep", str(p), "--out", str(out), "--workers", "2"]) == 0
    assert main(["sweep", str(p), "--out", str(tmp_path / "whole"), "--workers", "2"]) == 0
    assert _table(out) == _table(tmp_path / "whole")
