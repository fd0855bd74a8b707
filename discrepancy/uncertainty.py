"""How far to trust a fitted effect's parameters: standard errors and the 95 % interval.

Five sources are combined (:func:`uncertainty`):

* statistical: the spread of the parameters over the k folds (jackknife), the Jacobian at the
  all-runs optimum (:func:`discrepancy.fit.jacobian_se`) and the measurement process
  through the closed loop (:func:`measurement_effect`, a parametric bootstrap);
* numerical (they matter when the data hold little noise, e.g. exact simulated data, where the
  statistical terms vanish): the optimiser's stopping point (:func:`optimiser_term`) and the
  simulation's floor (:func:`numerical_floor`).

The optimiser's term
--------------------
``least_squares`` stops on its tolerances (``xtol``, ``ftol`` in
:meth:`discrepancy.fit.Problem.fit`), not at the optimum ``x*``.  Near ``x*`` the
weighted residual is ``f(x) ~ f(x*) + J_t (x - x*)``; a Gauss-Newton step computed with the
finite-difference Jacobian ``J`` at the final ``x`` is ``dx1 = -(J'J)^-1 J'f(x) = -(I - E)(x - x*)``
with ``E = I - (J'J)^-1 J'J_t`` (the Jacobian's relative error; zero-residual or small-residual
problem).  Steps from ``x + dx1``, ``x + dx1 + dx2``, ... (at most :data:`OPTIMISER_STEPS`,
stopping once a step falls below :data:`CONVERGED_RATIO` of the first) contract with rate
``kappa ~ |dx_k| / |dx_(k-1)|``; after ``K`` steps ``|x - x*| <= |x_K - x| + |dx_K| kappa /
(1 - kappa)`` (distance travelled plus the geometric tail; ``kappa`` capped at
:data:`KAPPA_MAX`, taken as that cap when only one step was needed).  Several steps matter
where the objective is not smooth (a backlash's contact events make the finite-difference
Jacobian a secant across events, so the first step undershoots).  This half-width ``b_opt``
(per parameter, component-wise) costs ``K - 1`` Jacobian evaluations (``p + 1`` simulations of
all runs each).

The simulation's floor
----------------------
The replay is a deterministic function of the parameters, but not an exactly smooth one: float
round-off of a closed-loop replay over thousands of steps, the constraint solver's tolerance
(frictionloss, noslip, limits) and discrete events make ``f(x)`` deviate from its local
linearisation by a small "numerical noise" ``e``.  Re-evaluating the residual at
``x + eta_k`` and ``x + 2 eta_k`` (each parameter alone, ``eta_k`` = :data:`FLOOR_STEP` of its
finite-difference step, so small that the curvature term is negligible; the sign flipped at an
upper bound) gives ``e_k = (f(x + 2 eta_k) - 2 f(x + eta_k) + f(x)) / 2``, what a linear model
cannot explain.  A residual perturbation ``e`` moves the
least-squares solution by ``(J'J)^-1 J'e``, whose component ``i`` is bounded by
``sqrt(((J'J)^-1)_ii) |e|`` (Cauchy-Schwarz); ``b_floor_i`` is that bound with the largest
``|e_k|`` (``2 p`` simulations).

Combination
-----------
The two numerical terms are bounds on errors whose sign is not known: they enter as Type B
components of the GUM (JCGM 100:2008, 4.3.7), a uniform distribution of half-width ``b`` with
standard uncertainty ``b / sqrt(3)``, root-sum-squared with the three statistical standard errors
into ``se``.  The reported 95 % half-width (``workflow.py``) is the Student-t factor of the
jackknife times ``se`` plus the bootstrap's mean shift; since ``t / sqrt(3) >= 1.13`` for any
number of folds, a numerical term alone is always covered.  The coverage study
(``scripts/discrepancy_coverage.py``, docs/studies/discrepancy/) checks the whole interval on data with
known truth, with and without noise, and reports the intervals' median width too.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .fit import Problem, correlation, damped_step, jacobian_cov, standard_errors
from .runs import ReplayRun
from .select import Scored


def uncertainty(builder, s: Scored, runs: list[ReplayRun], rep, encoder_step_rad: float) -> dict:
    """Standard errors and systematic shift of a candidate's parameters.

    ``builder`` compiles the candidate's models and ``rep`` simulates them (as in
    :mod:`.select`); ``encoder_step_rad`` is the quantisation step of a run whose metadata says
    ``encoder_quantized`` (:func:`encoder_step`).

    Returns a dict of arrays: ``jackknife`` (over the k folds' parameters), ``jacobian`` (at the
    all-runs optimum, :func:`jacobian_se`), ``measurement`` and ``measurement_bias`` (the
    measurement process through the closed loop, :func:`measurement_effect`), ``optimiser``
    and ``numerical_floor`` (half-widths, :func:`optimiser_term`, :func:`numerical_floor`),
    ``correlation`` (the parameters' correlation matrix at the all-runs optimum,
    the Jacobian's covariance, :func:`~discrepancy.fit.correlation`: which ones the data cannot
    tell apart), and
    ``se``, the root-sum-square of the three standard errors and the two half-widths / sqrt(3)
    (the reported one; see the module docstring).
    """
    if not s.fit.jac_at_x:  # a screening (chord) fit: its Jacobian is its start's, take it at x
        p0 = Problem(builder, [], s.effects, runs, rep)
        f, J, raw = p0.evaluate(s.fit.x)
        s.fit = dataclasses.replace(s.fit, jac=J, resid=f, raw_residuals=raw, jac_at_x=True)
    k = len(s.fold_x)
    X = np.array(s.fold_x)
    se_jk = np.sqrt((k - 1) / k * np.sum((X - X.mean(axis=0)) ** 2, axis=0)) if k > 1 else np.zeros(len(s.fit.x))
    prob = Problem(builder, [], s.effects, runs, rep)
    cov_jac = jacobian_cov(prob, s.fit)  # once: its diagonal and its correlations
    se_jac = standard_errors(cov_jac)  # = fit.jacobian_se
    se_meas, bias = measurement_effect(s, runs, rep, builder, encoder_step_rad)
    b_opt, opt_info = optimiser_term(prob, s.fit)
    b_floor = numerical_floor(prob, s.fit)
    se = np.sqrt(se_jk**2 + se_jac**2 + se_meas**2 + (b_opt**2 + b_floor**2) / 3.0)
    return {"se": se, "jackknife": se_jk, "jacobian": se_jac, "measurement": se_meas,
            "measurement_bias": bias, "optimiser": b_opt, "numerical_floor": b_floor,
            "optimiser_info": opt_info, "correlation": correlation(cov_jac)}


def coverage_factor(k: int) -> float:
    """Two-sided 95 % Student-t factor for a jackknife over ``k`` folds (k - 1 degrees of freedom)."""
    from scipy.stats import t
    return float(t.ppf(0.975, max(k - 1, 1)))


#: Realisations of the measurement process simulated by :func:`measurement_effect`.
MEASUREMENT_DRAWS = 8


def encoder_step(run: ReplayRun, step_rad: float) -> float:
    """Quantisation step [rad] of the run's logged yaw: ``step_rad`` (the Omni's encoder: 15000
    counts/rev) when the metadata says ``encoder_quantized``, else 0."""
    return float(step_rad) if run.meta.get("encoder_quantized") else 0.0


def measurement_effect(s: Scored, runs: list[ReplayRun], rep, builder, encoder_step_rad: float,
                       draws: int = MEASUREMENT_DRAWS, iterations: int = 4,
                       seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """What the measurement process does to the fitted parameters (parametric bootstrap).

    The device's controller acted on the *measured* angle (quantised encoder plus noise); the
    replay's controller acts on the model's exact angle.  That difference is not a parameter of
    any candidate, so it can bias the fit and add scatter that neither the jackknife over runs
    nor the Jacobian estimate sees (both take the replay's closed loop for the device's; with
    friction or a limit the estimate is not even a smooth function of the noise).  Here the
    fitted model is run ``draws`` times with a simulated measurement process in its loop:
    white noise of the records' stated ``noise_rad`` (metadata) or, without it, of the std left
    after the fit (the all-runs fit's residual RMS with the quantisation's ``step^2/12``
    removed: an upper bound, as the residual also holds any remaining model error), and the
    encoder's quantisation when the metadata says the angle was quantised.  The true start of
    each synthetic run is drawn around the measured first sample with the same measurement
    error (the replay starts from the measured sample: with friction an initial error of a
    fraction of a count stays in the record).  Each synthetic record is then fitted like the
    measured one (noise-free replay from its own first sample, Gauss-Newton from the fit,
    ``iterations`` steps, all draws in lockstep).

    Returns
    -------
    (sd, bias) : ndarray, ndarray
        Standard deviation over the draws and the mean shift of the parameters (the bias the
        noise-free replay gives on data measured through this process).
    """
    p = len(s.fit.x)
    if p == 0:
        return np.zeros(p), np.zeros(p)
    prob = Problem(builder, [], s.effects, runs, rep)
    steps = [encoder_step(r, encoder_step_rad) for r in runs]
    sigma = _measurement_noise(s, runs, steps)
    synth = _synthetic_records(prob, s, (sigma, steps), draws, np.random.default_rng(seed))
    xs = _refit_draws(prob, s, synth, rep, draws, iterations)
    dx = np.array(xs) - s.fit.x
    return (dx.std(axis=0, ddof=1) if draws > 1 else np.zeros(p)), dx.mean(axis=0)


def _measurement_noise(s: Scored, runs: list[ReplayRun], steps: list[float]) -> float:
    """The encoder noise std [rad] of the measurement process (:func:`measurement_effect`):
    the records' stated ``noise_rad``, else the all-runs fit's residual RMS with the
    quantisation's ``step^2/12`` removed."""
    res = s.fit.raw_residuals
    ms = np.mean([np.mean(r**2) for r in res]) if res else 0.0
    q2 = np.mean([st**2 / 12 for st in steps])
    stated = [r.meta.get("noise_rad") for r in runs]
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0
           for v in stated):
        return float(np.sqrt(np.mean(np.square(stated))))  # the records' stated encoder noise
    return math.sqrt(max(ms - q2, 0.0))


def _synthetic_records(prob: Problem, s: Scored, process: tuple[float, list[float]], draws: int,
                       rng: np.random.Generator) -> list[ReplayRun]:
    """``draws`` copies of every run of ``prob`` as the fitted model, measured through the
    process (``process``: the noise std ``sigma`` [rad] and each run's quantisation ``steps``)
    in its loop, would log them; draw-major."""
    runs, rep = prob.runs, prob.rep
    sigma, steps = process
    nr = len(runs)
    pairs = [(0, j) for _ in range(draws) for j in range(nr)]
    noise = [rng.normal(0.0, sigma, runs[j].steps) for _, j in pairs]  # on the control grid
    # the true start differs from the measured first sample by the measurement error too
    starts = []
    for _, j in pairs:
        th0 = runs[j].theta.copy()
        th0[0] += rng.normal(0.0, sigma) + rng.uniform(-0.5, 0.5) * steps[j]
        starts.append(dataclasses.replace(runs[j], theta=th0))
    meas = rep.simulate([prob.model(s.fit.x)], starts, [(0, b) for b in range(len(starts))],
                        measurement=(noise, [steps[j] for _, j in pairs]))
    # the synthetic records, replayed like measured ones (from their own first, measured sample)
    return [dataclasses.replace(runs[j], theta=y) for (_, j), y in zip(pairs, meas)]


def _refit_draws(prob: Problem, s: Scored, synth: list[ReplayRun], rep, draws: int,
                 iterations: int) -> list[np.ndarray]:
    """Each draw's synthetic records fitted like the measured ones: ``iterations`` damped
    Gauss-Newton steps from the fit, all draws in lockstep (one batch per step).

    The steps use the fit's own Jacobian (the chord method): the residual's derivative is the
    model's, ``d theta_model / dx``, the same for every record of the same commands up to the
    start's measurement error, and a draw moves its parameters by a noise-sized amount, so a
    fresh Jacobian per draw and step (``p`` more replays of every run each) changes nothing
    but the cost (on the bench's 12-run servo case: 16 M of the workflow's 66 M physics steps)."""
    nr = len(synth) // draws
    w = prob.weights
    Js = prob.jacobian_at(s.fit) * prob.scale
    xs = [s.fit.x.copy() for _ in range(draws)]
    for _ in range(iterations):
        th = rep.simulate([prob.model(x) for x in xs], synth,
                          [(d, d * nr + j) for d in range(draws) for j in range(nr)])
        for d in range(draws):
            f0 = np.concatenate([(th[d * nr + j] - synth[d * nr + j].theta) * w[j] for j in range(nr)])
            dz = damped_step(Js, f0)
            xs[d] = np.clip(xs[d] + dz * prob.scale, prob.lower, prob.upper)
    return xs


#: Largest contraction rate of the Gauss-Newton iteration the optimiser's term trusts: a rate
#: measured above it (steps that do not shrink, e.g. a rough objective) is taken as this, so the
#: tail bound stays finite (the floor term covers the roughness itself).
KAPPA_MAX = 0.5
#: Most Gauss-Newton steps the optimiser's term takes from the fit (each ``p + 1`` simulations).
OPTIMISER_STEPS = 4
#: The optimiser's term stops stepping when a step is below this share of the first (converged).
CONVERGED_RATIO = 1e-3
#: Perturbation of the floor test, as a fraction of each parameter's finite-difference step
#: (:meth:`Problem._steps`, 5 % of its scale): small enough that the curvature term
#: (~eta^2 f'') is far below the float round-off of the replay for the library's effects.
FLOOR_STEP = 1e-4


def _gn_step(prob: Problem, x: np.ndarray, f: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Gauss-Newton step from ``x`` (scaled least squares, kept inside the bounds)."""
    Js = J * prob.scale
    dz, *_ = np.linalg.lstsq(Js, -f, rcond=1e-12)
    return np.clip(x + dz * prob.scale, prob.lower, prob.upper) - x


def optimiser_term(prob: Problem, fit, max_steps: int = OPTIMISER_STEPS) -> tuple[np.ndarray, dict]:
    """Half-width [parameter units] of the distance between the fit's stopping point and the
    optimum of its objective (module docstring, "The optimiser's term").

    Gauss-Newton steps from the fit (each one Jacobian evaluation, ``p + 1`` simulations) until
    a step is below :data:`CONVERGED_RATIO` of the first or ``max_steps`` were taken; the
    half-width is the distance travelled plus the geometric tail of the last step.
    Returns ``(b_opt, info)``; ``info`` holds the steps and the last contraction rate."""
    p = len(fit.x)
    if p == 0 or fit.jac is None or fit.resid is None:
        return np.zeros(p), {}
    x, f, J = fit.x.copy(), fit.resid, fit.jac
    steps: list[np.ndarray] = []
    for k in range(max_steps):
        if k:
            f, J, _ = prob.evaluate(x)
        dx = _gn_step(prob, x, f, J)
        steps.append(dx)
        x = x + dx
        n0 = float(np.linalg.norm(steps[0] / prob.scale))
        if n0 == 0 or float(np.linalg.norm(dx / prob.scale)) <= CONVERGED_RATIO * n0:
            break
    kappa = 0.0
    if len(steps) > 1:
        prev = float(np.linalg.norm(steps[-2] / prob.scale))
        kappa = min(float(np.linalg.norm(steps[-1] / prob.scale)) / prev, KAPPA_MAX) if prev > 0 else 0.0
    else:
        kappa = KAPPA_MAX  # one step only: no rate measured, the cautious one
    # |x0 - x*| <= |x_K - x0| + |x_K - x*|, and |x_K - x*| <= |dx_K| kappa / (1 - kappa)
    b = np.abs(x - fit.x) + np.abs(steps[-1]) * kappa / (1.0 - kappa)
    return b, {"steps": [s.tolist() for s in steps], "kappa": kappa}


def numerical_floor(prob: Problem, fit) -> np.ndarray:
    """Half-width [parameter units] of the parameters' uncertainty from the replay's numerical
    noise (module docstring, "The simulation's floor")."""
    p = len(fit.x)
    if p == 0 or fit.jac is None or fit.resid is None:
        return np.zeros(p)
    x = fit.x
    etas = [FLOOR_STEP * abs(h) for h in prob.steps(x)]
    pts = []
    for i, eta in enumerate(etas):
        e = np.zeros(p)
        # one-sided second difference (f(x+2e) - 2 f(x+e) + f(x)): stays inside the bounds
        e[i] = eta if x[i] + 2 * eta <= prob.upper[i] else -eta
        pts += [x + e, x + 2 * e]
    raws = prob.simulate(pts)
    f0 = fit.resid
    worst = 0.0
    for i in range(p):
        f1, f2 = prob.weighted(raws[2 * i]), prob.weighted(raws[2 * i + 1])
        worst = max(worst, float(np.linalg.norm((f2 - 2 * f1 + f0) / 2)))
    Js = fit.jac * prob.scale
    try:
        cov = np.linalg.pinv(Js.T @ Js)
    except np.linalg.LinAlgError:
        return np.full(p, np.inf)
    return np.sqrt(np.maximum(np.diag(cov), 0.0)) * prob.scale * worst
