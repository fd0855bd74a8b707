"""The virtual Phantom Omni: MuJoCo model, the paper's experiments, datasets, environment.

Public API::

    yaw_inertia(gamma1_deg, gamma2_deg, model_path=None) -> float   # [kg*m^2]
    load_model(path=None, friction=None) -> mujoco.MjModel           # friction: coulomb | lugre
    equilibrium_pose(model, gamma1_set_deg, gamma2_set_deg) -> (gamma1_deg, gamma2_deg)
    Device(model)   # the device: gear, friction, inertia at a pose, equilibria, start state,
                    # encoder, P law, Engine (yaw_inertia and equilibrium_pose ask it)
    Device.load(path, target=Target("pivot", "servo"))  # a single-joint device of your own
    campaign(name_or_file, arm=True) -> [Experiment]; Experiment(name, kind, r=r) (no arm)
    simulate(device, exps, Settings(kp=..., command_limit=...)) -> [identification.Run]

A walk through them: docs/usage/python.md.
"""

import gymnasium

from .device import Device, Encoder, Engine
from .experiments import Experiment, Settings, campaign, simulate
from .model import DEFAULT_SCENE, FRICTION_FAMILIES, MODELS_DIR, OMNI_DIR, Target, load_model


def yaw_inertia(gamma1_deg: float, gamma2_deg: float, model_path=None, model=None) -> float:
    """MuJoCo's yaw inertia [kg*m^2] with the arm at these ACTUAL angles [deg]
    (:meth:`Device.inertia` of the model file, default the built-in scene, or of a compiled
    ``model``)."""
    device = Device(model) if model is not None else Device.load(model_path)
    return device.inertia(gamma1_deg, gamma2_deg)


def equilibrium_pose(model, gamma1_set_deg: float, gamma2_set_deg: float) -> tuple[float, float]:
    """The actual (sagged) arm angles [deg] of these servo set points
    (:meth:`Device.equilibrium`)."""
    return Device(model).equilibrium(gamma1_set_deg, gamma2_set_deg)


__all__ = ["DEFAULT_SCENE", "FRICTION_FAMILIES", "MODELS_DIR", "OMNI_DIR", "Device", "Encoder", "Engine",
           "Experiment", "Settings", "Target", "campaign", "equilibrium_pose", "load_model", "simulate",
           "yaw_inertia"]

# the gymnasium environments (gymnasium's documented way: registered when the package is imported)
gymnasium.register(id="omni_sim/OmniYaw-v0", entry_point="omni_sim.env:OmniYawEnv",
                   vector_entry_point="omni_sim.vector_env:OmniYawVectorEnv")
gymnasium.register(id="omni_sim/OmniWall-v0", entry_point="omni_sim.wall_env:OmniWallEnv")
