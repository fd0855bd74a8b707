"""A gymnasium environment of the virtual Omni's yaw axis, for controller tests.

The agent is the yaw controller: every control period it reads the (optionally quantised,
noisy) encoder and commands the yaw motor's voltage.  The arm (shoulder gamma1, elbow gamma2)
is held by the model's own P servos.  The environment is a :class:`omni_sim.device.Device`
stepped through its closed-loop engine, the same start state, encoder and engine as the dataset
generator (:mod:`omni_sim.experiments`) and the discrepancy replay, so a P controller acting
through this environment reproduces the generator's runs (``tests/test_device.py``).

Time convention (the project's, :mod:`omni_sim.device`): step ``k`` starts at
``t_k = k * dt``.  The observation returned by :meth:`OmniYawEnv.reset` (``k = 0``) or by the
previous step holds ``theta_k`` measured at ``t_k`` and the reference ``r_k``; the action ``v_k``
is clipped to the drive's range and held (zero-order hold) over ``[t_k, t_k + dt)``, i.e. for
``substeps`` physics steps; :meth:`OmniYawEnv.step` then returns the observation at ``t_{k+1}``.

Registered on ``import omni_sim`` as ``"omni_sim/OmniYaw-v0"``::

    import gymnasium as gym
    import omni_sim  # noqa: F401  (registers the environment)

    env = gym.make("omni_sim/OmniYaw-v0", reference="sine", frequency_hz=2.0)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(np.array([0.1]))

:class:`AlphaInvariantObservation` appends the running alpha-invariant (33) of the applied
voltage to the observation.

The code is laid out as dm_control's suite: the physics is the device and its engine
(:mod:`omni_sim.device`), a task owns the options, reference, observation, reward and
termination (:mod:`omni_sim.tracking_task`; the wall's: :mod:`omni_sim.wall_task`), and one
environment class, :class:`OmniEnv`, steps the physics and asks the task.  :class:`OmniYawEnv`
is :class:`OmniEnv` with the tracking task; rendering is :mod:`omni_sim.rendering`.
"""

from __future__ import annotations

import math
import os

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from identification.errors import UserError

from . import experiments as ex
from . import model as om
from .device import Device, Engine
from .options import InvalidOptionError, finite
from .rendering import RENDER_MODES, Viewport, available_render_modes, render_mode_problem
from .tracking_task import OBSERVATION_NAMES, VELOCITY_FILTER_HZ, TrackingTask

__all__ = ["OmniEnv", "OmniYawEnv", "AlphaInvariantObservation", "InvalidOptionError",
           "OBSERVATION_NAMES", "RENDER_MODES", "VELOCITY_FILTER_HZ", "available_render_modes",
           "render_mode_problem"]


class OmniEnv(gym.Env):
    """A task on the virtual Omni's yaw: the one environment class of ``OmniYaw-v0`` and
    ``OmniWall-v0``.

    The physics is the device's closed-loop :class:`~omni_sim.device.Engine` on this
    environment's ``MjData``; the task (:class:`omni_sim.tracking_task.TrackingTask`,
    :class:`omni_sim.wall_task.WallTask`) owns the options, the observation, the reward and the
    end of an episode.  Every step the task turns the action into a voltage
    (``task.before_step``), the engine holds it for one control period, and the task reports
    what happened (``task.after_step``).  A reset asks the task where the device starts
    (``task.start_episode``) and what it sees there (``task.first_observation``).
    :class:`OmniYawEnv` and :class:`omni_sim.wall_env.OmniWallEnv` only build the device and the
    task from their make-time arguments.

    Parameters
    ----------
    device : omni_sim.device.Device
    task : TrackingTask or WallTask
    render_mode, render_width, render_height, camera
        As :class:`OmniYawEnv`'s (:class:`omni_sim.rendering.Viewport`).
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 1000}

    def __init__(self, device: Device, task, render_mode: str | None = None,
                 render_width: int = 640, render_height: int = 480, camera: str | None = "side"):
        self.device = device
        self.model = device.model
        self.data = mujoco.MjData(self.model)  # the engine steps it; the rendering shows it
        self.task = task
        self.metadata = {**type(self).metadata, "render_modes": available_render_modes(),
                         "render_fps": int(round(1.0 / self.dt))}
        vlim = np.float32(device.voltage_limit)
        self.action_space = spaces.Box(-vlim, vlim, shape=(1,), dtype=np.float32)
        self.observation_space = task.observation_space
        self._viewport = Viewport(self.model, render_mode, render_width, render_height, camera)
        self.render_mode = render_mode
        self._engine: Engine | None = None

    @property
    def dt(self) -> float:
        """Control period [s]: ``model.opt.timestep * substeps``."""
        return self.device.dt

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode where the task says (the arm at the equilibrium of its set points,
        the yaw at rest); ``seed`` seeds the task's draws, ``options`` are the task's
        per-episode options."""
        super().reset(seed=seed)
        theta0, gamma_set = self.task.start_episode(options, self.np_random)
        if self._engine is not None:
            self._engine.close()
        self._engine = Engine([self.device], [theta0], [gamma_set], data=self.data)
        obs, info = self.task.first_observation(self._engine)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action):
        """Apply the task's voltage for the action over one control period; see the task."""
        v = self.task.before_step(action)
        if self._engine is None:
            raise RuntimeError("step() before reset()")
        v = float(self._engine.apply(v)[0])
        obs, reward, terminated, truncated, info = self.task.after_step(self._engine, v)
        if self.render_mode == "human" and not terminated:
            self.render()
        return obs, reward, terminated, truncated, info

    def render(self):
        """An RGB image ``(height, width, 3)`` uint8 (``"rgb_array"``), or update the viewer."""
        return self._viewport.render(self.data)

    def close(self):
        """Release the engine, the renderer and the viewer (safe to call twice)."""
        if self._engine is not None:
            self._engine.close()
            self._engine = None
        self._viewport.close()


class OmniYawEnv(OmniEnv):
    """The virtual Phantom Omni's yaw axis as a gymnasium environment.

    Plain :class:`gymnasium.Env` over :mod:`mujoco` (not ``MujocoEnv``).  The arm is placed at
    the static equilibrium (sagged) pose of its servo set points, yaw at ``theta0_rad`` at rest,
    exactly as the dataset generator starts its runs.

    **Action** -- ``Box(-V, V, shape=(1,), float32)``:

    ====  =========================  =======  ==========================================
    idx   quantity                   unit     bounds
    ====  =========================  =======  ==========================================
    0     yaw command voltage ``v``  V        ``+-V``, ``V = omni_sim.model.voltage_limit``
                                              (1.3 V for the built-in model)
    ====  =========================  =======  ==========================================

    An action outside the bounds is clipped (the drive saturates); an action of the wrong shape
    or with a NaN/inf raises :class:`InvalidOptionError` (a ``ValueError``).

    **Observation** -- ``Box(float64, shape=(5,))``:

    ====  ===============  =====  ===============  ==============================================
    idx   name             unit   bounds           meaning
    ====  ===============  =====  ===============  ==============================================
    0     ``theta``        rad    ``[-pi, pi]``    yaw angle as the encoder reads it (exact
                                                   unless ``quantize``/``noise_rad``); the
                                                   joint's stop is +-0.98 rad
    1     ``theta_dot``    rad/s  ``+-4 pi / dt``  yaw velocity: MuJoCo's ``qvel``
                                                   (``velocity="exact"``) or the device's
                                                   estimate (``"estimated"``): 2nd-order
                                                   backward difference of ``theta`` then a
                                                   first-order low-pass at
                                                   :data:`VELOCITY_FILTER_HZ` (20 Hz).  The bound
                                                   is the largest value that estimate can take
                                                   (12566 rad/s at dt = 1 ms); beyond it the
                                                   simulation has diverged
    2     ``r``            rad    yaw joint range  current reference ``r_k`` (+-0.98 rad)
    3     ``gamma1``       rad    ``[-pi, pi]``    actual upper-arm elevation (``shoulder`` qpos)
    4     ``gamma2``       rad    ``[-pi, pi]``    actual elbow interior angle (``elbow`` qpos)
    ====  ===============  =====  ===============  ==============================================

    ``gamma1``/``gamma2`` follow the paper's convention (:mod:`omni_sim.model`); they sag below
    the set points under gravity.

    **Divergence** -- as gymnasium's MuJoCo environments do, a step whose observation is
    non-finite or outside its bounds, or in which MuJoCo reset an unstable state (its
    ``mjWARN_BADQPOS``/``QVEL``/``QACC`` warnings), ends the episode: ``terminated=True``, reward 0,
    ``info["diverged"] = True`` and ``info["reason"]`` saying which entry left its bound; the
    returned observation is that one with non-finite entries set to 0 and clipped into the box.

    **Reward** -- squared, so that it is smooth for gradient-based and RL controllers::

        reward_k = -(r_{k+1} - theta_true(t_{k+1}))**2 - effort_weight * v_k**2

    with the *true* yaw angle (not the measured one) [rad^2], and the applied (clipped) voltage
    ``v_k`` [V]; ``effort_weight`` is in [rad^2/V^2].  ``info`` carries ``"tracking_error"``
    ``r - theta_true`` [rad], ``"voltage"`` (applied ``v_k``) [V], ``"theta_true"`` [rad] and
    ``"time"`` [s].

    **Episode** -- terminates only on divergence (above); truncated internally (``truncated=True``) after
    ``round(duration_s / dt)`` steps.  The environment is registered without gymnasium's
    ``max_episode_steps`` because the length is a per-episode option.  After the last reference
    sample the reference holds its final value (only visible in the final observation).

    **Time** -- ``control_period_s`` (default 1 ms, the Omni's servo rate) must be a whole
    multiple ``substeps`` of the model's timestep (``ValueError`` otherwise);
    ``dt == model.opt.timestep * substeps`` and ``metadata["render_fps"] == round(1 / dt)``.
    It is the action repeat (gymnasium's MuJoCo environments call it ``frame_skip``): the
    voltage is held for ``substeps`` physics steps.  It changes ``dt``, the episode length in
    steps (``round(duration_s / dt)``: 4000 at 1 ms, 400 at 10 ms for the default 4 s) and the
    reward's scale: one reward per control period, so an episode's return is about
    ``-(1/dt) * integral(e**2 dt)`` -- the same tracking gives a 10x smaller return at 10 ms.

    **With RL libraries** -- the action stays in volts (physical units, as gymnasium's MuJoCo
    environments keep their actuators' control ranges).  Normalise it the standard way, with
    float32 bounds so that the wrapper's box keeps the action's dtype::

        env = gymnasium.wrappers.RescaleAction(gym.make("omni_sim/OmniYaw-v0"),
                                               np.float32(-1), np.float32(1))

    stable-baselines3's ``check_env`` passes that wrapped environment with no warning (and warns
    about the raw ±1.3 V box); gymnasium's ``check_env`` is meant for the raw environment
    (``env.unwrapped``), where it passes with one warning, the same recommendation of a ±1 box
    (tests/test_env.py).

    Parameters
    ----------
    model_path : path, optional
        MJCF file keeping the contract's names (default: the built-in scene).  Make-time only:
        the spaces derive from it.
    friction : {"coulomb", "lugre", "matched"}, optional
        The built-in scene of this friction family (``models/omni/scene_<friction>.xml``; default
        ``scene.xml``, the ``lugre`` family).  Make-time only; not together with
        ``model_path``.  The attribute ``friction`` names the family in use (for a user's
        file: what its yaw carries, :meth:`omni_sim.device.Device.friction_family`).
    control_period_s : float [s]
        Control period (make-time only).
    render_mode : {None, "rgb_array", "human"}
        ``"rgb_array"`` renders offscreen with :class:`mujoco.Renderer` (headless: set
        ``MUJOCO_GL=egl`` or ``osmesa`` before importing mujoco); ``"human"`` opens the passive
        :mod:`mujoco.viewer` (needs a display).  A mode that cannot work in this process (no
        display for ``"human"``; for ``"rgb_array"`` MuJoCo's default GLFW backend and no
        display) raises :class:`InvalidOptionError` here, saying why, and is left out of the
        instance's ``metadata["render_modes"]`` (the class's lists both):
        :func:`render_mode_problem`.
    render_width, render_height : int [px]
        Image size (default 640 x 480).
    camera : str or None
        Named camera (default ``"side"`` when the model has it, else the free camera).
    gamma1_set_deg, gamma2_set_deg : float [deg]
        Arm servo set points (default 65, 90: the paper's Table 9 pose); must lie in the
        shoulder/elbow joint ranges.
    reference : {"sine", "square", "steps"} or array_like [rad]
        ``"sine"``: ``A sin(2 pi f t)``; ``"square"``: the paper's square wave (47), ``+A`` for
        the first half period (:func:`omni_sim.experiments.square_experiment`); ``"steps"``:
        piecewise-constant levels drawn uniformly in ``[-A, A]`` from the environment's seeded
        RNG, one every ``step_period_s``; an array: the user's reference, one sample per control
        period.  Every reference must stay inside the yaw joint range.
    frequency_hz : float [Hz], optional
        Sine / square frequency (> 0; default 2 Hz for the sine, 0.25 Hz for the square).
    amplitude_rad : float [rad], optional
        Amplitude ``A`` (>= 0; default: the paper campaign's A_r = 0.0498 rad for the sine,
        0.07 square, 0.1 steps).
    step_period_s : float [s]
        Hold time of each random step (> 0; default 0.5 s).
    duration_s : float [s], optional
        Episode length (default 4 s; for an array reference its length, and a given
        ``duration_s`` may only shorten it).
    theta0_rad : float [rad], optional
        Initial yaw angle, at rest (default as the generator: ``-A`` for the square wave, ``r[0]``
        for an array, else 0).
    friction_scale : float
        Factor (>= 0) on the yaw drive's dry friction (``frictionloss`` and the LuGre levels,
        :func:`omni_sim.model.scale_yaw_friction`) and viscous ``damping`` of the model file.
    quantize : bool
        Quantise the measured yaw to the encoder's 15000 counts/rev
        (:data:`omni_sim.device.ENCODER_STEP_RAD`) as the generator does.
    noise_rad : float [rad]
        Standard deviation of white measurement noise added before quantisation, drawn from the
        environment's RNG (seeded by ``reset(seed=...)``); ``0 <= noise_rad <= 0.05``.
    velocity : {"exact", "estimated"}
        Source of ``theta_dot`` (see the observation table).
    effort_weight : float [rad^2/V^2]
        Weight (>= 0) of the ``v**2`` penalty in the reward.

    Every option from ``gamma1_set_deg`` on may also be passed to ``reset(options={...})``;
    it then applies to that episode only (a reset without options returns to the make-time
    values).  Bad values raise :class:`InvalidOptionError` (a ``ValueError``).

    Attributes
    ----------
    device : omni_sim.device.Device
    task : omni_sim.tracking_task.TrackingTask
        The options, reference, observation, reward and termination of the episodes.
    model, data : mujoco.MjModel, mujoco.MjData
    control_period_s : float [s]
    substeps : int
        Physics steps per control period.
    voltage_limit : float [V]
    """

    def __init__(self, model_path: str | os.PathLike | None = None,
                 control_period_s: float = ex.CONTROL_PERIOD_S, render_mode: str | None = None,
                 render_width: int = 640, render_height: int = 480,
                 camera: str | None = "side", friction: str | None = None, **options):
        try:
            model = om.load_model(model_path, friction)
            device = Device(model, finite("control_period_s", control_period_s, 0.0, lo_open=True))
        except UserError as exc:
            if isinstance(exc, InvalidOptionError):
                raise
            raise InvalidOptionError(str(exc)) from None
        self.model_path = model_path
        self.friction = device.friction_family(om.model_path(model_path, friction))
        self.substeps = device.substeps
        self.control_period_s = float(control_period_s)
        self.voltage_limit = device.voltage_limit
        if not math.isfinite(self.voltage_limit):
            raise InvalidOptionError("the model's yaw_motor needs a ctrlrange (the drive's "
                                     "voltage limit) to bound the action space")
        super().__init__(device, TrackingTask(device), render_mode, render_width, render_height,
                         camera)
        self.task.defaults = self.task.merge(self.task.defaults, options)


class AlphaInvariantObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Append the running alpha-invariant (33) of the applied voltage to the observation.

    After step ``k`` (voltage ``v_k`` applied) the appended entry is the low-passed

        alpha_k = vdot_k**2 - v_k * vddot_k                         [V^2/s^2]   (33)

    with backward differences over the control period ``dt``:
    ``vdot_k = (v_k - v_{k-1}) / dt`` and ``vddot_k = (v_k - 2 v_{k-1} + v_{k-2}) / dt**2``,
    smoothed by a first-order low-pass ``a_k = a_{k-1} + (1 - exp(-dt/tau)) (alpha_k - a_{k-1})``.
    Before the first step the drive is taken to hold the first applied voltage (so the first
    raw value is 0), and the entry is 0 after reset.  For a pure sine ``v = A sin(w t)`` the
    invariant is the constant ``A**2 w**2``.

    ====  =========  =======  ======================================================
    idx   name       unit     bounds
    ====  =========  =======  ======================================================
    0-4   as :class:`OmniYawEnv`
    5     ``alpha``  V^2/s^2  ``+-8 V**2 / dt**2`` (the largest value the backward
                              differences can give for ``|v| <= V``)
    ====  =========  =======  ======================================================

    ``info["alpha_raw"]`` holds the unfiltered value; :attr:`alpha` the current filtered one.

    Parameters
    ----------
    env : gymnasium.Env
        An :class:`OmniYawEnv` (possibly wrapped); its ``info["voltage"]`` is used.
    time_constant_s : float [s]
        Low-pass time constant ``tau`` (default 0.1 s).  ``vddot`` over 1 ms amplifies encoder
        quantisation seen through the controller (8.4e-4 V steps at kp = 2 V/rad give
        ~840 V/s^2 spikes); 0.1 s averages ~200 samples (noise std down ~14x) and halves the
        2w ripple of distorted sines at >= 1.5 Hz (paper's sweep 1.5-7 Hz), while following a
        change of operating point within ~3 tau = 0.3 s, about one cycle of the slowest sine.
    """

    def __init__(self, env: gym.Env, time_constant_s: float = 0.1):
        gym.utils.RecordConstructorArgs.__init__(self, time_constant_s=time_constant_s)
        gym.ObservationWrapper.__init__(self, env)
        self.time_constant_s = finite("time_constant_s", time_constant_s, 0.0, lo_open=True)
        self._dt = float(env.unwrapped.dt)
        self._gain = 1.0 - math.exp(-self._dt / self.time_constant_s)
        box = env.observation_space
        # |alpha| <= 4 vmax^2/dt^2 + vmax * 4 vmax/dt^2 for any |v| <= vmax
        vmax = float(np.max(np.abs(env.action_space.high)))
        bound = 8.0 * vmax**2 / self._dt**2
        self.observation_space = spaces.Box(np.append(box.low, -bound), np.append(box.high, bound),
                                            dtype=np.float64)
        self._reset_state()

    def _reset_state(self) -> None:
        self._v_hist: tuple[float, float] | None = None
        self.alpha = 0.0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._reset_state()
        return self.observation(obs), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        v = float(info["voltage"])
        v1, v2 = self._v_hist if self._v_hist is not None else (v, v)
        vdot = (v - v1) / self._dt
        vddot = (v - 2.0 * v1 + v2) / self._dt**2
        raw = vdot * vdot - v * vddot
        self.alpha += self._gain * (raw - self.alpha)
        self._v_hist = (v, v1)
        info = {**info, "alpha_raw": raw}
        return self.observation(obs), reward, terminated, truncated, info

    def observation(self, observation):
        """The wrapped observation with the running alpha [V^2/s^2] appended."""
        return np.append(observation, self.alpha)
