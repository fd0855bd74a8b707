"""The one door from the installed packages to the validation bank.

The bank (the package ``bank``: its truths, hidden-effect cases and studies) is a distribution
of its own in the source checkout, ``omni-alpha-bank`` (``bank/pyproject.toml``), that a
regular install of the library does not have.  Three things of the ``omni`` command run its
cases: ``omni bench``'s discrepancy figures (``discrepancy_servo``; ``--discrepancy-campaign``)
and ``omni sweep``'s discrepancy pipeline (``hidden = NAME``).  They reach the bank through
:func:`load` only, when asked to run a case, and without the bank they stop at once with one
line that names the fix (:class:`~identification.errors.UserError`: ``error: ...``, exit 2).
No other module of the five packages imports ``bank`` (``tests/test_architecture.py``).
"""

from __future__ import annotations

from identification.errors import UserError

#: How to install the bank (from the root of the source checkout).
INSTALL = "pip install -e ./bank"


def load(needed_by: str):
    """The bank's package with its cases (``bank.hidden``) and geared-servo truth
    (``bank.servo_truth``) imported; ``needed_by`` names what asked for it in the message of
    the :class:`~identification.errors.UserError` raised when the bank is not installed."""
    try:
        import bank.hidden
        import bank.servo_truth
    except ModuleNotFoundError as exc:
        if exc.name not in ("bank", "bank.hidden", "bank.servo_truth"):
            raise  # the bank is there, something it imports is not: not ours to explain
        raise UserError(f"{needed_by} runs cases of the validation bank, which is not installed "
                        f"(a regular install of omni-alpha does not ship it): {INSTALL} from the "
                        "source checkout") from None
    return bank
