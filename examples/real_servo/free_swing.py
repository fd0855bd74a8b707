"""Sanity check of ``model.xml`` against the torque-off span of the lift_and_drop log, with
plain MuJoCo (no dataset contract, no replay): is the pendulum's inertia right (the swing's
period) and is the friction level plausible (the swing's decay)?

The log lifts the pendulum to about -1.54 rad, then switches the servo's torque off: the
pendulum falls and swings freely about q = 0.  The check starts the model at the first
torque-off sample's angle and speed, with control 0, in two readings of "torque off":

* ``brake``: zero volts on a motor whose back-EMF stays connected (kt^2/R = 0.6227 N*m*s/rad,
  the actuator's velocity bias), i.e. a shorted winding;
* ``coast``: the winding left open (what a servo that switches its H-bridge off does, and what
  the replay does while ``enabled`` = 0): the actuator's back-EMF removed, the gearbox's
  viscous 0.0349 N*m*s/rad and dry 0.199 N*m kept.

It prints the turning points (time, angle), the mean half period and the amplitude ratio
between successive turning points, for the log and both simulations, and the RMS difference
of the simulated angle to the log over the span.

Usage::

    python examples/real_servo/free_swing.py [--log FILE] [--model FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import mujoco
import numpy as np

HERE = Path(__file__).resolve().parent
LOG = HERE / "data" / "2024-10-26_12h23m42.json"  # trajectory lift_and_drop
MODEL = HERE / "model.xml"
JOINT = "servo_axis"
#: The actuator that holds the motor's back-EMF kt^2/R (its velocity bias; model.xml).
ACTUATOR = "servo"


def torque_off_span(path: Path = LOG) -> tuple[np.ndarray, np.ndarray, float]:
    """(t from the first torque-off sample [s], angle [rad], speed at that sample [rad/s])."""
    entries = json.loads(Path(path).read_text())["entries"]
    on = np.array([bool(e["torque_enable"]) for e in entries])
    if on.all():
        raise ValueError(f"{path}: the torque is never switched off")
    i0 = int(np.argmax(~on))
    if not (~on[i0:]).all():
        raise ValueError(f"{path}: the torque comes back on after it is switched off")
    t = np.array([e["timestamp"] for e in entries[i0:]], dtype=float)
    q = np.array([e["position"] for e in entries[i0:]], dtype=float)
    return t - t[0], q, float(entries[i0]["speed"])


def simulate(model: mujoco.MjModel, q0: float, v0: float, duration_s: float,
             joint: str = JOINT) -> tuple[np.ndarray, np.ndarray]:
    """Free swing with every control at 0: (t, angle) at every step."""
    data = mujoco.MjData(model)
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    qa, da = model.jnt_qposadr[j], model.jnt_dofadr[j]
    data.qpos[qa], data.qvel[da] = q0, v0
    data.ctrl[:] = 0.0
    n = int(round(duration_s / model.opt.timestep))
    t, q = np.empty(n + 1), np.empty(n + 1)
    t[0], q[0] = data.time, data.qpos[qa]
    for k in range(1, n + 1):
        mujoco.mj_step(model, data)
        t[k], q[k] = data.time, data.qpos[qa]
    return t, q


def models(path: Path = MODEL, joint: str = JOINT) -> dict[str, mujoco.MjModel]:
    """``brake``: the model as written at zero volts; ``coast``: the same with the actuator's
    back-EMF bias removed (an open winding)."""
    spec = mujoco.MjSpec.from_file(str(path))
    brake = spec.compile()
    act = spec.actuator(ACTUATOR)
    bias = list(act.biasprm)
    bias[2] = 0.0
    act.biasprm = bias
    return {"brake": brake, "coast": spec.compile()}


def turning_points(t: np.ndarray, q: np.ndarray, min_amplitude: float = 0.02) -> list[tuple[float, float]]:
    """The largest |q| between successive crossings of q = 0 (the hanging rest), for swings
    of at least ``min_amplitude`` [rad] (below it the encoder's 1.5 mrad steps and the
    dry-friction creep make no clean swing)."""
    sign = np.sign(q)
    cuts = np.where(np.diff(sign) != 0)[0] + 1
    out = []
    for seg in np.split(np.arange(len(q)), cuts):
        k = seg[np.argmax(np.abs(q[seg]))]
        if abs(q[k]) >= min_amplitude:
            out.append((float(t[k]), float(q[k])))
    return out


def summary(points: list[tuple[float, float]]) -> dict:
    """Mean half period [s] and amplitude ratios of successive turning points."""
    if len(points) < 2:
        return {"half_period_s": None, "ratios": []}
    ts = np.array([p[0] for p in points])
    amps = np.abs([p[1] for p in points])
    return {"half_period_s": float(np.mean(np.diff(ts))),
            "ratios": [float(b / a) for a, b in zip(amps[:-1], amps[1:])]}


def compare(log: Path = LOG, model: Path = MODEL) -> dict:
    """Turning points, summaries and RMS differences of the log and both simulations."""
    t, q, v0 = torque_off_span(log)
    out = {"release_rad": float(q[0]), "release_speed_rad_s": v0, "span_s": float(t[-1]),
           "final_rad": {"log": float(q[-1])}}
    pts = turning_points(t, q)
    out["log"] = {"points": pts, **summary(pts)}
    for name, m in models(model).items():
        ts, qs = simulate(m, float(q[0]), v0, float(t[-1]))
        p = turning_points(ts, qs)
        rms = float(np.sqrt(np.mean((np.interp(t, ts, qs) - q) ** 2)))
        out[name] = {"points": p, **summary(p), "rms_rad": rms}
        out["final_rad"][name] = float(qs[-1])
    return out


def _fmt(points):
    return ", ".join(f"({t:.3f} s, {q:+.3f})" for t, q in points) or "none"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--log", type=Path, default=LOG, help="the lift_and_drop log (BAM JSON)")
    ap.add_argument("--model", type=Path, default=MODEL, help="the model (joint servo_axis)")
    args = ap.parse_args(argv)
    try:
        r = compare(args.log, args.model)
    except (OSError, ValueError, KeyError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"torque off at {r['release_rad']:+.3f} rad, {r['release_speed_rad_s']:+.3f} rad/s; "
          f"span {r['span_s']:.2f} s")
    for name in ("log", "brake", "coast"):
        s = r[name]
        hp = "no swing" if s["half_period_s"] is None else f"half period {s['half_period_s']:.3f} s"
        ratios = " ".join(f"{x:.2f}" for x in s["ratios"]) or "-"
        rms = f"; RMS vs log {s['rms_rad']:.3f} rad" if "rms_rad" in s else ""
        print(f"{name:5s}: turning points {_fmt(s['points'])}")
        print(f"       {hp}; amplitude ratios {ratios}; final {r['final_rad'][name]:+.4f} rad{rms}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
