"""Find where a model and measurements disagree, name the missing effect, add it, show the gap
shrink (``omni discrepancy``; the command, its report and the demo live in :mod:`omni_app.discrepancy`).

Modules: :mod:`.replay` (closed-loop replay of measured runs, batched), :mod:`.localise` (maps
of the gap, and where it lives in words), :mod:`.effects` (the named candidate library, MJCF
changes written into a :class:`~omni_sim.model.Target`), :mod:`.fit` (simulation-error fits),
:mod:`.select` (prescreen, held-out scoring, pairs, acceptance), :mod:`.uncertainty` (standard
errors and the 95 % interval), :mod:`.workflow` (all of it), :mod:`.bank` (hidden-effect truth
models written independently of the library, for the demo, the tests and the coverage study).
"""

from .effects import LIBRARY, NAMES
from .workflow import run_discrepancy

__all__ = ["run_discrepancy", "LIBRARY", "NAMES"]
