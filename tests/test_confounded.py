"""A correction confounded with a named law: the parameters' correlation at the optimum
(discrepancy.fit.correlation of jacobian_cov) and the report's flag (discrepancy.report.confounded).

Independent truth for the correlation: a linear least-squares problem with a known design,
refitted on many noise draws; the estimates' empirical correlation is what the Jacobian
formula must predict."""

from types import SimpleNamespace

import numpy as np
import pytest

from discrepancy import effects as fx
from discrepancy.fit import correlation, jacobian_cov
from discrepancy.report import CONFOUNDED_CORRELATION, confounded


def _linear_problem(J, raw):
    """The duck-typed Problem and FitResult jacobian_cov reads: one run, unit weight, every sample used."""
    problem = SimpleNamespace(used=lambda r: r, weights=[1.0])
    fit = SimpleNamespace(jac=J, raw_residuals=[raw], x=np.zeros(J.shape[1]))
    return problem, fit


def test_correlation_matches_the_estimates_spread_over_noise_draws():
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 400)
    # two nearly collinear columns and a third independent one: x1 and x2 strongly (negatively)
    # correlated in the estimate, x3 not
    J = np.column_stack([t, t + 0.05 * np.sin(9 * t), np.cos(7 * t)])
    truth = np.array([1.0, -0.5, 0.3])
    estimates = []
    for _ in range(3000):
        y = J @ truth + 0.01 * rng.standard_normal(len(t))
        estimates.append(np.linalg.lstsq(J, y, rcond=None)[0])
    empirical = np.corrcoef(np.array(estimates).T)
    raw = 0.01 * rng.standard_normal(len(t))  # white residual: correlation time 1
    predicted = correlation(jacobian_cov(*_linear_problem(J, raw)))
    # 3000 draws: a correlation's sampling error is about (1 - r^2)/sqrt(3000) < 0.02
    assert np.allclose(predicted, empirical, atol=0.03), (predicted, empirical)
    assert predicted[0, 1] < -0.99  # the nearly collinear pair: the case the flag is for


def test_correlation_of_a_singular_problem_is_not_a_number_where_undefined():
    J = np.column_stack([np.ones(50), np.zeros(50)])  # the second parameter does nothing
    corr = correlation(jacobian_cov(*_linear_problem(J, np.full(50, 1e-3))))
    assert not np.isfinite(corr[1, 1]) and not np.isfinite(corr[0, 1])


def _best(names, values):
    effects = [fx.get(n) for n in names]
    return SimpleNamespace(effects=effects, fit=SimpleNamespace(x=np.concatenate(values)))


@pytest.mark.parametrize("r, flagged", [(0.95, True), (-0.93, True), (0.85, False)])
def test_a_correction_traded_against_a_named_parameter_is_flagged(r, flagged):
    gain, load = fx.get("torque_gain"), fx.get("load_friction")
    # values inside every bound: the middle of each parameter's range where finite
    mid = [np.array([0.5 * (p.lower + p.upper) if np.isfinite(p.upper - p.lower) else 1.0 for p in e.params])
           for e in (gain, load)]
    best = _best(("torque_gain", "load_friction"), mid)
    n = gain.nparam + load.nparam
    corr = np.eye(n)
    corr[0, gain.nparam] = corr[gain.nparam, 0] = r  # the gain against load_friction's first parameter
    out = confounded(best, corr, fixed=("torque_gain",))
    key = ("torque_gain", gain.params[0].name)
    assert (key in out) == flagged
    if flagged:
        assert out[key] == [("load_friction", load.params[0].name, r)]
    assert abs(r) >= CONFOUNDED_CORRELATION or not flagged
    # nothing is flagged when no effect is named beside the corrections, or both are corrections
    assert confounded(best, corr, fixed=("torque_gain", "load_friction")) == {}


def test_a_parameter_on_its_bound_is_never_flagged():
    gain, load = fx.get("torque_gain"), fx.get("load_friction")
    at_lower = np.array([p.lower for p in load.params])
    best = _best(("torque_gain", "load_friction"),
                 [np.array([0.5 * (p.lower + p.upper) for p in gain.params]), at_lower])
    corr = np.ones((gain.nparam + load.nparam,) * 2)
    assert confounded(best, corr, fixed=("torque_gain",)) == {}


def test_report_page_says_which_correction_is_confounded():
    """report.md's corrections section names the confounded pair with its correlation, and says
    nothing of the kind when no correction is confounded."""
    from omni_app.discrepancy_report import _md_corrections

    row = {"effect": "torque_gain", "parameter": "gear_nm_per_v", "unit": "N*m/V", "nominal": 0.5,
           "fitted": 0.564, "half_width_95": 0.008, "ratio_to_nominal": 1.128, "bounds": [0.0, 10.0],
           "within_factor": True, "plausible_factor": 2.0, "plausible": True, "at_bound": None,
           "confounded_with": [{"effect": "load_friction", "parameter": "mu_drive", "correlation": -0.97}]}
    text = "\n".join(_md_corrections({"corrections": [row]}))
    assert "Confounded with a named law" in text
    assert "torque_gain: gear_nm_per_v with load_friction: mu_drive (correlation -0.97)" in text
    assert "confounded with load_friction" in text  # the row's own column
    clean = "\n".join(_md_corrections({"corrections": [dict(row, confounded_with=[])]}))
    assert "onfounded" not in clean
