"""The paper's experiments on the virtual Omni: references, campaign files and the runner.

Campaigns are data: ``omni_sim/campaigns/paper.toml`` holds the paper's (Table 1 sine sweeps,
Table 2 square waves, the calibrated sine amplitude, durations, settling); a user's campaign
file in the same format runs with ``omni generate --campaign FILE.toml``
(:func:`load_campaign`).  The time convention is :mod:`omni_sim.device`'s.

Two ways to run the same physics:

* the fast path (default): the yaw P controller is folded into the model's ``yaw_motor``
  (``force = kp*r - kp*theta``, clamped to the voltage limit, times the gear) and all runs go
  through :func:`mujoco.rollout.rollout` in C over threads.  Valid when the physics step equals
  the control period, the measurement is exact, and ``yaw_motor`` is a plain motor.
* the reference path: the device's closed-loop engine (:func:`omni_sim.device.run_p_loop`),
  which reads the (optionally quantised and noisy) encoder, computes ``v`` and steps the physics
  ``substeps`` times per control period.  Used for everything else, and in the tests as the
  slow, obviously correct reference for the fast path.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from identification.dataset import Run
from identification import paper
from identification.errors import UserError

from .device import (CONTROL_PERIOD_S, ENCODER_STEP_RAD, Device, Encoder,  # noqa: F401 (re-exported)
                     default_threads, p_law, run_p_loop, substeps_of)

# --- Campaign files --------------------------------------------------------------------------
#: The built-in campaigns: ``paper`` is the file ``campaigns/paper.toml``, ``sine`` and ``step``
#: its two halves.
CAMPAIGNS = ("paper", "sine", "step")
#: Keys of a campaign file's groups: required ones, and optional ones with their defaults
#: (the paper file's values, its comments give their sources).
_SINE_KEYS = {"poses_deg": None, "frequencies_hz": None, "amplitude_rad": None,
              "settle_s": None, "record_s": None}
_STEP_KEYS = {"poses_deg": None, "frequency_hz": None, "amplitude_rad": None, "duration_s": None}


def _paper_text() -> bytes:
    return resources.files("omni_sim").joinpath("campaigns", "paper.toml").read_bytes()


def _campaign_error(source: str, key: str, problem: str) -> UserError:
    return UserError(f"{source}: {key}: {problem}")


def _number(source, key, value, positive=True, allow_zero=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _campaign_error(source, key, f"must be a finite number, got {value!r}")
    if positive and not (value > 0 or (allow_zero and value == 0)):
        raise _campaign_error(source, key, f"must be {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return value


def _groups(source: str, doc: dict, kind: str, keys: dict) -> list[dict]:
    raw = doc.get(kind, [])
    raw = [raw] if isinstance(raw, dict) else raw
    if not isinstance(raw, list) or not all(isinstance(g, dict) for g in raw):
        raise _campaign_error(source, kind, "must be a table [" + kind + "] or an array of tables [[" + kind + "]]")
    out = []
    for i, g in enumerate(raw):
        where = kind if len(raw) == 1 else f"{kind}[{i}]"
        for k in g:
            if k not in keys:
                raise _campaign_error(source, f"{where}.{k}", f"unknown key (known: {', '.join(keys)})")
        for k in keys:
            if k not in g and k != "poses_deg":  # poses: checked against the device (experiments)
                raise _campaign_error(source, f"{where}.{k}", "missing")
        poses = g.get("poses_deg")
        if poses is not None and (not isinstance(poses, list) or not poses
                                  or not all(isinstance(p, list) and len(p) == 2 for p in poses)):
            raise _campaign_error(source, f"{where}.poses_deg",
                                  "must be a non-empty list of [gamma1, gamma2] set points [deg]")
        for p in poses or ():
            for x in p:
                _number(source, f"{where}.poses_deg", x, positive=False)
        grp = {"where": where, "poses": None if poses is None else tuple(tuple(p) for p in poses)}
        for k in keys:
            if k == "poses_deg":
                continue
            if k == "frequencies_hz":
                fs = g[k]
                if not isinstance(fs, list) or not fs:
                    raise _campaign_error(source, f"{where}.{k}", "must be a non-empty list of frequencies [Hz]")
                grp[k] = tuple(_number(source, f"{where}.{k}", f) for f in fs)
            else:
                grp[k] = _number(source, f"{where}.{k}", g[k], allow_zero=k in ("amplitude_rad", "settle_s"))
        out.append(grp)
    return out


@dataclass(frozen=True)
class Campaign:
    """A campaign file, parsed: sine groups and step groups (see ``campaigns/paper.toml``).

    Attributes
    ----------
    source : str
        The file (or built-in name) it came from, for messages.
    sine, step : tuple of dict
        Groups: ``poses`` (set points [deg]; None for a group without ``poses_deg``, which
        only a device without the Omni's arm runs) and the group's keys.
    """

    source: str
    sine: tuple = ()
    step: tuple = ()

    def _poses(self, g: dict, arm: bool) -> tuple:
        """A group's set points: its poses on a device with the Omni's arm, ``((None, None),)``
        (one run, no pose) on one without; UserError when the group does not fit the device."""
        if arm and g["poses"] is None:
            raise _campaign_error(self.source, f"{g['where']}.poses_deg",
                                  "missing (the Omni's arm set points [[gamma1, gamma2], ...] [deg]; "
                                  "only a single-joint device without the arm runs a group without them)")
        if not arm and g["poses"] is not None:
            raise _campaign_error(self.source, f"{g['where']}.poses_deg",
                                  "this device has no arm to pose (a single-joint device): remove "
                                  "poses_deg (each group then runs once; docs/usage/campaigns.md)")
        return g["poses"] if arm else ((None, None),)

    def experiments(self, sine_amplitude_rad: float | None = None, arm: bool = True) -> list["Experiment"]:
        """Every run: each sine group's poses x frequencies, then each step group's poses.

        ``sine_amplitude_rad`` overrides the sine groups' amplitude (the calibration's search).
        ``arm`` False: the device has no arm (:attr:`omni_sim.model.OmniIndex.has_arm`); its
        groups must have no ``poses_deg`` and give one run per frequency, without set points."""
        out: list[Experiment] = []
        for g in self.sine:
            amp = g["amplitude_rad"] if sine_amplitude_rad is None else sine_amplitude_rad
            out += [sine_experiment(g1, g2, f, amp, settle_s=g["settle_s"], record_s=g["record_s"])
                    for g1, g2 in self._poses(g, arm) for f in g["frequencies_hz"]]
        for g in self.step:
            out += [square_experiment(g1, g2, g["frequency_hz"], g["amplitude_rad"], g["duration_s"])
                    for g1, g2 in self._poses(g, arm)]
        names = [e.name for e in out]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise UserError(f"{self.source}: two runs would share the name {dup[0]!r} "
                            "(same pose, frequency and amplitude in two groups)")
        return out


def parse_campaign(text: bytes | str, source: str) -> Campaign:
    """Parse a campaign file's text (UserError naming the key on any problem)."""
    try:
        doc = tomllib.loads(text.decode() if isinstance(text, bytes) else text)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{source}: not a valid TOML file ({exc})") from None
    for k in doc:
        if k not in ("sine", "step", "description"):
            raise _campaign_error(source, k, "unknown key (known: sine, step, description)")
    sine = _groups(source, doc, "sine", _SINE_KEYS)
    step = _groups(source, doc, "step", _STEP_KEYS)
    if not sine and not step:
        raise UserError(f"{source}: a campaign needs a [sine] or a [step] table")
    return Campaign(source, tuple(sine), tuple(step))


def load_campaign(name_or_path: str | os.PathLike) -> Campaign:
    """``paper``, ``sine``, ``step`` (the built-in file or its halves) or a campaign file's path."""
    key = str(name_or_path)
    if key in CAMPAIGNS:
        c = parse_campaign(_paper_text(), "campaigns/paper.toml")
        return Campaign(c.source, c.sine if key != "step" else (), c.step if key != "sine" else ())
    path = Path(name_or_path)
    if path.suffix != ".toml" and not path.exists():
        raise UserError(f"unknown campaign {key!r} (choose from {', '.join(CAMPAIGNS)}, or give "
                        "a campaign file FILE.toml)")
    if not path.is_file():
        raise UserError(f"{path}: campaign file not found")
    return parse_campaign(path.read_bytes(), str(path))


# The paper campaign's numbers, read from campaigns/paper.toml (used as defaults elsewhere).
_PAPER = load_campaign("paper")
#: Table 1: set points (gamma1, gamma2) [deg] of the frequency-response experiments.
TABLE1_POSES = _PAPER.sine[0]["poses"]
#: Section 2.4.2: sine frequencies [Hz].
TABLE1_FREQUENCIES_HZ = _PAPER.sine[0]["frequencies_hz"]
#: Table 2: set points (gamma1, gamma2) [deg] of the step-response experiments.
TABLE2_POSES = _PAPER.step[0]["poses"]
#: Sine reference amplitude A_r [rad] (calibrated; campaigns/paper.toml says how).
SINE_AMPLITUDE_RAD = _PAPER.sine[0]["amplitude_rad"]
SINE_SETTLE_S = _PAPER.sine[0]["settle_s"]
SINE_RECORD_S = _PAPER.sine[0]["record_s"]
#: Section 2.4.3: square wave 0.25 Hz, 0.07 rad, from theta = -0.07 rad at rest; 8 s record.
STEP_FREQUENCY_HZ = _PAPER.step[0]["frequency_hz"]
STEP_AMPLITUDE_RAD = _PAPER.step[0]["amplitude_rad"]
STEP_DURATION_S = _PAPER.step[0]["duration_s"]
#: Yaw P gain [V/rad]: Table 9, beta_linear / beta_tilde_linear = 445.6 / 222.8.
KP_DEFAULT = paper.kp()


@dataclass(frozen=True)
class Experiment:
    """One run to perform: arm set points (none on a single-joint device) and a sampled
    reference of the controlled joint.

    ``Experiment(name, kind, gamma1_set_deg, gamma2_set_deg, r, frequency_hz, amplitude_rad)``
    for the Omni; ``Experiment(name, "other", r=r)`` for a device without the Omni's arm.

    Attributes
    ----------
    name : str
        Run name (file stem of the dataset).
    kind : str
        ``"sine"``, ``"step"`` or ``"other"``.
    gamma1_set_deg, gamma2_set_deg : float or None [deg]
        Arm servo set points; None (both) for a device without the Omni's arm.
    r : ndarray [rad]
        Reference of the controlled joint (the yaw), one value per control period (required).
    frequency_hz, amplitude_rad : float
        Metadata of the reference (0 if not periodic).
    theta0_rad : float [rad]
        Initial yaw angle (at rest).
    """

    name: str
    kind: str
    gamma1_set_deg: float | None = None
    gamma2_set_deg: float | None = None
    r: np.ndarray = field(default=None, repr=False)
    frequency_hz: float = 0.0
    amplitude_rad: float = 0.0
    theta0_rad: float = 0.0

    def __post_init__(self):
        if self.r is None:
            raise TypeError(f"Experiment {self.name!r}: the reference r is required")
        r = np.asarray(self.r, dtype=float)
        if r.ndim != 1 or len(r) < 2 or not np.all(np.isfinite(r)):
            raise UserError(f"run {self.name}: the reference r must be >= 2 finite samples in a row")
        object.__setattr__(self, "r", r)
        if self.kind not in ("sine", "step", "other"):
            raise UserError(f"run {self.name}: kind must be sine, step or other, got {self.kind!r}")
        if (self.gamma1_set_deg is None) != (self.gamma2_set_deg is None):
            raise UserError(f"run {self.name}: give both arm set points gamma1, gamma2 (the Omni) "
                            "or neither (a device without the arm)")

    @property
    def pose(self) -> tuple[float, float] | None:
        """The arm set points ``(gamma1, gamma2)`` [deg], or None without them."""
        return None if self.gamma1_set_deg is None else (self.gamma1_set_deg, self.gamma2_set_deg)


def _time(duration_s: float, dt: float) -> np.ndarray:
    return np.arange(int(round(duration_s / dt))) * dt


def sine_experiment(gamma1_set_deg: float | None, gamma2_set_deg: float | None, frequency_hz: float,
                    amplitude_rad: float = SINE_AMPLITUDE_RAD, dt: float = CONTROL_PERIOD_S,
                    settle_s: float = SINE_SETTLE_S, record_s: float = SINE_RECORD_S) -> Experiment:
    """A sine run ``r = A_r sin(2 pi f t)``: settle, then whole cycles (>= ``record_s``).

    Set points None: a device without the Omni's arm (run name ``sine_fF_aA``)."""
    if not (frequency_hz > 0 and math.isfinite(frequency_hz)):
        raise UserError(f"sine frequency must be positive, got {frequency_hz}")
    cycles = math.ceil(record_s * frequency_hz - 1e-9)
    duration = settle_s + cycles / frequency_hz
    t = _time(duration, dt)
    r = amplitude_rad * np.sin(2 * np.pi * frequency_hz * t)
    if gamma1_set_deg is None:  # a device without the arm: the amplitude tells groups apart
        name = f"sine_f{frequency_hz:04.2f}_a{amplitude_rad:.3f}".replace(".", "p")
    else:
        name = f"sine_g{gamma1_set_deg:02.0f}_{gamma2_set_deg:03.0f}_f{frequency_hz:04.2f}".replace(".", "p")
    return Experiment(name, "sine", gamma1_set_deg, gamma2_set_deg, r, frequency_hz, amplitude_rad)


def square_experiment(gamma1_set_deg: float | None, gamma2_set_deg: float | None,
                      frequency_hz: float = STEP_FREQUENCY_HZ,
                      amplitude_rad: float = STEP_AMPLITUDE_RAD,
                      duration_s: float = STEP_DURATION_S, dt: float = CONTROL_PERIOD_S) -> Experiment:
    """The paper's square wave (47): ``r = +A_r`` for the first half period, from ``theta=-A_r``.

    Set points None: a device without the Omni's arm (run name ``step_fF_aA``)."""
    t = _time(duration_s, dt)
    phase = (t * frequency_hz) % 1.0
    r = np.where(phase < 0.5 - 1e-12, amplitude_rad, -amplitude_rad)
    if gamma1_set_deg is None:  # a device without the arm
        name = f"step_f{frequency_hz:04.2f}_a{amplitude_rad:.3f}".replace(".", "p")
    else:
        name = f"step_g{gamma1_set_deg:02.0f}_{gamma2_set_deg:03.0f}"
    return Experiment(name, "step", gamma1_set_deg, gamma2_set_deg, r, frequency_hz,
                      amplitude_rad, theta0_rad=-amplitude_rad)


def reference_experiment(path: str | os.PathLike, gamma1_set_deg: float | None = None,
                         gamma2_set_deg: float | None = None, dt: float = CONTROL_PERIOD_S) -> Experiment:
    """A run driven by a user's reference: a CSV with columns ``t`` [s], ``r`` [rad] (arm set
    points None: a device without the Omni's arm).

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


def campaign(name: str | os.PathLike, sine_amplitude_rad: float | None = None,
             arm: bool = True) -> list[Experiment]:
    """The experiments of a campaign (:func:`load_campaign`): ``paper`` = ``sine`` (Table 1) +
    ``step`` (Table 2), or a campaign file; ``sine_amplitude_rad`` overrides the sine amplitude;
    ``arm`` False: a device without the Omni's arm (:meth:`Campaign.experiments`)."""
    return load_campaign(name).experiments(sine_amplitude_rad, arm)


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
    command_limit : float, optional
        The P law's saturation, in the actuator's control units ([V] on the Omni): the command
        is clipped to +-command_limit, and the drive still clips to its own ``ctrlrange``.
        Default None: the device's own limit (:attr:`Device.voltage_limit`).  Written to the
        runs' metadata when given.
    """

    kp: float = KP_DEFAULT
    control_period_s: float = CONTROL_PERIOD_S
    quantize: bool = False
    noise_rad: float = 0.0
    seed: int = 0
    command_limit: float | None = None

    @property
    def encoder(self) -> Encoder:
        """The device's encoder with these settings."""
        return Encoder(quantize=self.quantize, noise_rad=self.noise_rad, seed=self.seed)


#: Physics steps per control period (UserError unless it divides exactly): the device's rule.
substeps = substeps_of


def _plain_motor(model: mujoco.MjModel, act: int) -> bool:
    return (model.actuator_dyntype[act] == mujoco.mjtDyn.mjDYN_NONE
            and model.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_FIXED
            and model.actuator_gainprm[act, 0] == 1.0
            and model.actuator_biastype[act] == mujoco.mjtBias.mjBIAS_NONE
            and getattr(model, "actuator_delay", np.zeros(model.nu))[act] == 0)


def fast_path_ok(device: Device, settings: Settings) -> bool:
    """True when the rollout fast path gives the same trajectory as the device's engine."""
    return (device.substeps == 1 and settings.encoder.exact and device.drive_friction is None
            and _plain_motor(device.model, device.ix.yaw_act))


def _limit(device: Device, settings: Settings) -> float:
    """The P law's saturation: the device's limit, or the settings' ``command_limit`` if lower."""
    if settings.command_limit is None:
        return device.voltage_limit
    return min(device.voltage_limit, float(settings.command_limit))


def _servo_model(device: Device, kp: float, vmax: float | None = None) -> mujoco.MjModel:
    """A copy of the device's model whose ``yaw_motor`` is the P controller: ctrl = r, force = v
    (clipped to +-``vmax``, default the device's limit)."""
    model = device.model
    m = _copy_model(model)
    a = device.ix.yaw_act
    vmax = device.voltage_limit if vmax is None else vmax
    lo, hi = (-vmax, vmax)
    if model.actuator_forcelimited[a]:
        lo, hi = max(lo, model.actuator_forcerange[a, 0]), min(hi, model.actuator_forcerange[a, 1])
    m.actuator_gainprm[a, 0] = kp
    m.actuator_biastype[a] = mujoco.mjtBias.mjBIAS_AFFINE
    # the affine bias acts on the actuator length, which is gear * theta
    m.actuator_biasprm[a, :3] = (0.0, -kp / device.torque_constant, 0.0)
    m.actuator_ctrllimited[a] = 0
    m.actuator_forcelimited[a] = int(math.isfinite(lo) or math.isfinite(hi))
    m.actuator_forcerange[a] = (lo if math.isfinite(lo) else -1e10, hi if math.isfinite(hi) else 1e10)
    return m


def _copy_model(model: mujoco.MjModel) -> mujoco.MjModel:
    import copy
    return copy.deepcopy(model)


def run_reference(device: Device, exps: list[Experiment], settings: Settings,
                  nthread: int | None = None) -> list[dict]:
    """The reference path: the runs through the device's closed-loop engine, in one batch.

    Runs of different lengths share the batch: a shorter run's reference holds its last value
    after its end and the extra samples are dropped (rows do not interact)."""
    enc = settings.encoder
    n = max(len(e.r) for e in exps)
    r = np.empty((len(exps), n))
    noise = None if enc.noise_rad == 0 else np.zeros((len(exps), n))
    for b, e in enumerate(exps):
        r[b, : len(e.r)] = e.r
        r[b, len(e.r):] = e.r[-1]
        if noise is not None:
            noise[b, : len(e.r)] = enc.noise(e.name, len(e.r))
    eng = device.engine([e.theta0_rad for e in exps], [e.pose for e in exps], nthread=nthread)
    with eng:
        res = run_p_loop(eng, r, settings.kp, noise, enc.quantum_rad, record_arm=True,
                         command_limit=settings.command_limit)
    return [{k: res[k][b, : len(e.r)].copy() for k in ("theta", "v", "q1", "q2")}
            for b, e in enumerate(exps)]


def run_fast(device: Device, exps: list[Experiment], settings: Settings,
             nthread: int) -> list[dict]:
    """The fast path: all runs through ``mujoco.rollout`` with the P loop inside the model."""
    model, ix = device.model, device.ix
    vmax = _limit(device, settings)
    servo = _servo_model(device, settings.kp, vmax)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(servo, spec)
    nstep = max(len(e.r) for e in exps)
    x0 = np.empty((len(exps), nstate))
    ctrl = np.zeros((len(exps), nstep, servo.nu))
    for b, exp in enumerate(exps):
        x0[b], ctrl[b] = device.start_state(exp.theta0_rad, exp.pose)
        ctrl[b, : len(exp.r), ix.yaw_act] = exp.r
        ctrl[b, len(exp.r):, ix.yaw_act] = exp.r[-1]
    datas = [mujoco.MjData(servo) for _ in range(max(1, nthread))]
    state, _ = rollout.rollout(servo, datas, x0, ctrl, nstep=nstep)
    qoff = 1  # FULLPHYSICS state = [time, qpos, qvel, ...]
    out = []
    for b, exp in enumerate(exps):
        n = len(exp.r)
        qpos = np.vstack([x0[b, qoff:qoff + model.nq], state[b, : n - 1, qoff:qoff + model.nq]])
        theta = qpos[:, ix.yaw_qpos]
        if not np.all(np.isfinite(theta)):
            raise RuntimeError(f"{exp.name}: simulation diverged")
        v = p_law(settings.kp, exp.r, theta, vmax)
        if ix.has_arm:
            q1, q2 = qpos[:, ix.shoulder_qpos].copy(), qpos[:, ix.elbow_qpos].copy()
        else:  # no arm: as the engine records it
            q1, q2 = np.full(n, np.nan), np.full(n, np.nan)
        out.append({"theta": theta.copy(), "v": v, "q1": q1, "q2": q2})
    return out


def _to_run(exp: Experiment, res: dict, settings: Settings, device: Device, friction: str) -> Run:
    dt = settings.control_period_s
    t = np.arange(len(exp.r)) * dt
    meta = {"kind": exp.kind}
    if exp.pose is not None:  # the Omni's arm: its actual (mean) angles and set points
        meta.update({
            "gamma1_deg": round(float(np.degrees(np.mean(res["q1"]))), 6),
            "gamma2_deg": round(float(np.degrees(np.mean(res["q2"]))), 6),
            "gamma1_set_deg": exp.gamma1_set_deg,
            "gamma2_set_deg": exp.gamma2_set_deg,
        })
    meta.update({
        "kp": settings.kp,
        "frequency_hz": exp.frequency_hz,
        "amplitude_rad": exp.amplitude_rad,
        "theta0_rad": exp.theta0_rad,
        "source": ("virtual Omni (omni_sim)" if device.ix.has_arm
                   else "simulated single-joint device (omni_sim)"),
        "model": device.run_model_name,
        "model_sha256": "in-memory model" if device.in_memory else device.digest,
        "friction": friction,
        "control_period_s": dt,
        "encoder_quantized": settings.quantize,
        "noise_rad": settings.noise_rad,
        "seed": settings.seed,
    })
    if device.target is not None:  # a device named by its joint and actuator
        meta.update(joint=device.target.joint, actuator=device.target.actuator)
    if settings.command_limit is not None:
        meta["command_limit"] = settings.command_limit
    return Run(exp.name, t, exp.r.copy(), res["theta"], res["v"], meta)


def check_experiment(device: Device, exp: Experiment) -> None:
    """Refuse (UserError naming the run) an experiment the device cannot run: set points on a
    device without the Omni's arm, none on one with it, or a pose outside the arm's ranges."""
    if device.ix.has_arm and exp.pose is None:
        raise UserError(f"run {exp.name}: this model has the Omni's arm (shoulder, elbow): a run "
                        "needs its two set points gamma1, gamma2 [deg]")
    if not device.ix.has_arm and exp.pose is not None:
        raise UserError(f"run {exp.name}: this device has no arm (no shoulder/elbow): give no "
                        "set points gamma1, gamma2")
    if exp.pose is not None:
        try:
            device.check_pose(*exp.pose)
        except UserError as exc:
            raise UserError(f"run {exp.name}: {exc}") from None


def simulate(device: Device, exps: list[Experiment], settings: Settings = Settings(),
             jobs: int | None = None, progress: bool = False,
             force_reference: bool = False) -> list[Run]:
    """Run experiments on the virtual Omni (or a single-joint device) and return them as
    dataset runs.

    Parameters
    ----------
    device : Device
        The model to run (:meth:`Device.load` for a file, which the runs' metadata then name
        with its digest; ``Device(model)`` for a model compiled in memory; a ``target`` for a
        device of your own).  Run at the settings' control period (the same model; its
        equilibrium poses are reused when the period is the device's).
    exps : list of Experiment
        With arm set points on a device with the Omni's arm, without (None) on one without it;
        the runs' metadata have the arm's actual angles ``gamma1_deg``/``gamma2_deg`` only then,
        and name the device's joint and actuator when it has a ``target``.
    settings : Settings
    jobs : int, optional
        Threads of the rollouts; default: :func:`omni_sim.device.default_threads`.
    progress : bool
        Show a progress bar (tqdm) on stderr.
    force_reference : bool
        Use the device's closed-loop engine even where the fast path applies.
    """
    from tqdm import tqdm

    device = device.at_period(settings.control_period_s)
    jobs = max(1, jobs or default_threads())
    settings.encoder  # validates the noise level
    if not (settings.kp > 0 and math.isfinite(settings.kp)):
        raise UserError(f"kp must be positive, got {settings.kp}")
    limit = settings.command_limit
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, (int, float))
                              or not limit > 0):
        raise UserError(f"command_limit must be > 0 (the P law's saturation, in the actuator's "
                        f"control units), got {limit!r}")
    for e in exps:
        check_experiment(device, e)
    bar = tqdm(total=len(exps), desc="simulating", unit="run", disable=not progress, leave=False)
    results: list[dict] = []
    fast = fast_path_ok(device, settings) and not force_reference
    chunk = max(jobs * 4, 8)
    for i in range(0, len(exps), chunk):
        part = exps[i:i + chunk]
        results += (run_fast(device, part, settings, jobs) if fast
                    else run_reference(device, part, settings, jobs))
        bar.update(len(part))
    bar.close()
    friction = device.friction_family()
    return [_to_run(e, r, settings, device, friction) for e, r in zip(exps, results)]
