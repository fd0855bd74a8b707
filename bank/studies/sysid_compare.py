"""MuJoCo's own identification (``mujoco.sysid``) beside ``omni discrepancy``'s fit, on the same
parameters of the same data: estimates, 95 % intervals, wall time, physics steps.

A study tool: ``mujoco.sysid`` is not a dependency of the project.  It ships with MuJoCo >= 3.5,
its optional requirements with the extra::

    pip install "mujoco[sysid]==4.0.0"      # the installed MuJoCo's version

Cases (each a set of parameters fitted by every method that can hold them):

* ``servo_off``: the bank's geared servo with nothing hidden and the nominal that is off
  (``hidden.case("nominal_off")``): the four MJCF constants armature, damping, frictionloss,
  gear, truth = ``models/servo_pendulum/servo_pendulum.xml``'s values;
* ``servo_load``: the bank's ``load_friction`` case: the named model's ``mu_drive``,
  ``mu_back`` (truth ``servo_truth.MU_DRIVE``, ``MU_BACK``), the MJCF constants at the truth;
  ``servo_load_mjcf``: the same data, the four MJCF constants alone (what a plain rollout can
  hold of that model);
* ``feetech``: ``examples/real_servo`` (four logs of a real STS3250): its nominal's four
  constants (no truth).

Methods:

* ``ours``: :class:`discrepancy.fit.Problem` (closed-loop replay, trust-region fit) from
  the common start, intervals 1.96 x :func:`discrepancy.fit.jacobian_se`;
  ``ours_workflow``: the interval the workflow reports (:meth:`discrepancy.select.Scorer.score_set`
  + :func:`discrepancy.uncertainty.uncertainty`: jackknife over 5 blocked folds, Jacobian,
  measurement bootstrap, numerical terms);
* ``sysid_open``: ``mujoco.sysid``'s own pipeline (``ModelSequences``, its residual, its default
  rollout: open loop on the logged command ``v``, interpolated to the timestep), optimizer
  ``"mujoco"`` with its defaults, intervals ``calculate_intervals``;
* ``sysid_closed``: ``sysid.optimize`` and ``calculate_intervals`` on sysid's residual (same
  normalisation) whose rollouts are the device's closed loop (the P law on the model's own
  angle, the torque switch, the engine's friction laws), with sysid's default finite-difference
  step; ``sysid_closed_scaled``: the same with each parameter in units of the library's scale
  and ``eps`` = 0.05 (our finite-difference step).

The study computes the record (:func:`record_header`, :func:`run_case` per case);
``scripts/sysid_compare.py`` is its command line, writing ``sysid_compare.json``;
:mod:`bank.writers.sysid_report` renders ``sysid.md`` from it.  ``mujoco.sysid`` is imported by
:func:`load_sysid` only, so importing this module needs no extra.  The Feetech case reads
``examples/real_servo`` of the checkout (:data:`ROOT`): the study runs from one.
"""

from __future__ import annotations

import datetime
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from identification.dataset import read_dataset
from omni_sim.device import Device
from discrepancy import effects as fx
from discrepancy import select as sel
from discrepancy import uncertainty as un
from discrepancy.fit import Problem, gap, jacobian_se
from discrepancy.replay import Replayer, control_period_of, prepare_runs
from omni_sim.model import Target

from bank import hidden, servo_truth

#: The checkout the study runs in (examples/real_servo, the truth models' paths in the record).
ROOT = Path(__file__).resolve().parents[2]

CASES = ("servo_off", "servo_load", "servo_load_mjcf", "feetech")
#: The MJCF constants of a nominal (library effects, one parameter each).
MJCF_SET = ("armature", "viscous_damping", "coulomb_friction", "torque_gain")
#: Fold count of the workflow's interval (its default ``k``).
FOLDS = 5
#: Finite-difference step of the scaled sysid variant, in units of the library's scale: the
#: step :meth:`discrepancy.fit.Problem._steps` takes (0.05 x scale).
SCALED_EPS = 0.05
#: Iteration cap of sysid's optimizer (its default, ``optimize``'s ``max_iters``).
SYSID_MAX_ITERS = 200
METHOD_LABELS = {
    "ours": "ours (closed loop, trust region; 1.96 x Jacobian se)",
    "ours_workflow": "ours, the workflow's reported interval (jackknife + Jacobian + bootstrap)",
    "sysid_open": "mujoco.sysid as shipped (open loop on logged v; defaults)",
    "sysid_closed": "mujoco.sysid, closed-loop rollouts, its default FD step",
    "sysid_closed_scaled": "mujoco.sysid, closed-loop rollouts, scaled parameters, FD step 0.05 scale",
}


# -- the cases ---------------------------------------------------------------------------------
class Case:
    """Runs, nominal spec, target and the parameter set of one comparison."""

    def __init__(self, cid: str, title: str, runs, path: Path, target: Target, names: tuple,
                 truth: list | None, note: str, truth_path: Path | None = None):
        self.cid, self.title, self.note = cid, title, note
        self.path, self.target = Path(path), target
        self.spec = mujoco.MjSpec.from_file(str(path))
        self.model = self.spec.compile()
        self.period = control_period_of(runs)
        self.raw_runs = runs
        self.runs = prepare_runs(runs, Device(self.model, self.period, target=target))
        self.builder = fx.ModelBuilder(self.spec, target)
        self.effects = [self.builder.effect(n) for n in names]
        self.names = names
        self.truth = truth
        self.truth_path = truth_path
        lo, hi, sc, x0, labels, units = [], [], [], [], [], []
        for e in self.effects:
            l, h = e.bounds()
            lo += list(l)
            hi += list(h)
            sc += list(e.scales())
            x0 += list(self.builder.nominal_values(e))
            labels += [f"{e.name}.{p.name}" for p in e.params]
            units += [p.unit for p in e.params]
        self.lower, self.upper, self.scale = np.array(lo), np.array(hi), np.array(sc)
        self.nominal = np.array(x0)
        self.x0 = off_bounds(self.nominal, self.lower, self.upper)
        self.labels, self.units = labels, units

    def changes(self, x):
        out, i = [], 0
        for e in self.effects:
            out.append((e, np.asarray(x[i:i + e.nparam], float)))
            i += e.nparam
        return out

    def data_summary(self) -> dict:
        dts = np.concatenate([np.diff(r.t) for r in self.runs])
        return {"runs": len(self.runs), "samples": int(sum(r.n for r in self.runs)),
                "duration_s": float(sum(r.t[-1] - r.t[0] for r in self.runs)),
                "median_log_period_s": float(np.median(dts)),
                "control_period_s": float(self.period),
                "torque_off_share": float(np.mean(np.concatenate(
                    [(~r.enabled) if r.enabled is not None else np.zeros(r.n, bool) for r in self.runs])))}


def off_bounds(x, lo, hi, fraction: float = 0.05, tol: float = 1e-3) -> np.ndarray:
    """``x`` with every value within ``tol`` of the box's width of a bound moved ``fraction`` of
    the width inside (sysid's ``Parameter.move_off_bound`` rule): the common start of every
    method."""
    w = hi - lo
    x = np.asarray(x, float).copy()
    x = np.where(x - lo <= tol * w, lo + fraction * w, x)
    return np.where(hi - x <= tol * w, hi - fraction * w, x)


def make_case(cid: str, feetech_data: Path | None) -> Case:
    if cid in ("servo_off", "servo_load", "servo_load_mjcf"):
        hc = hidden.case({"servo_off": "nominal_off"}.get(cid, "load_friction"))
        runs = hidden.generate(hc)
        path, target = hidden.nominal(hc)
        # the truth's values as its file states them (the MJCF attributes themselves)
        ts = mujoco.MjSpec.from_file(str(servo_truth.model_path()))
        tj, ta = ts.joint(servo_truth.JOINT), ts.actuator(servo_truth.ACTUATOR)
        mjcf_truth = [float(tj.armature), float(tj.damping[0]), float(tj.frictionloss), float(ta.gear[0])]
        if cid == "servo_off":
            return Case(cid, "geared servo, nothing hidden, nominal off (bank case nominal_off)", runs,
                        path, target, MJCF_SET, mjcf_truth,
                        "the nominal's armature 5.6e-3 (truth 2.5e-3) and frictionloss 0.018 (truth 0.03); "
                        "every parameter is an MJCF attribute, so a plain rollout can hold the truth",
                        truth_path=servo_truth.model_path())
        if cid == "servo_load":
            return Case(cid, "geared servo, load-dependent friction hidden (bank case load_friction): "
                        "the named model's coefficients", runs, path, target, ("load_friction",),
                        [servo_truth.MU_DRIVE, servo_truth.MU_BACK, servo_truth.B_EMF],
                        "the nominal holds the truth's MJCF constants; the law Fc + mu |tau| is the device "
                        "engine's, applied every control period (omni_sim/device.py DriveFriction)")
        return Case(cid, "geared servo, load-dependent friction hidden: the MJCF constants alone",
                    runs, path, target, MJCF_SET, None,
                    "the load_friction case's runs; the four MJCF constants fitted without the law (what a "
                    "plain rollout can hold): no truth, the truth has them at the nominal's values plus the law")
    if cid == "feetech":
        folder = feetech_data
        if folder is None:
            folder = Path(tempfile.mkdtemp(prefix="sysid_feetech_")) / "data"
            subprocess.run([sys.executable, str(ROOT / "examples/real_servo/convert.py"), "--out", str(folder)],
                           check=True, capture_output=True)
        runs = read_dataset(folder, require_pose=False, uniform=False)
        return Case(cid, "Feetech STS3250 pendulum (examples/real_servo, four real logs)", runs,
                    ROOT / "examples/real_servo/model.xml", Target("servo_axis", "servo"), MJCF_SET, None,
                    "real data: no truth; v is convert.py's estimate of the P law's command (not logged); "
                    "lift_and_drop switches the torque off")
    raise KeyError(cid)


# -- closed-loop gap of any estimate -----------------------------------------------------------
def closed_gap(case: Case, rep: Replayer, x) -> float:
    """Gap [rad] of the closed-loop replay (all runs, whole) of the nominal with ``x`` written."""
    model = case.builder.compile(case.changes(x))
    th = rep.simulate([model], case.runs)
    return gap([a - r.theta for a, r in zip(th, case.runs)])


def truth_closed_gap(case: Case, rep: Replayer) -> float | None:
    if case.truth_path is None:
        return None
    model = mujoco.MjModel.from_xml_path(str(case.truth_path))
    th = rep.simulate([model], case.runs)
    return gap([a - r.theta for a, r in zip(th, case.runs)])


# -- ours --------------------------------------------------------------------------------------
def run_ours(case: Case, rep: Replayer) -> tuple[dict, dict]:
    s0, t0 = rep.steps, time.perf_counter()
    prob = Problem(case.builder, [], case.effects, case.runs, rep)
    fit = prob.fit(case.x0)
    se = jacobian_se(prob, fit)
    wall, steps = time.perf_counter() - t0, rep.steps - s0
    ours = {"x": fit.x.tolist(), "half_width_95": (1.96 * se).tolist(),
            "interval": "1.96 x jacobian_se (sandwich, residual correlation time)",
            "wall_s": wall, "physics_steps": int(steps), "simulations": int(prob.nsim), "loop": "closed",
            "fd_step": "0.05 x scale (forward)"}
    # the workflow's interval on the same parameters (its estimator refits from the fit)
    s0, t0 = rep.steps, time.perf_counter()
    g0 = closed_gap(case, rep, case.nominal)
    folds = sel.make_folds(case.runs, FOLDS, "blocked")
    sc = sel.Scorer(case.builder, case.runs, rep, folds).score_set("set", case.effects, fit.x, g0)
    # the encoder's step counts only for runs whose metadata says encoder_quantized (the bank's)
    unc = un.uncertainty(case.builder, sc, case.runs, rep, servo_truth.ENCODER_STEP_RAD)
    cover = un.coverage_factor(len(sc.folds))
    hw = cover * unc["se"] + np.abs(unc["measurement_bias"])
    wf = {"x": sc.fit.x.tolist(), "half_width_95": hw.tolist(),
          "interval": f"t({len(sc.folds) - 1}) x se (jackknife, Jacobian, measurement, numerical) + |bias|",
          "wall_s": time.perf_counter() - t0, "physics_steps": int(rep.steps - s0),
          "heldout_gap_rad": float(sc.heldout_gap), "loop": "closed",
          "terms": {k: np.asarray(unc[k]).tolist() for k in ("jackknife", "jacobian", "measurement",
                                                              "measurement_bias", "optimiser", "numerical_floor")}}
    return ours, wf


# -- mujoco.sysid ------------------------------------------------------------------------------
def sysid_params(sysid, case: Case, scaled: bool, only_mjcf: bool = False):
    """One sysid ``Parameter`` per library parameter, written into the spec by the library's
    own writer (the same MJCF change as ours); ``scaled``: values in units of the scale."""
    params = sysid.ParameterDict()
    i = 0
    for e in case.effects:
        for k, p in enumerate(e.params):
            s = case.scale[i] if scaled else 1.0
            params.add(sysid.Parameter(case.labels[i], case.x0[i] / s, case.lower[i] / s, case.upper[i] / s,
                                       modifier=_writer(case, e, k, s)))
            i += 1
    return params


def _writer(case: Case, effect, k: int, s: float):
    def write(spec, param):
        x = np.asarray(effect.read(spec, case.target), float).copy()
        x[k] = float(param.value[0]) * s
        effect.write(spec, x, case.target)
    return write


def _initial_state(sysid, model, theta0: float) -> np.ndarray:
    qpos = np.zeros(model.nq)
    qpos[model.jnt_qposadr[model.joint(0).id]] = theta0
    return sysid.create_initial_state(model, qpos)


def _measured(sysid, case: Case, model):
    joint = case.target.joint
    out = []
    for r in case.runs:
        out.append((sysid.TimeSeries(r.t, r.v[:, None]),
                    sysid.TimeSeries.from_names(r.t, r.theta[:, None], model,
                                                names=[(joint, sysid.SignalType.MjStateQPos)]),
                    _initial_state(sysid, model, float(r.theta[0]))))
    return out


def run_sysid_open(sysid, case: Case, jobs: int) -> dict:
    """sysid's own pipeline: ModelSequences, its residual and default rollout (counted)."""
    spec = case.spec.copy()
    params = sysid_params(sysid, case, scaled=False)
    model = spec.compile()
    meas = _measured(sysid, case, model)
    ms = sysid.ModelSequences(case.cid, spec, [r.name for r in case.runs], [m[2] for m in meas],
                              [m[0] for m in meas], [m[1] for m in meas], allow_missing_sensors=True)
    count = {"steps": 0, "rollouts": 0}

    def rollout(models, datas, control_signal, initial_states, param_dicts, rollout_signal_mapping,
                rollout_state_mapping, ctrl_mapping):
        # exactly what model_residual runs without a custom rollout, with a count
        count["rollouts"] += len(models)
        count["steps"] += sum(len(c.times) - 1 for c in control_signal)
        return sysid.sysid_rollout(models=models, datas=datas, control_signal=control_signal,
                                   initial_states=initial_states, rollout_signal_mapping=rollout_signal_mapping,
                                   rollout_state_mapping=rollout_state_mapping, ctrl_mapping=ctrl_mapping)

    residual_fn = sysid.build_residual_fn(models_sequences=[ms], custom_rollout=rollout, n_threads=jobs)
    return _optimize(sysid, case, params, residual_fn, count, scale=np.ones(len(case.x0)), eps=None,
                     loop="open (logged v)")


def closed_residual_fn(sysid, case: Case, rep: Replayer, params):
    """sysid's residual (measured minus predicted at the logged times after the first,
    normalised per run by ``|measured| / sqrt(2)``) with the device's closed loop as the
    rollout: every run and finite-difference column in one batch of the replay."""
    spec = case.spec.copy()
    meas = [r.theta[1:, None] for r in case.runs]

    def fn(x, p, **_):
        X = x.reshape(len(x), -1) if x.ndim > 1 else x[:, None]
        models = []
        for i in range(X.shape[1]):
            p.update_from_vector(X[:, i])
            models.append(sysid.apply_param_modifiers(p, spec))
        th = rep.simulate(models, case.runs)
        out = []
        for j, (r, m) in enumerate(zip(case.runs, meas)):
            cols = []
            for i in range(X.shape[1]):
                pred = th[i * len(case.runs) + j][1:, None]
                res = sysid.normalize_residual(sysid.weighted_diff(predicted_data=pred, measured_data=m), m)
                cols.append(res.ravel())
            out.append(np.column_stack(cols) if x.ndim > 1 else cols[0])
        if x.ndim > 1:
            p.update_from_vector(X[:, 0])
        return out, None, None
    return fn


def hook_check(sysid, case: Case, params) -> dict:
    """The batched closed-loop residual against sysid's own per-trajectory ``model_residual``
    with the same rollout as its ``custom_rollout`` hook, at the start (residuals and time)."""
    spec = case.spec.copy()
    model = spec.compile()
    meas = _measured(sysid, case, model)
    nstate = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)

    def hook_for(run, replayer):
        def hook(models, datas, control_signal, initial_states, param_dicts, rollout_signal_mapping,
                 rollout_state_mapping, ctrl_mapping):
            th = replayer.simulate(list(models), [run])
            t = run.t[1:]
            out = []
            for m, c, s0, theta in zip(models, control_signal, initial_states, th):
                st = np.zeros((len(t), nstate))
                st[:, 0], st[:, 1 + m.jnt_qposadr[m.joint(case.target.joint).id]] = t, theta[1:]
                out.append(sysid.SystemTrajectory(model=m, control=c, sensordata=sysid.TimeSeries(
                    t, np.zeros((len(t), m.nsensordata))), initial_state=s0, state=sysid.TimeSeries(t, st)))
            return out
        return hook

    x = params.as_vector()
    X = np.column_stack([x] + [x + 0.05 * case.scale * e for e in np.eye(len(x))])
    build = lambda p: sysid.apply_param_modifiers(p, spec)  # noqa: E731
    # fresh replayers (no trajectory cache): both paths simulate everything
    with Replayer(1, case.target, case.period) as fresh:
        t0 = time.perf_counter()
        per_run = []
        for r, (c, s, s0) in zip(case.runs, meas):
            traj = sysid.SystemTrajectory(model=model, control=c, sensordata=s, initial_state=s0, state=None)
            res, _, _ = sysid.model_residual(X, params, build, traj, custom_rollout=hook_for(r, fresh),
                                             n_threads=1)
            per_run.append(res)
        t_hook = time.perf_counter() - t0
    with Replayer(1, case.target, case.period) as fresh:
        t0 = time.perf_counter()
        batched, _, _ = closed_residual_fn(sysid, case, fresh, params)(X, params)
        t_batch = time.perf_counter() - t0
    diff = max(float(np.max(np.abs(a - b))) for a, b in zip(per_run, batched))
    return {"columns": int(X.shape[1]), "max_abs_difference": diff, "per_trajectory_hook_s": t_hook,
            "batched_s": t_batch}


def run_sysid_closed(sysid, case: Case, rep: Replayer, scaled: bool) -> dict:
    params = sysid_params(sysid, case, scaled=scaled)
    fn = closed_residual_fn(sysid, case, rep, params)
    s0, u0 = rep.steps, rep.unstable_replays
    count = {"steps": 0, "rollouts": 0}
    out = _optimize(sysid, case, params, fn, count, scale=case.scale if scaled else np.ones(len(case.x0)),
                    eps=SCALED_EPS if scaled else None, loop="closed (device loop)", rep=rep)
    out["physics_steps"] = int(rep.steps - s0)
    out["unstable_replays"] = int(rep.unstable_replays - u0)
    return out


def _optimize(sysid, case: Case, params, residual_fn, count: dict, scale, eps, loop: str,
              rep: Replayer | None = None) -> dict:
    import contextlib
    import io

    kw = {"max_iters": SYSID_MAX_ITERS}
    if eps is not None:
        kw["eps"] = eps
    buf = io.StringIO()
    t0 = time.perf_counter()
    try:
        with contextlib.redirect_stdout(buf):
            opt, result = sysid.optimize(params, residual_fn, optimizer="mujoco", verbose=False, **kw)
    except Exception as exc:  # recorded, not hidden: a failed fit is a result of the comparison
        return {"failed": f"{type(exc).__name__}: {exc}", "wall_s": time.perf_counter() - t0,
                "physics_steps": int(count["steps"]), "loop": loop}
    wall = time.perf_counter() - t0
    res, _, _ = residual_fn(opt.as_vector(), opt)
    _, iv = sysid.calculate_intervals(res, result.jac)
    log = buf.getvalue().strip().splitlines()
    last = [ln for ln in log if ln.startswith("Terminated") or ln.startswith("total time")]
    iters = sum(1 for ln in log if ln.startswith("iter:"))
    x = opt.as_vector() * scale
    return {"x": x.tolist(), "half_width_95": (np.asarray(iv) * scale).tolist(),
            "interval": "calculate_intervals: t x sqrt(s^2 diag (J'J)^-1), J at the last iterate",
            "wall_s": wall, "physics_steps": int(count["steps"]), "rollouts": int(count["rollouts"]),
            "iterations": iters, "status": " ".join(last), "loop": loop,
            "fd_step": "eps 1.5e-8 x max(1, |x|) (default)" if eps is None
            else f"eps {eps:g} x max(1, |x / scale|), x in units of the scale"}


# -- open-loop drift ---------------------------------------------------------------------------
def open_loop_gap(sysid, case: Case, model: mujoco.MjModel) -> float:
    """Gap [rad] of sysid's default rollout (open loop on the logged v) of ``model``."""
    meas = _measured(sysid, case, model)
    data = [mujoco.MjData(model)]
    res = []
    for r, (c, _, s0) in zip(case.runs, meas):
        ctrl = c.resample(target_dt=model.opt.timestep)
        tr = sysid.sysid_rollout(models=[model], datas=data, control_signal=[ctrl], initial_states=[s0])[0]
        qadr = model.jnt_qposadr[model.joint(case.target.joint).id]
        th = np.interp(r.t[1:], tr.state.times, tr.state.data[:, 1 + qadr])
        res.append(th - r.theta[1:])
    return gap(res)


# -- the study ---------------------------------------------------------------------------------
def run_case(sysid, cid: str, jobs: int, feetech_data: Path | None, log, commit: str | None) -> dict:
    """One case's record: its data, parameters, gaps, every method's estimate, interval and
    costs, the hook check, the wall time, the load average before and after and ``commit``."""
    load0 = os.getloadavg()[0]
    t_case = time.perf_counter()
    case = make_case(cid, feetech_data)
    rec = {"id": cid, "title": case.title, "note": case.note, "data": case.data_summary(),
           "model": str(case.path.relative_to(ROOT)) if case.path.is_relative_to(ROOT) else case.path.name,
           "joint": case.target.joint, "actuator": case.target.actuator,
           "parameters": [{"name": n, "unit": u, "truth": None if case.truth is None else case.truth[i],
                           "nominal": float(case.nominal[i]), "start": float(case.x0[i]),
                           "lower": float(case.lower[i]), "upper": float(case.upper[i]),
                           "scale": float(case.scale[i])} for i, (n, u) in enumerate(zip(case.labels, case.units))],
           "methods": {}}
    mjcf_only = all(e.name in MJCF_SET for e in case.effects)
    with Replayer(jobs, case.target, case.period) as rep:
        rec["gap_nominal_rad"] = closed_gap(case, rep, case.nominal)
        rec["gap_start_rad"] = closed_gap(case, rep, case.x0)
        tg = truth_closed_gap(case, rep)
        if tg is not None:
            tm = mujoco.MjModel.from_xml_path(str(case.truth_path))
            rec["drift"] = {"closed_loop_truth_gap_rad": tg, "open_loop_truth_gap_rad": open_loop_gap(sysid, case, tm)}
        log(f"{cid}: nominal gap {rec['gap_nominal_rad']:.3e} rad")
        ours, wf = run_ours(case, rep)
        rec["methods"]["ours"], rec["methods"]["ours_workflow"] = ours, wf
        log(f"{cid}: ours {np.round(ours['x'], 5)} +- {np.round(ours['half_width_95'], 6)} ({ours['wall_s']:.0f} s)")
        if mjcf_only:
            so = run_sysid_open(sysid, case, jobs)
            rec["methods"]["sysid_open"] = so
            log(f"{cid}: sysid open {np.round(so['x'], 5)} +- {so['half_width_95']} ({so['wall_s']:.0f} s)")
        else:
            rec["methods"]["sysid_open"] = {"represents": False, "reason": (
                "the parameters are the coefficients of the device engine's law (the joint's frictionloss "
                "set every control period from the transmitted torque); a plain rollout holds one "
                "frictionloss for the whole run, so no Parameter modifier on MjSpec can express them")}
        rec["hook_check"] = hook_check(sysid, case, sysid_params(sysid, case, scaled=False))
        for key, scaled in (("sysid_closed", False), ("sysid_closed_scaled", True)):
            r = run_sysid_closed(sysid, case, rep, scaled)
            rec["methods"][key] = r
            log(f"{cid}: {key} {np.round(r['x'], 5)} +- {r['half_width_95']} ({r['wall_s']:.0f} s, {r['status']})")
        for key, m in rec["methods"].items():
            if "x" in m:
                m["gap_closed_loop_rad"] = closed_gap(case, rep, np.asarray(m["x"]))
    rec["wall_s"] = time.perf_counter() - t_case
    rec["load_average"] = [load0, os.getloadavg()[0]]
    rec["code_commit"] = commit
    return rec


#: What the study imports or reads (checked for uncommitted changes at its start).
CODE_PATHS = ("omni_sim", "identification", "discrepancy", "models", "examples/real_servo",
              "bank/hidden.py", "bank/servo_truth.py", "bank/studies/sysid_compare.py",
              "bank/writers/sysid_report.py", "omni_app/provenance.py", "scripts/sysid_compare.py")


def load_sysid():
    """``mujoco.sysid`` with its extra's requirements (absl's log at errors only), or None when
    the extra is not installed (``pip install "mujoco[sysid]"``)."""
    from mujoco import sysid  # the optional extra: pip install "mujoco[sysid]"
    if not hasattr(sysid, "optimize"):
        return None
    from absl import logging as absl_logging
    absl_logging.set_verbosity(absl_logging.ERROR)
    return sysid


def record_header(commit: str | None, uncommitted_code: list[str] | None, jobs: int) -> dict:
    """The record's fields beside its cases: the code's commit and its uncommitted files, MuJoCo's
    version, the date, the rollout threads, the cores and the extra's install line."""
    return {"code_commit": commit, "uncommitted_code": uncommitted_code, "mujoco": mujoco.__version__,
            "date": datetime.date.today().isoformat(), "jobs": jobs, "cpus": os.cpu_count(),
            "install": 'pip install "mujoco[sysid]==' + mujoco.__version__ + '"'}
