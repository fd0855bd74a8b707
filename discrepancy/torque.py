"""The missing torque, seen: what joint torque a model lacks along every logged run, by
inverse dynamics on the smoothed log.

The states come from :mod:`.smoothing`: the logged angle and command smoothed by one Hann
window of a stated bandwidth (consistent filtering), their discrete-time derivatives in the
model's timestep; what is estimated is the missing torque seen through that window.

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
direction and sticking share on the fine grid, through the window::

    s_f = K * sign(qdd + B qd),     w_f = K * [|qdd + B qd| < 3 sigma]

(``qd``, ``qdd`` here from the angle smoothed by a window :data:`~.smoothing.STICK_SHARE` as
wide: the smoothing's own window would leak a motion's onset back by its half-width and count
the rest before a step as sliding)
A smooth load law (:data:`omni_sim.device.LOAD_FRICTION_SMOOTH`) is single-valued: its force
``-mu |tau| tanh(qd / w_s)`` is the model's own torque too, its level at ``qd_start`` and the
transmitted torque, its sign on the fine grid through the window (:meth:`InverseModel.smooth_force`).

(MuJoCo's ``frictionloss`` row is a bounded servo of the velocity towards 0 with reference
acceleration ``-B qd``, :func:`friction_rate`: it opposes ``qdd + B qd``, not ``qd`` alone, so
braking harder than ``B qd`` it pushes along the motion; sigma: the noise of ``qdd + B qd``),
and::

    f = -F s_f + clip(tau_req + F s_f, -F w_f, F w_f),     tau_miss = tau_req - f

(moving: ``f = -F s_f``; stuck through the window: the friction takes whatever it can up to
``F``).  Sign: ``tau_miss > 0`` means the robot needed more torque in +q than the model
provides; a missing Coulomb friction ``Fc`` appears as ``-Fc sign(qd)``, a missing viscous
term ``c`` as ``-c qd``.

A passive LuGre ``dcmotor`` on the joint (the Omni's ``yaw_friction``) has a bristle state that
is not a function of the logged angle: its torque is integrated along the run's smoothed
velocity (:mod:`.bristles`), seen through the window, and taken from ``tau_req`` as the model's
own; the inverse's copy leaves it out (its gear 0).

Not supported (a one-line error): any other actuator activation state (a ``dcmotor`` with
inductance, filters) or a delay buffer (their state is not a function of the logged angle), or
a two-mass drive (a hinge tied to the joint by a tendon).

The noise band
--------------
Every state is a linear map of the logged angles, ``x = W theta`` (:mod:`.smoothing`).  White noise ``sigma`` on each logged angle (``sigma^2 = step^2 / 12 +
noise^2`` from the run's metadata ``encoder_step_rad``/``encoder_noise_rad``, the
:class:`Estimator`'s ``noise_rad``, else 1.4826 MAD of the third differences / sqrt(20), at
least the quantisation noise of the smallest step the log takes)
gives ``tau_miss`` the spread::

    band = 3 sqrt( sigma^2 || J_q W_q + J_qd W_qd + J_qdd W_qdd ||^2 + (sigma_v J_v ||W_v||)^2 ),

``J`` the derivatives of ``tau_req`` in each state and the command (finite differences through
``mj_inverse``); ``sigma_v`` the logged command's noise when the log is coarser than the
control period (the command between log samples is unknown: a quantised P loop's command
jumps by ``kp`` times a count every period), 1.4826 MAD of its third differences / sqrt(20).  The band is the estimator's noise alone: what the window smooths away of a
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

from omni_sim import model as om
from omni_sim.device import DRIVE_LAWS, Device, smooth_load_level
from . import bristles
from .runs import ReplayRun
from .smoothing import BAND_SIGMAS, HANN_CUTOFF, Estimator, Smoothed, hann_taps, row_norms, smooth

__all__ = ["BAND_SIGMAS", "HANN_CUTOFF", "Estimator", "Smoothed", "MissingTorque", "InverseModel",
           "hann_taps", "smooth", "missing_torque", "check_supported", "friction_rate"]


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


class InverseModel:
    """A model's inverse dynamics along smoothed runs (module docstring).

    Parameters
    ----------
    model : MjModel
        The (corrected nominal) model; not modified.
    target : omni_sim.model.Target, optional
        Its controlled joint and actuator (default None: the Omni's ``yaw``/``yaw_motor``).
    bristle_cache : dict, optional
        Where the LuGre torque of each smoothed run is kept, by the bristles' parameters (share
        one between models that differ elsewhere).

    Attributes
    ----------
    calls : int
        ``mj_inverse`` calls made so far (the cost).

    Raises
    ------
    UserError
        The model has activation states other than a LuGre drive's bristles, a delay buffer
        or a two-mass drive (not a function of the logged angle: replay it instead).
    """

    def __init__(self, model: mujoco.MjModel, target: om.Target | None = None, bristle_cache: dict | None = None):
        self.device = dev = Device(model, target=target)
        check_supported(model, dev)
        self.dof, self.act = dev.ix.yaw_dof, dev.ix.yaw_act
        self.qadr = dev.ix.yaw_qpos
        self.frictionloss = float(model.dof_frictionloss[self.dof])
        self.lugre_ids = bristles.with_bristles(model, dev.lugre_actuators())
        self.lugre = [bristles.parameters(model, a) for a in self.lugre_ids]
        # the LuGre torque of a smoothed run depends only on the bristles' parameters: models
        # that share them (the candidates of one evidence) can share one cache
        self._bristle_cache = {} if bristle_cache is None else bristle_cache
        self.on_model = self._inverse_copy(model)
        self.off_model = self._inverse_copy(dev.off_model())
        self.data = mujoco.MjData(self.on_model)
        self.rate = friction_rate(model, self.dof)
        # a firmware current limit (omni_sim.device.CURRENT_LIMIT) bounds the actuator's force
        # with the velocity, as the engine sets it at every control period
        law = dev.drive_friction
        self.limited_drive = law if law is not None and law.limit is not None else None
        self.calls = 0

    def _inverse_copy(self, model: mujoco.MjModel) -> mujoco.MjModel:
        m = copy.deepcopy(model)
        m.dof_frictionloss[self.dof] = 0.0  # the Coulomb friction is written out (set-valued)
        for a in self.lugre_ids:  # and the LuGre bristles (:meth:`bristle_torque`)
            m.actuator_gear[a, 0] = 0.0
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
            if self.limited_drive is not None and sm.on[i]:
                m.actuator_forcerange[act] = self.limited_drive.force_range(qd[i])
            mujoco.mj_inverse(m, d)
            mujoco.mj_fwdActuation(m, d)
            req[i] = d.qfrc_inverse[dof] - d.qfrc_actuator[dof]
            motor[i] = _moment(d, act, dof) * d.actuator_force[act]
        self.calls += len(q)
        return req, motor

    def bristle_torque(self, sm: Smoothed) -> np.ndarray | float:
        """The model's LuGre torque [N*m] at the output times (0 without LuGre): integrated on the
        fine grid along the narrow window's velocity, seen through the smoothing window."""
        if not self.lugre:
            return 0.0
        key = (id(sm), tuple(self.lugre))
        hit = self._bristle_cache.get(key)
        if hit is None or hit[0] is not sm:
            G0, vel = sm.fine[0], sm.fine[1]
            fine = sum(bristles.torque(p, vel, sm.dt) for p in self.lugre)
            hit = self._bristle_cache[key] = (sm, G0 @ fine)
        return hit[1]

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

    def missing(self, sm: Smoothed, ctrl=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``tau_miss`` [N*m], ``tau_motor`` [N*m] and ``steady`` (the window sees one
        friction direction and no sticking: ``|s_f| > 0.99``, ``w_f < 0.01``) at the output times;
        ``ctrl``: the (smoothed) command the drive applies, default the logged one."""
        req, motor = self.required(sm, ctrl=ctrl)
        req = req - self.bristle_torque(sm)
        F = self.level(sm, motor)
        s_f, w_f = self.direction(sm)
        moving = -F * s_f
        f = moving + np.clip(req - moving, -F * w_f, F * w_f)
        law = self.device.drive_friction
        if law is not None and law.smooth is not None:
            f = f + self.smooth_force(sm, motor, law.smooth)
        return req - f, motor, (np.abs(s_f) > 0.99) & (w_f < 0.01)

    @staticmethod
    def smooth_force(sm: Smoothed, motor: np.ndarray, values) -> np.ndarray:
        """A smooth load law's force [N*m] (:data:`omni_sim.device.LOAD_FRICTION_SMOOTH`,
        ``values`` its ``mu_drive mu_back b_emf w_s``) at the output times: its level
        (:func:`omni_sim.device.smooth_load_level`) at ``qd_start`` and the drive's torque, its
        sign ``tanh(qd / w_s)`` on the fine grid through the window, as the Coulomb friction's
        direction (a sign speed of 0.02 rad/s switches within the window: taken at the smoothed
        speed it would switch late and whole)."""
        v = np.asarray(values, float)[None, :]
        level = smooth_load_level(v, sm.qd_start, motor)
        G0, vel = sm.fine[0], sm.fine[1]
        return -level * (G0 @ np.tanh(vel / v[0, 3]))

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
        var = (sm.sigma_rad * row_norms(comb.tocsr())) ** 2
        var += (sm.weights[3][1] * jac[3] * row_norms(sm.weights[3][0])) ** 2
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
    lugre = set(bristles.with_bristles(model, device.lugre_actuators()))
    stateful = [a for a in range(model.nactuator) if model.actuator_actnum[a] > 0 and a not in lugre]
    if stateful:
        # every actuator, passive ones too (a dcmotor with input="none" is not in nu)
        names = ", ".join(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or str(a) for a in stateful)
        raise UserError(f"the model's actuator(s) {names} have activation states (inductance, filters, "
                        "LuGre on another joint): the missing torque cannot be seen by inverse dynamics; "
                        "compare replays instead (omni discrepancy)")
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
        Prepared runs (:func:`discrepancy.replay.prepare_runs`).
    target : Target, optional
        The controlled joint and actuator (default None: the Omni).
    est : Estimator

    Returns
    -------
    list of MissingTorque
    """
    inv = InverseModel(model, target)
    return invert(inv, [smooth(run, float(model.opt.timestep), est) for run in runs])


def invert(inv: "InverseModel", smoothed: list) -> list[MissingTorque]:
    """The missing torque of each smoothed run (:func:`discrepancy.smoothing.smooth`) under
    ``inv``'s model, with its band: the one loop :func:`missing_torque`, the shape fits and
    the report's evidence share."""
    out = []
    for sm in smoothed:
        tau, motor, steady = inv.missing(sm)
        out.append(MissingTorque(sm.name, sm.t, sm.q, sm.qd, sm.qdd, motor, tau, inv.band(sm),
                                 sm.trusted, steady))
    return out
