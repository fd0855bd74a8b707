"""Load the virtual Omni, check the contract's names, set poses, and compute the yaw inertia.

Pose convention (the paper's Fig. 1 and eq. (5)), used everywhere in this package:

* ``gamma1_deg`` -- elevation of the upper arm above the horizontal [deg] (``shoulder`` qpos);
* ``gamma2_deg`` -- the elbow's interior angle between upper arm and forearm [deg] (``elbow``
  qpos), so the forearm's elevation is ``psi = gamma1 + gamma2 - 180`` [deg].

Set points are what the arm servos are asked to hold; the *actual* angles sag below them under
gravity (:func:`equilibrium_pose`), as in the paper's Table 3.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from identification.errors import UserError

from omni_sim._resources import models_dir as _models_dir

#: Folder of the built-in model files: the data package ``omni_sim.models`` (the top-level
#: ``models/`` folder, shipped inside the package; see pyproject.toml), a real folder on disk.
MODELS_DIR = _models_dir()
#: The built-in scene (the default friction family; includes ``omni.xml``).
DEFAULT_SCENE = MODELS_DIR / "scene.xml"
#: The friction families of the built-in model: one scene each around the shared robot
#: ``omni.xml`` (README, "Friction families").  ``lugre`` is the default (``scene.xml``).
FRICTION_FAMILIES = ("coulomb", "lugre")
DEFAULT_FRICTION = "lugre"


def scene_path(friction: str | None = None) -> Path:
    """The built-in scene of a friction family (None: the default ``scene.xml``)."""
    if friction is None:
        return DEFAULT_SCENE
    if friction not in FRICTION_FAMILIES:
        raise UserError(f"unknown friction family {friction!r} (choose from "
                        f"{', '.join(FRICTION_FAMILIES)})")
    return MODELS_DIR / f"scene_{friction}.xml"


def model_path(path: str | os.PathLike | None = None, friction: str | None = None) -> Path:
    """The model file a command runs: ``path`` if given, else the family's built-in scene.
    Both at once is a user error (a family names a built-in scene)."""
    if path is not None and friction is not None:
        raise UserError("give either a model file or a friction family, not both (the family "
                        "picks one of the built-in scenes)")
    return Path(path) if path is not None else scene_path(friction)

def friction_family(model: mujoco.MjModel, path: str | os.PathLike | None = None) -> str:
    """The friction family a run's metadata names.

    ``path`` a built-in scene: its family (``scene.xml`` is the default family).  Otherwise
    (a user's file, or ``path`` None for a compiled model) what the ``model``'s yaw carries:
    ``"lugre"`` (a LuGre actuator with a non-zero level), ``"coulomb"`` (``frictionloss``),
    ``"lugre+coulomb"`` or ``"none"``."""
    if path is not None:
        resolved = Path(path).resolve()
        if resolved == DEFAULT_SCENE.resolve():
            return DEFAULT_FRICTION
        for fam in FRICTION_FAMILIES:
            if resolved == scene_path(fam).resolve():
                return fam
    f = yaw_friction(model)
    kinds = [k for k, on in (("lugre", f["lugre_Fc"] > 0 or f["lugre_Fs"] > 0),
                             ("coulomb", f["frictionloss"] > 0)) if on]
    return "+".join(kinds) or "none"


JOINTS = ("yaw", "shoulder", "elbow")
YAW_ACTUATOR = "yaw_motor"
ARM_ACTUATORS = ("shoulder_servo", "elbow_servo")


@dataclass(frozen=True)
class Target:
    """The controlled joint of a single-joint device and the actuator that drives it (the
    encoder reads the joint; discrepancy effects are written into them).

    Attributes
    ----------
    joint : str
        The controlled hinge (the encoder's joint).
    actuator : str
        The actuator of the controlled drive (its control is the command, its gear the torque
        constant).
    """

    joint: str = "yaw"
    actuator: str = "yaw_motor"


#: The virtual Omni's yaw drive (the dataset contract's names).
OMNI = Target()


@dataclass(frozen=True)
class OmniIndex:
    """Addresses of the contract's elements inside one compiled model.

    The ``yaw_*`` fields address the controlled drive: the Omni's ``yaw`` / ``yaw_motor``, or
    a :class:`Target`'s joint and actuator.  The arm fields are None when the model has no arm
    (a user's single-joint device: :func:`index` with a target and no ``shoulder``/``elbow``
    hinges); code that poses the arm uses them only when present (:attr:`has_arm`).
    """

    yaw_qpos: int
    yaw_dof: int
    shoulder_qpos: int | None
    elbow_qpos: int | None
    yaw_act: int
    shoulder_act: int | None
    elbow_act: int | None

    @property
    def has_arm(self) -> bool:
        """True when the model has the Omni's shoulder and elbow joints (a pose to set)."""
        return self.shoulder_qpos is not None and self.elbow_qpos is not None


def load_model(path: str | os.PathLike | None = None, friction: str | None = None,
               target: Target | None = None) -> mujoco.MjModel:
    """Compile an MJCF file (default: the built-in scene of the friction family ``friction``,
    or ``scene.xml``) and check the contract's names (:func:`index`: the Omni's with ``target``
    None, else the target's joint and actuator).

    Raises
    ------
    UserError
        The file is missing, does not compile, or lacks the joints ``yaw``, ``shoulder``,
        ``elbow`` or the actuator ``yaw_motor`` acting on ``yaw`` (with a ``target``: its hinge,
        or its actuator acting on that hinge).
    """
    path = model_path(path, friction)
    if not path.is_file():
        raise UserError(f"{path}: model file not found")
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except (ValueError, RuntimeError) as exc:  # MuJoCo reports XML/compile errors as ValueError
        msg = " ".join(str(exc).split())
        raise UserError(f"{path}: not a valid MJCF model ({msg})") from None
    index(model, path, target)
    return model


def _joint_id(model: mujoco.MjModel, name: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)


def _is_hinge(model: mujoco.MjModel, jid: int) -> bool:
    return jid >= 0 and model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_HINGE


def index(model: mujoco.MjModel, path: str | os.PathLike = "<model>",
          target: Target | None = None) -> OmniIndex:
    """Find the contract's joints and actuators in ``model`` (UserError if missing).

    ``target`` None: the virtual Omni's contract (hinges ``yaw``, ``shoulder``, ``elbow``, the
    actuator ``yaw_motor`` on ``yaw``).  A :class:`Target`: a single-joint device -- its
    ``joint`` must be a hinge and its ``actuator`` must act on that joint; the Omni's arm
    (hinges ``shoulder`` and ``elbow``, servos ``shoulder_servo``/``elbow_servo``) is used only
    if the model has both hinges and neither is the target joint, else the arm fields are None.
    """
    if target is None:
        missing = [j for j in JOINTS if _joint_id(model, j) < 0]
        if missing:
            raise UserError(f"{path}: model lacks the contract's joint(s) {', '.join(missing)}")
        jid = {j: _joint_id(model, j) for j in JOINTS}
        for j, i in jid.items():
            if model.jnt_type[i] != mujoco.mjtJoint.mjJNT_HINGE:
                raise UserError(f"{path}: joint {j!r} must be a hinge")
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, YAW_ACTUATOR)
        if aid < 0:
            raise UserError(f"{path}: model lacks the contract's actuator {YAW_ACTUATOR!r}")
        if model.actuator_trntype[aid] != mujoco.mjtTrn.mjTRN_JOINT or model.actuator_trnid[aid, 0] != jid["yaw"]:
            raise UserError(f"{path}: actuator {YAW_ACTUATOR!r} must act on joint 'yaw'")
        joint, actuator, has_arm = "yaw", YAW_ACTUATOR, True
    else:
        joint, actuator = target.joint, target.actuator
        j = _joint_id(model, joint)
        if j < 0:
            raise UserError(f"{path}: model has no joint {joint!r} (the controlled joint, --joint)")
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            raise UserError(f"{path}: joint {joint!r} must be a hinge (the controlled joint, --joint)")
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)
        if aid < 0:
            raise UserError(f"{path}: model has no actuator {actuator!r} (the controlled "
                            "joint's actuator, --actuator)")
        if model.actuator_trntype[aid] != mujoco.mjtTrn.mjTRN_JOINT or model.actuator_trnid[aid, 0] != j:
            raise UserError(f"{path}: actuator {actuator!r} must act on joint {joint!r} "
                            "(a joint transmission on the controlled hinge)")
        if model.actuator_ctrlnum[aid] < 1:  # a passive actuator (input="none"): no control
            raise UserError(f"{path}: actuator {actuator!r} takes no control (a passive actuator)")
        jid = {"yaw": j, "shoulder": _joint_id(model, "shoulder"), "elbow": _joint_id(model, "elbow")}
        has_arm = all(_is_hinge(model, jid[a]) and jid[a] != j for a in ("shoulder", "elbow"))
    arm = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in ARM_ACTUATORS]
    if not has_arm:
        arm = [-1, -1]
    # the code indexes data.ctrl by actuator id: true while passive (input="none") actuators,
    # which take no control, come after the controlled ones
    ctrladr = getattr(model, "actuator_ctrladr", None)
    if ctrladr is not None and any(a >= 0 and ctrladr[a] != a for a in (aid, *arm)):
        raise UserError(f"{path}: passive actuators must come after {actuator!r}"
                        + (" and the arm servos" if has_arm else "")
                        + " in <actuator> (their control index must equal their actuator index)")
    return OmniIndex(
        yaw_qpos=int(model.jnt_qposadr[jid["yaw"]]),
        yaw_dof=int(model.jnt_dofadr[jid["yaw"]]),
        shoulder_qpos=int(model.jnt_qposadr[jid["shoulder"]]) if has_arm else None,
        elbow_qpos=int(model.jnt_qposadr[jid["elbow"]]) if has_arm else None,
        yaw_act=int(aid),
        shoulder_act=int(arm[0]) if arm[0] >= 0 else None,
        elbow_act=int(arm[1]) if arm[1] >= 0 else None,
    )


def lugre_actuators(model: mujoco.MjModel) -> list[int]:
    """Ids of the passive LuGre friction actuators (``dcmotor`` bias) on the yaw joint."""
    yaw = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "yaw")
    return [a for a in range(model.nactuator)
            if model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_DCMOTOR
            and model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
            and model.actuator_trnid[a, 0] == yaw]


def yaw_friction(model: mujoco.MjModel) -> dict:
    """The yaw drive's dry friction: ``frictionloss`` [N*m] (hard stick) and the LuGre
    actuators' ``lugre_sigma0`` [N*m/rad], ``lugre_Fc``, ``lugre_Fs`` [N*m] (summed levels;
    stiffness of the first)."""
    ix = index(model)
    acts = lugre_actuators(model)
    return {
        "frictionloss": float(model.dof_frictionloss[ix.yaw_dof]),
        "lugre_sigma0": float(model.actuator_dynprm[acts[0], 5]) if acts else 0.0,
        "lugre_Fc": float(sum(model.actuator_biasprm[a, 3] for a in acts)),
        "lugre_Fs": float(sum(model.actuator_biasprm[a, 4] for a in acts)),
    }


def scale_yaw_friction(model: mujoco.MjModel, factor: float, base: mujoco.MjModel | None = None) -> None:
    """Set the yaw drive's dry-friction levels (``frictionloss`` and LuGre Fc, Fs) to
    ``factor`` times those of ``base`` (default: ``model`` itself), in place."""
    base = model if base is None else base
    ix = index(model)
    model.dof_frictionloss[ix.yaw_dof] = factor * base.dof_frictionloss[ix.yaw_dof]
    for a in lugre_actuators(model):
        model.actuator_biasprm[a, 3:5] = factor * base.actuator_biasprm[a, 3:5]


def without_friction(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` with no dry friction on the yaw axis (viscous damping kept)."""
    import copy

    m = copy.deepcopy(model)
    scale_yaw_friction(m, 0.0)
    return m


def torque_constant(model: mujoco.MjModel, target: Target | None = None) -> float:
    """The yaw motor's gear, i.e. the torque constant beta_bar [N*m/V] (with a ``target``:
    its actuator's gear)."""
    return float(model.actuator_gear[index(model, target=target).yaw_act, 0])


def voltage_limit(model: mujoco.MjModel, target: Target | None = None) -> float:
    """The drive's voltage limit [V] (``ctrlrange`` of ``yaw_motor``, or of the ``target``'s
    actuator; inf if unlimited)."""
    i = index(model, target=target).yaw_act
    if not model.actuator_ctrllimited[i]:
        return math.inf
    lo, hi = model.actuator_ctrlrange[i]
    return float(min(-lo, hi))


def set_arm_setpoints(model: mujoco.MjModel, data: mujoco.MjData, gamma1_set_deg: float,
                      gamma2_set_deg: float) -> None:
    """Write the shoulder/elbow servo set points [deg] into ``data.ctrl``."""
    ix = index(model)
    if ix.shoulder_act is not None:
        data.ctrl[ix.shoulder_act] = math.radians(gamma1_set_deg)
    if ix.elbow_act is not None:
        data.ctrl[ix.elbow_act] = math.radians(gamma2_set_deg)


def check_pose(model: mujoco.MjModel, gamma1_deg: float, gamma2_deg: float) -> None:
    """Raise UserError if a pose is outside the shoulder/elbow joint ranges."""
    for name, val in (("shoulder", gamma1_deg), ("elbow", gamma2_deg)):
        if not math.isfinite(val):
            raise UserError(f"{name} angle must be finite, got {val}")
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if model.jnt_limited[j]:
            lo, hi = np.degrees(model.jnt_range[j])
            if not lo - 1e-9 <= val <= hi + 1e-9:
                raise UserError(f"{name} angle {val:g} deg is outside the joint range "
                                f"[{lo:.1f}, {hi:.1f}] deg")


def equilibrium_pose(model: mujoco.MjModel, gamma1_set_deg: float, gamma2_set_deg: float,
                     tol_rad: float = 1e-10) -> tuple[float, float]:
    """Actual (sagged) arm angles [deg] where the servos balance gravity, yaw at rest.

    Solves ``qfrc_bias + qfrc_passive = qfrc_actuator`` for the shoulder and elbow with the
    yaw at 0 by Newton's method on MuJoCo's own forces (finite-difference Jacobian).
    """
    check_pose(model, gamma1_set_deg, gamma2_set_deg)
    ix = index(model)
    data = mujoco.MjData(model)
    set_arm_setpoints(model, data, gamma1_set_deg, gamma2_set_deg)
    dofs = [model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]
            for j in ("shoulder", "elbow")]
    qadr = [ix.shoulder_qpos, ix.elbow_qpos]
    q = np.radians([gamma1_set_deg, gamma2_set_deg])

    def residual(qa: np.ndarray) -> np.ndarray:
        data.qpos[:] = model.qpos0
        data.qpos[qadr] = qa
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        f = data.qfrc_actuator + data.qfrc_passive - data.qfrc_bias
        return f[dofs].copy()

    for _ in range(50):
        f = residual(q)
        h = 1e-7
        jac = np.column_stack([(residual(q + h * e) - f) / h for e in np.eye(2)])
        step = np.linalg.solve(jac, -f)
        q = q + step
        if np.max(np.abs(step)) < tol_rad:
            break
    return float(np.degrees(q[0])), float(np.degrees(q[1]))


def yaw_inertia(gamma1_deg: float, gamma2_deg: float,
                model_path: str | os.PathLike | None = None,
                model: mujoco.MjModel | None = None) -> float:
    """MuJoCo's yaw inertia [kg*m^2] with the arm at these ACTUAL angles [deg].

    The yaw diagonal element of the joint-space mass matrix (``mj_fullM``), armature included.
    """
    if model is None:
        model = load_model(model_path)
    ix = index(model)
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    data.qpos[ix.shoulder_qpos] = math.radians(gamma1_deg)
    data.qpos[ix.elbow_qpos] = math.radians(gamma2_deg)
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    return float(mass[ix.yaw_dof, ix.yaw_dof])


def analytic_yaw_inertia(gamma1_deg, gamma2_deg, I_base: float, m1: float, L1: float,
                         m2: float, L2: float, m_tip: float = 0.0, L_tip: float | None = None,
                         tip_offs_deg: float = 0.0, gamma_offs_deg: float = 0.0):
    """The paper's thin-rod inertia (5) [kg*m^2], extended by a point mass for the stylus.

    ``I = I_base + m1 L1^2 cos^2(g1)/3 + m2 (L1 cos g1 + L2 c2/2)^2 + m2 L2^2 c2^2/12
    + m_tip (L1 cos g1 + L_tip ct)^2`` with ``c2 = cos(pi - g1 - g2 - gamma_offs)`` and
    ``ct = cos(pi - g1 - g2 - gamma_offs - tip_offs)``.  ``m_tip = 0`` gives (5) exactly; the
    tip term is the stylus/gimbal that the paper lumps into link 2 (its centre of mass sits
    ``L_tip`` from the elbow, ``tip_offs`` off the forearm axis, positive upward as gamma_offs).

    Parameters
    ----------
    gamma1_deg, gamma2_deg : float or array [deg]
        Actual arm angles (paper convention).
    I_base : float [kg*m^2]
        Everything that turns with the yaw but not with the arm (turret, motors, rotor).
    m1, L1, m2, L2, m_tip, L_tip : float [kg], [m]
        Link masses and lengths; tip mass and its distance from the elbow (default ``L2``).
    tip_offs_deg, gamma_offs_deg : float [deg]
    """
    L_tip = L2 if L_tip is None else L_tip
    g1 = np.radians(gamma1_deg)
    c1 = np.cos(g1)
    a2 = np.pi - g1 - np.radians(gamma2_deg) - np.radians(gamma_offs_deg)
    c2 = np.cos(a2)
    ct = np.cos(a2 - np.radians(tip_offs_deg))
    return (I_base + m1 * L1**2 * c1**2 / 3 + m2 * (L1 * c1 + 0.5 * L2 * c2) ** 2
            + m2 * L2**2 * c2**2 / 12 + m_tip * (L1 * c1 + L_tip * ct) ** 2)
