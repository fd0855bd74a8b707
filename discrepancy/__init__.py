"""Find where a model and measurements disagree, name the missing effect, add it, show the gap
shrink (``omni discrepancy``; the command, its report and the demo live in :mod:`omni_app.discrepancy`).

Modules:

* the MuJoCo side: :mod:`.replay` (closed-loop replay of measured runs, batched),
  :mod:`.effects` (the named candidate library, MJCF changes written into a
  :class:`~omni_sim.model.Target`; a package, one module per family);
* the statistics, which import no MuJoCo (they get models from an
  :class:`~.effects.ModelBuilder` and simulations from a :class:`~.replay.Replayer`):
  :mod:`.runs` (a run prepared for replay), :mod:`.localise` (maps of the gap, and where it
  lives in words), :mod:`.fit` (simulation-error fits), :mod:`.select` (prescreen, held-out
  scoring, pairs, acceptance), :mod:`.uncertainty` (standard errors and the 95 % interval),
  :mod:`.report` (the content of ``report.json``, from what the search found);
* :mod:`.result` (what the workflow returns: :class:`~.result.DiscrepancyResult`, its named
  effects and corrections typed);
* :mod:`.search` (the search: one :class:`~.search.Search` through all its stages) and
  :mod:`.workflow` (all of it, step by step: load, prepare, search, report);
* hidden effects, written independently of the library: :mod:`.experiment_set` (the compact
  experiment set of the hidden-effect cases and its measurement noise) and :mod:`.demo`
  (``omni discrepancy --demo``'s hidden loop delay and its runs).  The validation bank's
  truths, cases and studies are not part of the library: they are the package ``bank`` of
  the source checkout, a distribution of its own (``bank/README.md``).
"""

from .effects import LIBRARY, NAMES
from .result import Correction, DiscrepancyResult, NamedEffect
from .workflow import run_discrepancy

__all__ = ["run_discrepancy", "DiscrepancyResult", "NamedEffect", "Correction", "LIBRARY", "NAMES"]
