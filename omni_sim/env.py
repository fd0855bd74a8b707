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
"""

from __future__ import annotations

import copy
import math
import os
import sys
from dataclasses import dataclass, fields, replace
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from identification.errors import UserError

from . import experiments as ex
from . import model as om
from .device import ENCODER_STEP_RAD, Device, Engine, read_encoder

__all__ = ["OmniYawEnv", "AlphaInvariantObservation", "InvalidOptionError", "OBSERVATION_NAMES",
           "RENDER_MODES", "VELOCITY_FILTER_HZ", "available_render_modes", "render_mode_problem"]

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


class InvalidOptionError(UserError, ValueError):
    """A bad option or action: both a :class:`ValueError` and the project's ``UserError``."""


# --- rendering (shared with omni_sim.wall_env) ------------------------------------------------
#: The render modes the environments implement (their class ``metadata``).  An instance's
#: ``metadata["render_modes"]`` lists those that can work in this process
#: (:func:`available_render_modes`), so that gymnasium's ``check_env``, which tries every
#: advertised mode, does not open a window without a display.
RENDER_MODES = ("human", "rgb_array")
#: MuJoCo's OpenGL backends that need no display: ``MUJOCO_GL=egl`` or ``osmesa`` (Linux), CGL
#: (macOS); the default, GLFW, opens an invisible window and so needs one.
_DISPLAYLESS_GL = ("mujoco.egl", "mujoco.osmesa", "mujoco.cgl")
_HEADLESS_HINT = ("headless, use render_mode='rgb_array' with MUJOCO_GL=egl (or osmesa) set "
                  "before mujoco is imported")


def _has_display() -> bool:
    """Whether a window can open: macOS and Windows have a desktop; elsewhere (X11, Wayland) a
    display must be named by ``DISPLAY`` or ``WAYLAND_DISPLAY``."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def render_mode_problem(mode: str) -> str | None:
    """Why ``mode`` cannot render in this process, or None when it can.

    ``"human"`` (MuJoCo's passive viewer, a GLFW window) needs a display; without one GLFW's
    failure ends the whole process, so it is refused here first.  ``"rgb_array"`` needs an
    OpenGL context from the backend MuJoCo chose when it was imported (``MUJOCO_GL``): EGL,
    OSMesa and CGL need no display, GLFW does.
    """
    if mode == "human":
        if _has_display():
            return None
        return ("render_mode='human' opens a window and needs a display (neither DISPLAY nor "
                f"WAYLAND_DISPLAY is set); {_HEADLESS_HINT}")
    backend = getattr(getattr(mujoco, "GLContext", None), "__module__", None)
    if backend in _DISPLAYLESS_GL or (backend == "mujoco.glfw" and _has_display()):
        return None
    why = ("MuJoCo's default backend, GLFW, needs a display and none is set" if backend == "mujoco.glfw"
           else f"MuJoCo has no usable OpenGL backend (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r})")
    return f"render_mode='rgb_array' needs an OpenGL context: {why}; {_HEADLESS_HINT}"


def available_render_modes() -> list[str]:
    """The render modes that can work in this process (see :func:`render_mode_problem`)."""
    return [m for m in RENDER_MODES if render_mode_problem(m) is None]


class _Viewport:
    """The picture of a model's data for an environment: offscreen with :class:`mujoco.Renderer`
    (``"rgb_array"``) or in MuJoCo's passive viewer (``"human"``).  The mode is checked when
    the environment is made: unknown, or unable to work here, raises :class:`InvalidOptionError`."""

    def __init__(self, model: mujoco.MjModel, render_mode: str | None, width: int, height: int,
                 camera: str | None):
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise InvalidOptionError(f"render_mode must be one of {list(RENDER_MODES)} or None, "
                                     f"got {render_mode!r}")
        problem = render_mode_problem(render_mode) if render_mode is not None else None
        if problem is not None:
            raise InvalidOptionError(problem)
        self.mode, self.model = render_mode, model
        self.size = (int(height), int(width))
        if min(self.size) < 1:
            raise InvalidOptionError(f"render size must be positive, got {width}x{height}")
        if camera is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
            if camera != "side":  # the default falls back to the free camera
                raise InvalidOptionError(f"the model has no camera named {camera!r}")
            camera = None
        self.camera = camera
        self._renderer = None
        self._viewer = None

    def render(self, data: mujoco.MjData):
        """An RGB image ``(height, width, 3)`` uint8 (``"rgb_array"``), or update the viewer."""
        if self.mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' "
                            "or 'human' when making the environment")
            return None
        if self.mode == "human":
            if self._viewer is None:
                from mujoco import viewer  # needs a display (checked when made)
                self._viewer = viewer.launch_passive(self.model, data)
            self._viewer.sync()
            return None
        if self._renderer is None:
            h, w = self.size
            vis = self.model.vis.global_
            vis.offheight, vis.offwidth = max(vis.offheight, h), max(vis.offwidth, w)
            self._renderer = mujoco.Renderer(self.model, h, w)
        self._renderer.update_scene(data, camera=self.camera if self.camera else -1)
        return self._renderer.render().copy()

    def close(self) -> None:
        """Release the renderer and the viewer (safe to call twice)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None


@dataclass(frozen=True)
class _Options:
    """The per-episode options (see :class:`OmniYawEnv` for their meaning and units)."""

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


_OPTION_NAMES = tuple(f.name for f in fields(_Options))
_MAKE_ONLY = ("model_path", "friction", "control_period_s", "render_mode", "render_width",
              "render_height", "camera")


def _finite(name: str, value, lo: float = -math.inf, hi: float = math.inf,
            lo_open: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InvalidOptionError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or x < lo or x > hi or (lo_open and x == lo):
        rel = ">" if lo_open else ">="
        rng = f"{rel} {lo:g}" if math.isinf(hi) else f"in [{lo:g}, {hi:g}]"
        raise InvalidOptionError(f"{name} must be finite and {rng}, got {value!r}")
    return x


class OmniYawEnv(gym.Env):
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
    model, data : mujoco.MjModel, mujoco.MjData
    control_period_s : float [s]
    substeps : int
        Physics steps per control period.
    voltage_limit : float [V]
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 1000}

    def __init__(self, model_path: str | os.PathLike | None = None,
                 control_period_s: float = ex.CONTROL_PERIOD_S, render_mode: str | None = None,
                 render_width: int = 640, render_height: int = 480,
                 camera: str | None = "side", friction: str | None = None, **options):
        try:
            model = om.load_model(model_path, friction)
            self.device = Device(model, _finite("control_period_s", control_period_s, 0.0,
                                                lo_open=True))
        except UserError as exc:
            if isinstance(exc, InvalidOptionError):
                raise
            raise InvalidOptionError(str(exc)) from None
        self.model = model
        self.model_path = model_path
        self.friction = self.device.friction_family(om.model_path(model_path, friction))
        self.data = mujoco.MjData(self.model)
        self._ix = self.device.ix
        self.substeps = self.device.substeps
        self.control_period_s = float(control_period_s)
        self.metadata = {**type(self).metadata, "render_modes": available_render_modes(),
                         "render_fps": int(round(1.0 / self.dt))}

        self.voltage_limit = self.device.voltage_limit
        if not math.isfinite(self.voltage_limit):
            raise InvalidOptionError("the model's yaw_motor needs a ctrlrange (the drive's "
                                     "voltage limit) to bound the action space")
        yaw_j = self.device.joint_id
        self._yaw_range = (tuple(float(x) for x in self.model.jnt_range[yaw_j])
                           if self.model.jnt_limited[yaw_j] else (-math.pi, math.pi))
        self._device0 = Device(copy.deepcopy(self.model), self.device.control_period_s)  # friction levels of the model file
        self._yaw_damping0 = self.device.yaw_damping

        vlim = np.float32(self.voltage_limit)
        self.action_space = spaces.Box(-vlim, vlim, shape=(1,), dtype=np.float32)
        vel_bound = 4 * math.pi / self.dt
        self.observation_space = spaces.Box(
            low=np.array([-math.pi, -vel_bound, self._yaw_range[0], -math.pi, -math.pi]),
            high=np.array([math.pi, vel_bound, self._yaw_range[1], math.pi, math.pi]),
            dtype=np.float64)

        self._viewport = _Viewport(self.model, render_mode, render_width, render_height, camera)
        self.render_mode = render_mode

        self._defaults = self._merge(_Options(), options)
        self._engine: Engine | None = None
        self._diverged = False
        self._opt = self._defaults
        self._r = np.zeros(1)
        self._noise = np.zeros(2)
        self._k = 0
        self._n = 1

    # --- options -------------------------------------------------------------------------
    @property
    def dt(self) -> float:
        """Control period [s]: ``model.opt.timestep * substeps``."""
        return float(self.model.opt.timestep) * self.substeps

    def _merge(self, base: _Options, options: dict | None) -> _Options:
        options = dict(options or {})
        for key in options:
            if key in _MAKE_ONLY:
                raise InvalidOptionError(f"option {key!r} can only be given when the environment "
                                         "is made (the spaces derive from it)")
            if key not in _OPTION_NAMES:
                raise InvalidOptionError(f"unknown option {key!r}; known options: "
                                         f"{', '.join(_OPTION_NAMES)}")
        if "reference" in options and not isinstance(options["reference"], str):
            options["reference"] = np.array(options["reference"], dtype=float, copy=True)
        opt = replace(base, **options)
        self._validate(opt)
        return opt

    def _validate(self, o: _Options) -> None:
        try:
            self.device.check_pose(_finite("gamma1_set_deg", o.gamma1_set_deg),
                                   _finite("gamma2_set_deg", o.gamma2_set_deg))
        except UserError as exc:
            if isinstance(exc, InvalidOptionError):
                raise
            raise InvalidOptionError(f"arm set point: {exc}") from None
        lo, hi = self._yaw_range
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
            _finite("frequency_hz", o.frequency_hz, 0.0, lo_open=True)
        if o.amplitude_rad is not None:
            _finite("amplitude_rad [rad] (the yaw joint range bounds it)", o.amplitude_rad, 0.0, half)
        _finite("step_period_s", o.step_period_s, 0.0, lo_open=True)
        if o.duration_s is not None:
            _finite("duration_s", o.duration_s, self.dt)
            if not isinstance(o.reference, str) and round(o.duration_s / self.dt) > o.reference.size:
                raise InvalidOptionError(f"duration_s = {o.duration_s} s is longer than the array "
                                         f"reference ({o.reference.size} samples of {self.dt} s)")
        if o.theta0_rad is not None:
            _finite("theta0_rad", o.theta0_rad, lo, hi)
        _finite("friction_scale", o.friction_scale, 0.0)
        _finite("noise_rad", o.noise_rad, 0.0, MAX_NOISE_RAD)
        if not isinstance(o.quantize, (bool, np.bool_)):
            raise InvalidOptionError(f"quantize must be a bool, got {o.quantize!r}")
        if o.velocity not in VELOCITY_MODES:
            raise InvalidOptionError(f"velocity must be one of {VELOCITY_MODES}, got {o.velocity!r}")
        _finite("effort_weight", o.effort_weight, 0.0)

    def _build_reference(self, o: _Options) -> tuple[np.ndarray, float]:
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
                levels = self.np_random.uniform(-amp, amp, size=-(-t.size // hold))
                r = np.repeat(levels, hold)[: t.size]
                theta0 = 0.0
        if o.theta0_rad is not None:
            theta0 = float(o.theta0_rad)
        return np.asarray(r, dtype=float), theta0

    # --- measurement -----------------------------------------------------------------------
    def _measure(self) -> float:
        """Encoder reading at the current time [rad] (:func:`omni_sim.device.read_encoder`)."""
        return float(read_encoder(self.data.qpos[self._ix.yaw_qpos], self._noise[self._k],
                                  ENCODER_STEP_RAD if self._opt.quantize else 0.0))

    def _instabilities(self) -> int:
        """How often MuJoCo has reset this data for a bad qpos, qvel or qacc."""
        w = self.data.warning
        return int(sum(w[int(k)].number for k in (mujoco.mjtWarning.mjWARN_BADQPOS,
                                                 mujoco.mjtWarning.mjWARN_BADQVEL,
                                                 mujoco.mjtWarning.mjWARN_BADQACC)))

    def _observe(self, y: float) -> tuple[np.ndarray, str | None]:
        """The observation, and why it is invalid (None when it is finite and in bounds)."""
        if self._opt.velocity == "exact":
            w = float(self.data.qvel[self._ix.yaw_dof])
        else:
            d = (3.0 * y - 4.0 * self._y_hist[0] + self._y_hist[1]) / (2.0 * self.dt)
            self._w_est += self._lp_gain * (d - self._w_est)
            self._y_hist = (y, self._y_hist[0])
            w = self._w_est
        r = self._r[min(self._k, self._r.size - 1)]
        obs = np.array([y, w, r, self.data.qpos[self._ix.shoulder_qpos],
                        self.data.qpos[self._ix.elbow_qpos]], dtype=np.float64)
        box = self.observation_space
        bad = ~(np.isfinite(obs) & (obs >= box.low) & (obs <= box.high))
        if not bad.any():
            return obs, None
        reason = (f"simulation diverged at t = {self.data.time:.6f} s: "
                  + ", ".join(f"{OBSERVATION_NAMES[i]} = {obs[i]:g} outside "
                              f"[{box.low[i]:g}, {box.high[i]:g}]" for i in np.flatnonzero(bad)))
        return np.clip(np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0), box.low, box.high), reason

    def _info(self, v: float) -> dict:
        theta = float(self.data.qpos[self._ix.yaw_qpos])
        r = float(self._r[min(self._k, self._r.size - 1)])
        return {"time": float(self.data.time), "theta_true": theta, "tracking_error": r - theta,
                "voltage": v}

    # --- gymnasium API -----------------------------------------------------------------------
    def _apply_friction_scale(self, o: _Options) -> None:
        """Scale the model's yaw dry friction and viscous damping to the episode's option."""
        self.device.scale_friction(o.friction_scale, base=self._device0)
        self.model.dof_damping[self._ix.yaw_dof] = self._yaw_damping0 * o.friction_scale

    def _episode(self, o: _Options) -> tuple[np.ndarray, float, np.ndarray]:
        """An episode's random draws from ``self.np_random``, in this order: the reference and
        initial yaw [rad], then the encoder noise [rad] (one sample per control period + 1).
        The vector environment draws each sub-environment's episode with this too."""
        r, theta0 = self._build_reference(o)
        noise = (self.np_random.normal(0.0, o.noise_rad, r.size + 1) if o.noise_rad > 0
                 else np.zeros(r.size + 1))
        return r, theta0, noise

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode: arm at its equilibrium pose, yaw at ``theta0_rad`` at rest.

        Parameters
        ----------
        seed : int, optional
            Seeds the RNG (random steps, encoder noise); equal seeds and options give equal
            episodes.
        options : dict, optional
            Per-episode overrides of the make-time options (see the class docstring).
        """
        super().reset(seed=seed)
        o = self._merge(self._defaults, options) if options else self._defaults
        self._opt = o
        if self._engine is not None:
            self._engine.close()
        self._apply_friction_scale(o)
        self._r, theta0, self._noise = self._episode(o)
        self._n = self._r.size
        # the device's start state and engine, on this environment's MjData
        self._engine = Engine([self.device], [theta0],
                              [(float(o.gamma1_set_deg), float(o.gamma2_set_deg))], data=self.data)
        self._diverged = False

        self._k = 0
        y = self._measure()
        self._y_hist = (y, y)  # at rest before the episode
        self._w_est = 0.0
        self._lp_gain = 1.0 - math.exp(-2 * math.pi * VELOCITY_FILTER_HZ * self.dt)
        obs, reason = self._observe(y)
        if reason is not None:  # the options are validated, so the start state is in bounds
            raise RuntimeError(reason)
        if self.render_mode == "human":
            self.render()
        return obs, self._info(0.0)

    def step(self, action):
        """Apply voltage ``action[0]`` [V] for one control period; see the class docstring."""
        a = np.asarray(action, dtype=float)
        if a.shape != (1,):
            raise InvalidOptionError(f"action must have shape (1,) (yaw voltage [V]), got shape "
                                     f"{a.shape}")
        v = float(a[0])
        if not math.isfinite(v):
            raise InvalidOptionError(f"action must be finite, got {v}")
        if self._engine is None:
            raise RuntimeError("step() before reset()")
        if self._diverged:
            raise RuntimeError("step() after the episode terminated (diverged); call reset()")
        if self._k >= self._n:
            raise RuntimeError("step() after the episode was truncated; call reset()")
        bad_before = self._instabilities()
        v = float(self._engine.apply(v)[0])
        self._k += 1
        obs, reason = self._observe(self._measure())
        if reason is None and self._instabilities() > bad_before:
            reason = (f"simulation diverged at t = {self.data.time:.6f} s: MuJoCo found a "
                      "non-finite or huge state and reset it (mjWARN_BADQPOS/QVEL/QACC)")
        info = self._info(v)
        if reason is not None:
            self._diverged = True
            info.update(diverged=True, reason=reason)
            return obs, 0.0, True, False, info
        reward = -info["tracking_error"] ** 2 - self._opt.effort_weight * v * v
        truncated = self._k >= self._n
        if self.render_mode == "human":
            self.render()
        return obs, float(reward), False, truncated, info

    def render(self):
        """An RGB image ``(height, width, 3)`` uint8 (``"rgb_array"``), or update the viewer."""
        return self._viewport.render(self.data)

    def close(self):
        """Release the renderer and the viewer (safe to call twice)."""
        if self._engine is not None:
            self._engine.close()
        self._viewport.close()


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
        self.time_constant_s = _finite("time_constant_s", time_constant_s, 0.0, lo_open=True)
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
