"""The paper's identification method (numpy/scipy only; never imports MuJoCo).

Works on any dataset in the contract's format (see :mod:`identification.dataset`), simulated
or measured on a real Phantom Omni.
"""

from .dataset import Run, read_dataset, read_run, write_run
from .errors import UserError
from .sine_fit import SineFit, RunSineFit, fit_sine, fit_run, steady_state_window
from .linear import (FrequencyPoint, PoseLinearModel, alpha_sine, fit_pose, global_coefficients,
                     local_coefficients)
from .inertia import (InertiaFit, InertiaParameters, c0_bar_regression, fit_inertia_model,
                      inertia_analytic, inertia_minimal, minimal_from_analytic)

__all__ = ["Run", "UserError", "read_dataset", "read_run", "write_run",
           "SineFit", "RunSineFit", "fit_sine", "fit_run", "steady_state_window",
           "FrequencyPoint", "PoseLinearModel", "alpha_sine", "fit_pose", "global_coefficients",
           "local_coefficients",
           "InertiaFit", "InertiaParameters", "c0_bar_regression", "fit_inertia_model",
           "inertia_analytic", "inertia_minimal", "minimal_from_analytic"]
