"""The paper's identification method (numpy/scipy only; never imports MuJoCo).

Works on any dataset in the contract's format (see :mod:`identification.dataset`), simulated
or measured on a real Phantom Omni.
"""

from .dataset import Run, read_dataset, read_run, write_run
from .errors import UserError

__all__ = ["Run", "UserError", "read_dataset", "read_run", "write_run"]
