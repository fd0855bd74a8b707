"""The paper's identification method (numpy/scipy only; never imports MuJoCo).

Works on any dataset in the contract's format (see :mod:`identification.dataset`), simulated
or measured on a real Phantom Omni: :func:`identify_runs` (``omni identify``) and
:func:`validate_runs` with :func:`read_params` (``omni validate``) run it end to end (a walk
through: docs/usage/python.md).  :mod:`identification.alpha` ((33)–(36)) also offers the
α-invariant of a measured command-voltage record (:func:`alpha_from_samples`,
:func:`alpha_cycle_average`) for users with real data; :mod:`identification.paper` holds the
paper's published tables.
"""

import importlib

#: The package's public names and the module each lives in.  They are imported on first use
#: (PEP 562), so that ``import identification.errors`` or ``identification.dataset`` does not
#: load scipy (a command that only reads or writes datasets never needs it).
_EXPORTS = {
    "dataset": ("Run", "read_dataset", "read_run", "write_dataset", "write_run"),
    "errors": ("UserError",),
    "alpha": ("alpha_cycle_average", "alpha_from_samples", "alpha_invariant"),
    "sine_fit": ("SineFit", "RunSineFit", "fit_sine", "fit_run", "steady_state_window"),
    "linear": ("FrequencyPoint", "PoseLinearModel", "alpha_sine", "fit_pose", "global_coefficients",
               "local_coefficients"),
    "inertia": ("InertiaFit", "InertiaParameters", "c0_bar_regression", "fit_inertia_model",
                "inertia_analytic", "inertia_minimal", "minimal_from_analytic"),
    # the paper's method end to end: ``omni identify`` and ``omni validate`` in Python
    "identify": ("Identification", "identify_runs"),
    "validation": ("Params", "read_params", "validate_runs", "Validation", "ValidationSummary"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}


def __getattr__(name: str):
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'identification' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))


__all__ = ["Run", "UserError", "read_dataset", "read_run", "write_dataset", "write_run",
           "alpha_invariant", "alpha_from_samples", "alpha_cycle_average",
           "SineFit", "RunSineFit", "fit_sine", "fit_run", "steady_state_window",
           "FrequencyPoint", "PoseLinearModel", "alpha_sine", "fit_pose", "global_coefficients",
           "local_coefficients",
           "InertiaFit", "InertiaParameters", "c0_bar_regression", "fit_inertia_model",
           "inertia_analytic", "inertia_minimal", "minimal_from_analytic",
           "Identification", "identify_runs", "Params", "read_params", "validate_runs",
           "Validation", "ValidationSummary"]
