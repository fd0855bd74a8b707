"""Localise the gap between measured runs and a model's replay.

All functions take the runs (:class:`~discrepancy.runs.ReplayRun`) and the model's
residual ``theta_model - theta_measured`` [rad] per run, and return plain dicts (JSON-ready):
where the residual's RMS is largest, by run, by sine frequency and amplitude (gain and phase of
the fundamental, harmonic content), by time window, by regime (speed, direction, position,
command near the actuator's limit, or the largest commands logged when none came near it), and
the lag at which the residual best correlates with the command.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

#: Time window [s] of the per-window map.
WINDOW_S = 0.5
#: A speed below this share of the data's 95th-percentile speed counts as "near zero".
NEAR_ZERO_SHARE = 0.05
#: A command at or above this share of the actuator's limit (the smaller of the run's
#: ``command_limit`` and the actuator's ``ctrlrange``) counts as "near its limit".  When no
#: command comes near a limit (or none is known), the same share of the largest |command|
#: logged marks "the largest commands" instead, never called a limit.
NEAR_LIMIT_SHARE = 0.8
#: A regime bin needs more samples than this to be compared (:func:`describe`) or ranked.
MIN_BIN_SAMPLES = 50
#: Half-width [s] of the window around a velocity reversal ("around reversals"): a few
#: periods of the bristle/pre-sliding transient at the Omni's speeds.
REVERSAL_S = 0.03
#: A regime whose RMS stands this many times above the average over the data is where the gap
#: "lives" (:func:`describe`).
CONCENTRATION = 1.3
#: Largest lag [s] searched for the residual/command correlation.
MAX_LAG_S = 0.1


def _rms(x) -> float:
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _fundamental(t, y, f, harmonics=(1, 2, 3)) -> dict:
    cols = [np.ones_like(t)]
    for h in harmonics:
        w = 2 * np.pi * f * h
        cols += [np.cos(w * t), np.sin(w * t)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), y, rcond=None)
    out = {}
    for i, h in enumerate(harmonics):
        c, s = coef[1 + 2 * i], coef[2 + 2 * i]
        out[h] = complex(s, c)  # y ~ Im(A e^{iwt}) -> amplitude |A|, phase arg(A)
    return out


def frequency_response(runs, theta_model) -> list[dict]:
    """Gain [-] and phase [deg] of theta/r at each sine run's frequency, measured and model,
    on the second half of the run (past the transient), and the 2nd/3rd harmonic share."""
    out = []
    for run, th in zip(runs, theta_model):
        if run.kind != "sine" or not run.frequency_hz > 0:
            continue
        keep = run.t >= run.t[0] + 0.5 * (run.t[-1] - run.t[0])
        t = run.t[keep]
        R = _fundamental(t, run.r[keep], run.frequency_hz)[1]
        M = _fundamental(t, run.theta[keep], run.frequency_hz)
        S = _fundamental(t, th[keep], run.frequency_hz)
        row = {"run": run.name, "frequency_hz": run.frequency_hz, "amplitude_rad": run.amplitude_rad,
               "gamma_set_deg": list(run.gamma_set_deg)}
        for tag, Y in (("measured", M), ("model", S)):
            H = Y[1] / R
            row[f"gain_{tag}"] = abs(H)
            row[f"phase_{tag}_deg"] = math.degrees(np.angle(H))
            row[f"h2_{tag}"] = abs(Y[2]) / max(abs(Y[1]), 1e-12)
            row[f"h3_{tag}"] = abs(Y[3]) / max(abs(Y[1]), 1e-12)
        row["gain_error_db"] = 20 * math.log10(max(row["gain_model"], 1e-12) / max(row["gain_measured"], 1e-12))
        row["phase_error_deg"] = (row["phase_model_deg"] - row["phase_measured_deg"] + 180) % 360 - 180
        out.append(row)
    return out


def _velocity(run) -> np.ndarray:
    # central difference of the measured angle, smoothed over 10 ms (encoder steps are 0.4 mrad)
    w = max(1, int(round(0.01 / run.dt)))
    th = np.convolve(run.theta, np.ones(w) / w, mode="same")
    return np.gradient(th, run.dt)


def command_bins(runs, actuator_limit: float = math.inf) -> dict:
    """Which samples count as a large command, and what that means.

    The limit of a run is the smaller of its ``command_limit`` (metadata, the P law's
    saturation) and ``actuator_limit`` (the actuator's ``ctrlrange``).  A sample is *near its
    limit* when ``|v| >= NEAR_LIMIT_SHARE * limit``.  When more than :data:`MIN_BIN_SAMPLES`
    samples are near a limit, the bins are ``"command: near its limit"`` / ``"command: below"``;
    otherwise (no limit known, or never approached) they are the largest commands logged,
    ``|v| >= NEAR_LIMIT_SHARE * max |v|``: ``"command: largest logged (>= X)"`` /
    ``"command: smaller"``.

    Returns
    -------
    dict
        ``masks`` (one boolean array per run), ``near``, ``below`` (the two bin names),
        ``kind`` (``"limit"`` or ``"largest logged"``), ``threshold`` (the command at the bins'
        edge for the largest-logged kind, else None), ``command_max`` (largest |v| logged) and
        ``limits`` (the finite limits of the runs, sorted, [] when none is known) and
        ``n_near_limit`` (the samples near a limit).
    """
    cmd_max = max(float(np.max(np.abs(r.v))) for r in runs)
    limits = [min(getattr(r, "command_limit", math.inf), actuator_limit) for r in runs]
    masks = [np.abs(r.v) >= NEAR_LIMIT_SHARE * lim for r, lim in zip(runs, limits)]
    finite = sorted({float(lim) for lim in limits if math.isfinite(lim)})
    n_near = sum(int(np.count_nonzero(m)) for m in masks)
    if n_near > MIN_BIN_SAMPLES:
        return {"masks": masks, "near": "command: near its limit", "below": "command: below",
                "kind": "limit", "threshold": None, "command_max": cmd_max, "limits": finite,
                "n_near_limit": n_near}
    thr = NEAR_LIMIT_SHARE * cmd_max
    return {"masks": [np.abs(r.v) >= thr for r in runs], "near": f"command: largest logged (>= {thr:.3g})",
            "below": "command: smaller", "kind": "largest logged", "threshold": thr,
            "command_max": cmd_max, "limits": finite, "n_near_limit": n_near}


def regimes(runs, residuals, actuator_limit: float = math.inf) -> dict:
    """RMS residual [rad] by speed (near zero / low / high), direction, position and command
    (near its limit, or the largest logged: :func:`command_bins`)."""
    vel = [_velocity(r) for r in runs]
    allv = np.abs(np.concatenate(vel))
    v95 = float(np.percentile(allv, 95)) if allv.size else 0.0
    cmd = command_bins(runs, actuator_limit)
    th_all = np.concatenate([r.theta for r in runs])
    edges = np.quantile(th_all, [0, 0.25, 0.5, 0.75, 1.0])
    abs_edges = np.quantile(np.abs(th_all), [0, 0.75]) if th_all.size else np.zeros(2)
    bins: dict[str, list] = defaultdict(list)
    for run, res, w, near in zip(runs, residuals, vel, cmd["masks"]):
        aw = np.abs(w)
        bins["speed: near zero"].append(res[aw < NEAR_ZERO_SHARE * v95])
        bins["speed: low"].append(res[(aw >= NEAR_ZERO_SHARE * v95) & (aw < 0.5 * v95)])
        bins["speed: high"].append(res[aw >= 0.5 * v95])
        bins["direction: +"].append(res[w > NEAR_ZERO_SHARE * v95])
        bins["direction: -"].append(res[w < -NEAR_ZERO_SHARE * v95])
        for i in range(4):
            lo, hi = edges[i], edges[i + 1]
            sel = (run.theta >= lo) & ((run.theta < hi) if i < 3 else (run.theta <= hi))
            bins[f"position: [{lo:+.3f}, {hi:+.3f}] rad"].append(res[sel])
        outer = np.abs(run.theta) >= abs_edges[1]
        bins["position: |theta| outer quarter"].append(res[outer])
        bins["position: |theta| inner three quarters"].append(res[~outer])
        rev = _near_reversal(w, NEAR_ZERO_SHARE * v95, max(1, int(round(REVERSAL_S / run.dt))))
        bins["motion: around reversals"].append(res[rev])
        bins["motion: away from reversals"].append(res[~rev])
        bins[cmd["near"]].append(res[near])
        bins[cmd["below"]].append(res[~near])
    out = {}
    for k, parts in bins.items():
        x = np.concatenate(parts) if parts else np.zeros(0)
        out[k] = {"rms_rad": _rms(x), "n": int(x.size)}
    return {"bins": out, "speed_p95_rad_s": v95, "command_max_v": cmd["command_max"],
            "command_limits": cmd["limits"], "command_bins": cmd["kind"],
            "command_threshold": cmd["threshold"], "command_near_limit_samples": cmd["n_near_limit"]}


def command_note(reg: dict) -> str | None:
    """A sentence for a report when the commands never came near a known limit (so no
    saturation bin was formed), else None.  ``reg``: :func:`regimes`'s output."""
    limits = reg.get("command_limits") or []
    if reg.get("command_bins") != "largest logged" or not limits:
        return None
    lim = (f"±{limits[0]:.3g}" if len(limits) == 1
           else f"±{limits[0]:.3g} to ±{limits[-1]:.3g} by run")
    largest = (f"largest |command| {reg['command_max_v']:.3g} of {lim}, in the actuator's control units")
    n = reg.get("command_near_limit_samples", 0)
    if n == 0:
        return (f"the command never came near its limit ({largest}; none reached "
                f"{100 * NEAR_LIMIT_SHARE:.0f} % of it): saturation is not where the gap lives")
    return (f"the command came near its limit (at least {100 * NEAR_LIMIT_SHARE:.0f} % of it) in only {n} samples "
            f"({largest}): too few to compare, so no saturation regime is reported")


def _near_reversal(vel: np.ndarray, vmin: float, half: int) -> np.ndarray:
    """Samples within ``half`` samples of a reversal: the velocity changes sign between two
    samples where its magnitude exceeds ``vmin`` (a stop and a restart the other way)."""
    sign = np.where(vel > vmin, 1, np.where(vel < -vmin, -1, 0))
    idx = np.nonzero(sign)[0]
    out = np.zeros(len(vel), bool)
    if len(idx) < 2:
        return out
    flips = np.nonzero(np.diff(sign[idx]) != 0)[0]
    for f in flips:
        a, b = idx[f], idx[f + 1]
        out[max(0, a - half): b + half + 1] = True
    return out


def time_windows(runs, residuals, window_s: float = WINDOW_S) -> list[dict]:
    """RMS residual [rad] per time window from the start of the runs (all runs pooled)."""
    acc: dict[int, list] = defaultdict(list)
    for run, res in zip(runs, residuals):
        idx = ((run.t - run.t[0]) // window_s).astype(int)
        for i in np.unique(idx):
            acc[int(i)].append(res[idx == i])
    return [{"t_start_s": i * window_s, "t_end_s": (i + 1) * window_s,
             "rms_rad": _rms(np.concatenate(acc[i]))} for i in sorted(acc)]


def command_lag(runs, residuals, max_lag_s: float = MAX_LAG_S) -> dict:
    """Lag [s] at which the residual correlates best with the measured command (positive: the
    residual follows the command), and that correlation, searched over ``±max_lag_s``.

    Returns
    -------
    dict
        ``lag_s``, ``correlation``, ``correlation_at_zero``, ``max_lag_s`` (the search's
        half-width) and ``at_edge`` (True when the best lag is the search's edge: the true lag
        may be larger).
    """
    dt = runs[0].dt
    L = int(round(max_lag_s / dt))
    lags = np.arange(-L, L + 1)
    num = np.zeros(len(lags))
    den_r = den_v = 0.0
    for run, res in zip(runs, residuals):
        v = run.v - run.v.mean()
        e = res - res.mean()
        n = len(e)
        for i, lag in enumerate(lags):
            if lag >= 0:
                num[i] += np.dot(e[lag:], v[: n - lag])
            else:
                num[i] += np.dot(e[: n + lag], v[-lag:])
        den_r += float(np.dot(e, e))
        den_v += float(np.dot(v, v))
    corr = num / math.sqrt(max(den_r * den_v, 1e-300))
    i = int(np.argmax(np.abs(corr)))
    return {"lag_s": float(lags[i] * dt), "correlation": float(corr[i]),
            "correlation_at_zero": float(corr[L]), "max_lag_s": float(L * dt),
            "at_edge": bool(L > 0 and abs(int(lags[i])) == L)}


def lag_text(cl: dict) -> str:
    """The command lag in words: ``"best correlation +0.71 at lag +34 ms (at zero lag +0.58)"``,
    with the search's edge named when the best lag sits there."""
    text = (f"best correlation {cl['correlation']:+.2f} at lag {cl['lag_s'] * 1000:+.0f} ms "
            f"(at zero lag {cl['correlation_at_zero']:+.2f})")
    if cl.get("at_edge"):
        text += (f", at the edge of the search (±{cl['max_lag_s'] * 1000:.0f} ms): the true lag "
                 "may be larger")
    return text


def localise(runs, theta_model, actuator_limit: float = math.inf) -> dict:
    """Every map of the gap for one model's replay, and the worst bins.  ``actuator_limit``:
    the actuator's command limit (``ctrlrange``; inf if unlimited), for the command regime
    (:func:`command_bins`)."""
    residuals = [th - r.theta for r, th in zip(runs, theta_model)]
    per_run = sorted(({"run": r.name, "kind": r.kind, "rms_rad": _rms(e),
                       "frequency_hz": r.frequency_hz, "amplitude_rad": r.amplitude_rad,
                       "gamma_set_deg": list(r.gamma_set_deg)}
                      for r, e in zip(runs, residuals)), key=lambda d: -d["rms_rad"])
    by_amp: dict[float, list] = defaultdict(list)
    by_freq: dict[float, list] = defaultdict(list)
    by_kind: dict[str, list] = defaultdict(list)
    for r, e in zip(runs, residuals):
        by_kind[r.kind].append(e)
        by_amp[round(r.amplitude_rad, 6)].append(e)
        if r.kind == "sine":
            by_freq[round(r.frequency_hz, 6)].append(e)
    reg = regimes(runs, residuals, actuator_limit)
    overall = float(np.sqrt(np.mean([np.mean(e**2) for e in residuals])))
    out = {
        "overall_rms_rad": overall,
        "per_run": per_run,
        "per_kind": {k: _rms(np.concatenate(v)) for k, v in by_kind.items()},
        "per_amplitude": {f"{a:g}": _rms(np.concatenate(v)) for a, v in sorted(by_amp.items())},
        "per_frequency": {f"{f:g}": _rms(np.concatenate(v)) for f, v in sorted(by_freq.items())},
        "frequency_response": frequency_response(runs, theta_model),
        "time_windows": time_windows(runs, residuals),
        "regimes": reg,
        "command_lag": command_lag(runs, residuals),
    }
    worst = []
    for k, b in reg["bins"].items():
        if b["n"] > MIN_BIN_SAMPLES:
            worst.append((b["rms_rad"], f"regime {k}"))
    for k, v in out["per_frequency"].items():
        worst.append((v, f"sine {k} Hz"))
    for k, v in out["per_amplitude"].items():
        worst.append((v, f"amplitude {k} rad"))
    for w in out["time_windows"]:
        worst.append((w["rms_rad"], f"window {w['t_start_s']:.1f}-{w['t_end_s']:.1f} s"))
    worst.sort(key=lambda p: -p[0])
    out["worst"] = [{"where": w, "rms_rad": v, "ratio_to_overall": v / overall if overall > 0 else float("nan")}
                    for v, w in worst[:6]]
    return out


def _ratio(a, b) -> float:
    return float(a / b) if (b and b > 0 and a is not None and math.isfinite(a)) else float("nan")


def describe(loc: dict, noise_rad: float = 0.0) -> list[dict]:
    """Where the gap lives, in words: the regimes whose residual RMS stands out.

    Compares each map of :func:`localise` with the RMS over the data and returns, strongest
    first, ``{"where": ..., "ratio": ..., "text": ...}`` for every regime that stands
    :data:`CONCENTRATION` times above its complement (low speed, reversals, a position band,
    the command near its limit, a frequency band, small or large amplitudes, the start of the
    runs, steps vs sines), plus a command lag when the residual follows the command.  An empty
    list: the gap is spread evenly (or at the noise floor).
    """
    out = []
    overall = loc.get("overall_rms_rad", float("nan"))
    if not (overall > 0) or overall <= 2 * noise_rad:
        return out
    # (where, RMS there, RMS of the complement, text with {r} for the ratio)
    comparisons = (_regime_comparisons(loc["regimes"]) + _frequency_comparisons(loc)
                   + _amplitude_comparisons(loc) + _record_comparisons(loc))
    for where, a, ref, text in comparisons:
        r = _ratio(a, ref)
        if math.isfinite(r) and r >= CONCENTRATION:
            out.append({"where": where, "ratio": r, "text": text.format(r=r)})
    cl = loc.get("command_lag", {})
    if abs(cl.get("correlation", 0.0)) >= 0.5 and abs(cl.get("lag_s", 0.0)) > 0:
        later = (f"at least {cl['lag_s'] * 1000:+.0f} ms later (the edge of the lag search: the true "
                 "lag may be larger)" if cl.get("at_edge") else f"{cl['lag_s'] * 1000:+.0f} ms later")
        out.append({"where": "follows the command", "ratio": float("nan"),
                    "text": f"the residual follows the command {later} "
                            f"(correlation {cl['correlation']:+.2f}): a loop delay or drive lag"})
    out.sort(key=lambda d: -(d["ratio"] if math.isfinite(d["ratio"]) else 0.0))
    return out


def _regime_comparisons(reg: dict) -> list[tuple]:
    """Speed, reversals, position and command regimes against their complements (``reg``:
    :func:`regimes`'s output)."""
    bins = reg["bins"]

    def rms(key):
        v = bins.get(key, {})
        return v.get("rms_rad") if v.get("n", 0) > MIN_BIN_SAMPLES else None

    out = []
    slow, low, fast = rms("speed: near zero"), rms("speed: low"), rms("speed: high")
    moving = max([x for x in (low, fast) if x is not None], default=None)
    out.append(("low speed", slow, moving,
                "at low speed: near standstill the error is {r:.1f}x that of the moving samples "
                "(friction, stiction, pre-sliding, backlash)"))
    out.append(("high speed", fast, max([x for x in (slow, low) if x is not None], default=None),
                "at high speed: {r:.1f}x the error of the slow samples (damping, back-EMF, drag)"))
    out.append(("reversals", rms("motion: around reversals"), rms("motion: away from reversals"),
                "around velocity reversals: {r:.1f}x the error away from them (dry friction, pre-sliding, "
                "backlash, cable compliance)"))
    out.append(("position band", rms("position: |theta| outer quarter"),
                rms("position: |theta| inner three quarters"),
                "in a position band: the outer quarter of |theta| has {r:.1f}x the error of the rest "
                "(a spring, gravity, an end stop, a position-dependent torque)"))
    pos = {k[len("position: ["):]: v["rms_rad"] for k, v in bins.items()
           if k.startswith("position: [") and v.get("n", 0) > MIN_BIN_SAMPLES}
    if pos:
        k = max(pos, key=pos.get)
        others = [v for kk, v in pos.items() if kk != k]
        out.append((f"positions [{k}", pos[k], float(np.sqrt(np.mean(np.square(others)))) if others else None,
                    "at positions [" + k + ": {r:.1f}x the error of the other quartiles"))
    if reg.get("command_bins", "limit") == "limit":
        out.append(("command near its limit", rms("command: near its limit"), rms("command: below"),
                    f"when the command is near its limit (at least {100 * NEAR_LIMIT_SHARE:.0f} % of it): "
                    "{r:.1f}x the error below it (saturation, a torque limit)"))
    else:
        thr = reg["command_threshold"]
        never = " (the command never came near its limit)" if reg.get("command_limits") else ""
        out.append(("largest commands", rms(f"command: largest logged (>= {thr:.3g})"), rms("command: smaller"),
                    f"at the largest commands (above {100 * NEAR_LIMIT_SHARE:.0f} % of the largest logged, "
                    f"{thr:.3g}){never}: {{r:.1f}}x the error of the smaller ones (a drive's "
                    "nonlinearity at large commands, or what the large commands coincide with: speed, "
                    "acceleration, the edges of steps)"))
    return out


def _frequency_comparisons(loc: dict) -> list[tuple]:
    """The sine frequency with the largest error against the other frequencies."""
    pf = loc.get("per_frequency", {})
    if len(pf) < 2:
        return []
    f = max(pf, key=pf.get)
    others = [v for k, v in pf.items() if k != f]
    fr = [row for row in loc.get("frequency_response", []) if f"{row['frequency_hz']:g}" == f]
    detail = ""
    if fr:
        g = float(np.mean([row["gain_error_db"] for row in fr]))
        ph = float(np.mean([row["phase_error_deg"] for row in fr]))
        detail = f" (model gain {g:+.1f} dB, phase {ph:+.1f} deg there)"
    return [(f"frequency {f} Hz", pf[f], float(np.sqrt(np.mean(np.square(others)))),
             f"in the sines at {f} Hz: {{r:.1f}}x the error of the other frequencies{detail}")]


def _amplitude_comparisons(loc: dict) -> list[tuple]:
    """The smallest amplitude against the largest, and the other way round."""
    pa = loc.get("per_amplitude", {})
    if len(pa) < 2:
        return []
    amps = sorted(pa, key=float)
    small, large = pa[amps[0]], pa[amps[-1]]
    return [("small amplitudes", small, large,
             f"at the smallest amplitude ({amps[0]} rad): {{r:.1f}}x the error at {amps[-1]} rad "
             "(effects that weaken with amplitude: dry friction, backlash, cogging)"),
            ("large amplitudes", large, small,
             f"at the largest amplitude ({amps[-1]} rad): {{r:.1f}}x the error at {amps[0]} rad "
             "(saturation, springs, end stops)")]


def _record_comparisons(loc: dict) -> list[tuple]:
    """The start of the runs against the rest; steps against sines and the other way round."""
    out = []
    tw = loc.get("time_windows", [])
    if len(tw) >= 2:
        rest = float(np.sqrt(np.mean([w["rms_rad"] ** 2 for w in tw[1:]])))
        out.append(("start of the runs", tw[0]["rms_rad"], rest,
                    "in the first {w:.1f} s of the runs: {{r:.1f}}x the error later (start transient, "
                    "initial state)".format(w=tw[0]["t_end_s"])))
    pk = loc.get("per_kind", {})
    if "step" in pk and "sine" in pk:
        out.append(("steps", pk["step"], pk["sine"], "in the step responses: {r:.1f}x the error of the sines"))
        out.append(("sines", pk["sine"], pk["step"], "in the sines: {r:.1f}x the error of the step responses"))
    return out
