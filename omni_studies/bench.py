"""``omni bench``'s performance figures, measured on this machine (the command, its printing and
its JSON file are :mod:`omni_app.commands`'; the figures are computed here).

Figures (issue targets in brackets, 2-core machine):

* ``generate_rtf``: simulated experiment time of the paper campaign / wall time of
  ``omni generate --campaign paper`` work (simulation + writing the dataset) [>= 100];
* ``simulate_rtf``: the same, simulation only;
* ``rollout_ratio``: the campaign's physics steps per second / raw ``mujoco.rollout`` steps per
  second for the same model, step count and threads with zero controls (the ceiling) [>= 0.8];
* ``alpha_simulation.ratio_alpha_to_lsim``: the quasilinear alpha-model simulation of 25 step
  runs / ``scipy.signal.lsim`` of the linear model over the same runs [<= 3];
* ``reproduce``: ``omni reproduce --out TMP`` as a user runs it, in a child process (wall
  time with imports, writing and figures, the fastest of the repeats as for the raw rollout,
  each run listed; ``real_time_factor`` [>= 50]; ``ratio_to_raw_rollout``: that wall time / the
  raw rollout time of the campaign's physics steps [<= 6]; ``peak_rss_mb`` of the child);
  ``reproduce.cold``: the same as the first run after an install (:func:`_bench_reproduce_cold`:
  no compiled α loop, bytecode or font cache yet), ``ratio_to_warm`` [<= 1.3];
* ``vector_env``: steps/s of ``gym.make_vec("omni_sim/OmniYaw-v0", num_envs=256,
  vectorization_mode="vector_entry_point")`` under P-controller actions, and its ratio to the
  raw rollout steps/s;
* ``discrepancy``: wall time of the discrepancy workflow on the demo case [minutes, not hours];
* ``discrepancy_servo``: ``omni discrepancy`` as a user runs it (a child process) on 12 runs of
  6 s of the bank's geared-servo case with its nominal off (``load_friction_nominal_off``: the
  hidden ``load_friction``, the nominal's inertia 15 % high and Coulomb level 40 % low; 200 Hz
  logs with jitter, a 1 kHz loop: 72 k control periods), with the physics steps per stage and
  the unstable replays [<= 3 min wall time, <= 1 GB peak memory on 2 cores; <= 30 M physics
  steps aimed at];
* ``sweep``: variants/s of ``omni sweep --example`` on 1 and 2 local Dask workers (cluster
  start-up included) and the speed-up [>= 1.7 on 2 cores].

``discrepancy_servo`` (and ``discrepancy_campaign``) run a case of the validation bank, which a
regular install does not have: without it :func:`run_bench` stops before it measures anything,
naming the fix (:mod:`omni_studies.bank_link`).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from discrepancy import demo as demo_truth
from discrepancy import effects as fx
from discrepancy.workflow import run_discrepancy
from omni_sim import experiments as ex
from omni_sim import model as om
from omni_sim.device import Device, default_threads
from omni_studies.bank_link import load as load_bank


def _rollout_ceiling(model: mujoco.MjModel, nbatch: int, nstep: int, nthread: int) -> float:
    """Raw rollout steps/s: same model, batch and steps, arm held at the home pose."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0) if model.nkey else mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, x0, spec)
    ctrl = np.tile(data.ctrl, (nbatch, nstep, 1))
    datas = [mujoco.MjData(model) for _ in range(nthread)]
    t0 = time.perf_counter()
    rollout.rollout(model, datas, np.tile(x0, (nbatch, 1)), ctrl, nstep=nstep)
    return nbatch * nstep / (time.perf_counter() - t0)


#: Figures ``omni bench --only`` can measure alone (the slow ones a user times by themselves).
ONLY = ("discrepancy_servo",)


def run_bench(jobs: int | None = None, repeats: int = 3, extended: bool = True,
              friction: str | None = None, discrepancy_campaign: bool = False,
              only: str | None = None) -> dict:
    """Measure the figures above (best of ``repeats``) and return them as a dict.

    ``only``: one figure of :data:`ONLY` alone (with the machine's description).

    ``extended=False`` measures only the campaign figures (fast).  ``friction``: the built-in
    scene of that friction family (default: ``scene.xml``) for the campaign and reproduce
    figures; the discrepancy figure always runs the demo case on the default scene.
    ``discrepancy_campaign``: also time the discrepancy workflow on the whole paper campaign
    with the whole library (minutes: off by default).
    """
    jobs = max(1, jobs or default_threads())
    if extended or only == "discrepancy_servo":  # its cases, before any measurement
        load_bank("omni bench")
    if only == "discrepancy_servo":
        return {"cores": os.cpu_count(), "jobs": jobs, "discrepancy_servo": _bench_discrepancy_servo(jobs)}
    if only is not None:
        raise ValueError(f"unknown figure {only!r} (one of {', '.join(ONLY)})")
    model = om.load_model(friction=friction)
    campaign, ceil = _bench_campaign(model, jobs, repeats)
    steps = campaign["physics_steps"]
    figures = {"cores": os.cpu_count(), "friction": friction or om.DEFAULT_FRICTION, "jobs": jobs,
               "paper_campaign": campaign}
    if extended:
        from identification.simulate import bench_simulation

        figures["alpha_simulation"] = bench_simulation(repeat=repeats)
        figures["reproduce"] = _bench_reproduce(jobs, friction, ceil, steps, repeats=repeats)
        figures["reproduce"]["cold"] = _bench_reproduce_cold(jobs, friction, figures["reproduce"]["wall_s"],
                                                             repeats=repeats)
        try:
            figures["vector_env"] = _bench_vector_env(ceiling_steps_per_s=ceil)
        except Exception as exc:  # noqa: BLE001  (reported, not fatal)
            figures["vector_env"] = {"error": f"{type(exc).__name__}: {exc}"}
        figures["discrepancy"] = bench_discrepancy(jobs=jobs)
        figures["discrepancy_servo"] = _bench_discrepancy_servo(jobs)
        if discrepancy_campaign:
            figures["discrepancy_campaign"] = bench_discrepancy_campaign(jobs=jobs)
        one, two = bench_sweep(1), bench_sweep(2)
        figures["sweep"] = {"variants_per_s_1_worker": round(one, 4),
                            "variants_per_s_2_workers": round(two, 4),
                            "speedup_2_workers": round(two / one, 3)}
    return figures


def _bench_campaign(model: mujoco.MjModel, jobs: int, repeats: int) -> tuple[dict, float]:
    """The paper campaign's figures on ``model`` (:func:`run_bench`'s ``paper_campaign``: the
    best of ``repeats`` simulations and dataset writes) and the raw rollout ceiling
    [steps/s] they are compared with."""
    from identification.dataset import write_dataset

    exps = ex.campaign("paper")
    sim_time = sum(len(e.r) for e in exps) * ex.CONTROL_PERIOD_S
    steps = sum(len(e.r) for e in exps) * ex.substeps(model, ex.CONTROL_PERIOD_S)
    t_sim, t_all, ceiling = [], [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        runs = ex.simulate(Device(model), exps, jobs=jobs)  # built each time, as a command does
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            write_dataset(runs, os.path.join(tmp, "ds"), force=False)
        t2 = time.perf_counter()
        t_sim.append(t1 - t0)
        t_all.append(t2 - t0)
        nstep = max(len(e.r) for e in exps)
        ceiling.append(_rollout_ceiling(model, len(exps), nstep, jobs))
    best_sim, best_all = min(t_sim), min(t_all)
    ceil = max(ceiling)
    return {
        "runs": len(exps),
        "simulated_time_s": round(sim_time, 3),
        "physics_steps": steps,
        "simulate_wall_s": round(best_sim, 3),
        "generate_wall_s": round(best_all, 3),
        "simulate_rtf": round(sim_time / best_sim, 1),
        "generate_rtf": round(sim_time / best_all, 1),
        "steps_per_s": round(steps / best_sim),
        "rollout_ceiling_steps_per_s": round(ceil),
        "rollout_ratio": round(steps / best_sim / ceil, 3),
    }, ceil


#: Runs argv[2:] and writes its wall time and peak RSS (with its children's) to argv[1].
_LAUNCHER = """
import json, os, sys, time
t0 = time.perf_counter()
pid = os.posix_spawn(sys.argv[2], sys.argv[2:], os.environ)
_, status, ru = os.wait4(pid, 0)
wall = time.perf_counter() - t0
with open(sys.argv[1], "w") as fh:
    json.dump({"wall_s": wall, "maxrss_kb": ru.ru_maxrss}, fh)
sys.exit(os.waitstatus_to_exitcode(status))
"""


def _bench_discrepancy_servo(jobs: int) -> dict:
    """``omni discrepancy`` on 12 runs of 6 s of the geared-servo case with its nominal off
    (:data:`SERVO_CASE`; its truth ``bank.servo_truth``, the validation bank's), in a child process
    started by :data:`_LAUNCHER`: wall time (imports and writing included), peak memory, the
    physics steps per stage, the unstable replays and whether the bank's criteria pass (and
    if not, why: ``bank_verdict``)."""
    import dataclasses
    import json
    import subprocess
    import sys

    from identification.dataset import write_dataset

    bank = load_bank("omni bench --only discrepancy_servo")
    hidden, st = bank.hidden, bank.servo_truth

    case = hidden.case(SERVO_CASE)
    exps = [dataclasses.replace(e, duration_s=6.0) for e in st.EXPERIMENTS]
    runs = hidden.generate(case, exps=exps)
    model, target = hidden.nominal(case)
    with tempfile.TemporaryDirectory() as tmp:
        data, out = os.path.join(tmp, "data"), os.path.join(tmp, "report")
        write_dataset(runs, data)
        cmd = [sys.executable, "-m", "omni_app", "discrepancy", "--measured", data,
               "--model", str(model), "--joint", target.joint, "--actuator",
               target.actuator, "--out", out]  # all cores, as a user runs it
        measured = os.path.join(tmp, "measured.json")
        subprocess.run([sys.executable, "-c", _LAUNCHER, measured, *cmd], check=True,
                       stdout=subprocess.DEVNULL)
        with open(measured) as fh:
            m = json.load(fh)
        with open(os.path.join(out, "report.json")) as fh:
            rep = json.load(fh)
    verdict = hidden.assess(case, rep)  # (passes, why): the bank's criteria (hidden.assess)
    return {"runs": len(runs), "log_samples": int(sum(len(r.t) for r in runs)),
            "control_periods": int(sum(round(r.t[-1] / st.CONTROL_PERIOD_S) + 1 for r in runs)),
            "wall_s": round(m["wall_s"], 1), "peak_rss_mb": round(m["maxrss_kb"] / 1024, 1),
            "case": SERVO_CASE, "named": [e["name"] for e in rep["effects"]],
            "corrections": {c["parameter"]: c["fitted"] for c in rep.get("corrections", [])},
            "shrink_factor": rep["shrink_factor"], "passes_bank_criteria": verdict[0],
            "bank_verdict": verdict[1],
            "physics_steps": rep["timings"]["physics_steps"],
            "physics_steps_per_stage": rep["timings"].get("physics_steps_per_stage", {}),
            "unstable_replays": rep["mujoco_warnings"]["unstable_simulations"]}


#: The bank case ``discrepancy_servo`` times (its runs lengthened to 6 s).
SERVO_CASE = "load_friction_nominal_off"


def _bench_reproduce(jobs: int, friction: str | None = None, ceiling_steps_per_s: float | None = None,
                     physics_steps: int | None = None, repeats: int = 3) -> dict:
    """``omni reproduce --out TMP`` as a user runs it: a child process, wall time (imports,
    simulation, identification, validation, writing and figures), its peak memory, and the
    ratio of that wall time to the raw rollout time of the campaign's physics steps.  The
    fastest of ``repeats`` runs (as the raw rollout's figure is the fastest of its repeats, so
    the ratio compares like with like); every run's wall time is listed too."""
    import json
    import subprocess
    import sys

    walls, rss = [], []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "results")
            cmd = [sys.executable, "-m", "omni_app", "reproduce", "--out", out, "--jobs", str(jobs)]
            if friction:
                cmd += ["--friction", friction]
            measured = os.path.join(tmp, "measured.json")
            # started by a small launcher: a child's peak RSS counts the memory of the process it
            # was spawned from (this one, hundreds of MB by now), the launcher's is ~10 MB
            subprocess.run([sys.executable, "-c", _LAUNCHER, measured, *cmd], check=True,
                           stdout=subprocess.DEVNULL)
            with open(measured) as fh:
                m = json.load(fh)
            walls.append(m["wall_s"])
            rss.append(m["maxrss_kb"])
            with open(os.path.join(out, "summary.json")) as fh:
                sim = json.load(fh)["run"]["simulated_time_s"]
    wall = min(walls)
    fig = {"wall_s": round(wall, 2), "wall_s_runs": [round(w, 2) for w in walls],
           "simulated_time_s": sim, "real_time_factor": round(sim / wall, 1),
           # the reproduce process and its children (the largest of them, largest over the runs;
           # KiB on Linux)
           "peak_rss_mb": round(max(rss) / 1024, 1) if all(rss) else None}
    if ceiling_steps_per_s and physics_steps:
        raw = physics_steps / ceiling_steps_per_s
        fig["raw_rollout_s"] = round(raw, 3)
        fig["ratio_to_raw_rollout"] = round(wall / raw, 1)
    return fig


#: ``reproduce.cold``'s target: the first run after an install at most this many times the others.
TARGET_COLD_RATIO = 1.3


def _source_copy(dest: str) -> None:
    """The project's packages (their ``.py`` files and data, no ``__pycache__``) into ``dest``, as
    imported here (an editable install's checkout or site-packages), the model files as the
    installed data package ``omni_sim.models``."""
    import importlib
    import shutil
    from pathlib import Path

    import omni_sim.models

    skip = shutil.ignore_patterns("__pycache__")
    for name in ("identification", "omni_sim", "discrepancy", "omni_studies", "omni_app"):
        shutil.copytree(importlib.import_module(name).__path__[0], Path(dest) / name, ignore=skip)
    models = omni_sim.models.__path__[0]
    if not (Path(dest) / "omni_sim" / "models").exists():  # an editable install maps models/ there
        shutil.copytree(models, Path(dest) / "omni_sim" / "models", ignore=skip)


def _bench_reproduce_cold(jobs: int, friction: str | None = None, warm_wall_s: float | None = None,
                          repeats: int = 3) -> dict:
    """``omni reproduce --out TMP`` as the first run after an install, ``repeats`` times, each in
    a child process (started as :func:`_bench_reproduce`'s) from a fresh copy of the project's
    packages without ``__pycache__`` (:func:`_source_copy`, first on ``PYTHONPATH``: no bytecode
    of the project, no numba cache beside ``alpha_kernel.py``), with an empty ``NUMBA_CACHE_DIR``
    (no compiled α loop), ``MPLCONFIGDIR`` and ``XDG_CACHE_HOME`` (no matplotlib font list).  The
    dependencies' bytecode is kept, as ``pip install`` writes it.  The fastest run, every run,
    and ``ratio_to_warm``: that / ``warm_wall_s`` (:func:`_bench_reproduce`'s, the same
    command with everything cached)."""
    import json
    import subprocess
    import sys

    walls = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            code = os.path.join(tmp, "code")
            _source_copy(code)
            env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, "numba"),
                       MPLCONFIGDIR=os.path.join(tmp, "mpl"), XDG_CACHE_HOME=os.path.join(tmp, "cache"),
                       PYTHONPATH=os.pathsep.join([code] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
            out = os.path.join(tmp, "results")
            cmd = [sys.executable, "-m", "omni_app", "reproduce", "--out", out, "--jobs", str(jobs)]
            if friction:
                cmd += ["--friction", friction]
            measured = os.path.join(tmp, "measured.json")
            subprocess.run([sys.executable, "-c", _LAUNCHER, measured, *cmd], check=True, env=env,
                           cwd=tmp, stdout=subprocess.DEVNULL)
            with open(measured) as fh:
                walls.append(json.load(fh)["wall_s"])
    fig = {"wall_s": round(min(walls), 2), "wall_s_runs": [round(w, 2) for w in walls]}
    if warm_wall_s:
        fig["warm_wall_s"] = round(warm_wall_s, 2)
        fig["ratio_to_warm"] = round(min(walls) / warm_wall_s, 2)
        fig["target_ratio_to_warm"] = TARGET_COLD_RATIO
        fig["target_met"] = fig["ratio_to_warm"] <= TARGET_COLD_RATIO
    return fig


def _bench_vector_env(num_envs: int = 256, n_steps: int = 200, ceiling_steps_per_s=None) -> dict:
    """Steps/s of the native vector environment (``num_envs`` Omnis, P-controller actions)
    beside the raw rollout ceiling."""
    import gymnasium as gym

    import omni_sim  # noqa: F401  (registers the environments)

    env = gym.make_vec("omni_sim/OmniYaw-v0", num_envs=num_envs,
                       vectorization_mode="vector_entry_point")
    try:
        obs, _ = env.reset(seed=0)
        low, high = env.single_action_space.low, env.single_action_space.high
        obs = np.asarray(obs, dtype=float)

        def action(o):
            # P controller: v = kp (r - theta), observations (theta, theta_dot, r, ...)
            o = o.reshape(num_envs, -1)
            return np.clip(2.0 * (o[:, 2:3] - o[:, 0:1]), low, high).astype(
                env.single_action_space.dtype)

        obs, *_ = env.step(action(obs))  # warm-up
        t0 = time.perf_counter()
        for _ in range(n_steps):
            obs, *_ = env.step(action(np.asarray(obs, dtype=float)))
        wall = time.perf_counter() - t0
    finally:
        env.close()
    sub = ex.substeps(om.load_model(), ex.CONTROL_PERIOD_S)  # physics steps per env step
    fig = {"num_envs": num_envs, "env_steps": n_steps * num_envs,
           "env_steps_per_s": round(n_steps * num_envs / wall),
           "physics_steps_per_s": round(n_steps * num_envs * sub / wall)}
    if ceiling_steps_per_s:
        fig["rollout_ceiling_steps_per_s"] = round(ceiling_steps_per_s)
        fig["ratio_to_raw_rollout"] = round(n_steps * num_envs * sub / wall / ceiling_steps_per_s, 3)
    return fig


# -- the discrepancy workflow and the sweep ----------------------------------------------------
def bench_discrepancy(jobs: int | None = None) -> dict:
    """Time the workflow on a representative case (the demo's: 16 runs, 32 s of data).

    Returns
    -------
    dict
        ``discrepancy_s`` (wall time of the workflow [s]), ``discrepancy_steps_per_s``,
        ``discrepancy_samples`` (measured samples), ``discrepancy_named`` (names found) and
        ``discrepancy_correct`` (they match the hidden effect).
    """
    runs = demo_truth.generate(jobs=jobs)
    t0 = time.perf_counter()
    outcome = run_discrepancy(runs, None, jobs=jobs)
    wall = time.perf_counter() - t0
    named = [e["name"] for e in outcome.report["effects"]]
    return {"discrepancy_s": wall,
            "discrepancy_steps_per_s": outcome.report["timings"]["steps_per_s"],
            "discrepancy_samples": int(sum(len(r.t) for r in runs)),
            "discrepancy_named": named,
            "discrepancy_correct": named == [demo_truth.CASE]}


#: The case hidden by the campaign benchmark (``omni bench --discrepancy-campaign``).
CAMPAIGN_CASE = "viscous_damping"


def bench_discrepancy_campaign(case_name: str = CAMPAIGN_CASE, jobs: int | None = None,
                               log=None) -> dict:
    """Time the workflow on the whole paper campaign (106 runs, 686 s at 1 kHz) with the
    whole library: the truth is the validation bank's hidden case ``case_name`` (``bank.hidden``,
    independent of the library; the bank must be installed: :mod:`omni_studies.bank_link`),
    measured with the quantised, noisy encoder of the compact experiment set
    (:mod:`discrepancy.experiment_set`).

    Returns
    -------
    dict
        ``wall_s``, ``samples``, ``candidates``, ``named``, ``correct``, ``parameters`` (fitted
        and truth, with the 95 % half-width), ``shrink_factor``, ``physics_steps``.
    """
    hidden = load_bank("the discrepancy campaign benchmark").hidden
    case = hidden.case(case_name)
    runs = hidden.generate(case, exps=ex.campaign("paper"), jobs=jobs)
    t0 = time.perf_counter()
    rep = run_discrepancy(runs, None, jobs=jobs, log=log).report
    wall = time.perf_counter() - t0
    named = [e["name"] for e in rep["effects"]]
    truth = dict(case.effects)
    params = {e["name"]: {p: {"fitted": v, "half_width_95": e["uncertainty"][p],
                              "truth": (truth[e["name"]][i] if e["name"] in truth else None)}
                          for i, (p, v) in enumerate(e["parameters"].items())}
              for e in rep["effects"] if e["name"] != "none"}
    return {"case": case_name, "wall_s": round(wall, 1), "runs": len(runs),
            "samples": int(sum(len(r.t) for r in runs)), "candidates": len(fx.NAMES),
            "named": named, "correct": sorted(named) == sorted(case.expect),
            "parameters": params, "shrink_factor": rep["shrink_factor"],
            "physics_steps": rep["timings"]["physics_steps"]}


def bench_sweep(workers: int) -> float:
    """Variants per second of the example study (``omni sweep --example``) on ``workers``
    local worker processes (a fresh temporary output folder; cluster start-up included)."""
    from .sweep import EXAMPLE, parse_study, run_sweep

    study = parse_study(EXAMPLE, "example")
    with tempfile.TemporaryDirectory(prefix="omni-sweep-bench-") as d:
        t0 = time.perf_counter()
        run_sweep(study, Path(d) / "out", workers=workers, progress=False)
        return len(study.variants) / (time.perf_counter() - t0)
