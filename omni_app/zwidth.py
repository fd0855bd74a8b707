"""``omni zwidth``: which virtual walls (K, B) the virtual Omni's yaw renders passively.

The wall is the standard one (:func:`omni_sim.wall_env.wall_torque`): a spring ``K`` and a
damper ``B`` on the backward-difference velocity of the encoder reading, computed every servo
period ``T`` and held (zero-order hold) through the motor's torque constant.  Colgate &
Schenkel (1997) showed this wall on a device with physical damping ``b`` is passive iff
``b > K T / 2 + |B|``.

**How "passive" is decided (the method, tested in tests/test_zwidth.py).**  Every (K, B) cell is
one row of a single batch of the device's closed loop (:class:`omni_sim.device.Engine`'s rows
and thread pool, one ``mujoco.rollout`` call per servo period for all cells).  Each row starts
at rest inside the wall at penetration ``START_PENETRATION``; the hand is a torque source at the
yaw: a constant push ``K p0`` that holds the stylus there (conservative: its work is bounded),
plus a probe.  Each cell runs once per probe (``PROBE_PERIODS``): a torque impulse at every
m-th sample instant that reverses the yaw's velocity, so the velocity is a square wave of
amplitude ``PROBE_SPEED`` and half-period ``m T`` and the position a triangle with its corners at
samples.  With ``m = 1`` (the Nyquist frequency) this is the motion that attains Colgate &
Schenkel's bound for ``B >= 0``: per period the wall returns ``2 X^2 (K + 2 B / T)`` and the
damper takes ``4 b X^2 / T``, X the corner amplitude (for ``B = 0`` every frequency is equally
bad).  The slower probes (m = 4, 16) cover the worst cases at low frequency (``B < 0``) and in
between (a loop delay).  Over the run after the first ``SETTLE_FRACTION`` the hand's work is
summed -- the probe's impulses and the push, ``sum_j F_j h (v_j + v_{j+1}) / 2`` (the exact work
of a force held over a physics step of MuJoCo's semi-implicit Euler) -- and the energy stored at
the window's two ends is taken out of it (the yaw's kinetic energy and the wall spring's
``K x^2 / 2``, x the true penetration), so that a finite window is not biased by where the
motion stands when it opens and closes.  What is left is what the device dissipated (viscous,
dry, LuGre) minus what the wall generated; it is divided by the viscous damping's dissipation
``D_b`` over the same steps: ``index = W / D_b``.  A cell is passive iff ``index >= -TOL``
under every probe (an input that draws net energy out of device and wall proves them active)
and every run stayed finite and inside the yaw range; for the ideal linear device ``index`` is
``1 - (K T / 2 + |B|) / b`` (measured: its boundary within 0.2 % of Colgate & Schenkel's at
every damping row up to 0.99 b).  The largest passive K of a damping row is interpolated where
``index`` crosses ``-TOL`` (:func:`boundary`).

The physics step is refined to ``T / substeps`` (default 20) for this tool: Colgate & Schenkel's
plant is continuous between samples, while the model's own 1 ms step equals the servo period.

The hand's torque goes to the yaw through the motor's own channel (the same joint torque,
held over the period like the wall's); the wall's part alone is clipped to the drive's limit.
"""

from __future__ import annotations

import copy
import json
import math
import time
from pathlib import Path

import numpy as np

from identification.errors import UserError

#: Probe speed [rad/s] of the Nyquist square-wave velocity (our choice: 0.02 rad/s, so the
#: triangle's corners are +-1e-5 rad -- a pure test of the sampled wall, below one encoder count).
PROBE_SPEED = 0.02
#: Start penetration [rad] (our choice: 0.01 rad, 24 encoder counts, a firm press).
START_PENETRATION = 0.01
#: Run length [s] and the fraction skipped before the energy is summed (our choice; the
#: Nyquist response is reached within a few periods, the 0.3 s covers the slower transients).
DURATION_S = 1.0
SETTLE_FRACTION = 0.3
#: Tolerance of the energy test (fraction of the viscous dissipation; our choice, 2 %: the
#: numerical energy error of the ideal device is far below it).
TOL = 1e-3
#: Half-periods of the probes' velocity square waves [servo periods] (our choice): 1 is the
#: Nyquist frequency (Colgate & Schenkel's worst case for B >= 0 without delay), 4 and 16 lower
#: frequencies (the worst case for B < 0 and, with a loop delay, in between).
PROBE_PERIODS = (1, 4, 16)
#: Physics steps per servo period for the map (the probe's impulse takes one: 1/20 of the
#: period, so the velocity square wave is within ~3 % of ideal).
SUBSTEPS = 20


def physical_damping(device) -> float:
    """The yaw's viscous damping ``b`` [N*m*s/rad] (the joint's ``damping``)."""
    return float(device.model.dof_damping[device.ix.yaw_dof])


def map_device(path=None, friction=None, ideal=False, control_period_s=1e-3, substeps=SUBSTEPS):
    """The device of a map: the model with its physics step refined and the drive's ctrlrange
    opened (the wall's own clip is applied in :func:`passivity_map`).  Returns
    ``(device, torque_limit)``."""
    from omni_sim import model as om
    from omni_sim.device import Device

    model = om.load_model(path, friction)
    dev0 = Device(model, control_period_s)
    act = dev0.ix.yaw_act
    torque_limit = dev0.voltage_limit * dev0.torque_constant
    model = copy.deepcopy(model)
    model.opt.timestep = control_period_s / substeps
    model.actuator_ctrlrange[act] = (-1e6, 1e6)
    dev = Device(model, control_period_s)
    if ideal:
        dev.scale_friction(0.0)
    return dev, torque_limit


def passivity_map(device, stiffness, damping, torque_limit=math.inf, quantize=False, delay=0,
                  probe_speed=PROBE_SPEED, probe_periods=PROBE_PERIODS, duration_s=DURATION_S,
                  gamma_set_deg=(65.0, 90.0), nthread=None, record=False):
    """Run every (K, B) cell under every probe and decide passivity (see the module doc).

    Returns a dict: ``passive`` (len(damping) x len(stiffness) bools), ``index`` (the smallest
    W / D_b over the probes), ``index_per_probe`` (probes x damping x stiffness),
    ``diverged``; with ``record`` also the rows' traces (row = probe-major, then cell)."""
    from omni_sim.device import ENCODER_STEP_RAD, Engine, encoder_reader
    from omni_sim.wall_env import wall_torque

    K = np.asarray(stiffness, dtype=float)
    Bv = np.asarray(damping, dtype=float)
    KK, BB = np.meshgrid(K, Bv)  # rows = damping, columns = stiffness
    periods = [int(m) for m in probe_periods]
    if not periods or min(periods) < 1:
        raise UserError(f"probe periods must be whole numbers >= 1, got {probe_periods!r}")
    P = len(periods)
    k_row, b_row = np.tile(KK.ravel(), P), np.tile(BB.ravel(), P)
    n_rows = k_row.size
    T = device.control_period_s
    kt = device.torque_constant
    sub = device.substeps
    h = T / sub
    wall = 0.0
    theta0 = wall + START_PENETRATION
    lo, hi = device.model.jnt_range[device.joint_id]
    n = int(round(duration_s / T))
    k0 = int(round(SETTLE_FRACTION * n))
    read = encoder_reader(ENCODER_STEP_RAD if quantize else 0.0)
    push = k_row * START_PENETRATION
    # probe m: a torque impulse over the first physics step of every m-th servo period that
    # reverses the yaw's velocity, so the velocity is a square wave of half-period m T and the
    # position a triangle with its corners at samples; the first impulse is half (the velocity
    # alternates about zero)
    inertia = device.inertia(*device.equilibrium(*gamma_set_deg))
    J = 2.0 * probe_speed * inertia
    imp_row = np.repeat(_probe_impulses(periods, n, J / h), KK.size, axis=0)  # (rows, n)
    bphys = physical_damping(device)
    eng = Engine([device] * n_rows, [theta0] * n_rows, [gamma_set_deg] * n_rows, nthread=nthread)
    try:
        y_prev = read(np.full(n_rows, theta0), 0.0)
        queue = [np.zeros(n_rows)] * delay
        W = np.zeros(n_rows)  # the hand's work (probe and push) over the window
        S = np.zeros(n_rows)
        bad = np.zeros(n_rows, dtype=bool)
        if record:
            rec = {"theta": np.empty((n_rows, n)), "tau_wall": np.empty((n_rows, n))}
        for k in range(n):
            th = eng.yaw()
            if k == k0:
                x_start, v_start = th.copy(), eng.yaw_velocity()
            y = read(th, 0.0)
            tau = wall_torque(y, y_prev, wall, k_row, b_row, T, torque_limit)
            y_prev = y
            if delay:
                queue.append(tau)
                tau = queue.pop(0)
            # a command per physics step: the wall's torque and the push held, the probe's
            # impulse in the first step
            cmd = np.repeat(((tau + push) / kt)[:, None], sub, axis=1)
            cmd[:, 0] += imp_row[:, k] / kt
            v0 = eng.yaw_velocity()
            vs = eng.apply_per_step(cmd)
            th1 = eng.yaw()
            if k >= k0:
                # the work of a force held over a physics step is F h (v_j + v_j+1) / 2 in
                # MuJoCo's semi-implicit Euler (its exact kinetic-energy balance)
                vprev = np.concatenate([v0[:, None], vs[:, :-1]], axis=1)
                mid = 0.5 * (vs + vprev)
                W += h * (imp_row[:, k] * mid[:, 0] + push * mid.sum(axis=1))
                S += bphys * h * (vs * mid).sum(axis=1)
            if record:
                rec["theta"][:, k], rec["tau_wall"][:, k] = th, tau
            bad |= ~np.isfinite(th1) | (th1 <= lo + 1e-3) | (th1 >= hi - 1e-3)
            if bad.all():
                break
        # the energies stored at the window's ends, taken out of the hand's work: the yaw's
        # kinetic energy and the wall spring's K x^2 / 2 (x the true penetration)
        x_end, v_end = eng.yaw(), eng.yaw_velocity()
        W -= 0.5 * inertia * (v_end**2 - v_start**2)
        W -= 0.5 * k_row * (np.maximum(x_end - wall, 0.0)**2 - np.maximum(x_start - wall, 0.0)**2)
    finally:
        eng.close()
    with np.errstate(invalid="ignore", divide="ignore"):
        index = np.where(S > 0, W / np.where(S > 0, S, 1.0), 0.0)
    index[bad] = -1.0
    per = index.reshape((P,) + KK.shape)
    worst = per.min(axis=0)
    diverged = bad.reshape((P,) + KK.shape).any(axis=0)
    out = {"passive": (worst >= -TOL) & ~diverged, "index": worst, "index_per_probe": per,
           "diverged": diverged, "probe_periods": periods}
    if record:
        out["trace"] = rec
    return out


def _probe_impulses(periods, n: int, torque: float) -> np.ndarray:
    """The probes' torques [N*m] in the first physics step of each of ``n`` servo periods, one
    row per probe: ``+-torque`` alternating every ``m`` periods, the first one halved (so the
    velocity alternates about zero)."""
    imp = np.zeros((len(periods), n))
    for i, m in enumerate(periods):
        ks = np.arange(0, n, m)
        imp[i, ks] = torque * np.where(np.arange(ks.size) % 2 == 0, 1.0, -1.0)
        imp[i, 0] *= 0.5
    return imp


def colgate_limit(b: float, B, T: float) -> np.ndarray:
    """Colgate & Schenkel's largest passive stiffness ``2 (b - |B|) / T`` [N*m/rad] (0 if
    negative)."""
    return np.maximum(0.0, 2.0 * (b - np.abs(np.asarray(B, dtype=float))) / T)


def boundary(stiffness, index) -> np.ndarray:
    """Per damping row, the stiffness [N*m/rad] where the energy index first falls below
    ``-TOL`` along the row (linear interpolation between grid points; NaN if the first column
    is already not passive, the last column if the whole row is passive)."""
    K = np.asarray(stiffness, dtype=float)
    idx = np.asarray(index, dtype=float) + TOL
    out = np.full(idx.shape[0], np.nan)
    for i, row in enumerate(idx):
        if row[0] < 0:
            continue
        neg = np.flatnonzero(row < 0)
        if neg.size == 0:
            out[i] = K[-1]
            continue
        j = int(neg[0])
        out[i] = K[j - 1] + (K[j] - K[j - 1]) * row[j - 1] / (row[j - 1] - row[j])
    return out


# --- the command --------------------------------------------------------------------------------
def _parse_range(text: str, what: str) -> list[float]:
    """``START:STOP:N`` (N evenly spaced values) or a comma-separated list."""
    try:
        if ":" in text:
            a, b, m = text.split(":")
            m = int(m)
            if m < 1:
                raise ValueError
            vals = np.linspace(float(a), float(b), m).tolist()
        else:
            vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UserError(f"--{what}: expected START:STOP:N or a comma-separated list of numbers, "
                        f"got {text!r}") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise UserError(f"--{what}: values must be finite numbers, got {text!r}")
    return vals


def zwidth_command(args) -> int:
    from identification.dataset import atomic_output_dir

    if args.ideal and (args.model or args.friction):
        raise UserError("--ideal uses the built-in scene: not with --model or --friction")
    if args.model and args.friction:
        raise UserError("--model and --friction are exclusive")
    dev, tlim = map_device(args.model, args.friction, ideal=args.ideal, substeps=args.substeps)
    b = physical_damping(dev)
    T = dev.control_period_s
    K = (_parse_range(args.stiffness, "stiffness") if args.stiffness
         else np.linspace(0.0, 3.0 * b / T, 20).tolist())
    B = (_parse_range(args.damping, "damping") if args.damping
         else np.linspace(0.0, 1.25 * b, 20).tolist())
    if len(K) < 2:
        raise UserError("--stiffness: give at least two values")
    if min(K) < 0:
        raise UserError(f"--stiffness: values must be >= 0, got {min(K)}")
    quantize = not args.ideal and not args.no_quantize
    t0 = time.perf_counter()
    if not (args.probe_speed > 0 and math.isfinite(args.probe_speed)):
        raise UserError(f"--probe-speed must be a finite speed > 0 [rad/s], got {args.probe_speed}")
    res = passivity_map(dev, K, B, torque_limit=tlim, quantize=quantize, delay=args.delay,
                        probe_speed=args.probe_speed, nthread=args.jobs)
    elapsed = time.perf_counter() - t0
    from omni_sim.model import model_path

    family = "ideal" if args.ideal else dev.friction_family(
        None if args.model else model_path(None, args.friction))
    doc = {
        "stiffness": K, "damping": B,
        "passive": res["passive"].tolist(),
        "physical_damping": b, "sample_period_s": T,
        "settings": {"model": str(args.model) if args.model else None, "friction": family,
                     "ideal": bool(args.ideal), "quantize": quantize, "delay_periods": args.delay,
                     "physics_substeps": args.substeps, "probe_speed": args.probe_speed,
                     "probe_periods": list(PROBE_PERIODS),
                     "start_penetration_rad": START_PENETRATION, "duration_s": DURATION_S,
                     "settle_fraction": SETTLE_FRACTION, "tolerance": TOL,
                     "torque_limit": tlim, "elapsed_s": round(elapsed, 2)},
        "energy_index": res["index"].round(6).tolist(),
        "energy_index_per_probe": {str(m): x.round(6).tolist()
                                   for m, x in zip(res["probe_periods"], res["index_per_probe"])},
        "boundary_stiffness": [None if not np.isfinite(x) else x for x in boundary(K, res["index"])],
        "colgate_stiffness": colgate_limit(b, B, T).tolist(),
    }
    with atomic_output_dir(args.out, force=args.force) as tmp:
        (tmp / "zwidth.json").write_text(json.dumps(doc, indent=1) + "\n")
        plot_map(doc, tmp / "zwidth.png")
    print(f"zwidth: {len(B)} x {len(K)} walls in {elapsed:.1f} s; b = {b:.4g} N*m*s/rad, "
          f"T = {T:g} s; wrote {Path(args.out) / 'zwidth.json'}, zwidth.png")
    return 0


def plot_map(doc: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    K, B = np.array(doc["stiffness"]), np.array(doc["damping"])
    P = np.array(doc["passive"], dtype=bool)
    b, T = doc["physical_damping"], doc["sample_period_s"]
    fig, ax = plt.subplots(figsize=(6, 4.5))
    KK, BB = np.meshgrid(K, B)
    ax.scatter(KK[P], BB[P], s=18, c="tab:green", marker="o", label="passive")
    ax.scatter(KK[~P], BB[~P], s=18, c="tab:red", marker="x", label="not passive")
    bb = np.linspace(min(B.min(), 0), B.max(), 200)
    ax.plot(colgate_limit(b, bb, T), bb, "k-", label="Colgate & Schenkel: b = K T/2 + |B|")
    kb = np.array([np.nan if x is None else x for x in doc["boundary_stiffness"]], dtype=float)
    ax.plot(kb, B, "b--", drawstyle="default", label="measured boundary (largest passive K)")
    ax.set_xlabel("wall stiffness K [N m/rad]")
    ax.set_ylabel("wall damping B [N m s/rad]")
    s = doc["settings"]
    ax.set_title(f"Z-width, {s['friction']}, T = {T * 1e3:g} ms, b = {b:.3g}, "
                 f"q={'on' if s['quantize'] else 'off'}, delay {s['delay_periods']}", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
