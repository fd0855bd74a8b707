"""Where the installed package's data files are on disk."""

from __future__ import annotations

import atexit
import contextlib
from importlib import resources
from pathlib import Path


def models_dir() -> Path:
    """The folder of the built-in model files, the data package ``omni_sim.models``.

    In an editable install that is the checkout's ``models/`` folder, in a regular install the
    copy inside ``site-packages``; either way a real folder with one folder per device
    (``omni/scene.xml`` includes ``omni.xml`` by a relative path, so MuJoCo needs a device's
    files side by side on disk).
    """
    stack = contextlib.ExitStack()
    path = Path(stack.enter_context(resources.as_file(resources.files("omni_sim.models"))))
    atexit.register(stack.close)
    return path
