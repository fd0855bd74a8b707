"""The tracking task of ``omni_sim/OmniYaw-v0``: follow a reference with the virtual Omni's yaw.

A task owns what the environment asks of it, and no physics: the episode's options (checked
here, :class:`TrackingOptions`), the reference and the encoder noise it draws, the observation
(encoder reading, velocity, reference, arm angles), the reward and the end of an episode.  The
physics is the device's closed-loop :class:`~omni_sim.device.Engine`, stepped by the
environment: :class:`omni_sim.env.OmniYawEnv` (one row) and
:class:`omni_sim.vector_env.OmniYawVectorEnv` (N rows in one batch) ask the same task, whose
arrays hold one row per sub-environment and whose formulas are numpy over the rows.

The options and their units are documented in :class:`omni_sim.env.OmniYawEnv`.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
from gymnasium import spaces

from identification.errors import UserError

from . import experiments as ex
from .device import ENCODER_STEP_RAD, Device, Engine, encoder_reader
from .options import InvalidOptionError, finite

__all__ = ["OBSERVATION_NAMES", "VELOCITY_FILTER_HZ", "MAX_NOISE_RAD", "TrackingOptions",
           "TrackingTask", "tracking_reward"]

#: Names of the observation entries, in order.
OBSERVATION_NAMES = ("theta", "theta_dot", "r", "gamma1", "gamma2")
#: Cut-off [Hz] of the first-order low-pass after the 2nd-order backward difference in the
#: device-like velocity estimate (models/omni/README.md: the Omni's drivers use a ~20 Hz low-pass).
VELOCITY_FILTER_HZ = 20.0
#: Largest encoder-noise standard deviation accepted [rad]: 0.05 rad is 120 encoder counts, far
#: beyond any encoder, and keeps the measured angle inside its observation bound (+-pi) with
#: overwhelming probability (|theta| <= 0.98 rad + 40 sigma).
MAX_NOISE_RAD = 0.05
REFERENCE_KINDS = ("sine", "square", "steps")
VELOCITY_MODES = ("exact", "estimated")
#: Defaults of the reference shapes [Hz], [rad]: sine 2 Hz (inside the paper's sweep, Section
#: 2.4.2) at the paper campaign's calibrated A_r (``campaigns/paper.toml``, 0.0498 rad); square
#: 0.25 Hz / 0.07 rad (Section 2.4.3); random steps 0.1 rad (our choice: twice A_r, well inside
#: the yaw range).
_DEFAULT_FREQUENCY_HZ = {"sine": 2.0, "square": ex.STEP_FREQUENCY_HZ}
_DEFAULT_AMPLITUDE_RAD = {"sine": ex.SINE_AMPLITUDE_RAD, "square": ex.STEP_AMPLITUDE_RAD,
                          "steps": 0.1}
_DEFAULT_DURATION_S = 4.0


@dataclass(frozen=True)
class TrackingOptions:
    """The per-episode options (see :class:`omni_sim.env.OmniYawEnv` for their meaning and
    units)."""

    gamma1_set_deg: float = 65.0
    gamma2_set_deg: float = 90.0
    reference: Any = "sine"
    frequency_hz: float | None = None
    amplitude_rad: float | None = None
    step_period_s: float = 0.5
    duration_s: float | None = None
    theta0_rad: float | None = None
    friction_scale: float = 1.0
    quantize: bool = False
    noise_rad: float = 0.0
    velocity: str = "exact"
    effort_weight: float = 0.0


OPTION_NAMES = tuple(f.name for f in fields(TrackingOptions))
#: The environment's make-time arguments: refused as per-episode options.
MAKE_ONLY = ("model_path", "friction", "control_period_s", "render_mode", "render_width",
             "render_height", "camera")


def tracking_reward(error, v, effort_weight):
    """The reward ``-error**2 - effort_weight * v**2`` of a tracking error ``r - theta_true``
    [rad] under the applied voltage ``v`` [V] (``effort_weight`` [rad^2/V^2]): elementwise on
    arrays (the vector environment), on Python floats in the single environment, whose
    ``error**2`` is Python's power (it can differ from numpy's ``x * x`` in the last bit)."""
    return -error ** 2 - effort_weight * v * v


class TrackingTask:
    """Track a reference with the yaw, on ``rows`` runs of one device (see the module doc).

    Per row it keeps the episode's options, reference and noise, the control-period counter
    ``k`` (step ``k`` starts at ``t_k = k dt``) of an episode of ``n`` periods, and the velocity
    estimator's state.  Every method that takes or returns arrays works on all rows at once.

    Parameters
    ----------
    device : omni_sim.device.Device
        The device the environment steps (its yaw friction is scaled per episode).
    rows : int
        Number of runs (1 for the single environment).
    """

    def __init__(self, device: Device, rows: int = 1):
        self.device = device
        self.dt = device.dt
        model = device.model
        yaw_j = device.joint_id
        self.yaw_range = (tuple(float(x) for x in model.jnt_range[yaw_j])
                          if model.jnt_limited[yaw_j] else (-math.pi, math.pi))
        # the friction levels and viscous damping of the model file, which friction_scale scales
        self._device0 = Device(copy.deepcopy(model), device.control_period_s)
        self._yaw_damping0 = device.yaw_damping
        vel_bound = 4 * math.pi / self.dt
        self.observation_space = spaces.Box(
            low=np.array([-math.pi, -vel_bound, self.yaw_range[0], -math.pi, -math.pi]),
            high=np.array([math.pi, vel_bound, self.yaw_range[1], math.pi, math.pi]),
            dtype=np.float64)
        self.defaults = TrackingOptions()
        self.lp_gain = 1.0 - math.exp(-2 * math.pi * VELOCITY_FILTER_HZ * self.dt)
        self.rows = int(rows)
        self.options = [self.defaults] * self.rows
        # per-row episode data as padded matrices (row i: its reference, then its noise), and
        # per-row settings, so that a step gathers them without a Python loop over the rows
        self._R = np.zeros((self.rows, 1))
        self._NZ = np.zeros((self.rows, 2))
        self._quantum = np.zeros(self.rows)
        self._read = encoder_reader(self._quantum.copy())  # made again when a row's step changes
        self._exact = np.ones(self.rows, dtype=bool)
        self._weight = np.zeros(self.rows)
        self._all = np.arange(self.rows)
        self.k = np.zeros(self.rows, dtype=np.int64)
        self.n = np.ones(self.rows, dtype=np.int64)
        self.y_hist = np.zeros((self.rows, 2))
        self.w_est = np.zeros(self.rows)
        self.diverged = False  # the single environment's episode ended by divergence

    # --- options ---------------------------------------------------------------------------
    def merge(self, base: TrackingOptions, options: dict | None) -> TrackingOptions:
        """``base`` with ``options`` (a dict of per-episode options) applied, checked."""
        options = dict(options or {})
        for key in options:
            if key in MAKE_ONLY:
                raise InvalidOptionError(f"option {key!r} can only be given when the environment "
                                         "is made (the spaces derive from it)")
            if key not in OPTION_NAMES:
                raise InvalidOptionError(f"unknown option {key!r}; known options: "
                                         f"{', '.join(OPTION_NAMES)}")
        if "reference" in options and not isinstance(options["reference"], str):
            options["reference"] = np.array(options["reference"], dtype=float, copy=True)
        opt = replace(base, **options)
        self.validate(opt)
        return opt

    def validate(self, o: TrackingOptions) -> None:
        """Raise :class:`InvalidOptionError` for a bad option."""
        try:
            self.device.check_pose(finite("gamma1_set_deg", o.gamma1_set_deg),
                                   finite("gamma2_set_deg", o.gamma2_set_deg))
        except UserError as exc:
            if isinstance(exc, InvalidOptionError):
                raise
            raise InvalidOptionError(f"arm set point: {exc}") from None
        lo, hi = self.yaw_range
        half = min(-lo, hi)
        if isinstance(o.reference, str):
            if o.reference not in REFERENCE_KINDS:
                raise InvalidOptionError(f"reference must be one of {REFERENCE_KINDS} or an "
                                         f"array, got {o.reference!r}")
        else:
            r = o.reference
            if r.ndim != 1 or r.size < 1 or not np.all(np.isfinite(r)):
                raise InvalidOptionError("an array reference must be 1-D, non-empty and finite "
                                         f"[rad], got shape {r.shape}")
            if r.min() < lo or r.max() > hi:
                raise InvalidOptionError(f"the reference leaves the yaw joint range "
                                         f"[{lo:g}, {hi:g}] rad")
        if o.frequency_hz is not None:
            finite("frequency_hz", o.frequency_hz, 0.0, lo_open=True)
        if o.amplitude_rad is not None:
            finite("amplitude_rad [rad] (the yaw joint range bounds it)", o.amplitude_rad, 0.0, half)
        finite("step_period_s", o.step_period_s, 0.0, lo_open=True)
        if o.duration_s is not None:
            finite("duration_s", o.duration_s, self.dt)
            if not isinstance(o.reference, str) and round(o.duration_s / self.dt) > o.reference.size:
                raise InvalidOptionError(f"duration_s = {o.duration_s} s is longer than the array "
                                         f"reference ({o.reference.size} samples of {self.dt} s)")
        if o.theta0_rad is not None:
            finite("theta0_rad", o.theta0_rad, lo, hi)
        finite("friction_scale", o.friction_scale, 0.0)
        finite("noise_rad", o.noise_rad, 0.0, MAX_NOISE_RAD)
        if not isinstance(o.quantize, (bool, np.bool_)):
            raise InvalidOptionError(f"quantize must be a bool, got {o.quantize!r}")
        if o.velocity not in VELOCITY_MODES:
            raise InvalidOptionError(f"velocity must be one of {VELOCITY_MODES}, got {o.velocity!r}")
        finite("effort_weight", o.effort_weight, 0.0)

    # --- episodes --------------------------------------------------------------------------
    def build_reference(self, o: TrackingOptions, rng: np.random.Generator) -> tuple[np.ndarray, float]:
        """The episode's reference (one sample per control period) and initial yaw [rad]."""
        dt = self.dt
        if not isinstance(o.reference, str):
            n = o.reference.size if o.duration_s is None else int(round(o.duration_s / dt))
            r = o.reference[:n].copy()
            theta0 = float(r[0])
        else:
            duration = _DEFAULT_DURATION_S if o.duration_s is None else o.duration_s
            amp = _DEFAULT_AMPLITUDE_RAD[o.reference] if o.amplitude_rad is None else o.amplitude_rad
            t = np.arange(int(round(duration / dt))) * dt  # as experiments._time
            if o.reference == "sine":
                f = _DEFAULT_FREQUENCY_HZ["sine"] if o.frequency_hz is None else o.frequency_hz
                r = amp * np.sin(2 * np.pi * f * t)
                theta0 = 0.0
            elif o.reference == "square":
                f = _DEFAULT_FREQUENCY_HZ["square"] if o.frequency_hz is None else o.frequency_hz
                exp = ex.square_experiment(o.gamma1_set_deg, o.gamma2_set_deg, f, amp, duration, dt)
                r, theta0 = exp.r, exp.theta0_rad
            else:  # random steps from the seeded RNG
                hold = max(1, int(round(o.step_period_s / dt)))
                levels = rng.uniform(-amp, amp, size=-(-t.size // hold))
                r = np.repeat(levels, hold)[: t.size]
                theta0 = 0.0
        if o.theta0_rad is not None:
            theta0 = float(o.theta0_rad)
        return np.asarray(r, dtype=float), theta0

    def draw_episode(self, o: TrackingOptions, rng: np.random.Generator) -> tuple[np.ndarray, float, np.ndarray]:
        """An episode's random draws from ``rng``, in this order: the reference and initial yaw
        [rad], then the encoder noise [rad] (one sample per control period + 1)."""
        r, theta0 = self.build_reference(o, rng)
        noise = rng.normal(0.0, o.noise_rad, r.size + 1) if o.noise_rad > 0 else np.zeros(r.size + 1)
        return r, theta0, noise

    def start_row(self, i: int, options: dict | None, rng: np.random.Generator) -> tuple[float, tuple]:
        """Start row ``i``'s episode: the make-time options with ``options`` applied, its draws
        from ``rng``.  Returns where the device starts: ``(theta0 [rad], (gamma1, gamma2) set
        points [deg])``."""
        o = self.merge(self.defaults, options) if options else self.defaults
        self.options[i] = o
        r, theta0, noise = self.draw_episode(o, rng)
        if r.size > self._R.shape[1]:  # grow the padded matrices to the longest episode
            grow = r.size - self._R.shape[1]
            self._R = np.pad(self._R, ((0, 0), (0, grow)))
            self._NZ = np.pad(self._NZ, ((0, 0), (0, grow)))
        self._R[i, : r.size] = r
        self._NZ[i, : noise.size] = noise
        quantum = ENCODER_STEP_RAD if o.quantize else 0.0
        if self._quantum[i] != quantum:
            self._quantum[i] = quantum
            self._read = encoder_reader(self._quantum.copy())
        self._exact[i] = o.velocity == "exact"
        self._weight[i] = o.effort_weight
        self.k[i] = 0
        self.n[i] = r.size
        self.w_est[i] = 0.0
        return theta0, (float(o.gamma1_set_deg), float(o.gamma2_set_deg))

    def apply_friction_scale(self, o: TrackingOptions) -> None:
        """Scale the model's yaw dry friction and viscous damping to the episode's option
        (one model for all rows)."""
        self.device.scale_friction(o.friction_scale, base=self._device0)
        self.device.yaw_damping = self._yaw_damping0 * o.friction_scale

    # --- observation, reward, termination (numpy over the rows) ----------------------------
    def measure(self, engine: Engine) -> np.ndarray:
        """Every row's encoder reading at its current time [rad]
        (:func:`omni_sim.device.read_encoder`)."""
        noise = self._NZ[self._all, np.minimum(self.k, self.n)]
        return self._read(engine.yaw(), noise)

    def reference(self) -> np.ndarray:
        """Every row's current reference sample [rad] (held at its last after the end)."""
        return self._R[self._all, np.minimum(self.k, self.n - 1)]

    def observe(self, engine: Engine, y: np.ndarray) -> np.ndarray:
        """The rows' observations ``(rows, 5)`` for the readings ``y`` (advances the velocity
        estimate: 2nd-order backward difference, then the first-order low-pass); not yet
        checked against the bounds (:meth:`out_of_bounds`)."""
        exact = self._exact
        d = (3.0 * y - 4.0 * self.y_hist[:, 0] + self.y_hist[:, 1]) / (2.0 * self.dt)
        self.w_est = np.where(exact, self.w_est, self.w_est + self.lp_gain * (d - self.w_est))
        self.y_hist[:, 1] = self.y_hist[:, 0]
        self.y_hist[:, 0] = y
        q = engine.qpos()
        obs = np.empty((self.rows, 5))  # filled column by column: one allocation a step
        obs[:, 0] = y
        obs[:, 1] = np.where(exact, engine.yaw_velocity(), self.w_est)
        obs[:, 2] = self.reference()
        obs[:, 3:5] = q[:, 1:3]
        return obs

    def out_of_bounds(self, obs: np.ndarray) -> np.ndarray:
        """Which entries of ``obs`` are non-finite or outside the observation box."""
        box = self.observation_space
        return ~(np.isfinite(obs) & (obs >= box.low) & (obs <= box.high))

    def clip(self, obs: np.ndarray) -> np.ndarray:
        """``obs`` with non-finite entries set to 0 and clipped into the box."""
        box = self.observation_space
        return np.clip(np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0), box.low, box.high)

    def info(self, engine: Engine, v: np.ndarray) -> dict:
        """Per row: ``time`` [s], ``theta_true`` [rad], ``tracking_error`` ``r - theta_true``
        [rad] and the applied ``voltage`` ``v`` [V]."""
        theta = engine.yaw()
        return {"time": engine.time(), "theta_true": theta,
                "tracking_error": self.reference() - theta, "voltage": v}

    def reward(self, info: dict) -> np.ndarray:
        """Every row's :func:`tracking_reward`."""
        return tracking_reward(info["tracking_error"], info["voltage"], self._weight)

    # --- the single environment's episode (row 0) ------------------------------------------
    def start_episode(self, options: dict | None, rng: np.random.Generator) -> tuple[float, tuple]:
        """:meth:`start_row` for the one row, with the episode's friction scale applied."""
        self.diverged = False
        start = self.start_row(0, options, rng)
        self.apply_friction_scale(self.options[0])
        return start

    def first_observation(self, engine: Engine) -> tuple[np.ndarray, dict]:
        """The observation and info at ``t_0`` (the device at rest before the episode)."""
        y = self.measure(engine)
        self.y_hist[:] = y[:, None]
        obs = self.observe(engine, y)
        if self.out_of_bounds(obs).any():  # the options are validated, so the start is in bounds
            raise RuntimeError(self.divergence(obs[0], engine))
        return obs[0], self._floats(self.info(engine, np.zeros(1)))

    def before_step(self, action) -> float:
        """The voltage [V] the action commands; refuses a bad action or a finished episode."""
        a = np.asarray(action, dtype=float)
        if a.shape != (1,):
            raise InvalidOptionError(f"action must have shape (1,) (yaw voltage [V]), got shape "
                                     f"{a.shape}")
        v = float(a[0])
        if not math.isfinite(v):
            raise InvalidOptionError(f"action must be finite, got {v}")
        if self.diverged:
            raise RuntimeError("step() after the episode terminated (diverged); call reset()")
        if self.k[0] >= self.n[0]:
            raise RuntimeError("step() after the episode was truncated; call reset()")
        return v

    def after_step(self, engine: Engine, v: float):
        """``(obs, reward, terminated, truncated, info)`` after one control period under the
        applied voltage ``v`` [V].  A divergence (an entry out of its bounds, or MuJoCo's reset
        of an unstable state, ``engine.unstable``) terminates with reward 0."""
        self.k += 1
        obs = self.observe(engine, self.measure(engine))[0]
        info = self._floats(self.info(engine, np.array([v])))
        reason = None
        if self.out_of_bounds(obs).any():
            reason = self.divergence(obs, engine)
            obs = self.clip(obs)
        elif engine.unstable[0]:
            reason = (f"simulation diverged at t = {engine.time()[0]:.6f} s: MuJoCo found a "
                      "non-finite or huge state and reset it (mjWARN_BADQPOS/QVEL/QACC)")
        if reason is not None:
            self.diverged = True
            info.update(diverged=True, reason=reason)
            return obs, 0.0, True, False, info
        reward = float(tracking_reward(info["tracking_error"], v, self.options[0].effort_weight))
        return obs, reward, False, bool(self.k[0] >= self.n[0]), info

    def divergence(self, obs: np.ndarray, engine: Engine) -> str:
        """Why one row's observation ``obs`` is invalid: the entries outside their bounds."""
        box = self.observation_space
        bad = self.out_of_bounds(obs)
        return (f"simulation diverged at t = {engine.time()[0]:.6f} s: "
                + ", ".join(f"{OBSERVATION_NAMES[i]} = {obs[i]:g} outside "
                            f"[{box.low[i]:g}, {box.high[i]:g}]" for i in np.flatnonzero(bad)))

    @staticmethod
    def _floats(info: dict) -> dict:
        return {key: float(x[0]) for key, x in info.items()}
