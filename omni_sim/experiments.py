"""The paper's experiments on the virtual Omni: references, campaigns and the runner.

Time/array convention (used throughout the project): a run is sampled at the servo rate
(``control_period_s``, 1 ms), sample ``k`` is at ``t_k = k * dt``; ``theta_k`` is the yaw angle
*measured* at ``t_k`` (before the controller acts), ``v_k = kp * (r_k - theta_k)`` (clipped to
the drive's limit) is the command voltage held (zero-order hold) over ``[t_k, t_k + dt)``.

Two ways to run the same physics:

* the fast path (default): the yaw P controller is folded into the model's ``yaw_motor``
  (``force = kp*r - kp*theta``, clamped to the voltage limit, times the gear) and all runs go
  through :func:`mujoco.rollout.rollout` in C over threads. Valid when the physics step equals
  the control period, the measurement is exact, and ``yaw_motor`` is a plain motor.
* the reference path: a Python loop that reads the (optionally quantised and noisy) encoder,
  computes ``v`` and steps the physics ``substeps`` times per control period. Used for
  everything else, and in the tests as the slow, obviously correct reference for the fast path.
"""

from __future__ import annotations

import hashlib
import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from identification.dataset import Run
from identification.errors import UserError

from . import model as om

# --- The paper's experiment design ---------------------------------------------------------
#: Table 1: set points (gamma1, gamma2) [deg] of the frequency-response experiments.
TABLE1_POSES = tuple((g1, g2) for g1 in (25, 45, 65) for g2 in (70, 90, 115))
#: Section 2.4.2: sine frequencies [Hz].
TABLE1_FREQUENCIES_HZ = (1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 7.0)
#: Table 2: set points (gamma1, gamma2) [deg] of the step-response experiments.
TABLE2_POSES = tuple((g1, g2) for g1 in (25, 35, 45, 55, 65) for g2 in (60, 70, 90, 110, 115))
#: Yaw P gain [V/rad]: Table 9, beta_linear / beta_tilde_linear = 445.6 / 222.8.
KP_DEFAULT = 2.0
#: Sine reference amplitude A_r [rad].  Not stated in the paper; 0.1 rad puts the alpha-invariant
#: (36) of a linear model with Table 9's coefficients at ~2 at 2 Hz and ~200 near resonance,
#: the range of Table 7's breakpoints (0, 2.2, 25, 250).  Calibrated in scripts/calibrate.py.
SINE_AMPLITUDE_RAD = 0.0498256
#: Section 2.4.3: square wave 0.25 Hz, 0.07 rad, from theta = -0.07 rad at rest.
STEP_FREQUENCY_HZ = 0.25
STEP_AMPLITUDE_RAD = 0.07
#: Square-wave record: two whole periods (four edges) [s].
STEP_DURATION_S = 8.0
#: Sine runs: settle for this long [s] (closed-loop time constant 2/C ~ 0.3 s at C ~ 6 1/s),
#: then record whole cycles lasting at least SINE_RECORD_S [s] (>= 6 cycles at 1.5 Hz).
SINE_SETTLE_S = 2.0
SINE_RECORD_S = 4.0
#: The Omni's servo period [s] (1 kHz, models/README.md).
CONTROL_PERIOD_S = 1e-3
#: Encoder resolution [rad]: 15000 counts per revolution (models/README.md).
ENCODER_STEP_RAD = 2 * math.pi / 15000
CAMPAIGNS = ("paper", "sine", "step")


@dataclass(frozen=True)
class Experiment:
    """One run to perform: arm set points and a sampled yaw reference.

    Attributes
    ----------
    name : str
        Run name (file stem of the dataset).
    kind : str
        ``"sine"``, ``"step"`` or ``"other"``.
    gamma1_set_deg, gamma2_set_deg : float [deg]
        Arm servo set points.
    r : ndarray [rad]
        Yaw reference, one value per control period.
    frequency_hz, amplitude_rad : float
        Metadata of the reference (0 if not periodic).
    theta0_rad : float [rad]
        Initial yaw angle (at rest).
    """

    name: str
    kind: str
    gamma1_set_deg: float
    gamma2_set_deg: float
    r: np.ndarray = field(repr=False)
    frequency_hz: float
    amplitude_rad: float
    theta0_rad: float = 0.0


def _time(duration_s: float, dt: float) -> np.ndarray:
    return np.arange(int(round(duration_s / dt))) * dt


def sine_experiment(gamma1_set_deg: float, gamma2_set_deg: float, frequency_hz: float,
                    amplitude_rad: float = SINE_AMPLITUDE_RAD, dt: float = CONTROL_PERIOD_S,
                    settle_s: float = SINE_SETTLE_S, record_s: float = SINE_RECORD_S) -> Experiment:
    """A sine run ``r = A_r sin(2 pi f t)``: settle, then whole cycles (>= ``record_s``)."""
    if not (frequency_hz > 0 and math.isfinite(frequency_hz)):
        raise UserError(f"sine frequency must be positive, got {frequency_hz}")
    cycles = math.ceil(record_s * frequency_hz - 1e-9)
    duration = settle_s + cycles / frequency_hz
    t = _time(duration, dt)
    r = amplitude_rad * np.sin(2 * np.pi * frequency_hz * t)
    name = f"sine_g{gamma1_set_deg:02.0f}_{gamma2_set_deg:03.0f}_f{frequency_hz:04.2f}".replace(".", "p")
    return Experiment(name, "sine", gamma1_set_deg, gamma2_set_deg, r, frequency_hz, amplitude_rad)


def square_experiment(gamma1_set_deg: float, gamma2_set_deg: float,
                      frequency_hz: float = STEP_FREQUENCY_HZ,
                      amplitude_rad: float = STEP_AMPLITUDE_RAD,
                      duration_s: float = STEP_DURATION_S, dt: float = CONTROL_PERIOD_S) -> Experiment:
    """The paper's square wave (47): ``r = +A_r`` for the first half period, from ``theta=-A_r``."""
    t = _time(duration_s, dt)
    phase = (t * frequency_hz) % 1.0
    r = np.where(phase < 0.5 - 1e-12, amplitude_rad, -amplitude_rad)
    name = f"step_g{gamma1_set_deg:02.0f}_{gamma2_set_deg:03.0f}"
    return Experiment(name, "step", gamma1_set_deg, gamma2_set_deg, r, frequency_hz,
                      amplitude_rad, theta0_rad=-amplitude_rad)


def reference_experiment(path: str | os.PathLike, gamma1_set_deg: float, gamma2_set_deg: float,
                         dt: float = CONTROL_PERIOD_S) -> Experiment:
    """A run driven by a user's reference: a CSV with columns ``t`` [s], ``r`` [rad].

    The reference is linearly interpolated onto the control grid ``0, dt, ..., t_end``.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: reference file not found")
    try:
        with open(path) as fh:
            header = [h.strip() for h in fh.readline().strip().split(",")]
            data = np.loadtxt(fh, delimiter=",", ndmin=2)
    except (ValueError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: malformed reference CSV ({exc})") from None
    if "t" not in header or "r" not in header or data.shape[1] != len(header):
        raise UserError(f"{path}: reference CSV needs a header with columns t and r")
    t_in, r_in = data[:, header.index("t")], data[:, header.index("r")]
    if len(t_in) < 2 or not np.all(np.isfinite(data)) or np.any(np.diff(t_in) <= 0):
        raise UserError(f"{path}: reference needs >= 2 finite samples with increasing t")
    t = np.arange(math.floor((t_in[-1] - t_in[0]) / dt + 1e-9) + 1) * dt  # both ends included
    r = np.interp(t + t_in[0], t_in, r_in)
    return Experiment(path.stem, "other", gamma1_set_deg, gamma2_set_deg, r, 0.0,
                      float(np.max(np.abs(r))), theta0_rad=float(r[0]))


def campaign(name: str, sine_amplitude_rad: float = SINE_AMPLITUDE_RAD) -> list[Experiment]:
    """The experiments of a campaign: ``paper`` = ``sine`` (Table 1) + ``step`` (Table 2)."""
    if name not in CAMPAIGNS:
        raise UserError(f"unknown campaign {name!r} (choose from {', '.join(CAMPAIGNS)})")
    out: list[Experiment] = []
    if name in ("paper", "sine"):
        out += [sine_experiment(g1, g2, f, sine_amplitude_rad)
                for g1, g2 in TABLE1_POSES for f in TABLE1_FREQUENCIES_HZ]
    if name in ("paper", "step"):
        out += [square_experiment(g1, g2) for g1, g2 in TABLE2_POSES]
    return out


# --- The runner ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Settings:
    """How the virtual device is run and measured.

    Attributes
    ----------
    kp : float [V/rad]
        Yaw P gain.
    control_period_s : float [s]
        Servo period; must be a whole multiple of the model's physics timestep.
    quantize : bool
        Quantise the measured yaw to the encoder's 15000 counts/rev (the controller sees it).
    noise_rad : float [rad]
        Standard deviation of white measurement noise (the controller sees it).
    seed : int
        Seed of the noise generator (one stream per run, derived from the seed and run name).
    """

    kp: float = KP_DEFAULT
    control_period_s: float = CONTROL_PERIOD_S
    quantize: bool = False
    noise_rad: float = 0.0
    seed: int = 0


def substeps(model: mujoco.MjModel, control_period_s: float) -> int:
    """Physics steps per control period (UserError unless it divides exactly)."""
    n = control_period_s / model.opt.timestep
    if not (n >= 1 and abs(n - round(n)) < 1e-9):
        raise UserError(f"control period {control_period_s} s is not a whole multiple of the "
                        f"physics timestep {model.opt.timestep} s")
    return int(round(n))


def _plain_motor(model: mujoco.MjModel, act: int) -> bool:
    return (model.actuator_dyntype[act] == mujoco.mjtDyn.mjDYN_NONE
            and model.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_FIXED
            and model.actuator_gainprm[act, 0] == 1.0
            and model.actuator_biastype[act] == mujoco.mjtBias.mjBIAS_NONE
            and getattr(model, "actuator_delay", np.zeros(model.nu))[act] == 0)


def fast_path_ok(model: mujoco.MjModel, settings: Settings) -> bool:
    """True when the rollout fast path gives the same trajectory as the reference loop."""
    ix = om.index(model)
    return (substeps(model, settings.control_period_s) == 1 and not settings.quantize
            and settings.noise_rad == 0 and _plain_motor(model, ix.yaw_act))


def _initial_data(model: mujoco.MjModel, exp: Experiment, pose: tuple[float, float]) -> mujoco.MjData:
    ix = om.index(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetData(model, data)
    data.qpos[ix.yaw_qpos] = exp.theta0_rad
    data.qpos[ix.shoulder_qpos] = math.radians(pose[0])
    data.qpos[ix.elbow_qpos] = math.radians(pose[1])
    om.set_arm_setpoints(model, data, exp.gamma1_set_deg, exp.gamma2_set_deg)
    mujoco.mj_forward(model, data)
    return data


def _servo_model(model: mujoco.MjModel, kp: float) -> mujoco.MjModel:
    """A copy of ``model`` whose ``yaw_motor`` is the P controller: ctrl = r, force = v."""
    ix = om.index(model)
    m = _copy_model(model)
    a = ix.yaw_act
    vmax = om.voltage_limit(model)
    lo, hi = (-vmax, vmax)
    if model.actuator_forcelimited[a]:
        lo, hi = max(lo, model.actuator_forcerange[a, 0]), min(hi, model.actuator_forcerange[a, 1])
    m.actuator_gainprm[a, 0] = kp
    m.actuator_biastype[a] = mujoco.mjtBias.mjBIAS_AFFINE
    # the affine bias acts on the actuator length, which is gear * theta
    m.actuator_biasprm[a, :3] = (0.0, -kp / model.actuator_gear[a, 0], 0.0)
    m.actuator_ctrllimited[a] = 0
    m.actuator_forcelimited[a] = int(math.isfinite(lo) or math.isfinite(hi))
    m.actuator_forcerange[a] = (lo if math.isfinite(lo) else -1e10, hi if math.isfinite(hi) else 1e10)
    return m


def _copy_model(model: mujoco.MjModel) -> mujoco.MjModel:
    import copy
    return copy.deepcopy(model)


def _stream(seed: int, name: str) -> np.random.Generator:
    digest = hashlib.sha256(f"{seed}:{name}".encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:8], "little"))


def _measure(theta: float, settings: Settings, noise: float) -> float:
    y = theta + noise
    if settings.quantize:
        y = round(y / ENCODER_STEP_RAD) * ENCODER_STEP_RAD
    return y


def run_reference_loop(model: mujoco.MjModel, exp: Experiment, settings: Settings,
                       pose: tuple[float, float]) -> dict:
    """The reference path: one run, Python loop at the control period (see module doc)."""
    ix = om.index(model)
    data = _initial_data(model, exp, pose)
    n_sub = substeps(model, settings.control_period_s)
    vmax = om.voltage_limit(model)
    n = len(exp.r)
    noise = (_stream(settings.seed, exp.name).normal(0.0, settings.noise_rad, n)
             if settings.noise_rad > 0 else np.zeros(n))
    theta = np.empty(n)
    v = np.empty(n)
    q1 = np.empty(n)
    q2 = np.empty(n)
    kp = settings.kp
    for k in range(n):
        y = _measure(data.qpos[ix.yaw_qpos], settings, noise[k])
        vk = kp * (exp.r[k] - y)
        vk = min(max(vk, -vmax), vmax)
        theta[k], v[k] = y, vk
        q1[k], q2[k] = data.qpos[ix.shoulder_qpos], data.qpos[ix.elbow_qpos]
        data.ctrl[ix.yaw_act] = vk
        for _ in range(n_sub):
            mujoco.mj_step(model, data)
    if not np.all(np.isfinite(theta)):
        raise RuntimeError(f"{exp.name}: simulation diverged")
    return {"theta": theta, "v": v, "q1": q1, "q2": q2}


def run_fast(model: mujoco.MjModel, exps: list[Experiment], settings: Settings,
             poses: list[tuple[float, float]], nthread: int) -> list[dict]:
    """The fast path: all runs through ``mujoco.rollout`` with the P loop inside the model."""
    ix = om.index(model)
    servo = _servo_model(model, settings.kp)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(servo, spec)
    nstep = max(len(e.r) for e in exps)
    x0 = np.empty((len(exps), nstate))
    ctrl = np.zeros((len(exps), nstep, servo.nu))
    for b, (exp, pose) in enumerate(zip(exps, poses)):
        data = _initial_data(servo, exp, pose)
        mujoco.mj_getState(servo, data, x0[b], spec)
        ctrl[b] = data.ctrl
        ctrl[b, : len(exp.r), ix.yaw_act] = exp.r
        ctrl[b, len(exp.r):, ix.yaw_act] = exp.r[-1]
    datas = [mujoco.MjData(servo) for _ in range(max(1, nthread))]
    state, _ = rollout.rollout(servo, datas, x0, ctrl, nstep=nstep)
    qoff = 1  # FULLPHYSICS state = [time, qpos, qvel, ...]
    vmax = om.voltage_limit(model)
    out = []
    for b, exp in enumerate(exps):
        n = len(exp.r)
        qpos = np.vstack([x0[b, qoff:qoff + model.nq], state[b, : n - 1, qoff:qoff + model.nq]])
        theta = qpos[:, ix.yaw_qpos]
        if not np.all(np.isfinite(theta)):
            raise RuntimeError(f"{exp.name}: simulation diverged")
        v = np.clip(settings.kp * (exp.r - theta), -vmax, vmax)
        out.append({"theta": theta.copy(), "v": v, "q1": qpos[:, ix.shoulder_qpos].copy(),
                    "q2": qpos[:, ix.elbow_qpos].copy()})
    return out


def model_digest(path: str | os.PathLike | None) -> str:
    """SHA-256 of the model file's bytes (first 16 hex digits), for run metadata."""
    p = Path(path) if path is not None else om.DEFAULT_SCENE
    h = hashlib.sha256()
    for f in sorted({p, *p.parent.glob("*.xml")}):
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def _to_run(exp: Experiment, res: dict, settings: Settings, model_path, digest: str) -> Run:
    dt = settings.control_period_s
    t = np.arange(len(exp.r)) * dt
    meta = {
        "kind": exp.kind,
        "gamma1_deg": round(float(np.degrees(np.mean(res["q1"]))), 6),
        "gamma2_deg": round(float(np.degrees(np.mean(res["q2"]))), 6),
        "gamma1_set_deg": exp.gamma1_set_deg,
        "gamma2_set_deg": exp.gamma2_set_deg,
        "kp": settings.kp,
        "frequency_hz": exp.frequency_hz,
        "amplitude_rad": exp.amplitude_rad,
        "theta0_rad": exp.theta0_rad,
        "source": "virtual Omni (omni_sim)",
        "model": Path(model_path).name if model_path is not None else "scene.xml (built-in)",
        "model_sha256": digest,
        "control_period_s": dt,
        "encoder_quantized": settings.quantize,
        "noise_rad": settings.noise_rad,
        "seed": settings.seed,
    }
    return Run(exp.name, t, exp.r.copy(), res["theta"], res["v"], meta)


def _loop_worker(args):
    model, exp, settings, pose = args
    return run_reference_loop(model, exp, settings, pose)


def simulate(exps: list[Experiment], model_path: str | os.PathLike | None = None,
             settings: Settings = Settings(), jobs: int | None = None,
             progress: bool = False, model: mujoco.MjModel | None = None,
             force_reference: bool = False) -> list[Run]:
    """Run experiments on the virtual Omni and return them as dataset runs.

    Parameters
    ----------
    exps : list of Experiment
    model_path : path, optional
        MJCF file keeping the contract's names (default: the built-in scene).
    settings : Settings
    jobs : int, optional
        Threads (fast path) or processes (reference path); default: all cores.
    progress : bool
        Show a progress bar (tqdm) on stderr.
    model : MjModel, optional
        An already compiled model (overrides ``model_path`` for the physics).
    force_reference : bool
        Use the Python reference loop even where the fast path applies.
    """
    from tqdm import tqdm

    in_memory = model is not None and model_path is None
    if model is None:
        model = om.load_model(model_path)
    jobs = max(1, jobs or os.cpu_count() or 1)
    if settings.noise_rad < 0 or not math.isfinite(settings.noise_rad):
        raise UserError(f"noise must be a finite standard deviation >= 0, got {settings.noise_rad}")
    if not (settings.kp > 0 and math.isfinite(settings.kp)):
        raise UserError(f"kp must be positive, got {settings.kp}")
    for e in exps:
        om.check_pose(model, e.gamma1_set_deg, e.gamma2_set_deg)
    substeps(model, settings.control_period_s)
    poses_cache: dict[tuple[float, float], tuple[float, float]] = {}
    poses = []
    for e in exps:
        key = (e.gamma1_set_deg, e.gamma2_set_deg)
        if key not in poses_cache:
            poses_cache[key] = om.equilibrium_pose(model, *key)
        poses.append(poses_cache[key])
    digest = "in-memory model" if in_memory else model_digest(model_path)
    bar = tqdm(total=len(exps), desc="simulating", unit="run", disable=not progress, leave=False)
    results: list[dict] = []
    if fast_path_ok(model, settings) and not force_reference:
        chunk = max(jobs * 4, 8)
        for i in range(0, len(exps), chunk):
            results += run_fast(model, exps[i:i + chunk], settings, poses[i:i + chunk], jobs)
            bar.update(len(exps[i:i + chunk]))
    elif jobs == 1 or len(exps) == 1:
        for e, p in zip(exps, poses):
            results.append(run_reference_loop(model, e, settings, p))
            bar.update(1)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for res in pool.map(_loop_worker, [(model, e, settings, p) for e, p in zip(exps, poses)]):
                results.append(res)
                bar.update(1)
    bar.close()
    return [_to_run(e, r, settings, model_path, digest) for e, r in zip(exps, results)]

