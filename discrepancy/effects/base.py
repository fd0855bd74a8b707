"""What every effect of the library is made of: :class:`Param`, :class:`Effect`, the
:class:`Target` it is written into, and the helpers the families share (the target's joint and
actuator, starting grids, names for added elements)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import mujoco
import numpy as np

from omni_sim import model as om


@dataclass(frozen=True)
class Param:
    """One physical parameter of an effect.

    Attributes
    ----------
    name : str
        Name with its unit (``frictionloss_nm``).
    unit : str
        Unit, for reports.
    lower, upper : float
        Box bounds of the fit (in the parameter's unit).
    scale : float
        Typical size of a realistic change (sets the fit's step and the starting grid).
    """

    name: str
    unit: str
    lower: float
    upper: float
    scale: float


@dataclass(frozen=True)
class Effect:
    """A named candidate effect: parameters, how to read them from a spec and how to write them.

    Attributes
    ----------
    name : str
        snake_case name (the report's ``effects[].name``).
    description : str
        One line: what it is physically.
    params : tuple of Param
    read : callable(spec, target) -> ndarray
        The parameter values the spec holds now (the nominal values) for ``target``
        (:class:`Target`: the controlled joint and its actuator).
    write : callable(spec, values, target) -> None
        Put parameter values into the spec (in place).
    grid : callable(nominal) -> ndarray (G, p)
        Starting points tried before the local fit (the fit is local; a saturation limit far
        above anything the data reaches has no gradient, so a coarse grid comes first).
    applies : callable(spec, target) -> bool
        Whether the effect can be written into this model (e.g. ``arm_mass`` needs the Omni's
        arm bodies); default: always.
    command : callable(v, dt, values) -> ndarray, optional
        For an effect on the command's path only (a delay, a filter): the command the drive
        applies, given the logged command ``v`` on a grid of step ``dt`` [s] -- what the effect
        does to the command, outside the model.  Equation error judges such an effect by
        feeding the model without it this command (:mod:`discrepancy.shape`); None: the effect
        is judged through the model it writes.
    """

    name: str
    description: str
    params: tuple[Param, ...]
    read: Callable[..., np.ndarray] = field(repr=False)
    write: Callable[..., None] = field(repr=False)
    grid: Callable[[np.ndarray], np.ndarray] = field(repr=False)
    applies: Callable[..., bool] = field(default=lambda spec, target=None: True, repr=False)
    command: Callable[..., np.ndarray] | None = field(default=None, repr=False)

    @property
    def nparam(self) -> int:
        return len(self.params)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([p.lower for p in self.params]), np.array([p.upper for p in self.params]))

    def scales(self) -> np.ndarray:
        return np.array([p.scale for p in self.params])

    def clip(self, x: np.ndarray) -> np.ndarray:
        lo, hi = self.bounds()
        return np.clip(x, lo, hi)


#: The virtual Omni's yaw drive (the dataset contract's names).
Target = om.Target
OMNI = om.OMNI


def joint_of(spec: mujoco.MjSpec, target: Target):
    """The target's joint in ``spec``."""
    return spec.joint(target.joint)


def actuator_of(spec: mujoco.MjSpec, target: Target):
    """The target's actuator in ``spec``."""
    return spec.actuator(target.actuator)


def scaled_grid(factors):
    """A one-parameter starting grid: the nominal value times each factor."""
    def grid(x0):
        return np.array([[x0[0] * f] for f in factors])
    return grid


def absolute_grid(values):
    """A one-parameter starting grid of fixed values (whatever the nominal value)."""
    def grid(x0):
        return np.array([[v] for v in values])
    return grid


def unique_name(spec: mujoco.MjSpec, objtype, name: str) -> str:
    """``name``, or ``name_2``, ``name_3``... if an element of ``objtype`` already has it."""
    out, k = name, 1
    while element_exists(spec, objtype, out):
        k += 1
        out = f"{name}_{k}"
    return out


def element_exists(spec: mujoco.MjSpec, objtype, name: str) -> bool:
    """Whether ``spec`` has a joint, body, tendon or actuator (``objtype``) called ``name``."""
    get = {mujoco.mjtObj.mjOBJ_JOINT: spec.joint, mujoco.mjtObj.mjOBJ_BODY: spec.body,
           mujoco.mjtObj.mjOBJ_TENDON: spec.tendon, mujoco.mjtObj.mjOBJ_ACTUATOR: spec.actuator}[objtype]
    return get(name) is not None


def suffixed(name: str, k: int) -> str:
    """``name`` for ``k`` = 1, else ``name_k``."""
    return name if k == 1 else f"{name}_{k}"
