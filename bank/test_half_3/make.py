"""Write the third test half's datasets: one folder of logged runs per truth, and ``cases.json``.

The campaign, the P law, the log's jitter and the metadata are the first half's
(``bank.test_half.make``: :func:`~bank.test_half.make.campaign`,
:func:`~bank.test_half.make.log_ticks`, ``KP``, ``COMMAND_LIMIT``, ``RUN_S``, ``REST_S``):
12 runs of 6 s per case, the servo's loop at 1 kHz, the host's log at about 200 Hz.  Only the
truths (``bank.test_half_3.truths``) are this half's; they run in the second half's loop
(:func:`bank.test_half_2.truths.simulate`, re-exported as ``bank.test_half_3.truths.simulate``),
and the second half's make writes them (:class:`bank.test_half_2.make.Half`).

Usage::

    python -m bank.test_half_3.make --out bank_data_3 [--seed 44] [--only j_null] [--force]

Same seed -> same bytes (each case's plant perturbation comes from ``seed * 100 + index``, its
log jitter from ``(seed, index, 3)``).
"""

from __future__ import annotations

from bank.test_half_2 import make as make2
from bank.test_half_3 import truths as tr3

DEFAULT_SEED = 44
#: The third entry of the log jitter's seed (the first half's is 1, the second's 2).
JITTER_SALT = 3
#: This half (the second half's make, :class:`bank.test_half_2.make.Half`, with its truths).
HALF = make2.Half(tr3, DEFAULT_SEED, JITTER_SALT, "the bank's third test half (bank/README.md)")


def run_case(index: int, name: str, seed: int, quick: bool = False):
    """Simulate one case's campaign (the second half's, with this half's truths).  ``quick``:
    the first and last runs only, 1.5 s each (tests)."""
    return make2.run_half_case(HALF, index, name, seed, quick)


def main(argv: list[str] | None = None) -> int:
    return make2.half_main(HALF, argv, __doc__.split("\n\n")[0])


if __name__ == "__main__":
    raise SystemExit(main())
