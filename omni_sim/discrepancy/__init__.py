"""Find where a model and measurements disagree, name the missing effect, add it, show the gap
shrink (``omni discrepancy``; the command, its report and the demo live in :mod:`omni_app.discrepancy`).

Modules: :mod:`.replay` (closed-loop replay of measured runs, batched), :mod:`.localise` (maps
of the gap), :mod:`.effects` (the named candidate library, MJCF changes), :mod:`.fit`
(simulation-error fits, uncertainties), :mod:`.select` (held-out scoring and acceptance),
:mod:`.workflow` (all of it),
:mod:`.bank` (hidden-effect truth models for the demo and tests).
"""

from .effects import LIBRARY, NAMES
from .workflow import run_discrepancy

__all__ = ["run_discrepancy", "LIBRARY", "NAMES"]
