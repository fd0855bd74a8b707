"""Load the virtual Omni and check the contract's names (the facts of a loaded model -- gear,
friction, inertia at a pose, the arm's equilibrium -- are :class:`omni_sim.device.Device`'s).

Pose convention (the paper's Fig. 1 and eq. (5)), used everywhere in this package:

* ``gamma1_deg`` -- elevation of the upper arm above the horizontal [deg] (``shoulder`` qpos);
* ``gamma2_deg`` -- the elbow's interior angle between upper arm and forearm [deg] (``elbow``
  qpos), so the forearm's elevation is ``psi = gamma1 + gamma2 - 180`` [deg].

Set points are what the arm servos are asked to hold; the *actual* angles sag below them under
gravity (:func:`equilibrium_pose`), as in the paper's Table 3.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from identification.errors import UserError

from omni_sim._resources import models_dir as _models_dir

#: Folder of the built-in model files: the data package ``omni_sim.models`` (the top-level
#: ``models/`` folder, shipped inside the package; see pyproject.toml), a real folder on disk
#: with one folder per device (models/README.md lists them).
MODELS_DIR = _models_dir()
#: The virtual Omni's folder: its robot ``omni.xml``, the scenes, ``stage.xml``, the
#: calibration records and the provenance of its numbers (``README.md``).
OMNI_DIR = MODELS_DIR / "omni"
#: The geared-servo pendulum's folder (not the Omni: the nominal model of the hidden-effect
#: bank's geared-servo case, :mod:`bank.servo_truth`).
SERVO_PENDULUM_DIR = MODELS_DIR / "servo_pendulum"
#: The geared-servo pendulum's model file (joint ``pivot``, actuator ``servo``).
SERVO_PENDULUM = SERVO_PENDULUM_DIR / "servo_pendulum.xml"
#: The built-in scene (the default friction family; includes ``omni.xml``).
DEFAULT_SCENE = OMNI_DIR / "scene.xml"
#: The friction families of the built-in model: one scene each around the shared robot
#: ``omni.xml`` (docs/method/friction-families.md).  ``lugre`` is the default (``scene.xml``);
#: ``matched`` is both at once, fitted to every published table (docs/studies/fidelity/search.md).
FRICTION_FAMILIES = ("coulomb", "lugre", "matched")
DEFAULT_FRICTION = "lugre"


def scene_path(friction: str | None = None) -> Path:
    """The built-in scene of a friction family (None: the default ``scene.xml``)."""
    if friction is None:
        return DEFAULT_SCENE
    if friction not in FRICTION_FAMILIES:
        raise UserError(f"unknown friction family {friction!r} (choose from "
                        f"{', '.join(FRICTION_FAMILIES)})")
    return OMNI_DIR / f"scene_{friction}.xml"


def model_path(path: str | os.PathLike | None = None, friction: str | None = None) -> Path:
    """The model file a command runs: ``path`` if given, else the family's built-in scene.
    Both at once is a user error (a family names a built-in scene)."""
    if path is not None and friction is not None:
        raise UserError("give either a model file or a friction family, not both (the family "
                        "picks one of the built-in scenes)")
    return Path(path) if path is not None else scene_path(friction)


def model_not_found(path: str | os.PathLike) -> str:
    """The one-line error of a model file that does not exist.  A path that names a built-in
    file directly in a ``models/`` folder gets the file's place in its device's folder
    (``models/scene.xml``: ``models/omni/scene.xml``); a folder gets the ``.xml`` file inside
    it to give (``models/servo_pendulum``: ``models/servo_pendulum/servo_pendulum.xml``)."""
    p = Path(path)
    if p.is_dir():
        return _folder_not_model(p)
    msg = f"{p}: model file not found"
    if p.parent.name == MODELS_DIR.name:
        for folder in (OMNI_DIR, SERVO_PENDULUM_DIR):
            if (folder / p.name).is_file():
                return msg + (f" (the built-in model files are in one folder per device: "
                              f"{p.parent / folder.name / p.name})")
    return msg


def _folder_not_model(folder: Path) -> str:
    """The one-line error of a folder given as the model: the file to give instead (the
    ``scene.xml``, else the ``.xml`` file named as the folder, else the first), and the folder's
    other ``.xml`` files."""
    names = sorted(f.name for f in folder.glob("*.xml") if f.is_file())
    if not names:
        return f"{folder}: is a folder, not a model file, and holds no .xml file; give the model's MJCF file"
    pick = next((n for n in ("scene.xml", f"{folder.name}.xml") if n in names), names[0])
    msg = f"{folder}: is a folder, not a model file; give the MJCF file inside it, e.g. {folder / pick}"
    return msg + (f" (its .xml files: {', '.join(names)})" if len(names) > 1 else "")


def model_digest(path: str | os.PathLike | None) -> str:
    """SHA-256 of the model file's bytes (first 16 hex digits), for run metadata."""
    p = Path(path) if path is not None else DEFAULT_SCENE
    h = hashlib.sha256()
    for f in sorted({p, *p.parent.glob("*.xml")}):
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def builtin_family(path: str | os.PathLike) -> str | None:
    """The friction family of a built-in scene file (``scene.xml``: the default family), or
    None for any other file (what a model carries: :meth:`omni_sim.device.Device.friction_family`)."""
    resolved = Path(path).resolve()
    if resolved == DEFAULT_SCENE.resolve():
        return DEFAULT_FRICTION
    for fam in FRICTION_FAMILIES:
        if resolved == scene_path(fam).resolve():
            return fam
    return None


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
        raise UserError(model_not_found(path))
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


#: What a model without the Omni's names is told (a single-joint robot of the user's own).
OWN_ROBOT_HINT = ("for a single-joint robot of your own, name its joint and actuator: "
                  "--joint NAME --actuator NAME")


def _names(model: mujoco.MjModel, obj, ids) -> str:
    """The names of the elements ``ids`` of type ``obj`` (unnamed ones left out), or "none"."""
    names = [mujoco.mj_id2name(model, obj, i) for i in ids]
    return ", ".join(n for n in names if n) or "none"


def found_names(model: mujoco.MjModel) -> str:
    """The model's hinge joints and actuators, for a message that asks the user to pick one
    (``the model has hinge joints: pivot; actuators: servo``)."""
    hinges = [j for j in range(model.njnt) if _is_hinge(model, j)]
    return (f"the model has hinge joints: {_names(model, mujoco.mjtObj.mjOBJ_JOINT, hinges)}; "
            f"actuators: {_names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, range(model.nu))}")


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
            raise UserError(f"{path}: model lacks the contract's joint(s) {', '.join(missing)} (the "
                            f"virtual Omni's); {OWN_ROBOT_HINT} ({found_names(model)})")
        jid = {j: _joint_id(model, j) for j in JOINTS}
        for j, i in jid.items():
            if model.jnt_type[i] != mujoco.mjtJoint.mjJNT_HINGE:
                raise UserError(f"{path}: joint {j!r} must be a hinge")
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, YAW_ACTUATOR)
        if aid < 0:
            raise UserError(f"{path}: model lacks the contract's actuator {YAW_ACTUATOR!r} (the "
                            f"virtual Omni's); {OWN_ROBOT_HINT} ({found_names(model)})")
        if model.actuator_trntype[aid] != mujoco.mjtTrn.mjTRN_JOINT or model.actuator_trnid[aid, 0] != jid["yaw"]:
            raise UserError(f"{path}: actuator {YAW_ACTUATOR!r} must act on joint 'yaw'")
        joint, actuator, has_arm = "yaw", YAW_ACTUATOR, True
    else:
        joint, actuator = target.joint, target.actuator
        j = _joint_id(model, joint)
        if j < 0:
            raise UserError(f"{path}: model has no joint {joint!r} (the controlled joint, --joint; "
                            f"{found_names(model)})")
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            raise UserError(f"{path}: joint {joint!r} must be a hinge (the controlled joint, --joint; "
                            f"{found_names(model)})")
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)
        if aid < 0:
            raise UserError(f"{path}: model has no actuator {actuator!r} (the controlled "
                            f"joint's actuator, --actuator; {found_names(model)})")
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
