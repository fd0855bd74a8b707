"""The missing torque, seen: what joint torque a model lacks along every logged run, by
inverse dynamics on the smoothed log.

The estimator (:class:`Estimator`, :func:`smooth`)
--------------------------------------------------
The logged angle ``theta_i`` at times ``t_i`` (any spacing, quantised) is interpolated linearly
onto the model's timestep grid ``tau_k = t_0 + k dt`` and smoothed by a Hann window of
half-width ``h``::

    K(s) = (1 + cos(pi s / h)) / (2 h)   for |s| <= h,   q_f = K * theta,

with ``h = 0.360 / f_c`` (:data:`HANN_CUTOFF`), so that the window passes ``1/sqrt(2)`` of a
sine at the stated bandwidth ``f_c`` [Hz].  The states are the discrete derivatives of ``q_f``
at each output time ``tau_k`` (every ``step_s``):

    q = q_f[k],  qd_start = (q_f[k] - q_f[k-1]) / dt,  qdd = (q_f[k+1] - 2 q_f[k] + q_f[k-1]) / dt^2

(``qd_start`` is the velocity at the start of MuJoCo's step, ``qdd`` its acceleration: the
model's own discrete time, so the model's replay gives ``tau_miss`` = 0 up to the noise).  The
logged command ``v`` (linear between log samples, 0 while ``enabled`` is 0) is smoothed by the
same window: *consistent filtering* -- every linear term of ``M qdd + D qd + ... = gear v +
tau_miss`` sees the same low-pass, so the window's attenuation cancels and what is estimated
is ``K * tau_miss``, the missing torque seen through the window (a jump, e.g. a missing Coulomb
level at a reversal, appears as a ramp over ``2 h``).  The model's Coulomb friction is filtered
the same way (below).  The first and last ``h`` of a run give no estimate.

The missing torque (:class:`InverseModel`)
------------------------------------------
At each output time, with the joint at ``(q, qd_start, qdd)`` (any Omni arm held at the run's
equilibrium pose, :meth:`omni_sim.device.Device.start_data`) and the control at the smoothed
command, MuJoCo's ``mj_inverse`` (``mjENBL_INVDISCRETE``: ``qdd`` is the step's velocity
change over ``dt``, the implicit damping accounted for) on a copy of the model whose joint has
no ``frictionloss`` gives ``qfrc_inverse``, and ``mj_fwdActuation`` the model's actuator torque
``qfrc_actuator`` (every actuator on the joint; while ``enabled`` is 0, on the device's
torque-off model, :meth:`~omni_sim.device.Device.off_model`)::

    tau_req = qfrc_inverse - qfrc_actuator          (what friction and the missing torque supply)

The model's Coulomb friction is set-valued, so it is written out here, not left to the
inverse's soft constraint: its level ``F = max(0, frictionloss + drive laws)`` (the device's
:class:`~omni_sim.device.DriveFriction` terms at ``qd_start`` and the transmitted torque), its
direction ``s_f = K * sign(qd)`` and its sticking share ``w_f = K * [|qd| < v_stick]`` on the
fine grid (``v_stick`` = 3 sigma of the velocity estimate), and::

    f = -F s_f + clip(tau_req + F s_f, -F w_f, F w_f),     tau_miss = tau_req - f

(moving: ``f = -F s_f``; stuck through the window: the friction takes whatever it can up to
``F``).  Sign: ``tau_miss > 0`` means the robot needed more torque in +q than the model
provides; a missing Coulomb friction ``Fc`` appears as ``-Fc sign(qd)``, a missing viscous
term ``c`` as ``-c qd``.

Not supported (a one-line error): a model with actuator activation states (a ``dcmotor`` with
LuGre or inductance, filters: ``model.na > 0``) or a delay buffer (their state is not a
function of the logged angle), or a two-mass drive (a hinge tied to the joint by a tendon).

The noise band
--------------
Every state is a linear map of the logged angles, ``x = W theta`` (rows of the interpolation
and the window).  White noise ``sigma`` on each logged angle (``sigma^2 = step^2 / 12 +
noise^2`` from the run's metadata ``encoder_step_rad``/``encoder_noise_rad``, the
:class:`Estimator`'s ``noise_rad``, else 1.4826 MAD of the third differences / sqrt(20))
gives ``tau_miss`` the spread::

    band = 3 sigma || J_q W_q + J_qd W_qd + J_qdd W_qdd ||,

``J`` the derivatives of ``tau_req`` in each state (finite differences through
``mj_inverse``).  The band is the estimator's noise alone: what the window smooths away of a
fast missing torque is not in it (that is the bandwidth's statement).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy import sparse

from identification.errors import UserError

from .. import model as om
from ..device import DRIVE_LAWS, Device
from .runs import ReplayRun

#: ``f_c h`` at which the Hann window of half-width ``h`` passes 1/sqrt(2) of a sine of
#: frequency ``f_c`` (computed numerically; tests/test_torque.py checks it).
HANN_CUTOFF = 0.3601
#: The band's width in standard deviations of the estimator's noise.
BAND_SIGMAS = 3.0


@dataclass(frozen=True)
class Estimator:
    """The derivative estimator's settings.

    Attributes
    ----------
    bandwidth_hz : float [Hz]
        ``f_c``: the window passes 1/sqrt(2) of a sine at ``f_c``; half-width ``h = 0.360 / f_c``.
    step_s : float [s], optional
        Spacing of the output times (default ``h / 4``, rounded to the model's timestep: the
        estimates are smooth on the scale of ``h``).
    noise_rad : float [rad], optional
        The logged angle's noise sigma (default: from the run, see the module docstring).
    """

    bandwidth_hz: float = 5.0
    step_s: float | None = None
    noise_rad: float | None = None

    @property
    def half_window_s(self) -> float:
        return HANN_CUTOFF / self.bandwidth_hz


@dataclass(frozen=True)
class Smoothed:
    """The smoothed states of one run at its output times (model-independent but for the
    timestep): what :class:`InverseModel` reads.  ``W0, W1, W2`` map the logged angles to
    ``q``, ``qd_start``, ``qdd`` (sparse, one row per output time)."""

    name: str
    t: np.ndarray
    q: np.ndarray
    qd_start: np.ndarray
    qdd: np.ndarray
    v: np.ndarray
    on: np.ndarray
    fine: tuple
    trusted: np.ndarray
    weights: tuple
    sigma_rad: float
    dt: float
    pose: tuple
    half_window_s: float

    @property
    def qd(self) -> np.ndarray:
        """Velocity [rad/s] at the output time (the mean of the step's start and end)."""
        return self.qd_start + 0.5 * self.dt * self.qdd


@dataclass(frozen=True)
class MissingTorque:
    """The missing torque along one run (arrays over the output times).

    Attributes
    ----------
    name : str
    t, q, qd, qdd : ndarray [s, rad, rad/s, rad/s^2]
        Output times and the smoothed states.
    tau_motor : ndarray [N*m]
        The model's drive torque (moment arm x ``actuator_force`` of the target actuator,
        ``gear * force`` for a joint transmission; 0 off).
    tau_miss : ndarray [N*m]
        The missing torque (> 0: the robot needed more torque in +q than the model gives).
    band : ndarray [N*m]
        Half-width of the noise band (3 sigma of the estimator's noise).
    trusted : ndarray of bool
        False within ``h`` of a torque on/off switch (the window mixes both drives).
    steady : ndarray of bool
        The window sees one direction of the model's friction and no sticking.  Elsewhere (a
        reversal, a stick) the friction switches inside the window and the estimate carries a
        bias the band does not hold (a few mN*m on the servo pendulum, tests/test_torque.py).
    """

    name: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau_motor: np.ndarray
    tau_miss: np.ndarray
    band: np.ndarray
    trusted: np.ndarray
    steady: np.ndarray

    @property
    def driving(self) -> np.ndarray:
        """Where the drive drives the load (``tau_motor qd > 0``); elsewhere it is back-driven
        (or at rest)."""
        return self.tau_motor * self.qd > 0


def hann_taps(h: float, dt: float) -> np.ndarray:
    """The Hann window ``K(s) = (1 + cos(pi s/h)) / (2h)`` at ``s = j dt``, ``|s| <= h``,
    scaled so that ``sum(K) dt = 1``; returned already multiplied by ``dt`` (taps)."""
    J = max(1, int(math.floor(h / dt)))
    s = np.arange(-J, J + 1) * dt
    k = 1.0 + np.cos(np.pi * s / h)
    return k / k.sum()


def noise_sigma(run: ReplayRun, est: Estimator) -> float:
    """The logged angle's noise sigma [rad] (module docstring: the estimator's, the run's
    metadata, else 1.4826 MAD(third differences) / sqrt(20))."""
    if est.noise_rad is not None:
        return float(est.noise_rad)
    step = run.meta.get("encoder_step_rad")
    if step is not None:
        return math.sqrt(float(step) ** 2 / 12 + float(run.meta.get("encoder_noise_rad", 0.0)) ** 2)
    d3 = np.diff(run.theta, 3)
    return float(1.4826 * np.median(np.abs(d3 - np.median(d3))) / math.sqrt(20.0))


def _interp_matrix(t_fine: np.ndarray, t_log: np.ndarray) -> sparse.csr_matrix:
    """Sparse ``L``: ``L @ y_log`` is ``np.interp(t_fine, t_log, y_log)``."""
    j = np.clip(np.searchsorted(t_log, t_fine, side="right") - 1, 0, len(t_log) - 2)
    f = np.clip((t_fine - t_log[j]) / (t_log[j + 1] - t_log[j]), 0.0, 1.0)
    rows = np.repeat(np.arange(len(t_fine)), 2)
    cols = np.stack([j, j + 1], axis=1).ravel()
    vals = np.stack([1.0 - f, f], axis=1).ravel()
    return sparse.csr_matrix((vals, (rows, cols)), shape=(len(t_fine), len(t_log)))


def _rows(taps: np.ndarray, centres: np.ndarray, nfine: int) -> sparse.csr_matrix:
    """Sparse rows applying ``taps`` (odd length, centred) at the fine indices ``centres``."""
    J = len(taps) // 2
    cols = centres[:, None] + np.arange(-J, J + 1)[None, :]
    rows = np.repeat(np.arange(len(centres)), len(taps))
    return sparse.csr_matrix((np.tile(taps, len(centres)), (rows, cols.ravel())),
                             shape=(len(centres), nfine))


def _derivative_taps(K: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Taps of ``q_f[k]``, ``(q_f[k] - q_f[k-1]) / dt`` and the second difference over
    ``dt^2``, on one common (padded) support."""
    k = np.concatenate([[0.0, 0.0], K, [0.0, 0.0]])
    # q_f[k + m] = sum_j K_j y[k + m + j]: the tap of y[k + i] is K_{i - m} (np.roll by m)
    shifted = {m: np.roll(k, m) for m in (-1, 0, 1)}
    g0 = shifted[0]
    g1 = (shifted[0] - shifted[-1]) / dt
    g2 = (shifted[-1] - 2 * shifted[0] + shifted[1]) / dt ** 2
    return g0, g1, g2


def smooth(run: ReplayRun, dt: float, est: Estimator = Estimator()) -> Smoothed:
    """The smoothed states of ``run`` on the model's timestep ``dt`` (module docstring).

    Raises
    ------
    UserError
        The run is shorter than the window (``2 h``) plus two output steps.
    """
    h = est.half_window_s
    t_log = np.asarray(run.t, float)
    nfine = int(math.floor((t_log[-1] - t_log[0]) / dt + 1e-9)) + 1
    K = hann_taps(h, dt)
    J = len(K) // 2 + 2  # support of the padded derivative taps
    stride = max(1, int(round((est.step_s if est.step_s else h / 4) / dt)))
    # two half-windows from either end: the fine grid's smoothed velocity read by the
    # friction's direction (InverseModel.direction) has its whole window there too
    centres = np.arange(2 * J, nfine - 2 * J, stride)
    if len(centres) < 2:
        raise UserError(f"run {run.name!r} lasts {t_log[-1] - t_log[0]:.3g} s, shorter than twice the "
                        f"estimator's window {2 * h:.3g} s (bandwidth {est.bandwidth_hz:g} Hz): "
                        "raise the bandwidth or use a longer run")
    t_fine = t_log[0] + np.arange(nfine) * dt
    L = _interp_matrix(t_fine, t_log)
    W = tuple((_rows(g, centres, nfine) @ L).tocsr() for g in _derivative_taps(K, dt))
    theta = np.asarray(run.theta, float)
    on_fine = _held(run, t_fine)
    v_fine = np.where(on_fine, np.interp(t_fine, t_log, np.asarray(run.v, float)), 0.0)
    G0 = _rows(K, centres, nfine)
    sigma = noise_sigma(run, est)
    # the command is known at the log times only: a log coarser than the control period
    # misses its sample-to-sample noise (a quantised P loop's), taken as white noise of the
    # logged command (1.4826 MAD of the third differences / sqrt(20)) through the same window
    sig_cmd = 0.0
    if run.dt > 1.01 * run.period:
        d3 = np.diff(np.asarray(run.v, float), 3)
        sig_cmd = float(1.4826 * np.median(np.abs(d3 - np.median(d3))) / math.sqrt(20.0))
    W = W + (((G0 @ L).tocsr(), sig_cmd),)
    q_f = np.convolve(L @ theta, K, mode="same")  # the fine grid's smoothed angle
    vel = np.diff(q_f, prepend=q_f[0]) / dt  # start-of-step velocity
    acc = np.diff(vel, append=vel[-1]) / dt
    fine = (G0, vel, acc, sigma * float(np.mean(_row_norms(W[1]))),
            sigma * float(np.mean(_row_norms(W[2]))))
    switch = np.flatnonzero(np.diff(on_fine.astype(int)) != 0)
    trusted = np.ones(len(centres), bool)
    for s in switch:
        trusted &= np.abs(centres - s) > len(K) // 2 + 1
    return Smoothed(run.name, t_fine[centres], W[0] @ theta, W[1] @ theta, W[2] @ theta,
                    G0 @ v_fine, on_fine[centres], fine, trusted, W, sigma, dt,
                    tuple(run.gamma_set_deg), h)


def _held(run: ReplayRun, t_fine: np.ndarray) -> np.ndarray:
    """``enabled`` on the fine grid: that of the last logged sample at or before each time
    (a servo holds its switch between host writes; all True without the column)."""
    if run.enabled is None:
        return np.ones(len(t_fine), bool)
    i = np.clip(np.searchsorted(run.t, t_fine + 1e-9, side="right") - 1, 0, len(run.t) - 1)
    return np.asarray(run.enabled, bool)[i]


def _row_norms(W: sparse.csr_matrix) -> np.ndarray:
    return np.sqrt(np.asarray(W.multiply(W).sum(axis=1)).ravel())


class InverseModel:
    """A model's inverse dynamics along smoothed runs (module docstring).

    Parameters
    ----------
    model : MjModel
        The (corrected nominal) model; not modified.
    target : omni_sim.model.Target, optional
        Its controlled joint and actuator (default None: the Omni's ``yaw``/``yaw_motor``).

    Attributes
    ----------
    calls : int
        ``mj_inverse`` calls made so far (the cost).

    Raises
    ------
    UserError
        The model has activation states, a delay buffer or a two-mass drive (not a function
        of the logged angle: replay it instead).
    """

    def __init__(self, model: mujoco.MjModel, target: om.Target | None = None):
        self.device = dev = Device(model, target=target)
        check_supported(model, dev)
        self.dof, self.act = dev.ix.yaw_dof, dev.ix.yaw_act
        self.qadr = dev.ix.yaw_qpos
        self.frictionloss = float(model.dof_frictionloss[self.dof])
        self.on_model = self._inverse_copy(model)
        self.off_model = self._inverse_copy(dev.off_model())
        self.data = mujoco.MjData(self.on_model)
        self.rate = friction_rate(model, self.dof)
        self.calls = 0

    def _inverse_copy(self, model: mujoco.MjModel) -> mujoco.MjModel:
        m = copy.deepcopy(model)
        m.dof_frictionloss[self.dof] = 0.0  # the Coulomb friction is written out (set-valued)
        m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_INVDISCRETE
        return m

    def _start(self, sm: Smoothed) -> None:
        """The data at the run's pose: the other joints still, the arm servos at their set points."""
        d0 = self.device.start_data(float(sm.q[0]), sm.pose or None)
        self.data.qpos[:] = d0.qpos
        self.data.ctrl[:] = d0.ctrl
        self.data.qvel[:] = 0.0
        self.data.qacc[:] = 0.0

    def required(self, sm: Smoothed, q=None, qd=None, qdd=None, ctrl=None) -> tuple[np.ndarray, np.ndarray]:
        """``tau_req = qfrc_inverse - qfrc_actuator`` [N*m] and the drive's torque
        ``tau_motor`` at each output time (states and command default to the smoothed ones)."""
        ctrl = sm.v if ctrl is None else ctrl
        q = sm.q if q is None else q
        qd = sm.qd_start if qd is None else qd
        qdd = sm.qdd if qdd is None else qdd
        self._start(sm)
        d, dof, act = self.data, self.dof, self.act
        req, motor = np.empty(len(q)), np.empty(len(q))
        for i in range(len(q)):
            m = self.on_model if sm.on[i] else self.off_model
            d.qpos[self.qadr], d.qvel[dof], d.qacc[dof] = q[i], qd[i], qdd[i]
            d.ctrl[act] = ctrl[i] if sm.on[i] else 0.0
            mujoco.mj_inverse(m, d)
            mujoco.mj_fwdActuation(m, d)
            req[i] = d.qfrc_inverse[dof] - d.qfrc_actuator[dof]
            motor[i] = _moment(d, act, dof) * d.actuator_force[act]
        self.calls += len(q)
        return req, motor

    def level(self, sm: Smoothed, motor: np.ndarray) -> np.ndarray:
        """The model's Coulomb level ``F`` [N*m]: ``frictionloss`` plus the drive laws."""
        F = np.full(len(motor), self.frictionloss)
        law = self.device.drive_friction
        if law is not None:
            for name, values in law.values.items():
                vals = np.tile(np.asarray(values, float), (len(motor), 1))
                F = F + DRIVE_LAWS[name].term(vals, sm.qd_start, motor)
        return np.maximum(F, 0.0)

    def direction(self, sm: Smoothed) -> tuple[np.ndarray, np.ndarray]:
        """The friction's direction ``s_f = K * sign(qdd + B qd)`` and sticking share
        ``w_f = K * [|qdd + B qd| < 3 sigma]`` at the output times (fine grid, module docstring)."""
        G0, vel, acc, sig_v, sig_a = sm.fine
        jar = acc + self.rate * vel
        stuck = np.abs(jar) < max(BAND_SIGMAS * math.hypot(sig_a, self.rate * sig_v), 1e-9)
        return G0 @ np.where(stuck, 0.0, np.sign(jar)), G0 @ stuck.astype(float)

    def missing(self, sm: Smoothed) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``tau_miss`` [N*m], ``tau_motor`` [N*m] and ``steady`` (the window sees one
        friction direction and no sticking: ``|s_f| > 0.99``, ``w_f < 0.01``) at the output times."""
        req, motor = self.required(sm)
        F = self.level(sm, motor)
        s_f, w_f = self.direction(sm)
        moving = -F * s_f
        f = moving + np.clip(req - moving, -F * w_f, F * w_f)
        return req - f, motor, (np.abs(s_f) > 0.99) & (w_f < 0.01)

    def band(self, sm: Smoothed) -> np.ndarray:
        """The noise band [N*m] (module docstring): 3 sigma of ``tau_req`` from the logged
        angle's and command's noise, through finite-difference derivatives in each."""
        base, _ = self.required(sm)
        jac = []
        for k, step in enumerate((1e-6, 1e-4, 1e-2, 1e-3)):
            x = [sm.q, sm.qd_start, sm.qdd, sm.v]
            x[k] = x[k] + step
            jac.append((self.required(sm, *x)[0] - base) / step)
        comb = sum(sparse.diags(j) @ w for j, w in zip(jac[:3], sm.weights[:3]))
        var = (sm.sigma_rad * _row_norms(comb.tocsr())) ** 2
        var += (sm.weights[3][1] * jac[3] * _row_norms(sm.weights[3][0])) ** 2
        return BAND_SIGMAS * np.sqrt(var)


def _moment(d: mujoco.MjData, act: int, dof: int) -> float:
    """The actuator's moment arm on the joint (its gear for a joint transmission), from
    MuJoCo's sparse ``actuator_moment`` (position stage done)."""
    adr, nnz = int(d.moment_rowadr[act]), int(d.moment_rownnz[act])
    for k in range(adr, adr + nnz):
        if d.moment_colind[k] == dof:
            return float(d.actuator_moment[k])
    return 0.0


def friction_rate(model: mujoco.MjModel, dof: int) -> float:
    """``B`` [1/s]: MuJoCo's ``frictionloss`` row drives the joint's velocity towards 0 with the
    reference acceleration ``-B qd`` (``efc_aref / efc_vel`` of the row; 105/s with the default
    ``solref``), so its force opposes ``qdd + B qd``, not ``qd`` alone: braking harder than
    ``B qd`` the friction pushes along the motion."""
    m = copy.deepcopy(model)
    m.dof_frictionloss[dof] = max(float(m.dof_frictionloss[dof]), 1.0)  # the row must exist
    d = mujoco.MjData(m)
    d.qvel[dof] = 1.0
    mujoco.mj_forward(m, d)
    for r in range(d.nefc):
        if d.efc_type[r] == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF and d.efc_id[r] == dof:
            return float(-d.efc_aref[r] / d.efc_vel[r])
    raise ValueError("no frictionloss row for the joint")  # cannot happen: frictionloss > 0


def check_supported(model: mujoco.MjModel, device: Device) -> None:
    """Raise UserError if the model has state that the logged angle does not fix."""
    if model.na > 0:
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or str(a)
                 for a in range(model.nu) if model.actuator_actnum[a] > 0]
        raise UserError(f"the model's actuators {names} have activation states (LuGre, inductance, "
                        "filters): the missing torque cannot be seen by inverse dynamics; compare "
                        "replays instead (omni discrepancy)")
    if model.nhistory > 0 or np.any(model.actuator_delay > 0):
        raise UserError("the model has a delay buffer: its torque depends on past commands the "
                        "inverse does not replay; compare replays instead (omni discrepancy)")
    if device.coupled:
        raise UserError("the model has a two-mass drive (a hinge tied to the joint by a tendon): "
                        "its rotor's state is hidden; compare replays instead (omni discrepancy)")


def missing_torque(model: mujoco.MjModel, runs: list[ReplayRun], target: om.Target | None = None,
                   est: Estimator = Estimator()) -> list[MissingTorque]:
    """The torque ``model`` lacks along each run (module docstring).

    Parameters
    ----------
    model : MjModel
        The (corrected nominal) model.
    runs : list of ReplayRun
        Prepared runs (:func:`omni_sim.discrepancy.replay.prepare_runs`).
    target : Target, optional
        The controlled joint and actuator (default None: the Omni).
    est : Estimator

    Returns
    -------
    list of MissingTorque
    """
    inv = InverseModel(model, target)
    out = []
    for run in runs:
        sm = smooth(run, float(model.opt.timestep), est)
        tau, motor, steady = inv.missing(sm)
        out.append(MissingTorque(run.name, sm.t, sm.q, sm.qd, sm.qdd, motor, tau, inv.band(sm),
                                 sm.trusted, steady))
    return out
