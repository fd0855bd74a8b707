"""The compiled α loop (:mod:`omni_studies.alpha_kernel`, numba), registered by the application.

``identification`` is numpy/scipy only: its α simulation runs a numpy time loop unless an
application registers a compiled one (:func:`identification.simulate.set_kernel`).
:func:`install` registers a stand-in that, at the first α simulation, imports numba, loads the
compiled loop from its on-disk cache (or compiles it), registers it in its own place and runs
it; so a command that simulates no α model never imports numba.  If numba is missing or fails,
a warning is given and the numpy loop is registered instead (the same numbers to a few ulps
per step, see :mod:`omni_studies.alpha_kernel`).

The first run after an install has no cached machine code: numba compiles the loop (~3.5 s of
CPU on the reference machine).  :func:`compile_ahead` starts that in a background thread when
a command begins (``omni reproduce``: while it simulates and identifies), so that the first α
simulation finds the loop compiled, or waits only for the rest of the compilation.
"""

from __future__ import annotations

import threading
import warnings

#: The background thread of :func:`compile_ahead` (None: not started).
_AHEAD: threading.Thread | None = None


def _first_call(*args):
    """The α time loop's first call: load the compiled loop, register it, run it (the numpy
    loop if that fails: numba compiles a loop before it runs, so a failure has written
    nothing)."""
    from identification import simulate

    ahead = threading.current_thread() is _AHEAD
    if _AHEAD is not None and not ahead:
        _AHEAD.join()  # the compilation under way (the loop is then compiled, or fails again)
    try:
        from .alpha_kernel import loop

        loop(*args)
    except Exception as exc:  # noqa: BLE001  (reported; the numpy loop gives the same numbers)
        if ahead:
            raise  # reported by the command's own first α simulation
        warnings.warn(f"numba α loop unavailable ({type(exc).__name__}: {exc}); using the numpy "
                      "loop", RuntimeWarning, stacklevel=2)
        simulate.set_kernel(None)
        simulate._batch_loop_numpy(*args)
        return
    simulate.set_kernel(loop)


def install() -> None:
    """Register the compiled α loop (loaded at its first use) with
    :func:`identification.simulate.simulate_alpha_batch`, unless a loop is registered."""
    from identification import simulate

    if simulate._KERNEL is None:
        simulate.set_kernel(_first_call)


def compile_ahead() -> None:
    """Load the compiled α loop (compile it, the first time after an install) in a background
    thread now, for the call :func:`identification.validation.validate_runs` makes (one batch,
    only θ kept), so that it is ready by the first α simulation.  Does nothing unless
    :func:`install`'s stand-in is registered and no thread was started.  The thread is not a
    daemon: a command that ends early waits for it (numba is never stopped half-way)."""
    global _AHEAD
    from identification import simulate

    if simulate._KERNEL is not _first_call or _AHEAD is not None:
        return
    _AHEAD = threading.Thread(target=_warm_up, name="compile α loop", daemon=False)
    _AHEAD.start()


def _warm_up() -> None:
    """An α simulation of two samples, as validation calls it (loads the loop through
    :func:`_first_call`); a failure is left to the first real α simulation to report."""
    import numpy as np

    from identification.nonlinear import paper_alpha_model
    from identification.simulate import simulate_alpha_batch

    r = np.zeros(2)
    try:
        simulate_alpha_batch(paper_alpha_model(), [0.005], [r], 1e-3, [2.0], C_linear=[1.0],
                             beta_tilde_linear=[1.0], theta0=[0.0], phi0=[0.0], r_dot=[r],
                             r_ddot=[r], groups=[0], keep=("theta",))
    except Exception:  # noqa: BLE001  (the first real α simulation loads it again and warns)
        pass
