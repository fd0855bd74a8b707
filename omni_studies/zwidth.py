"""Which virtual walls (K, B) the virtual Omni's yaw renders passively: the Z-width study
(``omni zwidth`` is its command, :mod:`omni_app.zwidth`).

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
``1 - (K T / 2 + |B|) / b`` (measured, ``docs/studies/haptics/zwidth_ideal.json``: its boundary
lies above Colgate & Schenkel's by at most 1.3 % up to 0.92 b (+0.05 to +1.3 % on those rows),
7.6 % at 0.99 b).
The largest passive K of a damping row is interpolated where ``index`` crosses ``-TOL``
(:func:`boundary`).  A passive cell past a row's first active one (a row that is not monotone)
is marked ``beyond_boundary`` and explained in the map's ``notes`` (:func:`map_notes`): with
quantisation and a probe below one encoder count it is not a result.

The physics step is refined to ``T / substeps`` (default 20) for this tool: Colgate & Schenkel's
plant is continuous between samples, while the model's own 1 ms step equals the servo period.

The hand's torque goes to the yaw through the motor's own channel (the same joint torque,
held over the period like the wall's); the wall's part alone is clipped to the drive's limit.

**What a map refuses** (:func:`check_map`, before anything runs; each bound's reason is at its
constant): a stiffness the drive cannot hold at the start press, a damping that saturates the
drive at the probe's speed, a device without viscous damping (the index is ``W / D_b``), a
delay reaching into the energy window, a probe leaving the wall, a probe too slow for the
physics step, more substeps than change a verdict, and a map larger than the memory budget.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from identification.errors import UserError
from identification.records import Record

#: Probe speed [rad/s] of the Nyquist square-wave velocity (our choice: 0.02 rad/s, so the
#: triangle's corners are +-1e-5 rad -- a pure test of the sampled wall, below one encoder count).
PROBE_SPEED = 0.02
#: Start penetration [rad] (our choice: 0.01 rad, 24 encoder counts, a firm press).
START_PENETRATION = 0.01
#: Run length [s] and the fraction skipped before the energy is summed (our choice; the
#: Nyquist response is reached within a few periods, the 0.3 s covers the slower transients).
DURATION_S = 1.0
SETTLE_FRACTION = 0.3
#: Tolerance of the energy test (fraction of the viscous dissipation; our choice, 0.1 %: it
#: moves the boundary by TOL * 2 b / T, 0.014 N*m/rad on the Omni; the method's own error at
#: the default probe is 0.65 TOL at K = 10 N*m/rad, see MIN_SPEED_X_SUBSTEPS).
TOL = 1e-3
#: Half-periods of the probes' velocity square waves [servo periods] (our choice): 1 is the
#: Nyquist frequency (Colgate & Schenkel's worst case for B >= 0 without delay), 4 and 16 lower
#: frequencies (the worst case for B < 0 and, with a loop delay, in between).
PROBE_PERIODS = (1, 4, 16)
#: Physics steps per servo period for the map (the probe's impulse takes one: 1/20 of the
#: period, so the velocity square wave is within ~3 % of ideal).
SUBSTEPS = 20
#: Most physics steps per servo period: the index's error against the ideal device's exact
#: value ``1 - K T / (2 b)`` falls as 1 / substeps (measured at K = 10 N*m/rad, B = 0, the Nyquist
#: probe at 0.02 rad/s: -6.5e-4 at 20 substeps, -1.6e-4 at 80, -1.2e-5 at 1000;
#: tests/test_zwidth.py checks the law), so beyond 1000 it is below 1/80 of TOL and changes no
#: verdict, while the run time grows in proportion (50 x the default's at 1000).
MAX_SUBSTEPS = 1000
#: Least probe speed x substeps [rad/s]: the same error grows as 1 / (V x substeps) (it grows
#: with START_PENETRATION: a cross-term of the press and the probe; measured as above: -6.1e-4 at
#: 0.005 rad/s with 80 substeps, against -1.6e-4 at 0.02 rad/s), so the product is held at the
#: default's, 0.02 x 20, where the error is 0.65 TOL at K = 10; a slower probe needs
#: proportionally more substeps.
MIN_SPEED_X_SUBSTEPS = PROBE_SPEED * SUBSTEPS
#: Memory budget [bytes] of one map: 2 GB, the project's peak-memory target for one command on
#: the 2-core machine (docs/reference/performance.md).  :func:`map_memory_bytes` estimates a map before it
#: runs; a larger one is refused (an unbounded 10^8-column grid was killed for its memory
#: without a message).
MEMORY_BUDGET_BYTES = 2.0e9


@dataclass(frozen=True)
class PassivityMap:
    """:func:`passivity_map`'s result: one entry per (damping row, stiffness column) cell."""

    passive: np.ndarray  #: len(damping) x len(stiffness) bools: passive under every probe
    index: np.ndarray  #: the smallest energy index W / D_b over the probes [-]
    index_per_probe: np.ndarray  #: probes x damping x stiffness [-]
    diverged: np.ndarray  #: cells whose run diverged or left the yaw's range under some probe
    probe_periods: tuple[int, ...]  #: the probes' half-periods [servo periods]
    #: with ``record``: the rows' traces ``theta``, ``tau_wall`` (row = probe-major, then cell)
    trace: dict | None = None


@dataclass(frozen=True)
class MapSettings(Record):
    """How a map was run (``zwidth.json``'s ``settings``)."""

    model: str | None  #: the model file given (None: a built-in scene)
    friction: str  #: its friction family, or "ideal"
    ideal: bool  #: no dry friction, exact encoder
    quantize: bool  #: the encoder's quantisation on
    delay_periods: int  #: loop delay [servo periods]
    physics_substeps: int  #: physics steps per servo period
    probe_speed: float  #: [rad/s]
    probe_periods: tuple[int, ...]  #: the probes' half-periods [servo periods]
    start_penetration_rad: float  #: [rad]
    duration_s: float  #: run length [s]
    settle_fraction: float  #: the part of the run before the energy window [-]
    tolerance: float  #: of the energy test [-]
    torque_limit: float  #: the drive's limit [N*m]
    encoder_step_rad: float  #: one encoder count [rad]
    elapsed_s: float  #: the map's wall time [s] (measured: varies)

    @classmethod
    def from_json(cls, d: dict) -> MapSettings:
        return cls(**{**d, "probe_periods": tuple(d["probe_periods"])})


@dataclass(frozen=True)
class MapRecord(Record):
    """One passivity map as ``omni zwidth`` writes it (``zwidth.json``): the contract's keys
    first, then the extras and the notes.  Rows are damping values, columns stiffness values."""

    stiffness: tuple[float, ...]  #: wall stiffness K, increasing [N*m/rad]
    damping: tuple[float, ...]  #: wall damping B [N*m*s/rad]
    passive: tuple[tuple[bool, ...], ...]  #: per cell
    physical_damping: float  #: the yaw's viscous damping b [N*m*s/rad]
    sample_period_s: float  #: the servo period T [s]
    settings: MapSettings  #: how the map was run
    energy_index: tuple[tuple[float, ...], ...]  #: the smallest W / D_b over the probes (6 decimals)
    #: per probe half-period (a string), W / D_b per cell (6 decimals)
    energy_index_per_probe: dict[str, tuple[tuple[float, ...], ...]]
    boundary_stiffness: tuple[float | None, ...]  #: per row, :func:`boundary` (None: none) [N*m/rad]
    colgate_stiffness: tuple[float, ...]  #: per row, Colgate & Schenkel's 2 (b - |B|) / T [N*m/rad]
    beyond_boundary: tuple[tuple[bool, ...], ...]  #: per cell, :func:`beyond_boundary`
    probe_amplitude_counts: dict[str, float]  #: per probe half-period (a string), its corners [counts]
    notes: tuple[str, ...]  #: what the cells do not say (:func:`map_notes`)

    @classmethod
    def from_json(cls, d: dict) -> MapRecord:
        return cls(**{**d, "stiffness": tuple(d["stiffness"]), "damping": tuple(d["damping"]),
                      "passive": _rows(d["passive"]), "settings": MapSettings.from_json(d["settings"]),
                      "energy_index": _rows(d["energy_index"]),
                      "energy_index_per_probe": {m: _rows(x) for m, x in d["energy_index_per_probe"].items()},
                      "boundary_stiffness": tuple(d["boundary_stiffness"]),
                      "colgate_stiffness": tuple(d["colgate_stiffness"]),
                      "beyond_boundary": _rows(d["beyond_boundary"]), "notes": tuple(d["notes"])})


def _rows(a) -> tuple:
    """A 2-D array (or list of lists) as a tuple of row tuples of Python numbers."""
    return tuple(tuple(r) for r in np.asarray(a).tolist())


def map_record(device, stiffness, damping, res: PassivityMap, settings: MapSettings) -> MapRecord:
    """The record of a map (``zwidth.json``): ``res`` from :func:`passivity_map` on ``device``
    for the walls ``stiffness`` x ``damping``, run as ``settings`` says; the boundaries, Colgate
    & Schenkel's line, the cells beyond the boundary and the notes are computed here."""
    b, T = physical_damping(device), device.control_period_s
    rec = MapRecord(
        stiffness=tuple(stiffness), damping=tuple(damping), passive=_rows(res.passive),
        physical_damping=b, sample_period_s=T, settings=settings,
        energy_index=_rows(res.index.round(6)),
        energy_index_per_probe={str(m): _rows(x.round(6)) for m, x in zip(res.probe_periods, res.index_per_probe)},
        boundary_stiffness=tuple(None if not np.isfinite(x) else float(x) for x in boundary(stiffness, res.index)),
        colgate_stiffness=tuple(colgate_limit(b, damping, T).tolist()),
        beyond_boundary=_rows(beyond_boundary(res.passive)),
        probe_amplitude_counts=probe_amplitude_counts(settings.probe_speed, settings.probe_periods, T),
        notes=())
    return dataclasses.replace(rec, notes=tuple(map_notes(rec.to_json())))


def physical_damping(device) -> float:
    """The yaw's viscous damping ``b`` [N*m*s/rad] (the joint's ``damping``)."""
    return device.yaw_damping


def map_device(path=None, friction=None, ideal=False, control_period_s=1e-3, substeps=SUBSTEPS):
    """The device of a map: the model with its physics step refined and the drive's ctrlrange
    opened (the wall's own clip is applied in :func:`passivity_map`).  Returns
    ``(device, torque_limit)``."""
    from omni_sim import model as om
    from omni_sim.device import Device

    if not 1 <= substeps <= MAX_SUBSTEPS:
        raise UserError(f"--substeps must be 1 to {MAX_SUBSTEPS}, got {substeps}: beyond "
                        f"{MAX_SUBSTEPS} no verdict changes (the index's step error falls as "
                        f"1/substeps) and the run time grows in proportion")
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


def require_damping(device) -> float:
    """The yaw's viscous damping b [N*m*s/rad]; a :class:`UserError` if it is not > 0."""
    b = physical_damping(device)
    if not b > 0:
        raise UserError(f"the yaw has no viscous damping (b = {b:g} N*m*s/rad): the map's energy "
                        f"index W / D_b divides by the viscous dissipation D_b, and Colgate & "
                        f"Schenkel's bound b > K T/2 + |B| passes no wall; give the yaw joint a "
                        f"damping > 0")
    return b


def map_memory_bytes(device, n_cells: int, n_probes: int, n_periods: int, delay: int = 0,
                     record: bool = False) -> float:
    """Estimated peak memory [bytes] of :func:`passivity_map`: per rollout row (cell x probe)
    the probes' impulse table (``n_periods`` floats; 3 x that with ``record``'s traces), the
    engine's state, control and sensor buffers and the period's work arrays (``substeps`` x
    (nstate + nu + nsensordata + 8) floats), the delay line (``delay`` floats) and 100 more; plus
    a copy of the model per row where the drive has friction laws (:class:`Engine` steps each
    row's own).  Measured peak growth on the ideal device: 73.9 MB for 6000 rows of 1000
    periods (estimate 75.3), 125 MB for 30000 rows of 50 periods (estimate 148)."""
    m = device.model
    floats = (n_periods * (3 if record else 1) + device.substeps * (device.nstate + m.nu
              + m.nsensordata + 8) + device.nstate + delay + 100)
    per_row = 8.0 * floats + (m.nbuffer if device.drive_friction is not None else 0)
    return float(n_cells) * n_probes * per_row


def check_map(device, stiffness, damping, torque_limit=math.inf, quantize=False, delay=0,
              probe_speed=PROBE_SPEED, probe_periods=PROBE_PERIODS, duration_s=DURATION_S,
              record=False) -> None:
    """Refuse (:class:`UserError`) a map that would test no wall, or not fit in memory, before
    anything runs; the reasons are at the module's constants."""
    from omni_sim.device import ENCODER_STEP_RAD

    K, B = np.asarray(stiffness, dtype=float), np.asarray(damping, dtype=float)
    if K.size < 1 or B.size < 1 or not (np.isfinite(K).all() and np.isfinite(B).all()):
        raise UserError("stiffness and damping: give finite numbers")
    if K.min() < 0:
        raise UserError(f"--stiffness: values must be >= 0, got {K.min():g}")
    require_damping(device)
    T, sub = device.control_period_s, device.substeps
    periods = [int(m) for m in probe_periods]
    if not periods or min(periods) < 1:
        raise UserError(f"probe periods must be whole numbers >= 1, got {probe_periods!r}")
    if not (probe_speed > 0 and math.isfinite(probe_speed)):
        raise UserError(f"--probe-speed must be a finite speed > 0 [rad/s], got {probe_speed}")
    v_out = 2.0 * START_PENETRATION / (max(periods) * T)
    if probe_speed >= v_out:
        raise UserError(f"--probe-speed {probe_speed:g} rad/s: the slowest probe's triangle "
                        f"(+-V {max(periods)} T/2) would leave the wall, pressed "
                        f"{START_PENETRATION} rad deep; give less than {v_out:g} rad/s")
    if probe_speed * sub < MIN_SPEED_X_SUBSTEPS * (1 - 1e-12):
        raise UserError(f"--probe-speed {probe_speed:g} rad/s with {sub} substeps: the energy "
                        f"test's own error grows as 1/(speed x substeps) and would pass its "
                        f"tolerance near Colgate's bound; give speed x substeps >= "
                        f"{MIN_SPEED_X_SUBSTEPS:g} rad/s (e.g. --substeps "
                        f"{math.ceil(MIN_SPEED_X_SUBSTEPS / probe_speed)})")
    if math.isfinite(torque_limit):
        k_max = torque_limit / START_PENETRATION
        if K.max() > k_max:
            raise UserError(f"--stiffness {K.max():g} N*m/rad: the drive's {torque_limit:g} N*m "
                            f"cannot hold the start press ({START_PENETRATION} rad) beyond "
                            f"{k_max:g} N*m/rad, the hand would push through the wall")
        v_wall = max(probe_speed, ENCODER_STEP_RAD / T) if quantize else probe_speed
        b_max = torque_limit / v_wall
        if np.abs(B).max() > b_max:
            raise UserError(f"--damping {B[np.argmax(np.abs(B))]:g} N*m*s/rad: at {v_wall:g} rad/s "
                            f"(the {'encoder count per period' if v_wall > probe_speed else 'probe'}"
                            f"'s speed) the damper alone saturates the drive's {torque_limit:g} "
                            f"N*m: the map would test the clip; give |B| <= {b_max:g}")
    n = int(round(duration_s / T))
    k0 = int(round(SETTLE_FRACTION * n))
    if not 0 <= delay < k0:
        raise UserError(f"--delay must be 0 to {k0 - 1} servo periods, got {delay}: the wall must "
                        f"act before the energy window opens ({SETTLE_FRACTION} of the "
                        f"{duration_s:g} s run)")
    need = map_memory_bytes(device, K.size * B.size, len(periods), n, delay, record)
    if need > MEMORY_BUDGET_BYTES:
        raise UserError(f"{B.size} x {K.size} walls x {len(periods)} probes need about "
                        f"{need / 1e9:.1f} GB, above the {MEMORY_BUDGET_BYTES / 1e9:g} GB budget: "
                        f"give fewer stiffness or damping values")


def passivity_map(device, stiffness, damping, torque_limit=math.inf, quantize=False, delay=0,
                  probe_speed=PROBE_SPEED, probe_periods=PROBE_PERIODS, duration_s=DURATION_S,
                  gamma_set_deg=(65.0, 90.0), nthread=None, record=False, progress=False):
    """Run every (K, B) cell under every probe and decide passivity (see the module doc), after
    :func:`check_map`.  ``progress``: a bar of the servo periods on stderr (tqdm).

    Returns a frozen :class:`PassivityMap`: ``passive`` (len(damping) x len(stiffness) bools),
    ``index`` (the smallest W / D_b over the probes), ``index_per_probe`` (probes x damping x
    stiffness), ``diverged``, ``probe_periods``; with ``record`` also the rows' traces (row =
    probe-major, then cell).  :func:`map_record` makes ``zwidth.json``'s record of it."""
    check_map(device, stiffness, damping, torque_limit, quantize, delay, probe_speed,
              probe_periods, duration_s, record)
    K = np.asarray(stiffness, dtype=float)
    Bv = np.asarray(damping, dtype=float)
    KK, BB = np.meshgrid(K, Bv)  # rows = damping, columns = stiffness
    periods = [int(m) for m in probe_periods]
    P = len(periods)
    k_row, b_row = np.tile(KK.ravel(), P), np.tile(BB.ravel(), P)
    run = _Probing(tuple(periods), probe_speed, duration_s, torque_limit, quantize, delay,
                   gamma_set_deg)
    W, S, bad, rec = _run_rows(device, k_row, b_row, run, nthread, record, progress)
    with np.errstate(invalid="ignore", divide="ignore"):
        index = np.where(S > 0, W / np.where(S > 0, S, 1.0), 0.0)
    index[bad] = -1.0
    per = index.reshape((P,) + KK.shape)
    worst = per.min(axis=0)
    diverged = bad.reshape((P,) + KK.shape).any(axis=0)
    return PassivityMap(passive=(worst >= -TOL) & ~diverged, index=worst, index_per_probe=per,
                        diverged=diverged, probe_periods=tuple(periods), trace=rec)


@dataclass(frozen=True)
class _Probing:
    """How the rows of a map run (:func:`passivity_map`'s settings, checked by
    :func:`check_map`): the probes' half-periods [servo periods] and speed [rad/s], the run's
    length [s], the drive's torque limit [N*m], the encoder's quantisation, the loop delay
    [servo periods] and the arm's set points [deg]."""
    periods: tuple[int, ...]
    probe_speed: float
    duration_s: float
    torque_limit: float
    quantize: bool
    delay: int
    gamma_set_deg: tuple[float, float]


def _run_rows(device, k_row, b_row, run: _Probing, nthread, record, progress):
    """Run the rows (cell x probe) of a map, stiffness ``k_row`` and damping ``b_row`` (the
    cells repeated probe by probe): returns the hand's work ``W`` over the energy window less
    the energy stored at its ends, the viscous dissipation ``S`` [J], the rows that diverged or
    left the yaw's range, and the traces (with ``record``)."""
    from tqdm import tqdm

    from omni_sim.device import ENCODER_STEP_RAD, Engine, encoder_reader
    from omni_sim.wall_env import wall_torque

    n_rows = k_row.size
    T, kt, sub = device.control_period_s, device.torque_constant, device.substeps
    h = T / sub
    wall = 0.0
    theta0 = wall + START_PENETRATION
    jid = device.joint_id
    lo, hi = device.model.jnt_range[jid] if device.model.jnt_limited[jid] else (-math.inf, math.inf)
    n = int(round(run.duration_s / T))
    k0 = int(round(SETTLE_FRACTION * n))
    read = encoder_reader(ENCODER_STEP_RAD if run.quantize else 0.0)
    push = k_row * START_PENETRATION
    # probe m: a torque impulse over the first physics step of every m-th servo period that
    # reverses the yaw's velocity, so the velocity is a square wave of half-period m T and the
    # position a triangle with its corners at samples; the first impulse is half (the velocity
    # alternates about zero)
    inertia = device.inertia(*device.equilibrium(*run.gamma_set_deg))
    J = 2.0 * run.probe_speed * inertia
    imp_row = np.repeat(_probe_impulses(run.periods, n, J / h), n_rows // len(run.periods), axis=0)
    bphys = physical_damping(device)
    eng = Engine([device] * n_rows, [theta0] * n_rows, [run.gamma_set_deg] * n_rows, nthread=nthread)
    bar = tqdm(total=n, desc="zwidth", unit="period", disable=not progress, leave=False)
    try:
        y_prev = read(np.full(n_rows, theta0), 0.0)
        queue = [np.zeros(n_rows)] * run.delay
        W = np.zeros(n_rows)  # the hand's work (probe and push) over the window
        S = np.zeros(n_rows)
        bad = np.zeros(n_rows, dtype=bool)
        rec = ({"theta": np.empty((n_rows, n)), "tau_wall": np.empty((n_rows, n))}
               if record else None)
        # the window's start (reset at k0; a batch whose rows all fail before it sums nothing)
        x_start, v_start = eng.yaw(), eng.yaw_velocity()
        for k in range(n):
            th = eng.yaw()
            if k == k0:
                x_start, v_start = th.copy(), eng.yaw_velocity()
            y = read(th, 0.0)
            tau = wall_torque(y, y_prev, wall, k_row, b_row, T, run.torque_limit)
            y_prev = y
            if run.delay:
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
            bar.update()
            if bad.all():
                break
        # the energies stored at the window's ends, taken out of the hand's work: the yaw's
        # kinetic energy and the wall spring's K x^2 / 2 (x the true penetration)
        x_end, v_end = eng.yaw(), eng.yaw_velocity()
        W -= 0.5 * inertia * (v_end**2 - v_start**2)
        W -= 0.5 * k_row * (np.maximum(x_end - wall, 0.0)**2 - np.maximum(x_start - wall, 0.0)**2)
    finally:
        bar.close()
        eng.close()
    return W, S, bad, rec


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
    is already not passive, the last column if the whole row is passive).  ``stiffness`` must
    increase (a ValueError otherwise: along an unsorted row the first crossing is no boundary)."""
    K = np.asarray(stiffness, dtype=float)
    if np.any(np.diff(K) <= 0):
        raise ValueError(f"boundary: the stiffness must increase, got {K.tolist()}")
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


def beyond_boundary(passive) -> np.ndarray:
    """The passive cells past their row's first cell that is not passive (the row is not
    monotone there): same shape as ``passive`` (rows = damping, columns = increasing K)."""
    P = np.asarray(passive, dtype=bool)
    past_active = np.cumsum(~P, axis=1) > 0
    return P & past_active


def probe_amplitude_counts(probe_speed: float, probe_periods, T: float) -> dict:
    """Each probe's corner amplitude ``V m T / 2`` in encoder counts (15000 counts/rev), keyed
    by its half-period m [servo periods]."""
    from omni_sim.device import ENCODER_STEP_RAD

    return {str(int(m)): probe_speed * int(m) * T / 2 / ENCODER_STEP_RAD for m in probe_periods}


def map_notes(doc: dict) -> list[str]:
    """What a reader of the map must know that its cells do not say: passive cells beyond the
    boundary and why, a probe the encoder does not see, a loop delay the probes miss."""
    s = doc["settings"]
    beyond = np.array(doc["beyond_boundary"], dtype=bool)
    counts = max(doc["probe_amplitude_counts"].values())
    sub_count = s["quantize"] and counts < 1
    notes = []
    if beyond.any():
        rows = [f"{doc['damping'][i]:.3g}" for i in np.flatnonzero(beyond.any(axis=1))]
        if sub_count:
            why = ("they come with quantisation and a probe below one encoder count (docs/studies/haptics/haptics.md: "
                   "the exact-encoder maps and the quantised map with a one-count probe have none)")
        elif s["delay_periods"]:
            why = "with a loop delay the probes miss the worst frequency (docs/studies/haptics/haptics.md)"
        else:
            why = "the probes' verdict is not monotone in K there"
        notes.append(f"{int(beyond.sum())} passive cell(s) lie beyond their row's boundary, past "
                     f"a wall found active at a lower K (B = {', '.join(rows)}): marked in "
                     f"beyond_boundary, they are not a result: {why}")
    if sub_count:
        notes.append(f"every probe moves less than one encoder count (at most {counts:.2f} counts): "
                     f"the encoder hardly sees the probe, and the boundary is the quantised loop's, "
                     f"not Colgate & Schenkel's (docs/studies/haptics/haptics.md); the Nyquist probe reaches one "
                     f"count at --probe-speed {_one_count_speed(doc):.3g} rad/s")
    if s["delay_periods"]:
        notes.append(f"a loop delay of {s['delay_periods']} period(s): the probes miss the delayed "
                     f"wall's worst frequency, so the map is optimistic (docs/studies/haptics/haptics.md, delay "
                     f"caveat)")
    return notes


def _one_count_speed(doc: dict) -> float:
    """The probe speed [rad/s] at which the Nyquist probe's corners are one count from the
    centre (``V T / 2`` = one count)."""
    from omni_sim.device import ENCODER_STEP_RAD

    return 2 * ENCODER_STEP_RAD / doc["sample_period_s"]
