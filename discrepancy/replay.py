"""Replay measured runs on a model: the closed yaw loop, batched over runs and models.

Each measured run is replayed as the device ran it (the project's time convention, see
:mod:`omni_sim.experiments`): the arm servos get the run's set points (``gamma1_set_deg``,
``gamma2_set_deg``; the actual angles if set points are absent) and the arm starts at the
model's equilibrium for them; the yaw starts at rest at the measured ``theta[0]``; at every
control period the model's yaw angle ``theta_k`` is read, ``v_k = kp (r_k - theta_k)`` clipped
to the drive's ``ctrlrange`` is written to ``yaw_motor`` and held for the period; while the
run's ``enabled`` column is 0 (torque off) the command is 0 and the drive is switched off
(:meth:`~omni_sim.device.Device.off_model`: the actuator's gain and bias zeroed, a ``dcmotor``'s
motor constant: no torque and no back-EMF braking, the joint swings free).

The control period is the device's own (run metadata ``control_period_s``, default the sample
period), independent of the log's: a servo logged at 200 Hz that closes its loop at 1 kHz is
replayed at 1 kHz, the reference held between log samples, and compared at the logged times
(:class:`~discrepancy.runs.ReplayRun`: the control grid, irregular timestamps).

A user's single-joint device (a :class:`~omni_sim.model.Target`: its hinge and actuator) is
replayed the same way: without the Omni's arm a run needs no pose; its P law saturates at the
run's ``command_limit`` (metadata, in the actuator's control units) if given, and the drive
clips at the actuator's ``ctrlrange`` in any case.

The loop is the device's (:mod:`omni_sim.device`): its start state, encoder, clipped P law and
closed-loop :class:`~omni_sim.device.Engine`, which advances the whole batch one period at a time
with :class:`mujoco.rollout.Rollout` (C, threads), so any MJCF effect of ``yaw_motor`` -- a
filter (``dyntype``), a ``delay`` with its ``nsample`` buffer, a ``forcerange`` or a bias --
acts on the command exactly as on the device.  One batch holds every (model, run) pair, so the
models of a finite-difference Jacobian or a parameter grid are simulated together.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict

import mujoco
import numpy as np
from mujoco import rollout

from identification.dataset import Run
from identification.errors import UserError

from omni_sim import model as om
from omni_sim.device import Device, Engine, default_threads, run_p_loop, substeps_of
from .runs import ReplayRun

#: Shortest run that can be replayed and localised [s]: one step edge's transient at the
#: Omni's ~3.4 Hz resonance.
MIN_DURATION_S = 0.2
#: Fewest logged samples a run needs (a 50 Hz log of 0.2 s has 10).
MIN_SAMPLES = 10
#: Relative tolerance within which runs share one control period [-] (text round trip).
PERIOD_RTOL = 1e-6


def control_period_of(runs: list[Run], source: str = "measured data") -> float:
    """The control period [s] of a set of runs: each run's metadata ``control_period_s``, else
    its sample period (``Run.dt``); one period for all runs (they are replayed in one batch).

    Raises
    ------
    UserError
        The runs do not share one control period.
    """
    if not runs:
        raise UserError(f"{source}: no runs")
    periods = {}
    for run in runs:
        c = run.meta.get("control_period_s")
        periods[run.name] = float(c) if c is not None else run.dt
    first = next(iter(periods.values()))
    odd = {k: v for k, v in periods.items() if abs(v - first) > PERIOD_RTOL * first}
    if odd:
        name, val = next(iter(odd.items()))
        raise UserError(f"{source}: runs have different control periods ({runs[0].name!r}: {first:g} s, "
                        f"{name!r}: {val:g} s); give each run's metadata the device's loop period "
                        "control_period_s, or replay them separately")
    return first
#: Samples of replayed trajectories a :class:`Replayer` keeps (8 bytes each), so a (model, run)
#: pair replayed again (a grid point that is also the fit's start, a fit's end point scored
#: again) is not simulated twice.
CACHE_SAMPLES = 4_000_000
#: Control periods (rows x periods) one batch of the replay simulates at most: a parameter
#: grid of thousands of models on long runs is stepped in batches of this size, so that its
#: command, angle and reference arrays (8 bytes each) stay near 32 MB each.
BATCH_SAMPLES = 4_000_000
#: Devices (compiled models with their start-state caches) a :class:`Replayer` keeps: 64, the
#: models of a few batches (a fit's point and its perturbations, a fold's).  Each holds its
#: compiled model, a scratch ``MjData`` and its torque-off copy: 0.66 MB measured for the
#: geared-servo pendulum, so the former 512 held 340 MB; a device evicted is rebuilt (its model
#: is compiled already; the start state is a few ``mj_forward`` calls).
MAX_DEVICES = 64


def prepare_runs(runs: list[Run], device: Device, source: str = "measured data") -> list[ReplayRun]:
    """Check that every run can be replayed on ``device`` and convert it.

    The device's target (None: the Omni) names the controlled joint and actuator.  A model with the
    Omni's arm needs each run's pose (``gamma1_set_deg``/``gamma2_set_deg`` or
    ``gamma1_deg``/``gamma2_deg``); without the arm a pose is not needed (any given is ignored).
    An optional ``command_limit`` (positive; the P law's saturation) is checked and kept in
    the run's ``meta``.  The runs' control period (:func:`control_period_of`) must be a whole
    multiple of the model's timestep; the device's own period is not used (the runs say theirs).

    Raises
    ------
    UserError
        A run is too short, has no usable ``kp``, a control period that is not a whole multiple
        of the model's timestep, a pose outside the model's joint ranges (or none where the
        model has the arm), or a ``command_limit`` that is not a positive number.
    """
    period = control_period_of(runs, source)
    model, has_arm = device.model, device.ix.has_arm
    try:
        substeps_of(model, period)
    except UserError as exc:
        raise UserError(f"{source}: {exc} (metadata control_period_s, default the sample period)") from None
    out = []
    for run in runs:
        where = f"{source}: run {run.name!r}"
        if len(run.t) < MIN_SAMPLES or run.t[-1] - run.t[0] < MIN_DURATION_S:
            raise UserError(f"{where} has {len(run.t)} samples over {run.t[-1] - run.t[0]:.3g} s; at "
                            f"least {MIN_SAMPLES} samples over {MIN_DURATION_S:g} s are needed to "
                            "localise anything")
        kp = run.meta.get("kp")
        if isinstance(kp, bool) or not isinstance(kp, (int, float)) or not (kp > 0 and math.isfinite(kp)):
            raise UserError(f"{where}: kp must be a positive number, got {kp!r}")
        dt = float(run.dt)
        meta = dict(run.meta)
        lim = meta.get("command_limit")
        if lim is not None:
            if (isinstance(lim, bool) or not isinstance(lim, (int, float))
                    or not (lim > 0 and not math.isnan(lim))):
                raise UserError(f"{where}: command_limit must be a positive number (the P law's "
                                f"saturation in the actuator's control units), got {lim!r}")
            meta["command_limit"] = float(lim)
        if has_arm:
            g1 = run.meta.get("gamma1_set_deg", run.meta.get("gamma1_deg"))
            g2 = run.meta.get("gamma2_set_deg", run.meta.get("gamma2_deg"))
            for name, val in (("gamma1", g1), ("gamma2", g2)):
                if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
                    raise UserError(f"{where}: metadata needs a finite {name}_set_deg or {name}_deg, got {val!r}")
            try:
                device.check_pose(float(g1), float(g2))
            except UserError as exc:
                raise UserError(f"{where}: unknown pose for this model ({exc})") from None
            pose = (float(g1), float(g2))
        else:
            pose = ()
        out.append(ReplayRun(run.name, run.kind, np.asarray(run.t, float), np.asarray(run.r, float),
                             np.asarray(run.theta, float), np.asarray(run.v, float), dt, float(kp),
                             pose, float(run.meta.get("frequency_hz", 0.0)),
                             float(run.meta.get("amplitude_rad", 0.0)), meta, period,
                             None if run.enabled is None else np.asarray(run.enabled, bool)))
    return out


class Replayer:
    """Closed-loop replay of many runs on many models in one batch.

    Parameters
    ----------
    nthread : int, optional
        Threads of the rollout pool (default: :func:`omni_sim.device.default_threads`).
    target : omni_sim.model.Target, optional
        The controlled joint and actuator of the devices built (default None: the Omni).
    control_period_s : float [s], optional
        The devices' loop period (default: the Omni's 1 ms); the runs replayed must have it
        (:attr:`ReplayRun.period`, set by :func:`prepare_runs`).

    Use as a context manager, or call :meth:`close` to stop the thread pool.
    """

    def __init__(self, nthread: int | None = None, target: om.Target | None = None,
                 control_period_s: float | None = None):
        self.nthread = max(1, nthread or default_threads())
        self.target = target
        self.control_period_s = control_period_s
        # one thread: rollouts run on the calling thread (Rollout(nthread=0)), not handed to a
        # one-thread pool at every control period; the trajectories are the same
        self._pool = rollout.Rollout(nthread=self.nthread if self.nthread > 1 else 0)
        self._devices: OrderedDict = OrderedDict()
        self.steps = 0  # physics steps simulated so far (for timings)
        self.unstable_warnings = 0  # MuJoCo's instability warnings during replays
        #: replays (model, run pairs) MuJoCo found unstable: returned as NaN, never scored
        self.unstable_replays = 0
        self.first_warning = ""
        # replayed trajectories by (model content, run content), least recently used first
        self._traj: OrderedDict = OrderedDict()
        self._traj_samples = 0
        self._runs: dict = {}

    def __enter__(self):
        return self

    def _warned(self, msg: str) -> None:
        self.unstable_warnings += 1
        if not self.first_warning:
            self.first_warning = " ".join(str(msg).split())

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        self._pool.close()

    def device(self, model: mujoco.MjModel) -> Device:
        """The device of ``model`` (built once per model object; keeps its equilibrium poses)."""
        return self._entry(model)[0]

    def _entry(self, model: mujoco.MjModel) -> list:
        key = id(model)
        if key not in self._devices:
            # [device, model (kept alive with its id), content digest (made when first needed)]
            period = self.control_period_s
            dev = (Device(model, target=self.target) if period is None
                   else Device(model, period, target=self.target))
            self._devices[key] = [dev, model, None]
        else:
            self._devices.move_to_end(key)
        # the least recently used devices go (each keeps its compiled model alive): a fit
        # compiles a model per parameter point, thousands over a workflow
        while len(self._devices) > MAX_DEVICES:
            self._devices.popitem(last=False)
        return self._devices[key]

    def _model_key(self, model: mujoco.MjModel) -> bytes:
        """Digest of everything the compiled model holds (``mj_saveModel``'s bytes): two
        models with the same digest simulate alike, bit for bit."""
        e = self._entry(model)
        if e[2] is None:
            buf = np.empty(mujoco.mj_sizeModel(model), np.uint8)
            mujoco.mj_saveModel(model, None, buf)
            e[2] = hashlib.blake2b(buf, digest_size=20).digest()
        return e[2]

    def _run_key(self, run: ReplayRun) -> tuple:
        """What the replay of ``run`` depends on: start angle, set points, kp, the P law's
        saturation, the reference and switch on the control grid."""
        e = self._runs.get(id(run))
        if e is None or e[1] is not run or len(run.r) != e[2]:
            r, on = run.grid_inputs()
            h = hashlib.blake2b(np.ascontiguousarray(r, dtype=float), digest_size=20)
            if on is not None:
                h.update(np.ascontiguousarray(on, dtype=np.uint8))
            key = (float(run.theta[0]), tuple(float(g) for g in run.gamma_set_deg), float(run.kp),
                   run.command_limit, len(r), on is not None, h.digest())
            e = self._runs[id(run)] = (key, run, len(run.r))  # the run kept alive with its id
        return e[0]

    def initial_state(self, model: mujoco.MjModel, run: ReplayRun) -> tuple[np.ndarray, np.ndarray]:
        """Full physics state and ctrl vector at the start of ``run`` on ``model``."""
        return self.device(model).start_state(float(run.theta[0]), run.gamma_set_deg)

    def simulate(self, models: list[mujoco.MjModel], runs: list[ReplayRun],
                 pairs: list[tuple[int, int]] | None = None,
                 measurement: tuple[list[np.ndarray], list[float]] | None = None) -> list[np.ndarray]:
        """Replay runs on models; return the model's yaw angle [rad] per pair.

        Parameters
        ----------
        models : list of MjModel
            Models with the same size signature (same candidate structure).
        runs : list of ReplayRun
        pairs : list of (model index, run index), optional
            What to simulate (default: every run on every model, model-major).
        measurement : (list of ndarray, list of float), optional
            A simulated measurement process ``(noise, step)`` per pair: the controller then sees
            ``y_k = step * round((theta_k + noise_k) / step)`` (no rounding if ``step`` is 0), as
            a device with a noisy, quantised encoder, and ``y`` is returned instead of ``theta``
            (it is what the device would log).  Used to propagate the measurement process
            through the closed loop (:func:`discrepancy.uncertainty.measurement_effect`).

            Noise arrays are on the control grid (``runs[j].steps`` samples).

        Returns
        -------
        list of ndarray
            ``theta`` [rad] of each pair at the run's logged times (``theta[0]`` = measured
            start).
        """
        if pairs is None:
            pairs = [(i, j) for i in range(len(models)) for j in range(len(runs))]
        if not pairs:
            return []
        lengths = [runs[j].steps for _, j in pairs]
        nmax = max(lengths)
        if measurement is not None:  # a simulated measurement process: never reused
            theta = self._simulate(models, runs, pairs, nmax, measurement)
            return [runs[j].at_logged_times(theta[b]) for b, (_, j) in enumerate(pairs)]
        # every pair is simulated for nmax samples (a shorter run's reference holds its last
        # value, as in one batch of all pairs); a trajectory kept from an earlier batch of at
        # least nmax samples is the same trajectory, and a pair repeated in this batch is
        # simulated once
        keys = [(self._model_key(models[i]), self._run_key(runs[j])) for i, j in pairs]
        where: dict = {}  # key -> the pairs that ask for it
        for b, key in enumerate(keys):
            where.setdefault(key, []).append(b)
        out: list = [None] * len(pairs)
        todo = []
        for key, bs in where.items():
            hit = self._traj.get(key)
            if hit is None or len(hit) < nmax:
                todo.append(key)
            else:
                self._traj.move_to_end(key)
                for b in bs:
                    out[b] = runs[pairs[b][1]].at_logged_times(hit)
        # the pairs to simulate, in batches of at most BATCH_SAMPLES control periods in all
        # (each row's trajectory is its own: batching changes nothing but the memory held)
        per = max(1, BATCH_SAMPLES // nmax)
        for c in range(0, len(todo), per):
            chunk = todo[c: c + per]
            theta = self._simulate(models, runs, [pairs[where[key][0]] for key in chunk], nmax, None)
            for key, th in zip(chunk, theta):
                for b in where[key]:
                    out[b] = runs[pairs[b][1]].at_logged_times(th)
                old = self._traj.pop(key, None)
                if old is not None:
                    self._traj_samples -= len(old)
                self._traj[key] = th.copy()
                self._traj_samples += nmax
            while self._traj_samples > CACHE_SAMPLES and len(self._traj) > 1:
                self._traj_samples -= len(self._traj.popitem(last=False)[1])
        return out

    def batch_signature(self, model: mujoco.MjModel) -> tuple:
        """What models must share to be stepped in one batch: the device engine's conditions
        (state size, substeps, the joint and actuator addresses) and the rollout's (controls,
        sensors)."""
        dev = self.device(model)
        return (dev.nstate, dev.substeps, dev.ix, model.nu, model.nsensordata)

    def simulate_grouped(self, models: list[mujoco.MjModel], runs: list[ReplayRun],
                         pairs: list[tuple[int, int]]) -> list[np.ndarray]:
        """:meth:`simulate` of ``pairs`` whose models may differ in structure: one batch per
        group of models that can share a batch (:meth:`batch_signature`); results in pair
        order."""
        groups: dict = {}
        for b, (i, _) in enumerate(pairs):
            groups.setdefault(self.batch_signature(models[i]), []).append(b)
        out: list = [None] * len(pairs)
        for rows in groups.values():
            th = self.simulate(models, runs, [pairs[b] for b in rows])
            for b, theta in zip(rows, th):
                out[b] = theta
        return out

    def _simulate(self, models, runs, pairs, nmax: int, measurement) -> np.ndarray:
        """One batch of ``pairs`` through the device engine for ``nmax`` samples, shape (B, nmax)."""
        B = len(pairs)
        rmat = np.empty((B, nmax))
        on = None
        kp = np.empty(B)
        limit = np.empty(B)
        for b, (_, j) in enumerate(pairs):
            rmat[b], onb = runs[j].grid_inputs(nmax)
            if onb is not None:
                if on is None:
                    on = np.ones((B, nmax), bool)
                on[b] = onb
            kp[b] = runs[j].kp
            limit[b] = runs[j].command_limit
        noise, qstep = None, 0.0
        if measurement is not None:
            noise = np.zeros((B, nmax))
            for b in range(B):
                nb = measurement[0][b]
                noise[b, : len(nb)] = nb[:nmax]
            qstep = np.asarray(measurement[1], dtype=float)
        devices = [self.device(models[i]) for i, _ in pairs]
        for (_, j), dev in zip(pairs, devices):
            if abs(runs[j].period - dev.dt) > 1e-6 * dev.dt:
                raise ValueError(f"run {runs[j].name!r} has control period {runs[j].period:g} s, the "
                                 f"replayer's devices {dev.dt:g} s (Replayer(control_period_s=...))")
        engine = Engine(devices,
                        [float(runs[j].theta[0]) for _, j in pairs],
                        [runs[j].gamma_set_deg for _, j in pairs],
                        nthread=self.nthread, pool=self._pool)
        # MuJoCo reports an unstable state (and resets that row's data) through its warning
        # handler, from the rollout's threads; by default it prints and appends to
        # MUJOCO_LOG.TXT in the working folder.  A candidate's parameter can make the model
        # unstable (a stiff cable on a light rotor): the warnings are counted
        # (``unstable_warnings``), not printed, and the rows the engine flagged unstable are
        # returned as NaN (``unstable_replays``): a reset trajectory is not physics, and the
        # statistics exclude it (:func:`discrepancy.fit.gap` is inf) instead of scoring it.
        prev = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(self._warned)
        try:
            out = run_p_loop(engine, rmat, kp, noise, qstep,
                             command_limit=None if np.all(np.isinf(limit)) else limit,
                             enabled=on)
        except RuntimeError:
            raise RuntimeError("replay diverged (non-finite yaw angle)") from None
        finally:
            mujoco.set_mju_user_warning(prev)
        theta = out["theta"]
        theta[out["unstable"]] = np.nan
        self.unstable_replays += int(np.count_nonzero(out["unstable"]))
        self.steps += B * nmax
        return theta
