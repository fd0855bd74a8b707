"""The paper's identification method (numpy/scipy only; never imports MuJoCo).

Works on any dataset in the contract's format (see :mod:`identification.dataset`), simulated
or measured on a real Phantom Omni.  :mod:`identification.alpha` ((33)–(36)) also offers the
α-invariant of a measured command-voltage record (:func:`alpha_from_samples`,
:func:`alpha_cycle_average`) for users with real data; :mod:`identification.paper` holds the
paper's published tables.
"""

from .dataset import Run, read_dataset, read_run, write_run
from .errors import UserError
from .alpha import alpha_cycle_average, alpha_from_samples, alpha_invariant
from .sine_fit import SineFit, RunSineFit, fit_sine, fit_run, steady_state_window
from .linear import (FrequencyPoint, PoseLinearModel, alpha_sine, fit_pose, global_coefficients,
                     local_coefficients)
from .inertia import (InertiaFit, InertiaParameters, c0_bar_regression, fit_inertia_model,
                      inertia_analytic, inertia_minimal, minimal_from_analytic)

__all__ = ["Run", "UserError", "read_dataset", "read_run", "write_run",
           "alpha_invariant", "alpha_from_samples", "alpha_cycle_average",
           "SineFit", "RunSineFit", "fit_sine", "fit_run", "steady_state_window",
           "FrequencyPoint", "PoseLinearModel", "alpha_sine", "fit_pose", "global_coefficients",
           "local_coefficients",
           "InertiaFit", "InertiaParameters", "c0_bar_regression", "fit_inertia_model",
           "inertia_analytic", "inertia_minimal", "minimal_from_analytic"]
