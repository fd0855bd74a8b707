"""How far to trust a fitted effect's parameters: standard errors and the 95 % interval.

Three sources are combined (:func:`uncertainty`): the spread of the parameters over the k folds
(jackknife), the Jacobian at the all-runs optimum (:func:`omni_sim.discrepancy.fit.jacobian_se`)
and the measurement process through the closed loop (:func:`measurement_effect`, a parametric
bootstrap).
"""

from __future__ import annotations

import math

import numpy as np

from .fit import Problem, jacobian_se
from .replay import Replayer, ReplayRun
from .select import Scored


def uncertainty(spec, s: Scored, runs, rep) -> dict:
    """Standard errors and systematic shift of a candidate's parameters.

    Returns a dict of arrays: ``jackknife`` (over the k folds' parameters), ``jacobian`` (at the
    all-runs optimum, :func:`jacobian_se`), ``measurement`` and ``measurement_bias`` (the
    measurement process through the closed loop, :func:`measurement_effect`), and ``se``, the
    root-sum-square of the three standard errors (the reported one).
    """
    k = len(s.fold_x)
    X = np.array(s.fold_x)
    se_jk = np.sqrt((k - 1) / k * np.sum((X - X.mean(axis=0)) ** 2, axis=0)) if k > 1 else np.zeros(len(s.fit.x))
    prob = Problem(spec, [], s.effects, runs, rep, s.target)
    se_jac = jacobian_se(prob, s.fit)
    se_meas, bias = measurement_effect(s, runs, rep, spec)
    return {"se": np.sqrt(se_jk**2 + se_jac**2 + se_meas**2), "jackknife": se_jk, "jacobian": se_jac,
            "measurement": se_meas, "measurement_bias": bias}


def coverage_factor(k: int) -> float:
    """Two-sided 95 % Student-t factor for a jackknife over ``k`` folds (k - 1 degrees of freedom)."""
    from scipy.stats import t
    return float(t.ppf(0.975, max(k - 1, 1)))


#: Realisations of the measurement process simulated by :func:`measurement_effect`.
MEASUREMENT_DRAWS = 8


def encoder_step(run: ReplayRun) -> float:
    """Quantisation step [rad] of the run's logged yaw: the encoder's 15000 counts/rev when the
    metadata says ``encoder_quantized``, else 0."""
    from ..experiments import ENCODER_STEP_RAD
    return float(ENCODER_STEP_RAD) if run.meta.get("encoder_quantized") else 0.0


def measurement_effect(s: Scored, runs: list[ReplayRun], rep: Replayer, spec,
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
    prob = Problem(spec, [], s.effects, runs, rep, s.target)
    nr = len(runs)
    steps = [encoder_step(r) for r in runs]
    res = s.fit.raw_residuals
    ms = np.mean([np.mean(r**2) for r in res]) if res else 0.0
    q2 = np.mean([st**2 / 12 for st in steps])
    stated = [r.meta.get("noise_rad") for r in runs]
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0
           for v in stated):
        sigma = float(np.sqrt(np.mean(np.square(stated))))  # the records' stated encoder noise
    else:
        sigma = math.sqrt(max(ms - q2, 0.0))
    rng = np.random.default_rng(seed)
    pairs = [(0, j) for _ in range(draws) for j in range(nr)]
    noise = [rng.normal(0.0, sigma, runs[j].n) for _, j in pairs]
    # the true start differs from the measured first sample by the measurement error too
    starts = []
    for _, j in pairs:
        r = runs[j]
        th0 = r.theta.copy()
        th0[0] += rng.normal(0.0, sigma) + rng.uniform(-0.5, 0.5) * steps[j]
        starts.append(ReplayRun(r.name, r.kind, r.t, r.r, th0, r.v, r.dt, r.kp, r.gamma_set_deg,
                                r.frequency_hz, r.amplitude_rad, r.meta))
    meas = rep.simulate([prob.model(s.fit.x)], starts, [(0, b) for b in range(len(starts))],
                        measurement=(noise, [steps[j] for _, j in pairs]))
    # the synthetic records, replayed like measured ones (from their own first, measured sample)
    synth = [ReplayRun(r.name, r.kind, r.t, r.r, y, r.v, r.dt, r.kp, r.gamma_set_deg, r.frequency_hz,
                       r.amplitude_rad, r.meta) for (_, j), y in zip(pairs, meas) for r in [runs[j]]]
    w = prob.weights
    xs = [s.fit.x.copy() for _ in range(draws)]
    for _ in range(iterations):
        batch, hs = [], []
        for x in xs:
            h = prob._steps(x)
            hs.append(h)
            batch += [x] + [x + hi * e for hi, e in zip(h, np.eye(p))]
        models = [prob.model(x) for x in batch]
        sim_pairs = [(d * (p + 1) + i, d * nr + j) for d in range(draws) for i in range(p + 1) for j in range(nr)]
        th = rep.simulate(models, synth, sim_pairs)
        for d in range(draws):
            def wres(i):
                base = (d * (p + 1) + i) * nr
                return np.concatenate([(th[base + j] - synth[d * nr + j].theta) * w[j] for j in range(nr)])
            f0 = wres(0)
            J = np.column_stack([(wres(1 + i) - f0) / hs[d][i] for i in range(p)]) * prob.scale
            A = J.T @ J
            dz = np.linalg.solve(A + 1e-6 * np.trace(A) / p * np.eye(p) + 1e-300 * np.eye(p), -J.T @ f0)
            xs[d] = np.clip(xs[d] + dz * prob.scale, prob.lower, prob.upper)
    dx = np.array(xs) - s.fit.x
    return (dx.std(axis=0, ddof=1) if draws > 1 else np.zeros(p)), dx.mean(axis=0)
