"""The device's named parameters, read and set in the model it reads live: the encoder joint's
damping and ``frictionloss``, a body's mass and inertia, the arm servos' gains, the LuGre
actuator's parameters, and the drive's dry friction (its levels, its family, a scaling).

:class:`DeviceParameters` is a part of :class:`~omni_sim.device.Device` (its base class): its
methods are the device's and use what the device holds (``model``, ``ix``, ``joint_id``,
``scene_family``).
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from identification.errors import UserError

from .. import model as om


class DeviceParameters:
    """The named parameters of a :class:`~omni_sim.device.Device` (a base class of it, not a
    device on its own: it reads the device's ``model``, ``ix``, ``joint_id`` and
    ``scene_family``)."""

    # -- named parameters: read and set in the model the device reads live ---------------------
    @property
    def yaw_damping(self) -> float:
        """The encoder joint's viscous damping [N*m*s/rad] (its MJCF ``damping``, as the model
        holds it now; settable)."""
        return float(self.model.dof_damping[self.ix.yaw_dof])

    @yaw_damping.setter
    def yaw_damping(self, value: float) -> None:
        self.model.dof_damping[self.ix.yaw_dof] = value

    @property
    def yaw_frictionloss(self) -> float:
        """The encoder joint's ``frictionloss`` [N*m] (the hard stick; settable)."""
        return float(self.model.dof_frictionloss[self.ix.yaw_dof])

    @yaw_frictionloss.setter
    def yaw_frictionloss(self, value: float) -> None:
        self.model.dof_frictionloss[self.ix.yaw_dof] = value

    def _named(self, kind: "mujoco.mjtObj", name: str, what: str) -> int:
        i = mujoco.mj_name2id(self.model, kind, name)
        if i < 0:
            raise UserError(f"the model has no {what} {name!r}")
        return int(i)

    def body(self, name: str) -> tuple[float, np.ndarray]:
        """A body's mass [kg] and principal inertia [kg*m^2] (a copy)."""
        b = self._named(mujoco.mjtObj.mjOBJ_BODY, name, "body")
        return float(self.model.body_mass[b]), self.model.body_inertia[b].copy()

    def set_body(self, name: str, mass: float | None = None, inertia=None) -> None:
        """Set a body's mass [kg] and/or principal inertia [kg*m^2] (call ``mj_setConst``
        after changing masses, as MuJoCo's derived constants depend on them)."""
        b = self._named(mujoco.mjtObj.mjOBJ_BODY, name, "body")
        if mass is not None:
            self.model.body_mass[b] = mass
        if inertia is not None:
            self.model.body_inertia[b] = inertia

    def servo_gain(self, joint: str) -> float:
        """The P gain [N*m/rad] of an arm servo (``shoulder`` or ``elbow``)."""
        return float(self.model.actuator_gainprm[self._servo(joint), 0])

    def set_servo_gain(self, joint: str, kp: float) -> None:
        """Set an arm servo's P gain (a ``position`` actuator: gain kp, bias -kp)."""
        a = self._servo(joint)
        self.model.actuator_gainprm[a, 0] = kp
        self.model.actuator_biasprm[a, 1] = -kp

    def _servo(self, joint: str) -> int:
        act = {"shoulder": self.ix.shoulder_act, "elbow": self.ix.elbow_act}.get(joint)
        if act is None:
            raise UserError(f"the model has no arm servo on {joint!r}")
        return act

    def friction_actuator(self) -> int | None:
        """The drive's LuGre friction actuator (the first of :meth:`lugre_actuators`), or None."""
        acts = self.lugre_actuators()
        return acts[0] if acts else None

    def lugre(self) -> dict:
        """The LuGre actuator's parameters (:meth:`friction_actuator`): bristle stiffness
        ``sigma0`` [N*m/rad] and damping ``sigma1`` [N*m*s/rad], Coulomb and static levels
        ``Fc``, ``Fs`` [N*m], Stribeck speed ``vs`` [rad/s] (UserError without one)."""
        m, f = self.model, self._lugre_actuator()
        return {"sigma0": float(m.actuator_dynprm[f, 5]), "sigma1": float(m.actuator_dynprm[f, 6]),
                "Fc": float(m.actuator_biasprm[f, 3]),
                "Fs": float(m.actuator_biasprm[f, 4]), "vs": float(m.actuator_biasprm[f, 5])}

    def set_lugre(self, sigma0: float, Fc: float, Fs: float, vs: float) -> None:
        """Set the LuGre actuator's parameters (names: :meth:`lugre`)."""
        m, f = self.model, self._lugre_actuator()
        m.actuator_dynprm[f, 5] = sigma0
        m.actuator_biasprm[f, 3:6] = Fc, Fs, vs

    def _lugre_actuator(self) -> int:
        f = self.friction_actuator()
        if f is None:
            raise UserError("the model has no LuGre friction actuator on its drive")
        return f

    # -- the drive's friction ------------------------------------------------------------------
    def lugre_actuators(self) -> list[int]:
        """Ids of the passive LuGre friction actuators (``dcmotor`` bias) on the encoder joint."""
        m = self.model
        return [a for a in range(m.nactuator)
                if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_DCMOTOR
                and m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                and m.actuator_trnid[a, 0] == self.joint_id]

    def friction(self) -> dict:
        """The drive's dry friction: ``frictionloss`` [N*m] (hard stick) and the LuGre
        actuators' ``lugre_sigma0`` [N*m/rad], ``lugre_Fc``, ``lugre_Fs`` [N*m] (summed levels;
        stiffness of the first)."""
        m, acts = self.model, self.lugre_actuators()
        return {
            "frictionloss": self.yaw_frictionloss,
            "lugre_sigma0": float(m.actuator_dynprm[acts[0], 5]) if acts else 0.0,
            "lugre_Fc": float(sum(m.actuator_biasprm[a, 3] for a in acts)),
            "lugre_Fs": float(sum(m.actuator_biasprm[a, 4] for a in acts)),
        }

    def friction_family(self, path: str | os.PathLike | None = None) -> str:
        """The friction family a run's metadata names.

        The model's file (``path``; default: the one the device was loaded from) a built-in scene:
        its family (``scene.xml`` is the default family).  Otherwise (a user's file, or a model
        compiled in memory) what the drive carries: ``"lugre"`` (a LuGre actuator with a
        non-zero level), ``"coulomb"`` (``frictionloss``), ``"lugre+coulomb"`` or ``"none"``."""
        family = om.builtin_family(path) if path is not None else self.scene_family
        if family is not None:
            return family
        f = self.friction()
        kinds = [k for k, on in (("lugre", f["lugre_Fc"] > 0 or f["lugre_Fs"] > 0),
                                 ("coulomb", f["frictionloss"] > 0)) if on]
        return "+".join(kinds) or "none"

    def scale_friction(self, factor: float, base: "DeviceParameters | None" = None) -> None:
        """Set the drive's dry-friction levels (``frictionloss`` and LuGre Fc, Fs) to ``factor``
        times those of ``base`` (default: this device itself), in place."""
        base = self if base is None else base
        m, b = self.model, base.model
        self.yaw_frictionloss = factor * base.yaw_frictionloss
        for a in self.lugre_actuators():
            m.actuator_biasprm[a, 3:5] = factor * b.actuator_biasprm[a, 3:5]
