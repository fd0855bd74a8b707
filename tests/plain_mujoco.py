"""A reference replay of an exported ``model.xml`` in plain MuJoCo, from the dataset contract.

An independent check of ``report.json``'s ``exported_model.gap_rad`` (``omni discrepancy``'s
own replay is the device engine, :mod:`omni_sim.device`): nothing of the engine or the
discrepancy package is used here, only ``mujoco`` and, when ``model.xml``'s header names one
(a line ``runtime: MODULE:FUNCTION``), that runtime imported by its name.  Written from
README.md's Data section and :mod:`omni_sim.runtime`'s docstring:

* the model is ``mujoco.MjModel.from_xml_string`` of the file's text (its header comment is
  ignored by MuJoCo);
* a run starts at rest with the joint at the measured ``theta[0]``, every other joint at
  ``qpos0`` (``mj_resetData``, then ``mj_forward``): a single-joint device (no Omni arm, no
  two-mass drive);
* the device's loop runs at the run's ``control_period_s`` (default: the sample period), on the
  grid ``t[0] + k P``: at each period the angle ``y_k`` is read, ``v_k = clip(kp (r_k - y_k),
  +-command_limit)`` (no clip without ``command_limit``; MuJoCo clips at the actuator's
  ``ctrlrange``) is written and held for the ``P / timestep`` physics steps; ``r_k`` and the
  ``enabled`` switch are the last logged sample's at or before the grid time;
* while ``enabled`` is 0 the command is 0 and the actuator's torque is off: its gain and bias
  zeroed (a ``dcmotor``'s motor constant), restored when it is on again;
* the runtime's callback, if any, is called before every ``mj_step``;
* the angle is read at the logged times (linear interpolation between the two grid samples
  around a time that is not on the grid) and the gap is the root of the mean over runs of
  each run's mean-square error.
"""

from __future__ import annotations

import importlib
import math
import re

import mujoco
import numpy as np

#: Fraction of a control period within which a logged time counts as on the grid (text
#: rounding of the times), as the README's contract allows.
ON_GRID = 1e-3


def runtime_of(xml_text: str):
    """The runtime factory ``model.xml``'s header names (``runtime: MODULE:FUNCTION``),
    imported; None if the header names none."""
    m = re.search(r"^runtime: ([\w.]+):(\w+)\s*$", xml_text, re.MULTILINE)
    if m is None:
        return None
    return getattr(importlib.import_module(m.group(1)), m.group(2))


def replay_plain(xml_text: str, run, joint: str, actuator: str, use_runtime: bool = True) -> np.ndarray:
    """The angle [rad] of ``joint`` at ``run``'s logged times, ``model.xml`` (its text) stepped
    with ``mujoco.mj_step`` in the contract's P loop (see the module docstring).

    Parameters
    ----------
    xml_text : str
        The exported file's text.
    run : identification.dataset.Run
        A measured run (``t``, ``r``, ``theta``, ``meta`` with ``kp`` and optional
        ``command_limit``, ``control_period_s``; the optional ``enabled`` column).
    joint, actuator : str
        The controlled hinge and its actuator.
    use_runtime : bool
        Call the header's runtime (if it names one) before each step; False: plain
        ``mj_step`` alone.
    """
    model = mujoco.MjModel.from_xml_string(xml_text)
    factory = runtime_of(xml_text) if use_runtime else None
    cb = factory(model) if factory is not None else None
    q = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)]
    a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)
    t = np.asarray(run.t, float) - run.t[0]
    period = float(run.meta.get("control_period_s") or np.median(np.diff(t)))
    substeps = round(period / model.opt.timestep)
    limit = float(run.meta.get("command_limit", math.inf))
    kp = float(run.meta["kp"])
    enabled = run.extra.get("enabled")
    # each logged time t_i = (j_i + f_i) P: grid index and fraction
    s = t / period
    j = np.floor(s + ON_GRID).astype(int)
    f = s - j
    f[np.abs(f) < ON_GRID] = 0.0
    n_grid = int(j[-1] + (1 if f[-1] > 0 else 0) + 1)
    last = np.clip(np.searchsorted(t, np.arange(n_grid) * period + ON_GRID * period, side="right") - 1,
                   0, len(t) - 1)  # the last logged sample at or before each grid time
    gain_on, bias_on = model.actuator_gainprm[a].copy(), model.actuator_biasprm[a].copy()
    d = mujoco.MjData(model)
    d.qpos[q] = run.theta[0]
    mujoco.mj_forward(model, d)
    grid = np.empty(n_grid)
    for k in range(n_grid):
        grid[k] = d.qpos[q]
        on = enabled is None or enabled[last[k]] > 0.5
        _torque(model, a, on, gain_on, bias_on)
        d.ctrl[a] = np.clip(kp * (run.r[last[k]] - grid[k]), -limit, limit) if on else 0.0
        for _ in range(substeps):
            if cb is not None:
                cb(model, d)
            mujoco.mj_step(model, d)
    out = grid[j].copy()
    m = f > 0
    out[m] += f[m] * (grid[j[m] + 1] - grid[j[m]])
    return out


def _torque(model, a: int, on: bool, gain_on: np.ndarray, bias_on: np.ndarray) -> None:
    """Switch actuator ``a``'s torque on (its own gain and bias) or off (gain and bias 0; a
    ``dcmotor``'s motor constant 0: no torque, no back-EMF)."""
    if on:
        model.actuator_gainprm[a] = gain_on
        model.actuator_biasprm[a] = bias_on
    elif model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_DCMOTOR:
        model.actuator_gainprm[a, 1] = 0.0
    else:
        model.actuator_gainprm[a] = 0.0
        model.actuator_biasprm[a] = 0.0


def plain_gap(xml_text: str, runs, joint: str, actuator: str, use_runtime: bool = True) -> float:
    """The gap [rad] of ``model.xml`` to ``runs``: the root of the mean over runs of each run's
    mean-square error of :func:`replay_plain` at the logged times."""
    ms = [np.mean((replay_plain(xml_text, r, joint, actuator, use_runtime) - r.theta) ** 2) for r in runs]
    return float(np.sqrt(np.mean(ms)))
