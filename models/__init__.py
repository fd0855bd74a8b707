"""The built-in model files, one folder per device: ``omni/`` (the virtual Omni) and
``servo_pendulum/`` (a geared-servo test case); ``README.md`` lists them.

This folder is installed as the data package ``omni_sim.models`` (see ``pyproject.toml``), each
device folder as a data package of its own; ``omni_sim.model.MODELS_DIR`` is its location on
disk, ``omni_sim.model.OMNI_DIR`` and ``omni_sim.model.SERVO_PENDULUM`` name the devices' files.
"""
