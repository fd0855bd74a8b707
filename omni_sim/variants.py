"""Model variants: set numeric attributes of named MJCF elements (via ``mujoco.MjSpec``) and the
run settings of a study (``omni sweep``).

A parameter is either a model attribute ``KIND.NAME.ATTR`` or ``KIND.NAME.ATTR[i]`` (``KIND`` one
of :data:`ELEMENT_KINDS`, e.g. ``joint.yaw.damping``, ``actuator.yaw_motor.gear``,
``body.upper_arm.mass``; an array attribute without an index means its first entry; the LuGre
fields of a ``dcmotor`` have names: ``actuator.yaw_friction.lugre_Fc``, see :data:`ALIASES`)
or one of the run settings :data:`SETTINGS` (``kp``, ``quantize``, ``noise_rad``,
``amplitude_rad``, ``friction_scale``).
"""

from __future__ import annotations

import math
import os
import re

import mujoco
import numpy as np

from identification.errors import UserError

from . import model as om
from .device import Device

#: MjSpec element kinds a parameter may name (``spec.<kind>(name)``).
ELEMENT_KINDS = ("joint", "actuator", "body", "geom", "site", "tendon")
#: Named fields of arrays: LuGre parameters of a ``dcmotor`` (MuJoCo 4 layout, the one
#: :func:`omni_sim.model.yaw_friction` reads).
ALIASES = {
    "lugre_Fc": ("biasprm", 3),       # Coulomb level [N*m]
    "lugre_Fs": ("biasprm", 4),       # static (Stribeck peak) level [N*m]
    "lugre_vs": ("biasprm", 5),       # Stribeck speed [rad/s]
    "lugre_sigma0": ("dynprm", 5),    # pre-sliding (bristle) stiffness [N*m/rad]
}
#: Run settings a study may vary (not model attributes):
#: kp [V/rad] yaw P gain; quantize (0/1) encoder quantisation; noise_rad [rad] encoder noise;
#: amplitude_rad [rad] the sine reference amplitude A_r; friction_scale: the yaw drive's dry
#: friction levels (frictionloss, LuGre Fc and Fs) times this factor
#: (:func:`omni_sim.model.scale_yaw_friction`, applied after the attribute edits).
SETTINGS = ("kp", "quantize", "noise_rad", "amplitude_rad", "friction_scale")

_PARAM = re.compile(r"^([a-z]+)\.([^.\[\]]+)\.([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


def parse_param(name: str) -> tuple[str, str, str, int | None]:
    """``KIND.NAME.ATTR[i]`` -> (kind, element name, attribute, index or None).

    Raises ValueError (the problem, for a message) on a malformed name."""
    m = _PARAM.match(name)
    if not m:
        raise ValueError(f"not a run setting ({', '.join(SETTINGS)}) nor KIND.NAME.ATTR[i] "
                         f"(KIND one of {', '.join(ELEMENT_KINDS)})")
    kind, elem, attr, idx = m.groups()
    if kind not in ELEMENT_KINDS:
        raise ValueError(f"unknown element kind {kind!r} (known: {', '.join(ELEMENT_KINDS)})")
    if attr in ALIASES:
        if idx is not None:
            raise ValueError(f"{attr} is a single number, it takes no index")
        attr, i = ALIASES[attr]
        return kind, elem, attr, i
    return kind, elem, attr, None if idx is None else int(idx)


def _element(spec: mujoco.MjSpec, kind: str, name: str):
    el = getattr(spec, kind)(name)
    if el is None:
        raise ValueError(f"the model has no {kind} named {name!r}")
    return el


def _current(el, attr: str, idx: int | None, kind: str):
    if attr.startswith("_") or not hasattr(el, attr):
        raise ValueError(f"a {kind} has no attribute {attr!r}")
    value = getattr(el, attr)
    if isinstance(value, (bool, str)) or callable(value):
        raise ValueError(f"{kind} attribute {attr!r} is not numeric")
    if isinstance(value, (int, float)):
        if idx not in (None, 0):
            raise ValueError(f"{kind} attribute {attr!r} is a single number, index {idx} is out of range")
        return float(value)
    try:
        arr = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"{kind} attribute {attr!r} is not numeric") from None
    i = 0 if idx is None else idx
    if not 0 <= i < arr.size:
        raise ValueError(f"{kind} attribute {attr!r} has {arr.size} entries, index {i} is out of range")
    return arr


def check_param(spec: mujoco.MjSpec, name: str) -> None:
    """ValueError unless ``name`` is a run setting or a numeric attribute of an element of ``spec``."""
    if name in SETTINGS:
        return
    kind, elem, attr, idx = parse_param(name)
    _current(_element(spec, kind, elem), attr, idx, kind)


def set_param(spec: mujoco.MjSpec, name: str, value: float) -> None:
    """Set one model attribute of ``spec`` (in place)."""
    kind, elem, attr, idx = parse_param(name)
    el = _element(spec, kind, elem)
    cur = _current(el, attr, idx, kind)
    if isinstance(cur, float):
        setattr(el, attr, type(getattr(el, attr))(value))
        return
    arr = np.array(getattr(el, attr), dtype=float)
    flat = arr.reshape(-1)
    flat[0 if idx is None else idx] = value
    setattr(el, attr, arr)


def base_spec(path: str | os.PathLike | None = None, friction: str | None = None) -> mujoco.MjSpec:
    """The MjSpec of a model file or of a built-in friction family's scene."""
    p = om.model_path(path, friction)
    if not p.is_file():
        raise UserError(om.model_not_found(p))
    try:
        return mujoco.MjSpec.from_file(str(p))
    except (ValueError, RuntimeError) as exc:
        raise UserError(f"{p}: not a valid MJCF model ({' '.join(str(exc).split())})") from None


def build(spec: mujoco.MjSpec, values: dict) -> tuple[mujoco.MjSpec, mujoco.MjModel]:
    """A copy of ``spec`` with the model attributes of ``values`` set, compiled, and the yaw dry
    friction scaled by ``values['friction_scale']`` (if given).

    Raises ValueError (MuJoCo's compile error, e.g. a negative mass) or UserError (the contract's
    names missing)."""
    spec = spec.copy()
    for name, v in values.items():
        if name not in SETTINGS:
            set_param(spec, name, float(v))
    model = spec.compile()
    device = Device(model, source="<variant>")
    scale = values.get("friction_scale")
    if scale is not None:
        scale = float(scale)
        if not (math.isfinite(scale) and scale >= 0):
            raise ValueError(f"friction_scale must be >= 0, got {scale}")
        # in the spec (so a written XML carries it), on what the compiled model says is the yaw
        # drive's dry friction (omni_sim.device.Device.scale_friction's elements)
        yaw = spec.joint("yaw")
        yaw.frictionloss = scale * yaw.frictionloss
        for a in device.lugre_actuators():
            el = spec.actuators[a]  # compiled in spec order
            prm = np.array(el.biasprm, dtype=float)
            prm[3:5] *= scale
            el.biasprm = prm
        model = spec.compile()
    return spec, model
