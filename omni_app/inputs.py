"""Checks of user input the commands share, made before any long work.

A run's pose is checked by the rule ``omni discrepancy`` applies when it replays a run
(:meth:`omni_sim.device.Device.check_pose`: finite angles inside the model's shoulder and elbow
joint ranges), so that ``identify``, ``validate``, ``fit-inertia`` and ``generate`` refuse the
poses ``discrepancy`` refuses.  The dataset's own rules (columns, times, metadata numbers) are
:func:`identification.dataset.read_run`'s; the output paths' are
:func:`identification.dataset.check_output_dir` and ``check_output_file``.
"""

from __future__ import annotations

from pathlib import Path

from identification.errors import UserError
from omni_sim import model as om


def omni_pose_check(model=None):
    """The rule ``omni discrepancy`` applies to a run's pose:
    :meth:`omni_sim.device.Device.check_pose` of the model file ``model`` (default: the
    built-in Omni; every friction family shares ``models/omni/omni.xml``): finite angles inside the
    shoulder and elbow joint ranges."""
    from omni_sim.device import Device

    return Device(om.load_model(model)).check_pose


def check_run_poses(runs, data, model=None, *, device=None) -> None:
    """Refuse a run whose pose the Omni of ``model`` (default: the built-in one), or of a
    loaded ``device`` (not compiled again), cannot take (:func:`omni_pose_check`): its actual
    angles ``gamma1_deg``/``gamma2_deg`` and its set points, where given.  ``data``: the
    dataset folder (for the message)."""
    check = device.check_pose if device is not None else omni_pose_check(model)
    for run in runs:
        for keys in (("gamma1_deg", "gamma2_deg"), ("gamma1_set_deg", "gamma2_set_deg")):
            g1, g2 = (run.meta.get(k) for k in keys)
            if g1 is None or g2 is None:
                continue
            try:
                check(float(g1), float(g2))
            except UserError as exc:
                raise UserError(f"{Path(data) / run.name}.json: {keys[0]}, {keys[1]}: {exc} "
                                "(the Omni's joint ranges)") from None


def require_run_poses(runs, data) -> None:
    """Refuse a run without an arm pose (each angle: its set point ``gammaI_set_deg`` or its
    actual ``gammaI_deg``, the replay's rule) where the model is the Omni's, which needs one: the
    message tells a user with a single-joint robot of their own how to name it.  ``data``: the
    dataset folder (for the message)."""
    for run in runs:
        if not all(run.meta.get(f"gamma{i}_set_deg") is not None or run.meta.get(f"gamma{i}_deg") is not None
                   for i in (1, 2)):
            raise UserError(f"{Path(data) / run.name}.json: no arm pose (gamma1_deg, gamma2_deg [deg]), "
                            f"which the Omni's model needs; {om.OWN_ROBOT_HINT}, and give its model: "
                            "--model FILE")
