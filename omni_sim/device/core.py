"""The :class:`Device`: the virtual Omni (or a user's single-joint device) built once from a
compiled model, the one place each fact about it is computed (see :mod:`omni_sim.device`).
Its named parameters are its base class's (:mod:`omni_sim.device.parameters`).
"""

from __future__ import annotations

import copy
import math
import os
from pathlib import Path

import mujoco
import numpy as np

from identification.errors import UserError

from .. import model as om
from .engine import CONTROL_PERIOD_S, STATE_SPEC, Engine, substeps_of
from .laws import DriveFriction
from .parameters import DeviceParameters


def coupled_hinges(model: mujoco.MjModel, joint_id: int) -> list[tuple[int, float]]:
    """Hinges tied to joint ``joint_id`` by a fixed tendon of exactly two joints (a two-mass
    drive: rotor and output coupled by a cable), as ``(qpos address, factor)``: the tendon's
    length ``c_j q_j + c_h q_h`` is zero at ``q_h = factor * q_j`` (``factor = -c_j / c_h``).
    Tendons with a zero coefficient on the other hinge are skipped."""
    out = []
    for t in range(model.ntendon):
        adr, num = int(model.tendon_adr[t]), int(model.tendon_num[t])
        if num != 2:
            continue
        wraps = range(adr, adr + num)
        if any(model.wrap_type[w] != mujoco.mjtWrap.mjWRAP_JOINT for w in wraps):
            continue  # a spatial tendon
        ids = [int(model.wrap_objid[w]) for w in wraps]
        coef = [float(model.wrap_prm[w]) for w in wraps]
        if joint_id not in ids or ids[0] == ids[1]:
            continue
        i = ids.index(joint_id)
        other, c_other = ids[1 - i], coef[1 - i]
        if model.jnt_type[other] != mujoco.mjtJoint.mjJNT_HINGE or c_other == 0:
            continue
        out.append((int(model.jnt_qposadr[other]), -coef[i] / c_other))
    return out


class Device(DeviceParameters):
    """The virtual Omni (or a user's single-joint device) built once from a compiled model.

    Parameters
    ----------
    model : MjModel
        A model keeping the contract's names (:func:`omni_sim.model.load_model`).  The device
        reads it live: a change of a parameter in place (friction scaling, a candidate effect's
        value) is seen by the next step, but not by the cached equilibrium poses.
    control_period_s : float [s]
        Servo period; a whole multiple of the model's timestep.
    target : omni_sim.model.Target, optional
        The controlled hinge (the encoder's joint) and its actuator of a user's device (default
        None: the Omni's contract, ``yaw``/``yaw_motor`` and the arm).  Without the Omni's arm
        (``ix.has_arm`` False) a run has no pose: its start leaves every other joint at
        ``qpos0`` (see :meth:`start_data`).
    source : str
        What the model is, for error messages (a file name, ``"<variant>"``).

    Attributes
    ----------
    model : MjModel
    ix : OmniIndex
        Addresses of the contract's joints and actuators.
    control_period_s, dt : float [s]
    substeps : int
        Physics steps per control period.
    voltage_limit : float [V]
        ``ctrlrange`` of ``yaw_motor`` / the target's actuator (inf if unlimited): the drive's
        clip of every command.
    torque_constant : float [N*m/V]
        Torque per unit of control of ``yaw_motor`` / the target's actuator (the paper's
        beta_bar): gear x gain of a ``motor``, gear x K/R of a ``dcmotor`` at rest.
    drive_friction : DriveFriction or None
        Friction laws the engine applies at every control period (the model's ``<custom>``
        numerics :data:`LOAD_FRICTION`, :data:`FRICTION_ASYMMETRY`, :data:`FRICTION_FAMILY`)
        and the current limit it moves with the back-EMF (:data:`CURRENT_LIMIT`).
    joint_id : int
        The encoder joint (``yaw`` or the target's hinge).
    target : Target or None
    coupled : list of (int, float)
        Hinges tied to the encoder joint by a two-joint fixed tendon (:func:`coupled_hinges`),
        started where that tendon's length is zero.
    """

    def __init__(self, model: mujoco.MjModel, control_period_s: float = CONTROL_PERIOD_S,
                 target: om.Target | None = None, source: str = "<model>",
                 file: str | None = None, digest: str | None = None):
        self.model = model
        self.target = target
        #: Where the model came from (:meth:`load` sets both): the MJCF file as the caller named
        #: it (None: the built-in ``scene.xml``) and its digest (:func:`omni_sim.model.model_digest`);
        #: ``digest`` None: a model compiled in memory.
        self.file, self.digest = file, digest
        #: The friction family of a built-in scene the device was loaded from (:meth:`load`;
        #: None: another file, or a model compiled in memory).
        self.scene_family: str | None = None
        self.ix = om.index(model, source, target)
        self.control_period_s = float(control_period_s)
        self.substeps = substeps_of(model, control_period_s)
        act = self.ix.yaw_act
        self.voltage_limit = (float(min(-model.actuator_ctrlrange[act, 0], model.actuator_ctrlrange[act, 1]))
                              if model.actuator_ctrllimited[act] else math.inf)
        gear = float(model.actuator_gear[act, 0])
        if model.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_DCMOTOR:
            # a dcmotor's torque per volt is gear * K / R (gainprm[1] = K, gainprm[0] = R;
            # docs/method/servo-actuators.md)
            gear *= float(model.actuator_gainprm[act, 1] / model.actuator_gainprm[act, 0])
        else:
            gear *= float(model.actuator_gainprm[act, 0])  # a motor's gain is 1
        self.torque_constant = gear
        self.joint_id = int(model.dof_jntid[self.ix.yaw_dof])
        arm = {self.ix.shoulder_qpos, self.ix.elbow_qpos}
        self.coupled = [(a, f) for a, f in coupled_hinges(model, self.joint_id) if a not in arm]
        self.nstate = mujoco.mj_stateSize(model, STATE_SPEC)
        #: the drive's friction laws the engine applies (None: the model declares none)
        self.drive_friction = DriveFriction.of(model, act, self.ix.yaw_dof, source)
        self._eq: dict[tuple[float, float], tuple[float, float]] = {}
        self._scratch: mujoco.MjData | None = None  # start_state's MjData (made on first use)
        self._off_model: mujoco.MjModel | None = None  # off_model()'s (made on first use)

    @classmethod
    def load(cls, path=None, control_period_s: float = CONTROL_PERIOD_S, friction: str | None = None,
             target: om.Target | None = None) -> "Device":
        """Compile an MJCF file (default: the built-in scene of the friction family
        ``friction``, or ``scene.xml``) into a device that knows its file and digest."""
        where = om.model_path(path, friction)
        model = om.load_model(where, target=target)
        # the file as the caller named it; None for the built-in scene.xml (runs say so)
        file = None if path is None and friction is None else str(where)
        device = cls(model, control_period_s, target, file=file, digest=om.model_digest(where))
        device.scene_family = om.builtin_family(where)
        return device

    def at_period(self, control_period_s: float) -> "Device":
        """This device at another servo period (itself if it is the same): the same model
        object, source and equilibrium poses (they do not depend on the period)."""
        if float(control_period_s) == self.control_period_s:
            return self
        other = copy.copy(self)
        other.control_period_s = float(control_period_s)
        other.substeps = substeps_of(self.model, control_period_s)
        other._scratch = None  # start_state's MjData: one per device (not shared by threads)
        return other

    # -- where the model came from ---------------------------------------------------------------
    @property
    def in_memory(self) -> bool:
        """True for a model compiled in memory (no file, no digest)."""
        return self.digest is None

    @property
    def run_model_name(self) -> str:
        """What a run's metadata calls the model: the file's name, ``scene.xml (built-in)``
        for the default scene, ``in-memory model`` for a model compiled in memory."""
        if self.in_memory:
            return "in-memory model"
        return "scene.xml (built-in)" if self.file is None else os.path.basename(self.file)

    @property
    def label(self) -> str:
        """The model for a reader: ``built-in scene_coulomb.xml`` for a built-in scene (where
        it is installed says nothing), the file as named, or ``in-memory model``."""
        if self.in_memory:
            return "in-memory model"
        if self.file is None:
            return "built-in scene.xml"
        p = Path(self.file)
        return f"built-in {p.name}" if p.resolve().parent == om.OMNI_DIR.resolve() else self.file

    def off_model(self) -> mujoco.MjModel:
        """The model with the drive switched off (torque disabled: the actuator exerts no force;
        a ``dcmotor``'s winding open, so no back-EMF braking either; back-EMF written as joint
        damping stays, it is the joint's).  Made once, from the model as it is then."""
        if self._off_model is None:
            m = copy.deepcopy(self.model)
            a = self.ix.yaw_act
            if m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_DCMOTOR:
                m.actuator_gainprm[a, 1] = 0.0  # motor constant K = 0: no torque, no back-EMF
            else:
                m.actuator_gainprm[a, :] = 0.0
                m.actuator_biasprm[a, :] = 0.0
            self._off_model = m
        return self._off_model

    def without_friction(self) -> "Device":
        """A device on a copy of the model with no dry friction on the drive (viscous damping
        kept)."""
        dev = Device(copy.deepcopy(self.model), self.control_period_s, self.target)
        dev.scale_friction(0.0)
        return dev

    # -- the arm and the inertia -----------------------------------------------------------------
    def _arm_joint(self, name: str) -> int:
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, name)

    def check_pose(self, gamma1_deg: float, gamma2_deg: float) -> None:
        """Raise UserError if a pose is not finite or outside the shoulder/elbow joint ranges."""
        for name, val in (("shoulder", gamma1_deg), ("elbow", gamma2_deg)):
            if not math.isfinite(val):
                raise UserError(f"{name} angle must be finite, got {val}")
            if not self.ix.has_arm:
                continue
            j = self._arm_joint(name)
            if self.model.jnt_limited[j]:
                lo, hi = np.degrees(self.model.jnt_range[j])
                if not lo - 1e-9 <= val <= hi + 1e-9:
                    raise UserError(f"{name} angle {val:g} deg is outside the joint range "
                                    f"[{lo:.1f}, {hi:.1f}] deg")

    def set_arm_control(self, data: mujoco.MjData, gamma1_set_deg: float, gamma2_set_deg: float) -> None:
        """Write the shoulder/elbow servo set points [deg] into ``data.ctrl`` (servos present)."""
        if self.ix.shoulder_act is not None:
            data.ctrl[self.ix.shoulder_act] = math.radians(gamma1_set_deg)
        if self.ix.elbow_act is not None:
            data.ctrl[self.ix.elbow_act] = math.radians(gamma2_set_deg)

    def inertia(self, gamma1_deg: float | None = None, gamma2_deg: float | None = None) -> float:
        """MuJoCo's inertia [kg*m^2] about the encoder joint with the arm at these ACTUAL angles
        [deg] (the others at ``qpos0``; without the Omni's arm no angles are needed): the
        joint's diagonal element of the joint-space mass matrix (``mj_fullM``), armature
        included."""
        m, ix = self.model, self.ix
        data = mujoco.MjData(m)
        data.qpos[:] = m.qpos0
        if ix.has_arm:
            data.qpos[ix.shoulder_qpos] = math.radians(gamma1_deg)
            data.qpos[ix.elbow_qpos] = math.radians(gamma2_deg)
        mujoco.mj_forward(m, data)
        mass = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, data, mass)
        return float(mass[ix.yaw_dof, ix.yaw_dof])

    @property
    def dt(self) -> float:
        """Control period [s]: ``timestep * substeps``."""
        return float(self.model.opt.timestep) * self.substeps

    def equilibrium(self, gamma1_set_deg: float, gamma2_set_deg: float) -> tuple[float, float]:
        """Actual (sagged) arm angles [deg] for these servo set points (cached per device)."""
        key = (float(gamma1_set_deg), float(gamma2_set_deg))
        if key not in self._eq:
            self._eq[key] = self._solve_equilibrium(*key)
        return self._eq[key]

    def _solve_equilibrium(self, gamma1_set_deg: float, gamma2_set_deg: float,
                           tol_rad: float = 1e-10) -> tuple[float, float]:
        """Solve ``qfrc_bias + qfrc_passive = qfrc_actuator`` for the shoulder and elbow, the
        encoder joint at 0, by Newton's method on MuJoCo's own forces (finite-difference
        Jacobian), in the device's scratch ``MjData``, reset first (a new ``MjData`` of the
        Omni's model costs ~1.4 ms: its 13.6 MB arena)."""
        m, ix = self.model, self.ix
        self.check_pose(gamma1_set_deg, gamma2_set_deg)
        data = self.scratch_data()
        mujoco.mj_resetData(m, data)
        self.set_arm_control(data, gamma1_set_deg, gamma2_set_deg)
        dofs = [int(m.jnt_dofadr[self._arm_joint(j)]) for j in ("shoulder", "elbow")]
        qadr = [ix.shoulder_qpos, ix.elbow_qpos]
        q = np.radians([gamma1_set_deg, gamma2_set_deg])

        def residual(qa: np.ndarray) -> np.ndarray:
            data.qpos[:] = m.qpos0
            data.qpos[qadr] = qa
            data.qvel[:] = 0
            mujoco.mj_forward(m, data)
            f = data.qfrc_actuator + data.qfrc_passive - data.qfrc_bias
            return f[dofs].copy()

        h, unit = 1e-7, np.eye(2)
        for _ in range(50):
            f = residual(q)
            jac = np.column_stack([(residual(q + h * e) - f) / h for e in unit])
            step = np.linalg.solve(jac, -f)
            q = q + step
            if np.max(np.abs(step)) < tol_rad:
                break
        return float(np.degrees(q[0])), float(np.degrees(q[1]))

    def start_data(self, theta0_rad: float, gamma_set_deg: tuple[float, float] | None,
                   data: mujoco.MjData | None = None) -> mujoco.MjData:
        """The start of a run: arm at the equilibrium of its set points, servos holding them,
        yaw at rest at ``theta0_rad``; ``mj_forward`` done.  Writes into ``data`` if given.

        Without the Omni's arm (``ix.has_arm`` False) ``gamma_set_deg`` is ignored (None or an
        empty tuple are fine) and the other joints start at ``qpos0``.  Every hinge tied to the
        encoder joint by a two-joint fixed tendon (:attr:`coupled`, a two-mass drive) starts
        where that tendon's length is zero: the cable unstretched, all at rest."""
        m, ix = self.model, self.ix
        if ix.has_arm:
            if gamma_set_deg is None or len(gamma_set_deg) != 2:
                raise UserError("this model has the Omni's arm (shoulder, elbow): a run needs its "
                                "two set points gamma1, gamma2 [deg]")
            g1, g2 = self.equilibrium(*gamma_set_deg)  # before d is written: it may be the scratch
        d = mujoco.MjData(m) if data is None else data
        mujoco.mj_resetData(m, d)
        d.qpos[ix.yaw_qpos] = theta0_rad
        if ix.has_arm:
            d.qpos[ix.shoulder_qpos] = math.radians(g1)
            d.qpos[ix.elbow_qpos] = math.radians(g2)
            self.set_arm_control(d, *gamma_set_deg)  # the arm servos hold their set points
        for adr, factor in self.coupled:
            d.qpos[adr] = factor * theta0_rad
        mujoco.mj_forward(m, d)
        return d

    def start_state(self, theta0_rad: float, gamma_set_deg: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray]:
        """The start of a run as ``(full physics state, ctrl vector)`` (see :meth:`start_data`).

        Computed in one scratch ``MjData`` of the device (``mj_resetData`` first, as a new one
        is), so a batch of many runs does not allocate an ``MjData`` per run; so one device's
        ``start_state`` is not for concurrent calls from several threads."""
        d = self.start_data(theta0_rad, gamma_set_deg, self.scratch_data())
        x0 = np.empty(self.nstate)
        mujoco.mj_getState(self.model, d, x0, STATE_SPEC)
        return x0, d.ctrl.copy()

    def scratch_data(self) -> mujoco.MjData:
        """The device's scratch ``MjData`` (made once: the start states and the arm's
        equilibria are computed in it, one at a time)."""
        if self._scratch is None:
            self._scratch = mujoco.MjData(self.model)
        return self._scratch

    def engine(self, theta0_rad, gamma_set_deg, nthread: int | None = None) -> "Engine":
        """An :class:`Engine` of B runs of this device (``theta0_rad``: B floats,
        ``gamma_set_deg``: B pairs, or B Nones without the Omni's arm)."""
        return Engine([self] * len(theta0_rad), theta0_rad, gamma_set_deg, nthread=nthread)
