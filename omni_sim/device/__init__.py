"""The virtual Omni as a device: built once from a model, stepped by one closed-loop engine.

In the spirit of dm_control's ``Physics``: a :class:`Device` is built once per compiled model and
owns everything that makes the model a *device* rather than a physics model, and is the one
place each fact about it is computed, for its :class:`~omni_sim.model.Target` (the Omni's yaw
or a user's hinge):

* the name index of the contract's joints and actuators (:class:`omni_sim.model.OmniIndex`;
  :func:`omni_sim.model.index` is called here and by the loader, nowhere else);
* the drive's torque constant (gear), voltage limit and the physics substeps of one control
  period;
* the drive's friction (:meth:`Device.friction`, :meth:`Device.friction_family`,
  :meth:`Device.scale_friction`) and the encoder joint's inertia at a pose
  (:meth:`Device.inertia`, from MuJoCo's mass matrix);
* the arm: its control (:meth:`Device.set_arm_control`), its joint ranges
  (:meth:`Device.check_pose`) and the equilibrium (sagged) pose of each pair of servo set
  points (:meth:`Device.equilibrium`, cached);
* the start state of a run: arm at that pose, yaw at rest at ``theta0``;
* the encoder (:class:`Encoder`: quantisation, white noise, seeded per-run streams);
* the clipped P law ``v = clip(kp (r - y), -V, V)`` of the paper's experiments;
* the drive's friction laws that no MJCF attribute can hold (a registry, :data:`DRIVE_LAWS`:
  friction set by the torque the gearbox transmits, direction-dependent Coulomb friction, the
  next one a user writes), declared in the model's ``<custom>`` numerics and applied by the
  engine at every control period (:class:`DriveFriction`).

:class:`Engine` is the one closed loop every user of the device steps through: the generator's
reference path (:func:`run_p_loop`, used by :func:`omni_sim.experiments.simulate`), the gymnasium
environment (:mod:`omni_sim.env`, an agent instead of the P law) and the discrepancy replay
(:mod:`discrepancy.replay`, many models in one batch).  The ``mujoco.rollout`` fast path
of :mod:`omni_sim.experiments` (the P law folded into the model) is a shortcut, tested bit for
bit against it.

Time convention (the whole project): sample ``k`` is at ``t_k = k dt`` with ``dt`` the control
period; ``y_k`` is the yaw *measured* at ``t_k`` (before the controller acts), the command
``v_k`` is held (zero-order hold) over ``[t_k, t_k + dt)``, i.e. for ``substeps`` physics steps.

The package's rooms (every name is importable from :mod:`omni_sim.device` itself):

* :mod:`~omni_sim.device.core`: :class:`Device` and :func:`coupled_hinges`;
* :mod:`~omni_sim.device.parameters`: the device's named parameters (masses, damping, servo
  gains, LuGre, the drive's dry friction), a base class of :class:`Device`;
* :mod:`~omni_sim.device.laws`: the drive-law registry and :class:`DriveFriction`;
* :mod:`~omni_sim.device.encoder`: :class:`Encoder`, :func:`encoder_reader`, :func:`read_encoder`;
* :mod:`~omni_sim.device.engine`: :class:`Engine`, :func:`p_law`, :func:`run_p_loop`, the
  control period and the physics substeps of one.
"""

from .core import Device, coupled_hinges
from .encoder import ENCODER_STEP_RAD, Encoder, encoder_reader, read_encoder
from .engine import (CONTROL_PERIOD_S, STATE_SPEC, THREADS_ENV, Engine, default_threads, p_law, run_p_loop,
                     substeps_of)
from .laws import (CURRENT_LIMIT, CURRENT_LIMIT_PARAMS, DRIVE_LAWS, FRICTION_ASYMMETRY, FRICTION_FAMILY,
                   LOAD_FRICTION, LOAD_FRICTION_BLEND_RAD_S, LOAD_FRICTION_SMOOTH, LOAD_FRICTION_SMOOTH_PARAMS,
                   DriveFriction, DriveLaw, register_drive_law, smooth_load_level)
from .laws import _DriveLaws, _numeric  # noqa: F401 (omni_sim.runtime's)

__all__ = ["CONTROL_PERIOD_S", "CURRENT_LIMIT", "CURRENT_LIMIT_PARAMS", "DRIVE_LAWS", "ENCODER_STEP_RAD",
           "FRICTION_ASYMMETRY", "FRICTION_FAMILY", "LOAD_FRICTION", "LOAD_FRICTION_BLEND_RAD_S",
           "LOAD_FRICTION_SMOOTH", "LOAD_FRICTION_SMOOTH_PARAMS", "STATE_SPEC",
           "THREADS_ENV", "Device", "DriveFriction", "DriveLaw", "Encoder", "Engine", "coupled_hinges",
           "default_threads", "encoder_reader",
           "p_law", "read_encoder", "register_drive_law", "run_p_loop", "smooth_load_level", "substeps_of"]
