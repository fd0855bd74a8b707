"""N virtual Omnis stepped in one call: the native vector environment of ``omni_sim/OmniYaw-v0``.

``gym.make_vec("omni_sim/OmniYaw-v0", num_envs=N, vectorization_mode="vector_entry_point")``
makes an :class:`OmniYawVectorEnv`.  Its N rows are one batch of the device's closed-loop
:class:`~omni_sim.device.Engine`: every :meth:`~OmniYawVectorEnv.step` advances all N yaw axes
by one control period in a single :func:`mujoco.rollout` call on all cores.  The encoder,
velocity estimate, observation and reward are the single environment's task
(:class:`omni_sim.tracking_task.TrackingTask`) over N rows, numpy over the batch; this class
adds the seeding per row, the reset mask and the autoreset.

Sub-environment ``i`` is the single environment (:class:`omni_sim.env.OmniYawEnv`, same
options) seeded ``seed + i`` (gymnasium's seeding rule): the same reference, noise, start state
and trajectory, step for step (``tests/test_vector_env.py``).  Autoreset follows gymnasium's
default ``NextStep`` mode: the step after a sub-environment ends resets it (its action is
ignored, its reward is 0 and its observation is the new episode's first).

Differences from N single environments, both documented in :class:`omni_sim.env.OmniYawEnv`'s
terms: ``render`` is not offered; a divergence is detected from the observation's bounds only
(MuJoCo's own instability reset inside a batched rollout is not reported per row).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from .device import Engine
from .env import OBSERVATION_NAMES, InvalidOptionError, OmniYawEnv
from .tracking_task import TrackingTask

__all__ = ["OmniYawVectorEnv"]


class OmniYawVectorEnv(VectorEnv):
    """N virtual Omni yaw axes as one gymnasium vector environment (see the module doc).

    Parameters
    ----------
    num_envs : int
        Number of sub-environments N (>= 1).
    nthread : int, optional
        Rollout threads (default: :func:`omni_sim.device.default_threads`).
    **kwargs
        The options of :class:`omni_sim.env.OmniYawEnv` (make-time ones included, rendering
        excepted), the same for every sub-environment; per-episode options may also be passed
        to :meth:`reset` and then apply to every sub-environment that resets.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, nthread: int | None = None, **kwargs):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise InvalidOptionError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if kwargs.get("render_mode") is not None:
            raise InvalidOptionError("the vector environment does not render; make single "
                                     "environments to render")
        kwargs.pop("max_episode_steps", None)  # gymnasium passes the spec's (None) along
        self.num_envs = int(num_envs)
        self._env = OmniYawEnv(**kwargs)  # the make-time options and spaces: the single env's
        self.device = self._env.device
        # the single env's task over N rows: sub-environment i is row i
        self.task = TrackingTask(self.device, rows=self.num_envs)
        self.task.defaults = self._env.task.defaults
        self.single_action_space = self._env.action_space
        self.single_observation_space = self._env.observation_space
        self.action_space = spaces.Box(np.tile(self.single_action_space.low, (self.num_envs, 1)),
                                       np.tile(self.single_action_space.high, (self.num_envs, 1)),
                                       dtype=self.single_action_space.dtype)
        self.observation_space = spaces.Box(
            np.tile(self.single_observation_space.low, (self.num_envs, 1)),
            np.tile(self.single_observation_space.high, (self.num_envs, 1)), dtype=np.float64)
        self.metadata = {**self._env.metadata, "autoreset_mode": AutoresetMode.NEXT_STEP}
        self.render_mode = None
        self.dt = self._env.dt
        self._nthread = nthread
        self._engine: Engine | None = None
        N = self.num_envs
        self._rngs: list[np.random.Generator | None] = [None] * N
        self._done = np.zeros(N, dtype=bool)
        self._last_obs = np.zeros((N, len(OBSERVATION_NAMES)))

    # --- episodes -----------------------------------------------------------------------------
    def _start(self, i: int, seed: int | None, options: dict | None) -> tuple[float, tuple]:
        """Draw sub-environment ``i``'s episode exactly as the single env's reset does."""
        if seed is not None or self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random(seed)
        self._done[i] = False
        return self.task.start_row(i, options, self._rngs[i])

    def _check_uniform_model_options(self) -> None:
        opts = self.task.options
        if len({o.friction_scale for o in opts}) > 1:
            raise InvalidOptionError("friction_scale must be the same for every sub-environment")
        self.task.apply_friction_scale(opts[0])

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every sub-environment (or those in ``options["reset_mask"]``).

        ``seed``: None, an int (sub-environment ``i`` gets ``seed + i``) or a list of N seeds.
        """
        N = self.num_envs
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(N, dtype=bool)
        mask = np.asarray(mask)
        if mask.shape != (N,) or mask.dtype != np.bool_ or not mask.any():
            raise InvalidOptionError(f"reset_mask must be a bool array of shape ({N},) with a True")
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(N)]
        else:
            seeds = list(seed)
            if len(seeds) != N:
                raise InvalidOptionError(f"seed must be None, an int or {N} seeds, got {len(seeds)}")
        rows = np.flatnonzero(mask)
        starts = [self._start(int(i), seeds[i], options) for i in rows]
        self._check_uniform_model_options()
        if self._engine is None or rows.size == N:
            if self._engine is not None:
                self._engine.close()
            th0 = np.zeros(N)
            gs = [(0.0, 0.0)] * N
            for i, (t, g) in zip(rows, starts):
                th0[i], gs[i] = t, g
            self._engine = Engine([self.device] * N, th0, gs, nthread=self._nthread)
        else:
            self._engine.reset_rows(rows, [t for t, _ in starts], [g for _, g in starts])
        task, keep = self.task, ~mask  # the others keep their estimator state and last observation
        hist, w = task.y_hist.copy(), task.w_est.copy()
        y = task.measure(self._engine)
        task.y_hist[rows] = y[rows, None]
        obs, _ = self._observe(y)
        task.y_hist[keep], task.w_est[keep] = hist[keep], w[keep]
        if keep.any():
            obs[keep] = self._last_obs[keep]
        self._last_obs = obs.copy()
        return obs, task.info(self._engine, np.zeros(N))

    def _observe(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows' observations, those out of bounds clipped, and which rows those are."""
        obs = self.task.observe(self._engine, y)
        bad = self.task.out_of_bounds(obs).any(axis=1)
        if bad.any():
            obs[bad] = self.task.clip(obs[bad])
        return obs, bad

    # --- stepping -------------------------------------------------------------------------------
    def step(self, actions):
        """Apply one voltage [V] per sub-environment for one control period."""
        if self._engine is None:
            raise RuntimeError("step() before reset()")
        a = np.asarray(actions, dtype=float)
        if a.shape != (self.num_envs, 1):
            raise InvalidOptionError(f"actions must have shape ({self.num_envs}, 1) (one yaw "
                                     f"voltage [V] per sub-environment), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise InvalidOptionError("actions must be finite")
        task = self.task
        again = np.flatnonzero(self._done)  # NextStep autoreset: these start a new episode
        run = ~self._done
        v = self._engine.vmax.copy()
        v = np.clip(a[:, 0], -v, v)
        v[again] = 0.0
        if again.size:
            starts = [self._start(int(i), None, None) for i in again]
            self._check_uniform_model_options()
        self._engine.apply(v)  # rows that start again are overwritten below
        task.k[run] += 1
        if again.size:
            self._engine.reset_rows(again, [t for t, _ in starts], [g for _, g in starts])
        y = task.measure(self._engine)
        if again.size:
            task.y_hist[again] = y[again, None]
        obs, bad = self._observe(y)
        info = task.info(self._engine, v)
        reward = task.reward(info)
        terminated = bad & run
        truncated = run & ~terminated & (task.k >= task.n)
        reward[again] = 0.0
        reward[terminated] = 0.0
        self._done = terminated | truncated
        info["diverged"] = terminated
        self._last_obs = obs.copy()
        return obs, reward, terminated, truncated, info

    def close_extras(self, **kwargs: Any) -> None:
        if self._engine is not None:
            self._engine.close()
            self._engine = None
        self._env.close()
