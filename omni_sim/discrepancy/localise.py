"""Localise the gap between measured runs and a model's replay.

All functions take the runs (:class:`~omni_sim.discrepancy.replay.ReplayRun`) and the model's
residual ``theta_model - theta_measured`` [rad] per run, and return plain dicts (JSON-ready):
where the residual's RMS is largest, by run, by sine frequency and amplitude (gain and phase of
the fundamental, harmonic content), by time window, by regime (speed, direction, position,
command near its limit), and the lag at which the residual best correlates with the command.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

#: Time window [s] of the per-window map.
WINDOW_S = 0.5
#: A speed below this share of the data's 95th-percentile speed counts as "near zero".
NEAR_ZERO_SHARE = 0.05
#: A command above this share of the data's largest |v| counts as "near its limit".
NEAR_LIMIT_SHARE = 0.8
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


def regimes(runs, residuals) -> dict:
    """RMS residual [rad] by speed (near zero / low / high), direction, position and command."""
    vel = [_velocity(r) for r in runs]
    allv = np.abs(np.concatenate(vel))
    v95 = float(np.percentile(allv, 95)) if allv.size else 0.0
    cmd_max = max(float(np.max(np.abs(r.v))) for r in runs)
    th_all = np.concatenate([r.theta for r in runs])
    edges = np.quantile(th_all, [0, 0.25, 0.5, 0.75, 1.0])
    bins: dict[str, list] = defaultdict(list)
    for run, res, w in zip(runs, residuals, vel):
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
        near = np.abs(run.v) >= NEAR_LIMIT_SHARE * cmd_max
        bins["command: near its limit"].append(res[near])
        bins["command: below"].append(res[~near])
    out = {}
    for k, parts in bins.items():
        x = np.concatenate(parts) if parts else np.zeros(0)
        out[k] = {"rms_rad": _rms(x), "n": int(x.size)}
    return {"bins": out, "speed_p95_rad_s": v95, "command_max_v": cmd_max}


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
    residual follows the command), and that correlation."""
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
            "correlation_at_zero": float(corr[L])}


def localise(runs, theta_model) -> dict:
    """Every map of the gap for one model's replay, and the worst bins."""
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
    reg = regimes(runs, residuals)
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
        if b["n"] > 50:
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
