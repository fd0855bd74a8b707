"""Compiled kernels for the method layer, registered by the application.

``identification`` is numpy/scipy only.  Where a compiled version of one of its loops exists,
the application registers it here and the method uses it, with the same results (the CSV
formatter: the same bytes; the α loop: the same numbers to a few ulps per step, see
:mod:`omni_app.alpha_kernel`):

* the α-model simulation's time loop (:mod:`omni_app.alpha_kernel`, registered with
  :func:`identification.simulate.set_kernel`);
* the ``%.17g`` CSV formatter of datasets and predictions (:mod:`omni_app.csv_kernel`,
  registered with :func:`identification.csvformat.set_kernel`).

Nothing is imported or compiled until the first call needs it (numba compiles a kernel then,
or loads it from its on-disk cache); if numba is missing or fails, the numpy/Python code is
kept, with a warning.
"""

from __future__ import annotations

import warnings

_loaded: dict = {}     # name -> the compiled function, or None when it failed


def _load(name: str):
    if name not in _loaded:
        try:
            if name == "alpha":
                from .alpha_kernel import loop as fn
            else:
                from .csv_kernel import format_rows as fn
            _loaded[name] = fn
        except Exception as exc:  # noqa: BLE001  (reported; the fallback gives the same results)
            _loaded[name] = None
            warnings.warn(f"numba kernel {name!r} unavailable ({type(exc).__name__}: {exc}); "
                          "using the numpy code", RuntimeWarning, stacklevel=3)
    return _loaded[name]


def _lazy(name: str, module, fallback):
    """A function for ``module.set_kernel``: on its first call loads the kernel, registers it in
    place of itself, and runs it (``fallback`` if it is unavailable or fails)."""

    def first_call(*args):
        fn = _load(name)
        module.set_kernel(fn)
        if fn is None:
            return fallback(*args)
        try:
            return fn(*args)
        except Exception as exc:  # noqa: BLE001  (e.g. a compiler error at the first call)
            _loaded[name] = None
            module.set_kernel(None)
            warnings.warn(f"numba kernel {name!r} failed ({type(exc).__name__}: {exc}); "
                          "using the numpy code", RuntimeWarning, stacklevel=2)
            return fallback(*args)

    return first_call


def install() -> None:
    """Register the compiled kernels (where none is registered yet): the α simulation of
    :func:`identification.simulate.simulate_alpha_batch` (and ``simulate_alpha``), and
    :func:`identification.csvformat.format_rows` (datasets, predictions)."""
    from identification import csvformat, simulate

    for name, module, fallback in (("alpha", simulate, simulate._batch_loop_numpy),
                                   ("csv", csvformat, csvformat.format_rows_reference)):
        if module._KERNEL is None and _loaded.get(name, True) is not None:
            module.set_kernel(_loaded.get(name) or _lazy(name, module, fallback))


def prewarm() -> None:
    """Load the registered kernels now (numba's import, its JIT and the cached machine code:
    ~0.5 s warm, several seconds when they must be compiled) by running each once on a tiny
    input of the real argument types."""
    import numpy as np

    from identification import csvformat, simulate
    from identification.nonlinear import paper_alpha_model

    install()
    for keep in (None, ("theta",)):  # all arrays, and validation's theta only
        simulate.simulate_alpha_batch(paper_alpha_model(), [0.005], [np.zeros(4)], 1e-3, [2.0],
                                      C_linear=[1.0], beta_tilde_linear=[1.0], groups=[0],
                                      keep=keep)
    csvformat.format_rows(np.zeros((1, 4)))


def start_prewarm(modules=()):
    """:func:`prewarm` in a background thread (e.g. while MuJoCo's rollout threads run, which
    release the GIL), then ``import`` each of ``modules`` (what a later stage loads at its
    first use); returns the thread, to be joined (before any fork)."""
    import importlib
    import threading

    def run():
        try:
            prewarm()
            for name in modules:
                importlib.import_module(name)
        except Exception:  # noqa: BLE001  (the first real call or import reports any problem)
            pass

    thread = threading.Thread(target=run, name="omni-prewarm", daemon=True)
    thread.start()
    return thread

