"""The one closed loop: :class:`Engine` (B devices advanced one control period at a time),
the paper's clipped P law (:func:`p_law`) closed around the encoder (:func:`run_p_loop`), and
the loop's timing (:data:`CONTROL_PERIOD_S`, :func:`substeps_of`, :data:`STATE_SPEC`).

Time convention (the whole project): sample ``k`` is at ``t_k = k dt`` with ``dt`` the control
period; ``y_k`` is the yaw *measured* at ``t_k`` (before the controller acts), the command
``v_k`` is held (zero-order hold) over ``[t_k, t_k + dt)``, i.e. for ``substeps`` physics steps.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from identification.errors import UserError

from .encoder import encoder_reader
from .laws import DriveFriction, _DriveLaws

#: The Omni's servo period [s] (1 kHz, models/omni/README.md).
CONTROL_PERIOD_S = 1e-3
#: The physics state the engine carries between control periods.
STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS
#: Batches of fewer rows are stepped on the calling thread, not handed to a pool's threads at
#: every control period: the hand-off costs ~40 us a period, more than a small batch's steps.
#: Measured (2 cores, one rollout call of one physics step per row, best of 3 x 3000 calls):
#: the bank's servo pendulum 24 rows 44 us on the calling thread, 73 us on two threads; 32
#: rows 59 / 82 us; 48 rows 88 / 81 us; the Omni 24 rows 64 / 98 us, 32 rows 85 / 79 us, 48
#: rows 127 / 99 us.  The trajectories are the same either way (tests/test_device.py).
SERIAL_BELOW = 32
#: The environment variable that sets how many threads a batch uses when a caller names none
#: (a machine shared with other jobs, several test processes on one machine); unset: all cores.
THREADS_ENV = "OMNI_THREADS"


def default_threads() -> int:
    """Threads of a batch when none is asked for: ``OMNI_THREADS`` (a positive whole
    number) if set, else all cores.  UserError if it is set to anything else."""
    raw = os.environ.get(THREADS_ENV, "").strip()
    if not raw:
        return max(1, os.cpu_count() or 1)
    n = int(raw) if raw.isdigit() else 0
    if n < 1:
        raise UserError(f"{THREADS_ENV} must be a positive whole number of threads, got {raw!r}")
    return n


def p_law(kp, r, y, vmax):
    """The paper's P controller, clipped to the drive: ``clip(kp (r - y), -vmax, vmax)`` [V]."""
    return np.clip(kp * (r - y), -vmax, vmax)


def substeps_of(model: mujoco.MjModel, control_period_s: float) -> int:
    """Physics steps per control period (UserError unless it divides exactly)."""
    n = control_period_s / model.opt.timestep
    if not (n >= 1 - 1e-9 and abs(n - round(n)) < 1e-9):
        raise UserError(f"control period {control_period_s} s is not a whole multiple of the "
                        f"physics timestep {model.opt.timestep} s")
    return int(round(n))


def _pose(gamma_set_deg):
    """A run's set points as a tuple (None stays None: a device without the Omni's arm)."""
    return None if gamma_set_deg is None else tuple(gamma_set_deg)


#: MuJoCo's warnings of an unstable state (it resets the data when it issues one).
_INSTABILITY = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL,
                mujoco.mjtWarning.mjWARN_BADQPOS)


def _instability_warnings(datas) -> int:
    """How many instability warnings these ``MjData`` have issued so far."""
    return sum(int(d.warning[w].number) for d in datas for w in _INSTABILITY)


def _warns(model: mujoco.MjModel, state: np.ndarray, ctrl: np.ndarray) -> bool:
    """Whether one control period from ``state`` under ``ctrl`` (substeps x nu, or substeps x
    (nu + nv) with the joint forces after the controls) makes MuJoCo reset the data (a fresh
    ``MjData``; the same steps as the rollout's)."""
    d = mujoco.MjData(model)
    mujoco.mj_setState(model, d, state, STATE_SPEC)
    for u in ctrl:
        d.ctrl[:] = u[:model.nu]
        if len(u) > model.nu:
            d.qfrc_applied[:] = u[model.nu:]
        mujoco.mj_step(model, d)
    return _instability_warnings([d]) > 0


class Engine:
    """The closed loop of B virtual devices, advanced one control period at a time.

    Row ``b`` is a run on ``devices[b]`` (devices may wrap different models of one size
    signature, e.g. the candidates of a parameter fit) started by :meth:`Device.start_state`.
    Each :meth:`apply` clips the commands to each drive's limit, holds them for one control
    period (``substeps`` physics steps) and advances every row.  One row is stepped with
    ``mj_step`` on its own ``MjData``; a batch with :func:`mujoco.rollout` on ``pool``'s
    threads.  Both give the same trajectory bit for bit (``tests/test_device.py``).

    Parameters
    ----------
    devices : list of Device
    theta0_rad : sequence of float [rad]
    gamma_set_deg : sequence of (float, float) [deg]
        One pair per row (None, or an empty tuple, per row for a device without the arm).
    nthread : int, optional
        Threads for a batch (default: :func:`default_threads`).
    pool : mujoco.rollout.Rollout, optional
        A thread pool of ``nthread`` threads to share between engines (default: the engine
        makes its own, stopped by :meth:`close`).
    data : MjData, optional
        For one row: the ``MjData`` to start and step (e.g. one a viewer shows).
    """

    def __init__(self, devices: list, theta0_rad, gamma_set_deg,
                 nthread: int | None = None, pool=None, data: mujoco.MjData | None = None):
        if not devices:
            raise ValueError("an engine needs at least one run")
        d0 = devices[0]
        if any(d.substeps != d0.substeps or d.nstate != d0.nstate for d in devices):
            raise ValueError("the devices of one engine need the same substeps and state size")
        if any(d.ix != d0.ix for d in devices):
            raise ValueError("the devices of one engine need the same joint and actuator addresses")
        self.devices = devices
        self.B = len(devices)
        self.substeps = d0.substeps
        self.vmax = np.array([d.voltage_limit for d in devices])
        self._yaw_act = d0.ix.yaw_act
        #: the rows' models have the Omni's arm (else :meth:`qpos` gives NaN arm angles)
        self.has_arm = d0.ix.has_arm
        self._q = ((d0.ix.yaw_qpos, d0.ix.shoulder_qpos, d0.ix.elbow_qpos) if self.has_arm
                   else (d0.ix.yaw_qpos,))
        self._qadr = 1 + np.array(self._q)  # FULLPHYSICS state = [time, qpos, qvel, act, ...]
        self._init_laws(devices)
        # torque-off periods (run_p_loop's ``enabled``) step each row's off model
        self._on_models = self._law_models if self._laws else [d.model for d in devices]
        self._off_models = None  # made at the first torque-off period
        self._off_fl = None  # their dof_frictionloss arrays (with drive laws; made with them)
        self._off_dm = None  # their dof_damping arrays (with LOAD_FRICTION_SMOOTH)
        if self.B == 1:
            m1 = self._law_models[0] if self._laws else d0.model
            self._data = d0.start_data(float(theta0_rad[0]), _pose(gamma_set_deg[0]), data)
            self._m1 = m1
            self._vmax1 = float(self.vmax[0])
            self.unstable = np.zeros(1, bool)  # see the batch's below
            self._own_pool = False
            self.pool = None
            return
        self._data = None
        self.x = np.empty((self.B, d0.nstate))
        self._nu = d0.model.nu
        self._ctrl = np.zeros((self.B, self.substeps, self._nu + (d0.model.nv if self._smooth else 0)))
        self._control_spec = mujoco.mjtState.mjSTATE_CTRL
        if self._smooth:
            self._control_spec |= mujoco.mjtState.mjSTATE_QFRC_APPLIED
            self._qfrc_col = self._nu + self._laws.dof
        for b, (dev, th0, gs) in enumerate(zip(devices, theta0_rad, gamma_set_deg)):
            self.x[b], self._ctrl[b, :, :self._nu] = dev.start_state(float(th0), _pose(gs))
        self._models = list(self._on_models)
        self._models_on = np.ones(self.B, bool)  # which rows _models steps with the drive on
        nthread = max(1, nthread or default_threads())
        if self.B < SERIAL_BELOW:  # a small batch: the calling thread steps it (see SERIAL_BELOW)
            nthread, pool = 1, None
        self._own_pool = pool is None
        # one thread: the calling thread steps the batch (no hand-off to a pool thread at
        # every control period); same trajectories either way
        self.pool = rollout.Rollout(nthread=nthread if nthread > 1 else 0) if pool is None else pool
        self._datas = [mujoco.MjData(d0.model) for _ in range(nthread)]
        # a row's simulated time advances by one control period per apply; MuJoCo resets an
        # unstable row's data (time back to 0) and warns without saying which row: a row whose
        # time fell behind is flagged in ``unstable`` for good (its trajectory is not physics)
        self._half_period = 0.5 * np.array([d.model.opt.timestep * self.substeps for d in devices])
        self._vel = 1 + d0.model.nq + d0.ix.yaw_dof  # the yaw velocity's column of the state
        if self._laws:  # each row's actuatorfrc sensor (its address, 0 where a row has none)
            self._has_sensor = self._laws.sensor >= 0
            self._sensor_adr = np.maximum(self._laws.sensor, 0)
            self._rows = np.arange(self.B)
        self.unstable = np.zeros(self.B, bool)
        self._state = np.empty((self.B, self.substeps, d0.nstate))
        self._sens = np.empty((self.B, self.substeps, d0.model.nsensordata))
        self._chunk = max(1, -(-self.B // len(self._datas)))  # one task per thread

    def _init_laws(self, devices: list) -> None:
        """The rows' drive laws (:class:`DriveFriction`): each row steps its own copy of its
        model, whose frictionloss the engine sets at every control period."""
        laws = [d.drive_friction for d in devices]
        self._laws = None
        if any(f is not None for f in laws):
            # a row without laws (a candidate model without them, batched with ones that have
            # them) keeps its own frictionloss: the null law
            self._laws = _DriveLaws([f if f is not None else
                                     DriveFriction.none(d.ix.yaw_dof, d.model.dof_frictionloss[d.ix.yaw_dof],
                                                        d.ix.yaw_act)
                                     for f, d in zip(laws, devices)])
            self._force = np.zeros(self.B)  # each row's actuator force of its last step
            self._law_models = [copy.deepcopy(d.model) for d in devices]
            self._law_fl = [m.dof_frictionloss for m in self._law_models]  # written every period
            self._fl_now = self._law_fl  # a batch's: those of the models its rows step now
        # LOAD_FRICTION_SMOOTH: the rows' damping is written every period too, and the law's
        # force is a joint force (the rollout's control then holds qfrc_applied after ctrl)
        self._smooth = self._laws is not None and self._laws.any_smooth
        if self._smooth:
            self._law_dm = [m.dof_damping for m in self._law_models]
            self._dm_now = self._law_dm

    def close(self) -> None:
        """Stop the engine's own thread pool (if it made one)."""
        if self._own_pool and self.pool is not None:
            self.pool.close()
            self.pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def data(self) -> mujoco.MjData | None:
        """The ``MjData`` of a one-row engine (None for a batch)."""
        return self._data

    def qpos(self) -> np.ndarray:
        """True ``(yaw, shoulder, elbow)`` angles [rad] of every row, shape ``(B, 3)``; yaw is
        the controlled joint.  Without the Omni's arm (:attr:`has_arm` False) the shoulder and
        elbow columns are NaN (the shape stays ``(B, 3)``)."""
        if not self.has_arm:
            out = np.full((self.B, 3), np.nan)
            out[:, 0] = self.yaw()
            return out
        if self._data is not None:
            return self._data.qpos[list(self._q)][None, :].copy()
        return self.x[:, self._qadr].copy()

    def yaw(self) -> np.ndarray:
        """True yaw angle [rad] of every row, shape ``(B,)``."""
        if self._data is not None:
            return np.array([self._data.qpos[self._q[0]]])
        return self.x[:, self._qadr[0]].copy()

    def yaw_velocity(self) -> np.ndarray:
        """True yaw velocity [rad/s] of every row, shape ``(B,)``."""
        dof = self.devices[0].ix.yaw_dof
        if self._data is not None:
            return np.array([self._data.qvel[dof]])
        return self.x[:, self._vel].copy()

    def time(self) -> np.ndarray:
        """Simulated time [s] of every row since its start, shape ``(B,)``."""
        if self._data is not None:
            return np.array([self._data.time])
        return self.x[:, 0].copy()

    def reset_rows(self, rows, theta0_rad, gamma_set_deg) -> None:
        """Start rows ``rows`` again from :meth:`Device.start_state` (the others go on)."""
        for b, th0, gs in zip(rows, theta0_rad, gamma_set_deg):
            dev = self.devices[b]
            self.unstable[b] = False
            if self._laws:
                self._force[b] = 0.0
            if self._data is not None:
                dev.start_data(float(th0), _pose(gs), self._data)
            else:
                self.x[b], self._ctrl[b, :, :self._nu] = dev.start_state(float(th0), _pose(gs))

    def _off(self) -> list:
        if self._off_models is None:
            self._off_models = [copy.deepcopy(d.off_model()) if self._laws else d.off_model()
                                for d in self.devices]
            if self._laws:
                self._off_fl = [m.dof_frictionloss for m in self._off_models]
            if self._smooth:
                self._off_dm = [m.dof_damping for m in self._off_models]
        return self._off_models

    def apply(self, v, on=None) -> np.ndarray:
        """Hold the commands ``v`` [V] (one per row, clipped to each drive) for one control
        period and advance the physics; returns the applied (clipped) commands.  ``on`` (B
        bools, default all True): rows switched off step with the drive off
        (:meth:`Device.off_model`; their command is 0)."""
        if self._data is not None:  # one row: plain floats and mj_step (the env's hot path)
            vk = float(v[0]) if np.ndim(v) else float(v)
            vk = min(max(vk, -self._vmax1), self._vmax1)
            m, d = self._m1, self._data
            if on is not None and not bool(np.ravel(on)[0]):
                m, vk = self._off()[0], 0.0
            if self._laws:
                self._set_friction()
            d.ctrl[self._yaw_act] = vk
            warned = _instability_warnings([d])
            for _ in range(self.substeps):
                mujoco.mj_step(m, d)
            if _instability_warnings([d]) > warned:
                self.unstable[0] = True
            if self._laws and self._laws.sensor[0] >= 0:
                self._force[0] = d.sensordata[self._laws.sensor[0]]
            return np.array([vk])
        v = np.clip(np.asarray(v, dtype=float).reshape(self.B), -self.vmax, self.vmax)
        if on is not None:
            v = np.where(on, v, 0.0)
        self._advance(v, on)
        return v

    def apply_per_step(self, v) -> np.ndarray:
        """As :meth:`apply` for a batch, with a command for every physics step of the control
        period: ``v`` (B, substeps) [V], clipped to each drive.  Returns the yaw velocity
        [rad/s] after each physics step, shape (B, substeps) (e.g. to integrate the power of
        a force held over each step)."""
        if self._data is not None:
            raise ValueError("apply_per_step steps a batch engine (two rows or more)")
        v = np.asarray(v, dtype=float).reshape(self.B, self.substeps)
        self._advance(np.clip(v, -self.vmax[:, None], self.vmax[:, None]))
        return self._state[:, :, self._vel].copy()

    def _advance(self, v: np.ndarray, on=None) -> None:
        """A batch's :meth:`apply` after the clip: ``v`` (B,) or (B, substeps) already within
        each drive's limit (one command for the period, or one per physics step); ``on``: see
        :meth:`apply`."""
        self._ctrl[:, :, self._yaw_act] = v[:, None] if v.ndim == 1 else v
        if on is not None or self._off_models is not None:
            off = self._off()
            state = np.ones(self.B, bool) if on is None else np.asarray(on, bool)
            if not np.array_equal(state, self._models_on):  # the rows' models change only at a switch
                self._models = [mo if state[b] else off[b] for b, mo in enumerate(self._on_models)]
                self._models_on = state.copy()
                if self._laws:  # the friction level goes to the model each row steps
                    self._fl_now = [fl if state[b] else self._off_fl[b] for b, fl in enumerate(self._law_fl)]
                if self._smooth:
                    self._dm_now = [dm if state[b] else self._off_dm[b] for b, dm in enumerate(self._law_dm)]
        if self._laws:
            self._set_friction()
        x_before = self.x
        first = x_before[:, 0] < self._half_period
        in_first = bool(first.any())
        warnings = []
        if in_first:  # count MuJoCo's warnings of this period (the handler chains to the caller's)
            prev = mujoco.get_mju_user_warning()
            mujoco.set_mju_user_warning(lambda msg: (warnings.append(msg), prev and prev(msg)))
        try:
            self.pool.rollout(self._models, self._datas, self.x, self._ctrl, nstep=self.substeps,
                              control_spec=self._control_spec, skip_checks=True, state=self._state,
                              sensordata=self._sens, chunk_size=self._chunk)
        finally:
            if in_first:
                mujoco.set_mju_user_warning(prev)
        self.x = self._state[:, -1, :].copy()
        self.unstable |= self.x[:, 0] < x_before[:, 0] + self._half_period
        if warnings:
            # a reset at a row's very first physics step leaves its time as expected: the rows
            # in their first period are stepped again one by one, each on its own MjData, to see
            # which of them warned
            self.unstable[first] |= [_warns(self._models[b], x_before[b], self._ctrl[b])
                                     for b in np.flatnonzero(first)]
        if self._laws and self._has_sensor.any():
            self._force = np.where(self._has_sensor, self._sens[self._rows, -1, self._sensor_adr], 0.0)

    def _set_friction(self) -> None:
        """Every row's :class:`DriveFriction` level for the coming control period, written into
        the row's own model."""
        if self._data is None:  # a batch: each row's level into the model it steps this period
            self._laws.write(self._law_models, self.x[:, self._vel], self._force, self._fl_now,
                             self._dm_now if self._smooth else None)
            if self._smooth:
                self._ctrl[:, :, self._qfrc_col] = self._laws.applied[:, None]
            return
        # the one row's model is _law_models[0]
        levels = self._laws.write(self._law_models, self.yaw_velocity(), self._force, self._law_fl,
                                  self._law_dm if self._smooth else None)
        dof = self._laws.dof
        if self._off_models is not None:  # the drive off: no force, only the friction level
            for fl, f in zip(self._off_fl, levels):
                fl[dof] = f
            if self._smooth:
                self._off_dm[0][dof] = self._law_dm[0][dof]
        if self._smooth:
            self._data.qfrc_applied[dof] = self._laws.applied[0]


def run_p_loop(engine: Engine, r: np.ndarray, kp, noise: np.ndarray | None = None,
               quantum_rad=0.0, record_arm: bool = False, command_limit=None,
               enabled: np.ndarray | None = None) -> dict:
    """The paper's experiment: the clipped P law closed around the encoder, for every row.

    Parameters
    ----------
    engine : Engine
        B rows at their start states.
    r : ndarray, shape (B, n) [rad]
        References, one sample per control period.
    kp : float or ndarray (B,) [V/rad]
    noise : ndarray, shape (B, n), optional [rad]
        Measurement noise of each sample (:meth:`Encoder.noise`).
    quantum_rad : float or ndarray (B,) [rad]
        Encoder rounding step (0: none).
    record_arm : bool
        Also return the true shoulder/elbow angles (NaN without the Omni's arm).
    command_limit : float or ndarray (B,), optional [V]
        The P law's own saturation (a run's metadata ``command_limit``); default: each drive's
        limit (``ctrlrange``).  The drive still clips what it receives to its ``ctrlrange``, so
        the applied command is clipped at the smaller of the two.
    enabled : ndarray of bool, shape (B, n), optional
        Whether the actuator is on at each period: while False the command is 0 and the drive
        exerts no force (torque off, :meth:`Device.off_model`: the joint swings free).
        Default: always on.

    Returns
    -------
    dict
        ``theta`` (measured, what the controller saw) and ``v`` (applied) of shape ``(B, n)``;
        ``unstable`` (B,) bool: rows MuJoCo found unstable and reset (:attr:`Engine.unstable`;
        their trajectories are not physics); with ``record_arm`` also ``q1``, ``q2`` [rad].
    """
    B, n = r.shape
    kp = np.broadcast_to(np.asarray(kp, dtype=float), (B,))
    theta = np.empty((B, n))
    v = np.empty((B, n))
    if record_arm:
        q1 = np.empty((B, n))
        q2 = np.empty((B, n))
    vmax = engine.vmax
    if command_limit is not None:
        vmax = np.minimum(vmax, np.broadcast_to(np.asarray(command_limit, dtype=float), (B,)))
    on = None if enabled is None else np.broadcast_to(np.asarray(enabled, dtype=bool), (B, n))
    loop = _PLoop(r, kp, noise, quantum_rad, vmax, on)
    if engine.data is None:  # a batch: the same steps as below, without the per-call overheads
        _batch_p_loop(engine, loop, theta, v, (q1, q2) if record_arm else None)
    else:
        _one_row_p_loop(engine, loop, theta, v, (q1, q2) if record_arm else None)
    if not np.all(np.isfinite(theta[~engine.unstable])):
        raise RuntimeError("simulation diverged (non-finite yaw angle)")
    out = {"theta": theta, "v": v, "unstable": engine.unstable.copy()}
    if record_arm:
        out.update(q1=q1, q2=q2)
    return out


@dataclass(frozen=True)
class _PLoop:
    """What :func:`run_p_loop`'s loops read, row by row (see its parameters): the references
    ``r`` (B, n) [rad], the gains ``kp`` (B,) [V/rad], the encoder's ``noise`` (B, n) or None
    and rounding step ``quantum_rad``, the P law's limit ``vmax`` (B,) [V] and the drive's
    ``on`` (B, n) or None (always on)."""
    r: np.ndarray
    kp: np.ndarray
    noise: np.ndarray | None
    quantum_rad: float | np.ndarray
    vmax: np.ndarray
    on: np.ndarray | None

    @property
    def exact(self) -> bool:
        """The controller sees the true yaw (no noise, no rounding)."""
        return self.noise is None and not np.any(np.asarray(self.quantum_rad) > 0)


def _one_row_p_loop(engine, loop: _PLoop, theta, v, arm) -> None:
    """:func:`run_p_loop` on a one-row engine, writing the measured yaw ``theta``, the applied
    command ``v`` and, unless ``arm`` is None, the arm angles ``arm`` (q1, q2), all (B, n)."""
    read = encoder_reader(loop.quantum_rad)
    exact, noise, on = loop.exact, loop.noise, loop.on
    for k in range(loop.r.shape[1]):
        if arm is not None:
            q = engine.qpos()
            th, arm[0][:, k], arm[1][:, k] = q[:, 0], q[:, 1], q[:, 2]
        else:
            th = engine.yaw()
        y = th if exact else read(th, 0.0 if noise is None else noise[:, k])
        theta[:, k] = y
        v[:, k] = engine.apply(p_law(loop.kp, loop.r[:, k], y, loop.vmax),
                               None if on is None else on[:, k])


def _batch_p_loop(engine, loop: _PLoop, theta, v, arm) -> None:
    """:func:`run_p_loop` on a batch engine (the outputs as :func:`_one_row_p_loop`'s): the same
    encoder and P law, reading the state and advancing the batch directly (no per-period
    copies; :meth:`Engine.apply`'s second clip would leave the clipped command as it is)."""
    qa = engine._qadr
    if arm is not None and not engine.has_arm:
        arm[0][:] = np.nan
        arm[1][:] = np.nan
        arm = None
    read = encoder_reader(loop.quantum_rad)
    exact, noise, on = loop.exact, loop.noise, loop.on
    for k in range(loop.r.shape[1]):
        x = engine.x
        th = x[:, qa[0]]
        if arm is not None:
            arm[0][:, k] = x[:, qa[1]]
            arm[1][:, k] = x[:, qa[2]]
        y = th if exact else read(th, 0.0 if noise is None else noise[:, k])
        theta[:, k] = y
        u = p_law(loop.kp, loop.r[:, k], y, loop.vmax)
        if on is not None:
            u = np.where(on[:, k], u, 0.0)
        v[:, k] = u
        engine._advance(u, None if on is None else on[:, k])
