"""The wall task of ``omni_sim/OmniWall-v0``: a virtual wall rendered on the yaw, pushed by a hand.

The task owns the wall's settings, the hand model it puts into the physics (:func:`add_hand`),
the encoder reading, the optional loop delay, the passivity observer's energy, the observation,
the reward and the end of an episode; :class:`omni_sim.env.OmniEnv` steps the device's engine
and asks it.  The module doc of :mod:`omni_sim.wall_env` describes the hand models, the
observer and the spaces.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from gymnasium import spaces

from .device import ENCODER_STEP_RAD, Device, Engine, read_encoder
from .options import InvalidOptionError

__all__ = ["GRASPS", "TIP_RADIUS_M", "WallTask", "add_hand", "grasp_impedance", "wall_torque"]

#: Tip radius from the yaw axis [m]: ~0.2 m, the radius at which the drive's limit gives the
#: 3.3 N peak tip force (models/omni/omni.xml's ctrlrange comment).
TIP_RADIUS_M = 0.2
#: Grasp impedances at the tip: (mass [kg], damping [N s/m], stiffness [N/m]); see
#: :mod:`omni_sim.wall_env`.
GRASPS = {"loose": (0.05, 1.5, 50.0), "medium": (0.2, 3.0, 200.0), "firm": (0.55, 6.5, 400.0)}


def wall_torque(y, y_prev, wall_rad, K, B, T, torque_limit=math.inf):
    """The standard virtual wall's torque [N*m]: ``-(K pen + B (y - y_prev) / T)`` while the
    measured penetration ``pen = y - wall_rad`` is positive, 0 outside, clipped to
    ``+-torque_limit`` (elementwise)."""
    y = np.asarray(y, dtype=float)
    pen = y - wall_rad
    tau = np.where(pen > 0, -(K * pen + B * (y - y_prev) / T), 0.0)
    return np.clip(tau, -torque_limit, torque_limit)


def check_wall_settings(stiffness, damping, wall_rad, push_rad, duration_s, delay) -> None:
    """Raise :class:`InvalidOptionError` for a bad wall setting."""
    for name, val in (("stiffness", stiffness), ("damping", damping), ("wall_rad", wall_rad),
                      ("push_rad", push_rad), ("duration_s", duration_s)):
        if not math.isfinite(float(val)):
            raise InvalidOptionError(f"{name} must be finite, got {val!r}")
    if float(duration_s) <= 0 or float(stiffness) < 0:
        raise InvalidOptionError("duration_s must be > 0 and stiffness >= 0")
    if isinstance(delay, bool) or int(delay) != delay or delay < 0:
        raise InvalidOptionError(f"delay must be a whole number of periods >= 0, got {delay!r}")


def grasp_impedance(grasp) -> dict:
    """The hand's yaw ``inertia`` [kg*m^2], ``damping`` [N*m*s/rad] and ``stiffness``
    [N*m/rad] of a grasp (a name of :data:`GRASPS` or a (mass, damping, stiffness) tuple at the
    tip), converted with :data:`TIP_RADIUS_M`."""
    if isinstance(grasp, str):
        if grasp not in GRASPS:
            raise InvalidOptionError(f"grasp must be one of {sorted(GRASPS)} or (m, c, k), got {grasp!r}")
        m_h, c_h, k_h = GRASPS[grasp]
    else:
        m_h, c_h, k_h = (float(x) for x in grasp)
        if min(m_h, c_h, k_h) < 0:
            raise InvalidOptionError("grasp mass, damping and stiffness must be >= 0")
    r2 = TIP_RADIUS_M ** 2
    return {"inertia": m_h * r2, "damping": c_h * r2, "stiffness": k_h * r2}


def add_hand(model: mujoco.MjModel, device: Device, hand: dict, rest_rad: float) -> None:
    """Put the hand into the model: the yaw dof's ``armature`` += inertia, ``damping`` +=
    damping, a joint spring of the hand's stiffness at rest at ``rest_rad`` (a point behind the
    wall the hand pushes towards).  ``device`` is one of ``model`` (its addresses)."""
    ix = device.ix
    model.dof_armature[ix.yaw_dof] += hand["inertia"]
    model.dof_damping[ix.yaw_dof] += hand["damping"]
    model.jnt_stiffness[device.joint_id] = hand["stiffness"]
    model.qpos_spring[ix.yaw_qpos] = rest_rad


class WallTask:
    """A virtual wall at ``wall_rad`` on the yaw of ``device`` (whose model holds the hand).

    The settings and their defaults are those of :class:`omni_sim.wall_env.OmniWallEnv`
    (checked there: :func:`check_wall_settings`): the renderer's ``stiffness`` K [N*m/rad] and
    ``damping`` B [N*m*s/rad], the wall at ``wall_rad`` [rad], the hand's rest ``push_rad``
    [rad] behind it, the encoder's rounding (``quantize``), the loop's ``delay`` [periods], the
    episode's ``duration_s`` [s], the start angle ``start_rad`` (None: wall - 0.005) and the
    arm's set points ``gamma_set`` (γ1, γ2) [deg].  ``hand`` is the grasp put into the model
    (:func:`grasp_impedance`, :func:`add_hand`).  ``T`` is the servo period [s], ``kt`` the
    motor's torque constant [N*m/V], ``vlim`` the drive's limit [V] and ``n`` the episode's
    length in periods.
    """

    def __init__(self, device: Device, hand: dict, stiffness=5.0, damping=0.002, wall_rad=0.0,
                 push_rad=0.02, quantize=True, delay=0, duration_s=1.0, start_rad=None,
                 gamma_set=(65.0, 90.0)):
        self.device, self.hand = device, hand
        self.wall_rad, self.push_rad = float(wall_rad), float(push_rad)
        self.K, self.B = float(stiffness), float(damping)
        self.quantize, self.delay = bool(quantize), int(delay)
        self.T = device.control_period_s
        self.kt = device.torque_constant
        self.vlim = device.voltage_limit
        self.n = int(round(float(duration_s) / self.T))
        self.start_rad = self.wall_rad - 0.005 if start_rad is None else float(start_rad)
        self.gamma_set = gamma_set
        vb = 4 * math.pi / self.T
        self.observation_space = spaces.Box(np.array([-math.pi, -vb, -2 * math.pi]),
                                            np.array([math.pi, vb, 2 * math.pi]), dtype=np.float64)
        self._queue = [0.0] * self.delay  # the commands on their way to the drive [V]

    # --- episodes --------------------------------------------------------------------------
    def start_episode(self, options: dict | None, rng=None) -> tuple[float, tuple]:
        """Where the device starts: ``(start_rad, gamma_set)``; the wall has no per-episode
        options (nor random draws)."""
        if options:
            raise InvalidOptionError("OmniWall-v0 takes its options when made")
        return self.start_rad, self.gamma_set

    def first_observation(self, engine: Engine) -> tuple[np.ndarray, dict]:
        """The observation and info at the start: the reading held as the previous one, an
        empty delay line, the observer at zero energy."""
        self._y = self._y_prev = self._read(engine)
        self._queue = [0.0] * self.delay
        self._E = 0.0
        self._k = 0
        return self.observation(), self.info(engine, 0.0)

    # --- a step ----------------------------------------------------------------------------
    def before_step(self, action) -> float:
        """The command [V] that reaches the drive this period: the action clipped to the drive,
        through the delay line."""
        a = np.asarray(action, dtype=float)
        if a.shape != (1,) or not np.isfinite(a).all():
            raise InvalidOptionError(f"action must be one finite voltage [V], shape (1,), got {a!r}")
        v = min(max(float(a[0]), -self.vlim), self.vlim)
        if self.delay:
            self._queue.append(v)
            v = self._queue.pop(0)
        return v

    def after_step(self, engine: Engine, v: float):
        """``(obs, reward, terminated, truncated, info)`` after one period under command ``v``
        [V]: the observer adds the motor's work ``v kt (y_{k+1} - y_k)``; an observation out of
        its bounds terminates with reward 0."""
        y = self._read(engine)
        self._E += v * self.kt * (y - self._y)
        self._y_prev, self._y = self._y, y
        self._k += 1
        obs = self.observation()
        info = self.info(engine, v)
        box = self.observation_space
        if not (np.isfinite(obs).all() and (obs >= box.low).all() and (obs <= box.high).all()):
            info["diverged"] = True
            return np.clip(np.nan_to_num(obs), box.low, box.high), 0.0, True, False, info
        return obs, self.reward(info), False, self._k >= self.n, info

    def _read(self, engine: Engine) -> float:
        return float(read_encoder(engine.yaw()[0], 0.0, ENCODER_STEP_RAD if self.quantize else 0.0))

    def observation(self) -> np.ndarray:
        """Measured yaw [rad], its backward difference [rad/s], measured penetration [rad]."""
        return np.array([self._y, (self._y - self._y_prev) / self.T, self._y - self.wall_rad])

    def info(self, engine: Engine, v: float) -> dict:
        """The observer's ``energy`` and ``wall_energy`` [J], the true ``penetration`` [rad],
        the applied ``voltage`` [V], ``time`` [s] and ``theta_true`` [rad]."""
        th = float(engine.yaw()[0])
        return {"energy": self._E, "wall_energy": -self._E, "penetration": th - self.wall_rad,
                "voltage": v, "time": float(engine.time()[0]), "theta_true": th}

    @staticmethod
    def reward(info: dict) -> float:
        """``-penetration_true**2`` [rad^2]."""
        return -info["penetration"] ** 2

    def wall_command(self) -> np.ndarray:
        """The built-in renderer's command [V] for the current reading (shape (1,))."""
        tau = wall_torque(self._y, self._y_prev, self.wall_rad, self.K, self.B, self.T)
        return np.array([float(tau) / self.kt], dtype=np.float32)
