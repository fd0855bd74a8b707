"""The virtual Phantom Omni: MuJoCo model, the paper's experiments, datasets, environment.

Public API::

    yaw_inertia(gamma1_deg, gamma2_deg, model_path=None) -> float   # [kg*m^2]
    load_model(path=None, friction=None) -> mujoco.MjModel           # friction: coulomb | lugre
    equilibrium_pose(model, gamma1_set_deg, gamma2_set_deg) -> (gamma1_deg, gamma2_deg)
    Device(model)                       # the device: start state, encoder, P law, Engine
    experiments.campaign(name_or_file), experiments.simulate(exps, model_path, settings)
"""

from .device import Device, Encoder, Engine
from .model import (DEFAULT_SCENE, FRICTION_FAMILIES, MODELS_DIR, equilibrium_pose, load_model,
                    yaw_inertia)

__all__ = ["DEFAULT_SCENE", "FRICTION_FAMILIES", "MODELS_DIR", "Device", "Encoder", "Engine",
           "equilibrium_pose", "load_model", "yaw_inertia"]

import gymnasium as _gym  # register the environment (omni_sim/env.py) once per process
if "omni_sim/OmniYaw-v0" not in _gym.registry:
    _gym.register(id="omni_sim/OmniYaw-v0", entry_point="omni_sim.env:OmniYawEnv",
                  vector_entry_point="omni_sim.vector_env:OmniYawVectorEnv")
