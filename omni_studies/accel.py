"""The compiled α loop (:mod:`omni_studies.alpha_kernel`, numba), registered by the application.

``identification`` is numpy/scipy only: its α simulation runs a numpy time loop unless an
application registers a compiled one (:func:`identification.simulate.set_kernel`).
:func:`install` registers a stand-in that, at the first α simulation, imports numba, loads the
compiled loop from its on-disk cache (or compiles it), registers it in its own place and runs
it; so a command that simulates no α model never imports numba.  If numba is missing or fails,
a warning is given and the numpy loop is registered instead (the same numbers to a few ulps
per step, see :mod:`omni_studies.alpha_kernel`).
"""

from __future__ import annotations

import warnings


def _first_call(*args):
    """The α time loop's first call: load the compiled loop, register it, run it (the numpy
    loop if that fails: numba compiles a loop before it runs, so a failure has written
    nothing)."""
    from identification import simulate

    try:
        from .alpha_kernel import loop

        loop(*args)
    except Exception as exc:  # noqa: BLE001  (reported; the numpy loop gives the same numbers)
        warnings.warn(f"numba α loop unavailable ({type(exc).__name__}: {exc}); using the numpy "
                      "loop", RuntimeWarning, stacklevel=2)
        simulate.set_kernel(None)
        simulate.batch_loop_numpy(*args)
        return
    simulate.set_kernel(loop)


def install() -> None:
    """Register the compiled α loop (loaded at its first use) with
    :func:`identification.simulate.simulate_alpha_batch`, unless a loop is registered."""
    from identification import simulate

    if simulate.current_kernel() is None:
        simulate.set_kernel(_first_call)
