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



def _register_env() -> None:
    """Register the environment (omni_sim/env.py) with gymnasium, once per process."""
    import gymnasium as gym

    if "omni_sim/OmniYaw-v0" not in gym.registry:
        gym.register(id="omni_sim/OmniYaw-v0", entry_point="omni_sim.env:OmniYawEnv",
                     vector_entry_point="omni_sim.vector_env:OmniYawVectorEnv")


class _RegisterWhenGymnasiumLoads:
    """A meta-path finder that registers the environment right after ``gymnasium`` is first
    imported: importing gymnasium takes ~0.3 s, which the command line (simulation,
    identification) does not need, while ``import omni_sim`` then ``gym.make(...)`` works in
    either order."""

    def find_spec(self, name, path=None, target=None):
        if name != "gymnasium":
            return None
        import importlib.util

        sys.meta_path.remove(self)  # find the real spec without this finder
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        exec_module = spec.loader.exec_module

        def exec_and_register(module):
            exec_module(module)
            _register_env()

        spec.loader.exec_module = exec_and_register
        return spec


import sys  # noqa: E402

if "gymnasium" in sys.modules:
    _register_env()
elif not any(isinstance(f, _RegisterWhenGymnasiumLoads) for f in sys.meta_path):
    sys.meta_path.insert(0, _RegisterWhenGymnasiumLoads())
