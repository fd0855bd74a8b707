"""The virtual Phantom Omni: MuJoCo model, the paper's experiments, datasets, environment.

Public API::

    yaw_inertia(gamma1_deg, gamma2_deg, model_path=None) -> float   # [kg*m^2]
    load_model(path=None) -> mujoco.MjModel
    equilibrium_pose(model, gamma1_set_deg, gamma2_set_deg) -> (gamma1_deg, gamma2_deg)
    experiments.campaign(name), experiments.simulate(exps, model_path, settings)
"""

from .model import DEFAULT_SCENE, MODELS_DIR, equilibrium_pose, load_model, yaw_inertia

__all__ = ["DEFAULT_SCENE", "MODELS_DIR", "equilibrium_pose", "load_model", "yaw_inertia"]

import gymnasium as _gym  # register the environment (omni_sim/env.py) once per process
if "omni_sim/OmniYaw-v0" not in _gym.registry:
    _gym.register(id="omni_sim/OmniYaw-v0", entry_point="omni_sim.env:OmniYawEnv")
