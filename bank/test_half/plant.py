"""The plant of every test-half truth: the geared servo pendulum the nominal file describes.

Split out of :mod:`bank.test_half.truths` (whose docstring describes the plant, the servo and
the integration) without a change of content: the nominal file ``models/servo_pendulum/`` is
compiled with MuJoCo only to read its constants (:func:`nominal_plant`), and each truth puts
them 5-15 % off (:func:`perturbed`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
#: The nominal model: the plant of every truth and the model given to ``omni discrepancy``.
NOMINAL_REL = "models/servo_pendulum/servo_pendulum.xml"
NOMINAL = ROOT / NOMINAL_REL
JOINT, ACTUATOR = "pivot", "servo"

CONTROL_PERIOD_S = 1e-3
SUBSTEPS = 10
H = CONTROL_PERIOD_S / SUBSTEPS
COUNTS_PER_REV = 4096
ENCODER_STEP_RAD = 2 * math.pi / COUNTS_PER_REV
#: Share of the file's joint damping that is back-EMF: its comment gives 0.36 of 0.37
#: (kt^2/R with kt = 1.2 N m/A, R = 4 ohm), the other 0.01 bearing and gear viscous loss.
EMF_SHARE = 0.36 / 0.37


@dataclass(frozen=True)
class Plant:
    """The joint's constants at the output shaft.

    Attributes
    ----------
    j_link : float
        Pendulum inertia about the pivot, without the rotor [kg m^2].
    mgl : float
        Gravity torque at 90 deg [N m] (``theta`` = 0 hanging down).
    armature : float
        Reflected rotor inertia [kg m^2].
    gear : float
        Torque per volt ``kt/R`` [N m/V].
    emf : float
        Back-EMF damping ``kt^2/R`` [N m s/rad].
    bearing : float
        Bearing and gear viscous loss [N m s/rad].
    coulomb : float
        Load-independent Coulomb friction of the gear train [N m].
    supply : float
        Supply voltage, the drive's clip [V].
    """

    j_link: float
    mgl: float
    armature: float
    gear: float
    emf: float
    bearing: float
    coulomb: float
    supply: float

    @property
    def kt(self) -> float:
        """Torque constant at the output [N m/A]: ``(kt^2/R) / (kt/R)``."""
        return self.emf / self.gear

    @property
    def resistance(self) -> float:
        """Winding resistance [ohm]: ``kt / (kt/R)``."""
        return self.kt / self.gear

    @property
    def inertia(self) -> float:
        """Total inertia about the pivot [kg m^2]."""
        return self.j_link + self.armature


def nominal_plant(path: str | Path = NOMINAL) -> Plant:
    """Read the plant of an MJCF file with MuJoCo (joint ``pivot``, motor ``servo``)."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    dof = int(m.joint(JOINT).dofadr[0])
    act = m.actuator(ACTUATOR).id
    armature = float(m.dof_armature[dof])
    damping = float(m.dof_damping[dof])
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    d.qpos[m.joint(JOINT).qposadr[0]] = math.pi / 2
    mujoco.mj_forward(m, d)
    return Plant(j_link=float(full[dof, dof]) - armature, mgl=float(d.qfrc_bias[dof]),
                 armature=armature,
                 gear=float(m.actuator_gear[act, 0] * m.actuator_gainprm[act, 0]),
                 emf=damping * EMF_SHARE, bearing=damping * (1 - EMF_SHARE),
                 coulomb=float(m.dof_frictionloss[dof]),
                 supply=float(m.actuator_ctrlrange[act, 1]))


def perturbed(plant: Plant, seed: int) -> tuple[Plant, dict]:
    """The truth's plant: armature, gear, damping (back-EMF and bearing together) and
    Coulomb friction each scaled by ``1 +- U(0.05, 0.15)`` (sign and size from ``seed``).

    Returns the plant and the factors.  The back-EMF follows the gear as a motor's does
    (``kt^2/R = (kt/R) kt``): its factor is the damping's, so kt = emf/gear moves too.
    """
    rng = np.random.default_rng([seed, 7])
    names = ("armature", "gear", "damping", "coulomb")
    size = rng.uniform(0.05, 0.15, len(names))
    sign = rng.choice([-1.0, 1.0], len(names))
    f = {n: float(1 + s * z) for n, s, z in zip(names, sign, size)}
    return replace(plant, armature=plant.armature * f["armature"], gear=plant.gear * f["gear"],
                   emf=plant.emf * f["damping"], bearing=plant.bearing * f["damping"],
                   coulomb=plant.coulomb * f["coulomb"]), f
