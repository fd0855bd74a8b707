"""``omni_sim/OmniWall-v0``: a virtual wall rendered on the virtual Omni's yaw, pushed by a hand.

The stylus's yaw is held by a hand model and pushed into a virtual wall at ``wall_rad``
(penetration ``theta - wall_rad > 0``).  Every servo period the agent outputs the motor command
[V]; :meth:`OmniWallEnv.wall_command` gives the standard renderer's command (a spring ``K`` and
a damper ``B`` on the backward-difference velocity of the encoder reading, through the motor's
torque constant, :func:`wall_torque`), so ``env.step(env.unwrapped.wall_command())`` renders it.
Same :class:`~omni_sim.device.Device` and :class:`~omni_sim.device.Engine` as ``OmniYaw-v0``,
the same friction families, encoder quantisation (15000 counts/rev) and an optional loop delay
(whole servo periods, between the command and the drive).

**Hand model** -- the grasp is a mass-spring-damper at the stylus tip, put into the physics
(the yaw dof's ``armature`` += I_h, ``damping`` += c_h, a joint spring k_h whose rest angle is
``wall_rad + push_rad``: the hand pushes towards a point ``push_rad`` behind the wall).
Translational values at the tip, converted with the tip radius ``TIP_RADIUS_M`` (I = m r^2,
c r^2, k r^2); all are ESTIMATES of the order the literature reports, not measurements:

* ``loose``: 0.05 kg, 1.5 N s/m, 50 N/m -- a light fingertip hold; the lower end of Hajian &
  Howe (1997, fingertip: a few grams, 1.5-3.5 N s/m, 50-400 N/m as grip force rises);
* ``medium``: 0.2 kg, 3 N s/m, 200 N/m -- a pen grasp of a stylus, of the order Fu & Cavusoglu
  (2012, stylus on a Phantom Premium, 1-3 N grip) identify;
* ``firm``: 0.55 kg, 6.5 N s/m, 400 N/m -- arm and hand: mass and damping of one identified
  trial on a HapticMaster (Nature Sci. Rep. 5:18004, 2015: 0.554 kg, 6.45 N s/m, 135 N/m), the
  stiffness raised to a firm grip's (our estimate).

**Passivity observer** (Hannaford & Ryu 2002) -- ``info["energy"]`` is
``E_k = sum_{j<k} tau_j (y_{j+1} - y_j)`` [J]: the energy the motor's torque ``tau_j`` (applied
command x torque constant) put into the device over each servo period, computed from the encoder
readings ``y`` as a real observer must.  Sign: positive = energy flowed into the device from the
rendering port (the wall gave energy: active); a passive wall keeps ``E_k <= 0`` up to the
energy its spring stores (``info["wall_energy"] = -E_k``, the energy the wall absorbed, is the
observer in Hannaford & Ryu's sign, negative when active).  ``info["penetration"]`` is the true
penetration [rad] (``theta - wall_rad``, negative outside).

**Observation** ``Box(float64, (3,))``: measured yaw [rad], its backward difference
``(y_k - y_{k-1}) / T`` [rad/s], measured penetration [rad].  **Action** ``Box(-V, V, (1,))``:
the motor command [V] (clipped by the drive).  **Reward**: ``-penetration_true**2`` [rad^2].
**Episode**: ``duration_s`` (truncated), terminated if the state leaves its bounds.

Vector environments: ``gym.make_vec("omni_sim/OmniWall-v0", num_envs=N,
vectorization_mode="sync")`` (gymnasium's ``SyncVectorEnv``: sub-environment i is this
environment seeded ``seed + i``); no native batch version.
"""

from __future__ import annotations

import copy
import math

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from identification.errors import UserError

from . import model as om
from .device import CONTROL_PERIOD_S, ENCODER_STEP_RAD, Device, Engine, read_encoder
from .env import RENDER_MODES, InvalidOptionError, _Viewport, available_render_modes

__all__ = ["OmniWallEnv", "wall_torque", "GRASPS", "TIP_RADIUS_M"]

#: Tip radius from the yaw axis [m]: ~0.2 m, the radius at which the drive's limit gives the
#: 3.3 N peak tip force (models/omni/omni.xml's ctrlrange comment).
TIP_RADIUS_M = 0.2
#: Grasp impedances at the tip: (mass [kg], damping [N s/m], stiffness [N/m]); see module doc.
GRASPS = {"loose": (0.05, 1.5, 50.0), "medium": (0.2, 3.0, 200.0), "firm": (0.55, 6.5, 400.0)}


def wall_torque(y, y_prev, wall_rad, K, B, T, torque_limit=math.inf):
    """The standard virtual wall's torque [N*m]: ``-(K pen + B (y - y_prev) / T)`` while the
    measured penetration ``pen = y - wall_rad`` is positive, 0 outside, clipped to
    ``+-torque_limit`` (elementwise)."""
    y = np.asarray(y, dtype=float)
    pen = y - wall_rad
    tau = np.where(pen > 0, -(K * pen + B * (y - y_prev) / T), 0.0)
    return np.clip(tau, -torque_limit, torque_limit)


class OmniWallEnv(gym.Env):
    """A virtual wall on the virtual Omni's yaw, pushed by a hand model (see the module doc).

    Parameters (all make-time): ``model_path``/``friction`` (as ``OmniYaw-v0``), ``stiffness``
    K [N*m/rad] (default 5) and ``damping`` B [N*m*s/rad] (default 0.002) of the built-in
    renderer, ``wall_rad`` (0), ``push_rad`` (0.02), ``grasp`` ("loose", "medium", "firm" or a
    (mass, damping, stiffness) tuple at the tip), ``quantize`` (True), ``delay`` (0 servo
    periods), ``duration_s`` (1.0), ``start_rad`` (start angle at rest, default wall - 0.005),
    ``gamma1_set_deg``/``gamma2_set_deg`` (65, 90), ``control_period_s`` (1 ms), and the
    rendering's ``render_mode`` (None, ``"rgb_array"`` or ``"human"``), ``render_width``,
    ``render_height`` (640 x 480) and ``camera`` (``"side"``) as ``OmniYaw-v0``'s: a mode that
    cannot work in this process raises :class:`InvalidOptionError` when made and is not in the
    instance's ``metadata["render_modes"]`` (:func:`omni_sim.env.render_mode_problem`).
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 1000}

    def __init__(self, model_path=None, friction=None, stiffness=5.0, damping=0.002,
                 wall_rad=0.0, push_rad=0.02, grasp="medium", quantize=True, delay=0,
                 duration_s=1.0, start_rad=None, gamma1_set_deg=65.0, gamma2_set_deg=90.0,
                 control_period_s=CONTROL_PERIOD_S, render_mode=None, render_width=640,
                 render_height=480, camera="side"):
        try:
            model = copy.deepcopy(om.load_model(model_path, friction))
            dev = Device(model, float(control_period_s))
            dev.check_pose(float(gamma1_set_deg), float(gamma2_set_deg))
        except UserError as exc:
            raise InvalidOptionError(str(exc)) from None
        for name, val in (("stiffness", stiffness), ("damping", damping), ("wall_rad", wall_rad),
                          ("push_rad", push_rad), ("duration_s", duration_s)):
            if not math.isfinite(float(val)):
                raise InvalidOptionError(f"{name} must be finite, got {val!r}")
        if float(duration_s) <= 0 or float(stiffness) < 0:
            raise InvalidOptionError("duration_s must be > 0 and stiffness >= 0")
        if isinstance(delay, bool) or int(delay) != delay or delay < 0:
            raise InvalidOptionError(f"delay must be a whole number of periods >= 0, got {delay!r}")
        if isinstance(grasp, str):
            if grasp not in GRASPS:
                raise InvalidOptionError(f"grasp must be one of {sorted(GRASPS)} or (m, c, k), got {grasp!r}")
            m_h, c_h, k_h = GRASPS[grasp]
        else:
            m_h, c_h, k_h = (float(x) for x in grasp)
            if min(m_h, c_h, k_h) < 0:
                raise InvalidOptionError("grasp mass, damping and stiffness must be >= 0")
        r2 = TIP_RADIUS_M ** 2
        self.hand = {"inertia": m_h * r2, "damping": c_h * r2, "stiffness": k_h * r2}
        ix = dev.ix
        self.wall_rad, self.push_rad = float(wall_rad), float(push_rad)
        model.dof_armature[ix.yaw_dof] += self.hand["inertia"]
        model.dof_damping[ix.yaw_dof] += self.hand["damping"]
        model.jnt_stiffness[dev.joint_id] = self.hand["stiffness"]
        model.qpos_spring[ix.yaw_qpos] = self.wall_rad + self.push_rad
        self.device = Device(model, float(control_period_s))
        self.model = model
        self.K, self.B = float(stiffness), float(damping)
        self.quantize, self.delay = bool(quantize), int(delay)
        self.T = self.device.control_period_s
        self.kt = self.device.torque_constant
        self.vlim = self.device.voltage_limit
        self.n = int(round(float(duration_s) / self.T))
        self.start_rad = self.wall_rad - 0.005 if start_rad is None else float(start_rad)
        self.gamma_set = (float(gamma1_set_deg), float(gamma2_set_deg))
        self.data = mujoco.MjData(model)  # the engine steps it; the rendering shows it
        self._viewport = _Viewport(model, render_mode, render_width, render_height, camera)
        self.render_mode = render_mode
        self.metadata = {**type(self).metadata, "render_modes": available_render_modes(),
                         "render_fps": int(round(1.0 / self.T))}
        self.action_space = spaces.Box(-np.float32(self.vlim), np.float32(self.vlim), (1,), np.float32)
        vb = 4 * math.pi / self.T
        self.observation_space = spaces.Box(np.array([-math.pi, -vb, -2 * math.pi]),
                                            np.array([math.pi, vb, 2 * math.pi]), dtype=np.float64)
        self._engine = None

    def _read(self) -> float:
        return float(read_encoder(self._engine.yaw()[0], 0.0,
                                  ENCODER_STEP_RAD if self.quantize else 0.0))

    def _obs(self) -> np.ndarray:
        return np.array([self._y, (self._y - self._y_prev) / self.T, self._y - self.wall_rad])

    def _info(self, v: float) -> dict:
        th = float(self._engine.yaw()[0])
        return {"energy": self._E, "wall_energy": -self._E, "penetration": th - self.wall_rad,
                "voltage": v, "time": float(self._engine.time()[0]), "theta_true": th}

    def wall_command(self) -> np.ndarray:
        """The built-in renderer's command [V] for the current reading (shape (1,))."""
        tau = wall_torque(self._y, self._y_prev, self.wall_rad, self.K, self.B, self.T)
        return np.array([float(tau) / self.kt], dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if options:
            raise InvalidOptionError("OmniWall-v0 takes its options when made")
        if self._engine is not None:
            self._engine.close()
        self._engine = Engine([self.device], [self.start_rad], [self.gamma_set], data=self.data)
        self._y = self._y_prev = self._read()
        self._queue = [0.0] * self.delay
        self._E = 0.0
        self._k = 0
        if self.render_mode == "human":
            self.render()
        return self._obs(), self._info(0.0)

    def step(self, action):
        a = np.asarray(action, dtype=float)
        if a.shape != (1,) or not np.isfinite(a).all():
            raise InvalidOptionError(f"action must be one finite voltage [V], shape (1,), got {a!r}")
        if self._engine is None:
            raise RuntimeError("step() before reset()")
        v = min(max(float(a[0]), -self.vlim), self.vlim)
        if self.delay:
            self._queue.append(v)
            v = self._queue.pop(0)
        self._engine.apply(v)
        y = self._read()
        self._E += v * self.kt * (y - self._y)
        self._y_prev, self._y = self._y, y
        self._k += 1
        obs = self._obs()
        info = self._info(v)
        box = self.observation_space
        if not (np.isfinite(obs).all() and (obs >= box.low).all() and (obs <= box.high).all()):
            info["diverged"] = True
            return np.clip(np.nan_to_num(obs), box.low, box.high), 0.0, True, False, info
        if self.render_mode == "human":
            self.render()
        return obs, -info["penetration"] ** 2, False, self._k >= self.n, info

    def render(self):
        """An RGB image ``(height, width, 3)`` uint8 (``"rgb_array"``), or update the viewer."""
        return self._viewport.render(self.data)

    def close(self):
        if self._engine is not None:
            self._engine.close()
            self._engine = None
        self._viewport.close()
