"""The virtual Omni's model files (``omni.xml``, ``scene.xml``, ``calibration.json``).

This folder is installed as the data package ``omni_sim.models`` (see ``pyproject.toml``);
``omni_sim.model.MODELS_DIR`` is its location on disk.
"""
