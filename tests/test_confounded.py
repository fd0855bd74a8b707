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


def test_multiple_correlation_matches_a_regression_over_noise_draws():
    """Independent truth: a linear least-squares problem whose first parameter trades against the
    other two jointly though against neither alone (correlation 0.65 with each); over noise draws
    the share of the first estimate's variance a linear regression on the other two estimates
    takes is R^2, which multiple_correlation must give from the Jacobian's correlation."""
    from discrepancy.report import multiple_correlation
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 1.0, 400)
    # the design whose estimates' correlation is `target`: 0.65 with each of the others, which are
    # nearly uncorrelated (-0.1) with each other; J = Q target^(-1/2), so J^T J = target^-1
    target = np.array([[1.0, 0.65, 0.65], [0.65, 1.0, -0.1], [0.65, -0.1, 1.0]])
    w, v = np.linalg.eigh(target)
    Q = np.linalg.qr(np.column_stack([np.sin(3 * t), np.cos(5 * t), t]))[0]
    J = Q @ (v @ np.diag(w ** -0.5) @ v.T)
    truth = np.array([0.4, 0.2, -0.1])
    est = np.array([np.linalg.lstsq(J, J @ truth + 0.01 * rng.standard_normal(len(t)), rcond=None)[0]
                    for _ in range(3000)])
    X = np.column_stack([np.ones(len(est)), est[:, 1:]])
    resid = est[:, 0] - X @ np.linalg.lstsq(X, est[:, 0], rcond=None)[0]
    r2_empirical = 1.0 - resid.var() / est[:, 0].var()
    corr = correlation(jacobian_cov(*_linear_problem(J, 0.01 * rng.standard_normal(len(t)))))
    r = multiple_correlation(corr, 0, [1, 2])
    # 3000 draws: R^2's sampling error is about 2 R (1 - R^2) / sqrt(3000) < 0.01 here
    assert r ** 2 == pytest.approx(r2_empirical, abs=0.01)
    assert r > CONFOUNDED_CORRELATION and max(abs(corr[0, 1]), abs(corr[0, 2])) < CONFOUNDED_CORRELATION


def test_a_correction_traded_against_a_named_law_jointly_is_flagged():
    """A gain correlated 0.7 with each of load_friction's two coefficients, which are
    uncorrelated with each other: no pair reaches 0.9, the two together do (R^2 = 0.98)."""
    gain, load = fx.get("torque_gain"), fx.get("load_friction")
    mid = [np.array([0.5 * (p.lower + p.upper) if np.isfinite(p.upper - p.lower) else 1.0 for p in e.params])
           for e in (gain, load)]
    best = _best(("torque_gain", "load_friction"), mid)
    n = gain.nparam + load.nparam
    corr = np.eye(n)
    for j in (gain.nparam, gain.nparam + 1):
        corr[0, j] = corr[j, 0] = 0.7
    out = confounded(best, corr, fixed=("torque_gain",))
    joined = "+".join(p.name for p in load.params)
    assert out == {("torque_gain", gain.params[0].name): [("load_friction", joined, pytest.approx(0.98 ** 0.5))]}
    corr[0, gain.nparam] = corr[gain.nparam, 0] = 0.3  # R^2 = 0.58: not flagged
    assert confounded(best, corr, fixed=("torque_gain",)) == {}


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
    joint = dict(row, confounded_with=[{"effect": "load_friction", "parameter": "mu_drive+mu_back",
                                        "correlation": 0.96}])
    assert ("torque_gain: gear_nm_per_v with load_friction: mu_drive+mu_back together (multiple correlation "
            "+0.96)") in "\n".join(_md_corrections({"corrections": [joint]}))
    clean = "\n".join(_md_corrections({"corrections": [dict(row, confounded_with=[])]}))
    assert "onfounded" not in clean
