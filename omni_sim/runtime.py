"""The drive laws MuJoCo cannot express, for a user's own ``mujoco.mj_step`` loop.

A model may declare drive friction laws (:data:`omni_sim.device.DRIVE_LAWS`: ``load_friction``,
``friction_asymmetry``, ``friction_family``), the smooth load law
(:data:`omni_sim.device.LOAD_FRICTION_SMOOTH`: the callback also sets the joint's
``model.dof_damping`` and ``data.qfrc_applied``, held for the period) and a current limit whose
torque bound moves with the back-EMF (:data:`omni_sim.device.CURRENT_LIMIT`) as
``<custom><numeric>`` data.  MuJoCo ignores custom numerics: stepped
with ``mujoco.mj_step`` alone, such a model is the model WITHOUT the law (the joint keeps its
own ``frictionloss``).  Our engine (:class:`omni_sim.device.Engine`) applies them; this module
applies them in plain MuJoCo, with the same arithmetic (it calls the engine's law terms,
:class:`omni_sim.device.DriveFriction`, and writes no equation of its own)::

    import mujoco
    from omni_sim.runtime import drive_laws

    model = mujoco.MjModel.from_xml_path("model.xml")
    data = mujoco.MjData(model)
    cb = drive_laws(model)                  # once, after loading
    for k in range(n_physics_steps):
        ...                                 # your controller writes data.ctrl
        cb(model, data)                     # before each step
        mujoco.mj_step(model, data)

What the callback does, as the engine does: at the start of every control period (the physics
steps where ``data.time`` is a whole multiple of the period, so ``data.time`` must count from 0
at the start of a run, as ``mj_resetData`` leaves it) it sets the joint's
``model.dof_frictionloss`` to ``max(0, Fc + terms)`` from the joint velocity ``data.qvel`` and
the transmitted torque of the LAST physics step (the ``actuatorfrc`` sensor's
``data.sensordata``, 0 at time 0), and with a current limit the actuator's
``model.actuator_forcerange`` from the joint velocity; at the other steps it does nothing.  So: call it before
every ``mj_step`` (not only at the period starts), and call no ``mj_forward`` between steps
(it would recompute the sensor at the new state, which the engine never reads).  ``Fc`` is the
joint's ``frictionloss`` when :func:`drive_laws` is called: call it once per model, before
stepping (the callback overwrites that field).

The control period, the joint and the actuator are read from the model when the file declares
them (``omni discrepancy`` writes them into ``model.xml``, :func:`declare`):
``<custom><numeric name="drive_laws_control_period_s" data="P"/>`` and
``<custom><text name="drive_laws_target" data="JOINT ACTUATOR"/>``; else pass them to
:func:`drive_laws` (the joint and actuator default to the Omni's ``yaw``/``yaw_motor``).

Why not ``mujoco.set_mjcb_control``: MuJoCo calls the control callback inside ``mj_step`` after
it has built the step's constraints (``mj_fwdPosition``), so a ``frictionloss`` written there
acts one step late, and a joint whose level passes from 0 to positive has no friction row
that step: not the engine's physics.  The callback is therefore called by the user's loop,
before ``mj_step``.

:func:`runtime_note` says whether a model needs this runtime and gives the lines
``omni discrepancy`` writes at the top of ``model.xml``.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .device import (CURRENT_LIMIT, CURRENT_LIMIT_PARAMS, DRIVE_LAWS, FRICTION_ASYMMETRY, FRICTION_FAMILY,
                     LOAD_FRICTION, LOAD_FRICTION_SMOOTH, LOAD_FRICTION_SMOOTH_PARAMS, DriveFriction,
                     substeps_of)
from .device.laws import _DriveLaws, _numeric

#: ``MODULE:FUNCTION`` of the runtime, as the header of an exported model names it.
RUNTIME = "omni_sim.runtime:drive_laws"
#: ``<custom><numeric>``: the control period [s] at whose starts the laws' level is set.
PERIOD_NUMERIC = "drive_laws_control_period_s"
#: ``<custom><text>``: ``"JOINT ACTUATOR"``, the joint whose friction the laws set and the
#: actuator whose transmitted torque they read.
TARGET_TEXT = "drive_laws_target"
#: The laws this package defines (a law a user registers with
#: :func:`omni_sim.device.register_drive_law` exists only in the process that registers it).
BUILTIN_LAWS = (FRICTION_ASYMMETRY, LOAD_FRICTION, FRICTION_FAMILY, CURRENT_LIMIT, LOAD_FRICTION_SMOOTH)
#: The laws the engine applies outside :data:`~omni_sim.device.DRIVE_LAWS` (which holds the
#: Coulomb level's terms), with their numerics' parameters.
OTHER_LAWS = {CURRENT_LIMIT: CURRENT_LIMIT_PARAMS, LOAD_FRICTION_SMOOTH: LOAD_FRICTION_SMOOTH_PARAMS}


class DriveLawsCallback:
    """``cb(model, data)``: the declared drive laws' Coulomb level, set before a physics step
    (see the module docstring; made by :func:`drive_laws`).

    Attributes
    ----------
    laws : dict
        ``{law name: its values}`` the model declares (empty: the callback does nothing).
    dof : int
        The joint's degree of freedom.
    substeps : int
        Physics steps per control period.
    """

    def __init__(self, friction: DriveFriction | None, dof: int, substeps: int):
        self.laws = {} if friction is None else dict(friction.values)
        self.dof = dof
        self.substeps = substeps
        self._friction = friction
        self._levels = None if friction is None else _DriveLaws([friction])

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if self._levels is None:
            return
        k = round(data.time / model.opt.timestep)  # physics steps since the run's start
        if k % self.substeps:
            return  # within a control period: the level stays as set at its start
        adr = self._friction.sensor_adr
        force = 0.0 if k == 0 or adr < 0 else float(data.sensordata[adr])
        self._levels.write([model], np.array([data.qvel[self.dof]]), np.array([force]))
        if self._friction.smooth is not None:  # the smooth law's force, held for the period
            data.qfrc_applied[self.dof] = self._levels.applied[0]


def _target(model: mujoco.MjModel) -> tuple[str, str] | None:
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, TARGET_TEXT)
    if i < 0:
        return None
    a, n = int(model.text_adr[i]), int(model.text_size[i])
    words = bytes(model.text_data[a: a + n]).rstrip(b"\0").decode().split()
    if len(words) != 2:
        raise ValueError(f'<custom><text name="{TARGET_TEXT}"> must hold "JOINT ACTUATOR", got {words}')
    return words[0], words[1]


def drive_laws(model: mujoco.MjModel, control_period_s: float | None = None,
               joint: str | None = None, actuator: str | None = None) -> DriveLawsCallback:
    """The callback that applies ``model``'s drive laws in a plain ``mj_step`` loop.

    Parameters
    ----------
    model : MjModel
        The model to step (its joint's ``frictionloss`` now is the law's ``Fc``).
    control_period_s : float [s], optional
        The controller's period (default: the model's ``drive_laws_control_period_s``
        numeric); a whole multiple of ``model.opt.timestep``.
    joint, actuator : str, optional
        The joint the laws act on and its actuator (default: the model's
        ``drive_laws_target`` text, else ``yaw``/``yaw_motor``).

    Returns
    -------
    DriveLawsCallback
        ``cb(model, data)``, to call before every ``mujoco.mj_step(model, data)``.  A model
        that declares no law, or only laws at zero (:func:`needed_laws`), gets a callback that
        does nothing (the engine's level is then the joint's own ``frictionloss``, bit for bit).

    Raises
    ------
    ValueError
        No control period given or declared; a joint or actuator the model lacks.
    identification.errors.UserError
        A law's values are not a law (e.g. a negative coefficient), or ``load_friction``
        without an ``actuatorfrc`` sensor on the actuator.
    """
    declared = _target(model) or ("yaw", "yaw_motor")
    joint = joint or declared[0]
    actuator = actuator or declared[1]
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    act = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)
    if j < 0 or act < 0:
        raise ValueError(f"the model has no joint {joint!r} or no actuator {actuator!r}: pass "
                         "joint= and actuator= (the drive the laws act on)")
    dof = int(model.jnt_dofadr[j])
    friction = DriveFriction.of(model, act, dof, "model")
    if friction is None or not needed_laws(model):  # laws at zero: the engine's level is Fc
        return DriveLawsCallback(None, dof, 1)
    if control_period_s is None:
        p = _numeric(model, PERIOD_NUMERIC)
        if p is None or len(p) != 1:
            raise ValueError(f"the model declares no control period (<custom><numeric "
                             f'name="{PERIOD_NUMERIC}" data="P"/>): pass control_period_s=')
        control_period_s = float(p[0])
    return DriveLawsCallback(friction, dof, substeps_of(model, control_period_s))


def declare(spec: mujoco.MjSpec, joint: str, actuator: str, control_period_s: float) -> mujoco.MjSpec:
    """``spec`` with its drive laws' control period and target declared for :func:`drive_laws`
    (a copy with the numeric :data:`PERIOD_NUMERIC` and the text :data:`TARGET_TEXT` set), or
    ``spec`` itself when it needs no runtime (:func:`runtime_note`)."""
    if not runtime_note(spec)[0]:
        return spec
    out = spec.copy()
    n = out.numeric(PERIOD_NUMERIC)
    if n is None:
        out.add_numeric(name=PERIOD_NUMERIC, data=[float(control_period_s)])
    else:
        n.data = [float(control_period_s)]
    t = out.text(TARGET_TEXT)
    if t is None:
        out.add_text(name=TARGET_TEXT, data=f"{joint} {actuator}")
    else:
        t.data = f"{joint} {actuator}"
    return out


def needed_laws(model) -> dict:
    """The drive laws ``model`` (an ``MjModel`` or ``MjSpec``) declares with a value other than
    zero, ``{name: values}`` in :data:`~omni_sim.device.DRIVE_LAWS`'s order: what plain MuJoCo
    leaves out.  (A law declared at zero adds nothing: the engine's level is then the joint's
    own ``frictionloss``.)"""
    if isinstance(model, mujoco.MjSpec):
        model = model.copy().compile()
    return {name: v for name in (*DRIVE_LAWS, *OTHER_LAWS)
            if (v := _numeric(model, name)) is not None
            and np.any((v[:3] if name == LOAD_FRICTION_SMOOTH else v) != 0)}  # its w_s alone: no force


def _params(name: str) -> tuple:
    """The parameter names of a law's numeric (a drive law's, or one of :data:`OTHER_LAWS`)."""
    return OTHER_LAWS[name] if name in OTHER_LAWS else DRIVE_LAWS[name].params


def runtime_note(model) -> tuple[bool, list[str]]:
    """Whether ``model`` (an ``MjModel`` or ``MjSpec``) needs :func:`drive_laws` to be the
    model it declares, and the lines that say so (``omni discrepancy``'s ``model.xml`` header).

    A declared law whose values are all zero adds nothing (:func:`needed_laws`): such a model
    runs in plain MuJoCo.

    Returns
    -------
    needs : bool
    lines : list of str
        ``"runs in plain MuJoCo, no runtime"``, or: what the laws are, that ``mj_step`` alone
        is not this model, ``runtime: MODULE:FUNCTION`` and how to call it.
    """
    if isinstance(model, mujoco.MjSpec):
        model = model.copy().compile()
    laws = needed_laws(model)
    if not laws:
        return False, ["runs in plain MuJoCo, no runtime"]
    params = "; ".join(f"{name} (" + ", ".join(f"{p}={x:.6g}" for p, x in zip(_params(name), v))
                       + ")" for name, v in laws.items())
    target = _target(model)
    where = f" on joint {target[0]!r} (actuator {target[1]!r})" if target else ""
    fc = ""
    if target and (j := mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, target[0])) >= 0:
        fc = f" (its own frictionloss {model.dof_frictionloss[model.jnt_dofadr[j]]:.6g} N*m only)"
    period = _numeric(model, PERIOD_NUMERIC)
    lines = [f"NEEDS THE RUNTIME: drive law(s) {params}{where}, written as <custom><numeric> data "
             "that MuJoCo ignores.",
             "Stepped with mujoco.mj_step alone this file is NOT the named model: "
             + " and ".join(([f"the joint keeps a constant friction{fc}"]
                             if set(laws) - {CURRENT_LIMIT, LOAD_FRICTION_SMOOTH} else [])
                            + (["the joint lacks the smooth load friction's force"]
                               if LOAD_FRICTION_SMOOTH in laws else [])
                            + (["the actuator keeps its force range at rest (the current limit's "
                                "bound does not move with the back-EMF)"] if CURRENT_LIMIT in laws else []))
             + "."]
    foreign = [name for name in laws if name not in BUILTIN_LAWS]
    if foreign:
        lines.append(", ".join(foreign) + ": a law registered outside omni_sim "
                     "(omni_sim.device.register_drive_law): its equation is not carried by model.xml, "
                     "only its values; register the same law before calling the runtime.")
    lines += [f"runtime: {RUNTIME}",
              "call: cb = drive_laws(model) once after loading; cb(model, data) before each "
              "mujoco.mj_step(model, data); data.time from 0 at the run's start (mj_resetData)."]
    if period is not None and len(period) == 1:
        lines.append(f"control period {period[0]:.6g} s ({PERIOD_NUMERIC}): the level is set at "
                     "each period's start from the joint velocity and the actuatorfrc sensor of the "
                     "last physics step.")
    else:
        lines.append("no control period declared: pass drive_laws(model, control_period_s=P).")
    return True, lines
