"""The environments' option errors and number checks (:mod:`omni_sim.env`, its tasks)."""

from __future__ import annotations

import math

from identification.errors import UserError

__all__ = ["InvalidOptionError", "finite"]


class InvalidOptionError(UserError, ValueError):
    """A bad option or action: both a :class:`ValueError` and the project's ``UserError``."""


def finite(name: str, value, lo: float = -math.inf, hi: float = math.inf,
           lo_open: bool = False) -> float:
    """``value`` as a float, or :class:`InvalidOptionError` naming ``name`` when it is not a
    finite number in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InvalidOptionError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or x < lo or x > hi or (lo_open and x == lo):
        rel = ">" if lo_open else ">="
        rng = f"{rel} {lo:g}" if math.isinf(hi) else f"in [{lo:g}, {hi:g}]"
        raise InvalidOptionError(f"{name} must be finite and {rng}, got {value!r}")
    return x
