"""Write the fourth test half's datasets: one folder of logged runs per truth, and ``cases.json``.

The campaign, the P law, the log's jitter and the metadata are the first half's
(``bank.test_half.make``: :func:`~bank.test_half.make.campaign`,
:func:`~bank.test_half.make.log_ticks`, ``KP``, ``COMMAND_LIMIT``, ``RUN_S``, ``REST_S``):
12 runs of 6 s per case, the servo's loop at 1 kHz, the host's log at about 200 Hz.  Only the
truths (``bank.test_half_4.truths``) are this half's; they run in the second half's loop
(through :func:`bank.test_half_4.truths.simulate`, which profiles the goal for the goal-profile
case), and the second half's make writes them (:class:`bank.test_half_2.make.Half`).

Usage::

    python -m bank.test_half_4.make --out bank_data_4 [--seed 45] [--only j_null] [--force]

Same seed -> same bytes (each case's plant perturbation comes from ``seed * 100 + index``, its
log jitter from ``(seed, index, 4)``).
"""

from __future__ import annotations

from bank.test_half_2 import make as make2
from bank.test_half_4 import truths as tr4

DEFAULT_SEED = 45
#: The third entry of the log jitter's seed (the first half's is 1, the second's 2, the third's 3).
JITTER_SALT = 4
#: This half (the second half's make, :class:`bank.test_half_2.make.Half`, with its truths).
HALF = make2.Half(tr4, DEFAULT_SEED, JITTER_SALT, "the bank's fourth test half (bank/README.md)")


def run_case(index: int, name: str, seed: int, quick: bool = False):
    """Simulate one case's campaign (the second half's, with this half's truths).  ``quick``:
    the first and last runs only, 1.5 s each (tests)."""
    return make2.run_half_case(HALF, index, name, seed, quick)


def main(argv: list[str] | None = None) -> int:
    return make2.half_main(HALF, argv, __doc__.split("\n\n")[0])


if __name__ == "__main__":
    raise SystemExit(main())
