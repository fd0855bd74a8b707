"""Numeric CSV rows: every number as ``"%.17g"`` (the dataset contract's and the predictions'
format: 17 significant digits, ``repr``-exact, trailing zeros removed, e.g. ``0.001``,
``-0.00046958826471445994``, ``1.5e-05``).

:func:`format_rows` is Python's ``%`` operator over the whole array (about 0.4 µs a number).
An application can register a compiled formatter giving the same bytes (:func:`set_kernel`,
e.g. ``omni_app.csv_kernel``); this package stays numpy-only and never imports a compiler.
"""

from __future__ import annotations

import numpy as np

__all__ = ["format_rows", "format_rows_reference", "set_kernel"]

#: A compiled replacement of :func:`format_rows_reference` (same arguments, same bytes),
#: registered with :func:`set_kernel`; None: the reference.
_KERNEL = None


def set_kernel(kernel):
    """Register ``kernel(data) -> bytes``, a faster :func:`format_rows_reference` giving the
    same bytes; ``None`` restores the reference.  Returns the previous one."""
    global _KERNEL
    previous, _KERNEL = _KERNEL, kernel
    return previous


def format_rows_reference(data) -> bytes:
    """The rows of the 2-D float array ``data`` as CSV (ASCII bytes): each number as
    ``"%.17g" % x``, separated by ``,``, each row ended by ``\\n``."""
    data = np.asarray(data, dtype=float)
    if data.ndim != 2:
        raise ValueError(f"data must be 2-D, got shape {data.shape}")
    row = ",".join(["%.17g"] * data.shape[1]) + "\n"
    return ((row * data.shape[0]) % tuple(data.ravel().tolist())).encode("ascii")


def format_rows(data) -> bytes:
    """:func:`format_rows_reference`, by the registered kernel if there is one."""
    if _KERNEL is None:
        return format_rows_reference(data)
    data = np.asarray(data, dtype=float)
    if data.ndim != 2:
        raise ValueError(f"data must be 2-D, got shape {data.shape}")
    return _KERNEL(data)
