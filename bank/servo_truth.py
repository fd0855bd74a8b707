"""A pendulum on a geared servo whose gearbox friction grows with the torque it transmits, or
depends on the direction of motion: the truth of the hidden-effect bank's geared-servo cases,
and their "measured" runs as a host logs a real servo.

Written independently of the effect library (:mod:`discrepancy.effects`) and of the
device's closed-loop engine (:mod:`omni_sim.device`): a plain loop over physics steps with
``mujoco.mj_step`` on a private copy of the nominal model
``models/servo_pendulum/servo_pendulum.xml`` (joint ``pivot``, actuator ``servo``, control in
volts).

The hidden law (load-dependent and direction-dependent gearbox friction)
------------------------------------------------------------------------
At every physics step (timestep = the servo's 1 ms loop period): ``w`` = the hinge velocity
before the step; ``tau`` = the torque the motor transmits, ``gear * actuator_force`` of the
servo's actuator as computed in the previous step (0 before the first step); the hinge's
Coulomb friction for this step is::

    frictionloss = max(0, Fc + a * sign(w) + mu * |tau|),
    mu = (mu_drive + mu_back)/2 + (mu_drive - mu_back)/2 * tanh(w / W_B)   if tau > 0
         (mu_drive + mu_back)/2 - (mu_drive - mu_back)/2 * tanh(w / W_B)   otherwise

(``mu_drive``: the motor drives the load, ``tau * w > 0``; ``mu_back``: the load back-drives
the motor; their mean at rest, the coefficient passing from one to the other over speeds of
about ``W_B`` = :data:`BLEND_SPEED_RAD_S`), ``Fc`` the nominal model's own ``frictionloss`` of
the hinge, ``a`` [N*m] the direction-dependent part of the Coulomb level (``Fc + a`` moving positive, ``Fc - a`` moving
negative, ``Fc`` at ``w = 0`` exactly; ``sign`` is -1, 0 or +1).  It is written into the private
model's ``dof_frictionloss`` before each ``mj_step``.  With ``a`` and both coefficients 0 the
loop is the nominal model's, bit for bit (``tests/test_servo_truth.py``).

Magnitudes (the ``load_friction`` case's values, :data:`MU_DRIVE`, :data:`MU_BACK`): a driving
gearbox passes ``eta_f * tau`` to the load and loses ``(1 - eta_f) * tau``, so
``mu_drive = 1 - eta_f``; a back-driven one loses ``T - eta_b * T`` of the load torque ``T``
while the motor holds ``tau = eta_b * T``, so ``mu_back = 1/eta_b - 1``.  The
``asymmetric_friction`` case's ``a`` is :data:`ASYMMETRY_NM` (its truth has no load-dependent
part: ``mu_drive = mu_back = 0``).

The experiment and its log
--------------------------
The servo closes its own P loop at 1 kHz in volts, ``u = clip(kp (goal - y), -12, 12)`` on its
encoder reading ``y`` (4096 counts/rev after white noise :data:`NOISE_RAD`), and drives 0 V
while its torque is disabled.  The host talks to it at 200 Hz with timing jitter: at each of its
log times it writes the goal (and the torque enable) and reads the position; the servo holds
the last goal (and enable) written until the next write, so at the loop tick at time ``k dt``
it uses the values of the last log time ``t_j <= k dt``.  A log row holds ``t_j``, the goal
``r`` written then, the position ``theta`` read then, the command ``v`` the servo was applying
at ``t_j`` (that of the last tick ``<= t_j``) and ``enabled``.  The position read at ``t_j`` is
the encoder's reading (a fresh noise sample, rounded to a count) of the truth's angle at that
instant, the 1 kHz trajectory interpolated linearly between the ticks around ``t_j`` (what the
replay compares against: its own 1 kHz trajectory interpolated at the logged times).  The
timestamps are the true instants of the reads (no clock error).  Every run starts at rest
hanging straight down (``theta = 0``).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from identification.dataset import Run

from omni_sim import model as om

#: The nominal model's controlled joint and actuator (the bank case's ``--joint``/``--actuator``;
#: its ``--model`` is :func:`model_path`).
JOINT, ACTUATOR = "pivot", "servo"
#: The hidden load-dependent friction's coefficients [-] (absolute; the nominal model has 0):
#: forward efficiency eta_f = 0.85 of a 4-5 stage spur gearbox (0.96-0.97 per mesh, textbook
#: spur-gear figure, over ~350:1) -> mu_drive = 1 - 0.85 = 0.15; back-driving efficiency
#: eta_b = 0.69 -> mu_back = 1/0.69 - 1 = 0.45.  eta_b is an ESTIMATE: back-driving a small
#: servo's gearbox loses markedly more than driving it (docs/method/servo-actuators.md, "Typical
#: geared servos": the friction is larger when the load back-drives the motor, up to
#: self-locking), while the
#: textbook mesh-friction relation eta_b = 2 - 1/eta per mesh would give ~0.83; 0.69 stands for
#: the larger back-drive losses (bearing preload, the motor's brushes and cogging seen through
#: the gear) reported for such servos, not a measured figure.
MU_DRIVE = 0.15
MU_BACK = 0.45
#: The back-EMF damping [N*m*s/rad] the library's ``load_friction`` may take out of the
#: transmitted torque (``b_emf_nms_per_rad``): this truth's law reads ``tau = gear * actuator_force``,
#: the actuator's torque alone, i.e. 0.
B_EMF = 0.0
#: The hidden direction-dependent Coulomb part [N*m] of the bank's ``asymmetric_friction`` case
#: (the nominal model has none): +7.5 mN*m, 25 % of the nominal Fc = 30 mN*m (friction 37.5
#: mN*m moving positive, 22.5 mN*m moving negative).  An ESTIMATE, set before the case was
#: run: about half of a small servo's no-load friction is the motor's own (brushes on the
#: commutator, reflected through the gear; the rest the gear train), and a brushed motor's
#: brush friction differs with the direction of rotation (brushes in inclined holders trail one
#: way and lead the other; wear and the commutator's edges make it worse) by up to about half
#: (estimate, not a measured figure): 0.5 x 0.5 x Fc = 0.25 Fc.  Inside the library effect's
#: "a few to ~30 % of the Coulomb level" (effects/drive.py).
ASYMMETRY_NM = 0.0075
#: The servo's loop period [s] (1 kHz: the usual rate of a servo's internal loop,
#: docs/method/servo-actuators.md, "Typical geared servos"); the model's timestep is the same.
CONTROL_PERIOD_S = 1e-3
#: The host's log period [s] (200 Hz: the top of the 50-200 Hz hosts log at, same page).
LOG_PERIOD_S = 5e-3
#: Host timing jitter: N(0, 0.4 ms) on every log time, clipped to +-1.5 ms (a USB-serial
#: round trip on a non-real-time OS, estimate); the first time is 0.
JITTER_S = 0.4e-3
JITTER_CLIP_S = 1.5e-3
#: Probability that a log frame is missed (the next one then comes ~2 periods later, never
#: more than 2 periods after the previous one): a few per run (estimate).
MISSED_FRAME_P = 0.01
#: The servo's P gain [V/rad]: full supply at 0.3 rad of error (a stiff position servo, servo
#: stiffness kp * gear = 12 N*m/rad, ten times the pendulum's gravity stiffness; estimate of a
#: hobby servo's default proportional band of ~15-20 deg).
KP = 40.0
#: The P loop's saturation [V]: the 12 V supply (duty 100 %), = the model's ctrlrange.
COMMAND_LIMIT = 12.0
#: Magnetic encoder: 4096 counts/rev (12-bit, as on Dynamixel X / Feetech STS servos).
ENCODER_COUNTS = 4096
ENCODER_STEP_RAD = 2 * math.pi / ENCODER_COUNTS
#: The speed [rad/s] over which the gearbox's coefficient passes from mu_back to mu_drive: the
#: device engine's law has the same (omni_sim.device.LOAD_FRICTION_BLEND_RAD_S, its provenance;
#: written here on its own, as the rest of this truth); 0: a switch on sign(tau w), mu_back at rest.
BLEND_SPEED_RAD_S = 0.05
#: White noise [rad] added before rounding, ~1/4 count (the bank's Omni encoder noise is 1/4 of
#: its count too; estimate).
NOISE_RAD = 0.4e-3
#: Run length [s]: 5 s, 1000 log rows at 200 Hz.
DURATION_S = 5.0
#: The bank's ``current_limit`` case: the firmware limits the winding's current to
#: ``i_max`` = 1.5 A (half the 3 A stall current of the 12 V supply on R = 4 ohm; servos of this
#: class ship a settable current limit, and half the stall is an ESTIMATE of a protective
#: setting, not a datasheet figure), so the motor's net torque ``kt i`` after the gear stays
#: within ``kt i_max`` = 1.2 x 1.5 = 1.8 N*m.  ``kt^2/R`` = 0.36 N*m*s/rad is the back-EMF
#: part of the model's joint damping (models/servo_pendulum/servo_pendulum.xml: 0.37 = 0.36 +
#: 0.01 of bearing loss).
CURRENT_LIMIT_NM = 1.8
BACK_EMF_NMS_PER_RAD = 0.36
#: The bank's ``friction_family_stribeck`` case: the load_friction case's gearbox with a
#: Stribeck rise of the Coulomb level, ``rise exp(-(|w|/w_s)^delta)``: rise 0.03 N*m (a static
#: level twice the model's 0.03 N*m Coulomb level at rest and no load; static-to-kinetic ratios of
#: 1.2-2 are the survey's range, Armstrong-Helouvry et al. 1994), w_s 0.1 rad/s at the output
#: shaft and delta 1 (Tustin's exponential).  Estimates, fixed before the case ran.
STRIBECK_RISE_NM, STRIBECK_SPEED_RAD_S, STRIBECK_SHAPE = 0.03, 0.1, 1.0


def model_path() -> Path:
    """The nominal model's file (shipped in the data package ``omni_sim.models``, its folder
    ``servo_pendulum/``)."""
    return om.SERVO_PENDULUM


def target() -> om.Target:
    """The controlled joint and actuator (``--joint pivot --actuator servo``)."""
    return om.Target(JOINT, ACTUATOR)


# -- the truth: one closed-loop run, a step at a time -----------------------------------------
@dataclass
class Trajectory:
    """One closed-loop run of the truth at its 1 kHz ticks.

    Attributes
    ----------
    t : ndarray (n + 1,) [s]
        Tick times ``k dt``; the state arrays hold the state at each (the last: after the last
        step).
    theta, omega : ndarray (n + 1,) [rad, rad/s]
        True hinge angle and velocity.
    y : ndarray (n,) [rad]
        What the servo's loop read at each tick.
    u : ndarray (n,) [V]
        The command of each tick (held for its step).
    frictionloss : ndarray (n,) [N*m]
        The hinge's Coulomb friction of each step (the law above).
    tau : ndarray (n,) [N*m]
        The torque the motor transmitted in each step (``gear * actuator_force``).
    """

    t: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    y: np.ndarray
    u: np.ndarray
    frictionloss: np.ndarray
    tau: np.ndarray


def read_encoder(theta, noise, step_rad):
    """The encoder's reading: ``theta + noise`` rounded to ``step_rad`` (0: not rounded)."""
    y = np.asarray(theta, dtype=float) + noise
    return np.round(y / step_rad) * step_rad + 0.0 if step_rad > 0 else y


def held_index(t_log: np.ndarray, t_tick: np.ndarray) -> np.ndarray:
    """For each tick time, the index of the last log time at or before it (what the servo
    holds then); ticks before the first log time get 0."""
    return np.maximum(np.searchsorted(t_log, t_tick, side="right") - 1, 0)


def _sign(w: float) -> float:
    """-1, 0 or +1 (0 at exactly 0)."""
    return 1.0 if w > 0 else (-1.0 if w < 0 else 0.0)


def simulate(t_log, r_log, enabled_log, *, mu_drive: float = MU_DRIVE, mu_back: float = MU_BACK,
             asymmetry_nm: float = 0.0, kp: float = KP, command_limit: float = COMMAND_LIMIT, noise=None,
             step_rad: float = ENCODER_STEP_RAD, theta0: float = 0.0, path=None,
             friction_law: bool = True, current_limit: tuple | None = None,
             stribeck: tuple = (0.0, 1.0, 1.0), smooth_load: tuple | None = None) -> Trajectory:
    """Run the truth's servo loop from rest at ``theta0`` until the last log time.

    Parameters
    ----------
    t_log, r_log, enabled_log : array (N,)
        The host's writes: times [s] (strictly increasing, the first <= 0 + its tick), goals
        [rad], torque enable (0/1).
    mu_drive, mu_back : float [-]
        The load-dependent friction's coefficients (0, 0: the nominal model).
    asymmetry_nm : float [N*m]
        The direction-dependent Coulomb part ``a`` (0: the nominal model).
    kp, command_limit : float
        The P law ``clip(kp (goal - y), +-command_limit)`` [V/rad, V].
    noise : array (n,), optional [rad]
        Encoder noise of each tick (default none).
    step_rad : float
        Encoder count (0: no rounding).
    path : path, optional
        The model file (default :func:`model_path`); compiled afresh (a private copy).
    friction_law : bool
        False: never write ``dof_frictionloss`` (the plain nominal loop, for comparison).
    current_limit : (float, float), optional
        ``(kt i_max, kt^2/R)`` [N*m, N*m*s/rad]: the firmware's current limit while the torque
        is on.  The winding's current is ``i = (u - ke w)/R`` (``ke = kt`` in SI units), so the
        motor's torque after the gear is ``kt i = gear u - (kt^2/R) w``; the firmware holds
        ``|i| <= i_max`` by lowering the voltage it applies (the model's damping already holds
        the back-EMF term, so the voltage applied is ``(clip(gear u - b w, +-kt i_max) + b w) /
        gear``), with ``w`` the hinge velocity at the tick.  ``u`` (the P law's output) is what
        the log records as the command.  None: no limit (the nominal servo).
    stribeck : (float, float, float)
        ``(rise, w_s, delta)`` [N*m, rad/s, -]: a Stribeck rise of the Coulomb level,
        ``rise exp(-(|w| / w_s)^delta)`` (Armstrong-Helouvry, Dupont, Canudas de Wit 1994, the
        generalised exponential curve), added to the level at every period; rise 0: none.
    smooth_load : (float, float, float, float), optional
        ``(mu_drive, mu_back, b_emf, w_s)``: a load-dependent friction behind a smooth sign
        instead of ``mu_drive, mu_back``'s sticking level, the user's pendulum of the first test
        half (``-mu |tau_m| tanh(w / w_s)``, Makkar, Dixon, Sawyer and Hu 2005's regularised
        Coulomb law with a level proportional to the motor's net torque ``tau_m = tau - b_emf
        w``, ``mu = mu_drive`` while ``tau_m w > 0`` else ``mu_back``), applied linearly
        implicitly as :func:`gear_loss` (its slope in the joint's damping); None: none.
    """
    m = mujoco.MjModel.from_xml_path(str(path or model_path()))
    d = mujoco.MjData(m)
    jid, aid = m.joint(JOINT).id, m.actuator(ACTUATOR).id
    dof, qadr = int(m.jnt_dofadr[jid]), int(m.jnt_qposadr[jid])
    gear = float(m.actuator_gear[aid, 0])
    fc = float(m.dof_frictionloss[dof])
    dt = float(m.opt.timestep)
    t_log = np.asarray(t_log, float)
    n = int(math.floor(t_log[-1] / dt + 1e-9)) + 1  # ticks up to and past the last log time
    t = np.arange(n + 1) * dt
    hold = held_index(t_log, t[:n])
    goal = np.asarray(r_log, float)[hold]
    on = np.asarray(enabled_log, float)[hold] != 0
    noise = np.zeros(n) if noise is None else np.asarray(noise, float)
    theta, omega = np.empty(n + 1), np.empty(n + 1)
    y, u, fl, taus = (np.empty(n) for _ in range(4))
    d.qpos[qadr] = theta0
    mujoco.mj_forward(m, d)
    theta[0], omega[0] = d.qpos[qadr], d.qvel[dof]
    tau = 0.0
    base_damping = float(m.dof_damping[dof])
    for k in range(n):
        y[k] = read_encoder(theta[k], noise[k], step_rad)
        u[k] = min(max(kp * (goal[k] - y[k]), -command_limit), command_limit) if on[k] else 0.0
        if smooth_load is not None:
            _smooth_load(m, d, dof, tau, base_damping, smooth_load)
        if friction_law:
            m.dof_frictionloss[dof] = _friction_level(tau, d.qvel[dof], fc, (mu_drive, mu_back),
                                                      asymmetry_nm, stribeck)
        fl[k] = m.dof_frictionloss[dof]
        d.ctrl[aid] = u[k]
        if current_limit is not None and on[k]:
            d.ctrl[aid] = _current_limited(u[k], d.qvel[dof], gear, current_limit)
        mujoco.mj_step(m, d)
        tau = gear * float(d.actuator_force[aid])
        taus[k] = tau
        theta[k + 1], omega[k + 1] = d.qpos[qadr], d.qvel[dof]
    if not np.all(np.isfinite(theta)):
        raise RuntimeError("servo truth diverged (non-finite angle)")
    return Trajectory(t, theta, omega, y, u, fl, taus)


def _friction_level(tau: float, w: float, fc: float, mus: tuple, asymmetry_nm: float,
                    stribeck: tuple) -> float:
    """The dry friction level [N*m] of one period of :func:`simulate`: ``fc`` plus the
    direction-dependent part, the load-dependent part ``mu |tau|`` (``mus`` = ``(mu_drive,
    mu_back)``, blended over :data:`BLEND_SPEED_RAD_S`) and the Stribeck rise; never below 0."""
    mu_drive, mu_back = mus
    rise, w_s, delta = stribeck
    if BLEND_SPEED_RAD_S == 0:  # a switch, mu_back at rest (scripts/valley_scan.py)
        mu = mu_drive if tau * w > 0 else mu_back
    else:
        half_sum, half_diff = 0.5 * (mu_drive + mu_back), 0.5 * (mu_drive - mu_back)
        mu = half_sum + half_diff * math.tanh((w if tau > 0 else -w) / BLEND_SPEED_RAD_S)
    level = fc + asymmetry_nm * _sign(w) + mu * abs(tau)
    if rise:
        level += rise * math.exp(-(abs(w) / w_s) ** delta)
    return max(0.0, level)


def _smooth_load(m, d, dof: int, tau: float, base_damping: float, law: tuple) -> None:
    """Write the smooth load law's force of one period of :func:`simulate` (``law`` its
    ``smooth_load``): its slope into the joint's damping, the rest into ``qfrc_applied``."""
    mu_drive, mu_back, b_emf, w_s = law
    w = float(d.qvel[dof])
    loss, slope = gear_loss(tau - b_emf * w, w, 1.0 - mu_drive, 1.0 / (1.0 + mu_back), w_s)
    m.dof_damping[dof] = base_damping + slope
    d.qfrc_applied[dof] = -loss + slope * w


def _current_limited(u: float, w: float, gear: float, current_limit: tuple) -> float:
    """The voltage the firmware applies for the P law's ``u`` under its current limit
    (``current_limit`` = ``(kt i_max, kt^2/R)``, see :func:`simulate`)."""
    limit, b = current_limit
    net = gear * u - b * w  # kt i: the motor's torque after the gear
    if abs(net) > limit:
        return (math.copysign(limit, net) + b * w) / gear
    return u


def at_log_times(traj: Trajectory, t_log) -> tuple[np.ndarray, np.ndarray]:
    """The truth's angle at the log times (linear between the ticks around each) and the
    command in force then (that of the last tick at or before it)."""
    t_log = np.asarray(t_log, float)
    theta = np.interp(t_log, traj.t, traj.theta)
    k = np.minimum(held_index(traj.t[:-1], t_log), len(traj.u) - 1)
    return theta, traj.u[k]


# -- the host's log times and the experiments -------------------------------------------------
def _rng(seed: int, name: str, what: str) -> np.random.Generator:
    """One random stream per (seed, run, purpose): a run's data do not depend on the others."""
    digest = hashlib.sha256(f"{seed}:{name}:{what}".encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:8], "little"))


def log_times(duration_s: float, rng: np.random.Generator, period_s: float = LOG_PERIOD_S,
              jitter_s: float = JITTER_S, clip_s: float = JITTER_CLIP_S,
              missed_p: float = MISSED_FRAME_P) -> np.ndarray:
    """The host's log times over ``[0, duration_s]``: every ``period_s`` plus clipped Gaussian
    jitter, the first at 0; a frame is missed with probability ``missed_p`` (never two in a
    row, nor the first or last), and no gap exceeds two periods."""
    n = int(round(duration_s / period_s)) + 1
    t = np.arange(n) * period_s + np.clip(rng.normal(0.0, jitter_s, n), -clip_s, clip_s)
    t[0] = 0.0
    keep = np.ones(n, bool)
    miss = rng.random(n) < missed_p
    for j in range(1, n - 1):
        if miss[j] and keep[j - 1]:
            keep[j] = False
    t = t[keep]
    for j in range(1, len(t)):  # a missed frame: at most two periods between reads
        t[j] = min(t[j], t[j - 1] + 2 * period_s)
    assert np.all(np.diff(t) > 0)
    return t


def _ramp(t, rise_s: float = 1.0):
    """0 -> 1 over ``rise_s`` (half a cosine), then 1."""
    x = np.clip(np.asarray(t, float) / rise_s, 0.0, 1.0)
    return 0.5 * (1 - np.cos(np.pi * x))


@dataclass(frozen=True)
class Experiment:
    """One run's design: the goal as a function of time, the torque-off span, its metadata."""

    name: str
    kind: str  # "sine" | "step" | "other" (the dataset contract's kinds)
    frequency_hz: float
    amplitude_rad: float
    offset_rad: float = 0.0
    shape: str = "sine"  # sine | square | slow | lift_drop
    off_s: tuple = ()  # (start, end) of the torque-off span [s]
    duration_s: float = DURATION_S

    def goal(self, t):
        t = np.asarray(t, float)
        a, f, o = self.amplitude_rad, self.frequency_hz, self.offset_rad
        if self.shape == "sine":  # about an offset reached in the first second
            return o * _ramp(t) + a * np.sin(2 * np.pi * f * t)
        if self.shape == "square":  # o + a, o - a, ... from the start
            return np.where((t * f) % 1.0 < 0.5, o + a, o - a)
        if self.shape == "slow":  # 0 -> a -> 0 once, 1 - cos, over 1/f
            return a * 0.5 * (1 - np.cos(2 * np.pi * f * np.minimum(t, 1 / f)))
        if self.shape == "lift_drop":  # lift to a in 1 s, hold (through the torque-off span)
            return a * _ramp(t)
        raise ValueError(self.shape)

    def enabled(self, t):
        t = np.asarray(t, float)
        if not self.off_s:
            return np.ones_like(t)
        return np.where((t >= self.off_s[0]) & (t < self.off_s[1]), 0.0, 1.0)


#: The runs (12 x 5 s).  The closed loop's resonance with the nominal numbers: stiffness
#: kp*gear + m*g*l = 12 + 1.18 N*m/rad, inertia 2.07e-2 kg*m^2 -> ~4 Hz, damping ratio ~0.35.
#: Sines about the hanging pose (gravity load changes sign with theta), about +0.6 and -0.9
#: rad (the gravity load of one sign throughout: the motor drives the load up and is
#: back-driven on the way down), square waves (saturated moves, then holding against gravity),
#: slow up-and-down moves to +1.2 / -1.0 rad, and "lift and drop" runs: lifted in 1 s, torque
#: off for 1.5 s (0 V: the pendulum falls, braked by the back-EMF), torque on again (the servo
#: lifts it back).
EXPERIMENTS: tuple[Experiment, ...] = (
    Experiment("sine_o000_a030_f05", "sine", 0.5, 0.30),
    Experiment("sine_o000_a030_f15", "sine", 1.5, 0.30),
    Experiment("sine_o000_a010_f30", "sine", 3.0, 0.10),
    Experiment("sine_o060_a030_f05", "sine", 0.5, 0.30, 0.6),
    Experiment("sine_o060_a010_f20", "sine", 2.0, 0.10, 0.6),
    Experiment("sine_om090_a020_f10", "sine", 1.0, 0.20, -0.9),
    Experiment("square_o025_a025", "step", 0.5, 0.25, 0.25, "square"),
    Experiment("square_o060_a030", "step", 0.5, 0.30, 0.6, "square"),
    Experiment("slow_up_a120", "other", 0.2, 1.20, shape="slow"),
    Experiment("slow_up_am100", "other", 0.25, -1.00, shape="slow"),
    Experiment("lift_drop_a060", "other", 0.0, 0.60, shape="lift_drop", off_s=(2.0, 3.5)),
    Experiment("lift_drop_a100", "other", 0.0, 1.00, shape="lift_drop", off_s=(2.0, 3.5)),
)


def measure(e: Experiment, *, mu_drive: float = MU_DRIVE, mu_back: float = MU_BACK,
            asymmetry_nm: float = 0.0, seed: int = 1, exact: bool = False, path=None,
            current_limit: tuple | None = None, stribeck: tuple = (0.0, 1.0, 1.0),
            smooth_load: tuple | None = None) -> Run:
    """One run of the truth, logged as the host logs it (irregular times, goal held, encoder
    counts and noise; ``exact``: neither noise nor rounding, on the loop or in the log)."""
    def run(t_log, r, en, noise, step):
        return simulate(t_log, r, en, mu_drive=mu_drive, mu_back=mu_back, asymmetry_nm=asymmetry_nm,
                        noise=noise, step_rad=step, path=path, current_limit=current_limit,
                        stribeck=stribeck, smooth_load=smooth_load)
    law = ("a firmware current limit" if current_limit is not None else
           "load-dependent or direction-dependent gearbox friction")
    return _logged_run(e, run, seed, exact, f"models/servo_pendulum/servo_pendulum.xml + {law}")


def _logged_run(e: Experiment, run, seed: int, exact: bool, law: str) -> Run:
    """The run of experiment ``e`` as the host logs it: log times, goal and switch, the loop
    ``run(t_log, r, enabled, loop noise, encoder step)`` (a truth's 1 kHz trajectory), then the
    positions read at the log times (same random streams for the same seed and run name)."""
    t_log = log_times(e.duration_s, _rng(seed, e.name, "clock"))
    r, en = e.goal(t_log), e.enabled(t_log)
    n = int(math.floor(t_log[-1] / CONTROL_PERIOD_S + 1e-9)) + 1
    noise_rad = 0.0 if exact else NOISE_RAD
    step = 0.0 if exact else ENCODER_STEP_RAD
    loop_noise = _rng(seed, e.name, "loop").normal(0.0, noise_rad, n) if noise_rad else None
    traj = run(t_log, r, en, loop_noise, step)
    theta_true, v = at_log_times(traj, t_log)
    log_noise = _rng(seed, e.name, "log").normal(0.0, noise_rad, len(t_log)) if noise_rad else 0.0
    theta = read_encoder(theta_true, log_noise, step)
    meta = {"kind": e.kind, "kp": KP, "command_limit": COMMAND_LIMIT,
            "frequency_hz": e.frequency_hz, "amplitude_rad": e.amplitude_rad,
            "offset_rad": e.offset_rad, "control_period_s": CONTROL_PERIOD_S,
            "log_period_s": LOG_PERIOD_S, "theta0_rad": 0.0,
            "encoder_quantized": not exact, "encoder_step_rad": step, "encoder_noise_rad": noise_rad,
            "units": {"r": "rad", "theta": "rad", "v": "V (motor voltage command)", "kp": "V/rad",
                      "command_limit": "V", "enabled": "torque enable (0: 0 V)"},
            "device": f"pendulum on a geared servo ({law}, bank/servo_truth.py)"}
    return Run(e.name, t_log, r, theta, v, meta, {"enabled": en})


#: The user's pendulum (the first test half's ``i_users_pendulum``, its law as the user wrote it:
#: 0.2 |tau_m| tanh(w / 0.02), the same both ways) on this servo: ``load_friction_smooth``'s
#: ``(mu_drive, mu_back, b_emf, w_s)``, ``tau_m`` the motor's net torque (b_emf = the back-EMF
#: kt^2/R = :data:`BACK_EMF_NMS_PER_RAD`, as the first half's truth takes it).
USERS_PENDULUM = (0.2, 0.2, BACK_EMF_NMS_PER_RAD, 0.02)

#: The effects this truth simulates (library names) and their parameters' order.
SIMULATED = ("load_friction", "asymmetric_friction", "current_limit", "friction_family_stribeck",
             "load_friction_smooth")


def generate(effects=(("load_friction", (MU_DRIVE, MU_BACK, B_EMF)),), seed: int = 1, exact: bool = False,
             experiments=EXPERIMENTS) -> list[Run]:
    """The "measured" runs of the truth with the hidden ``effects``: ``load_friction``
    (mu_drive, mu_back, b_emf = :data:`B_EMF`), ``asymmetric_friction`` (a [N*m]), ``current_limit`` (kt i_max
    [N*m], kt^2/R [N*m*s/rad]) and ``friction_family_stribeck`` (mu_drive, mu_back, b_emf, rise [N*m],
    w_s [rad/s], delta: the load law with a Stribeck rise) and ``load_friction_smooth`` (mu_drive,
    mu_back, b_emf [N*m*s/rad], w_s [rad/s]: the load law behind a smooth sign, :func:`simulate`'s
    ``smooth_load``), any of them but two load laws together (none: the nominal model)."""
    effects = dict(effects)
    unknown = set(effects) - set(SIMULATED)
    if unknown:
        raise ValueError(f"the servo truth simulates only {', '.join(SIMULATED)}, not {sorted(unknown)}")
    loads = [n for n in ("load_friction", "friction_family_stribeck", "load_friction_smooth") if n in effects]
    if len(loads) > 1:
        raise ValueError(f"{' and '.join(loads)} are one law: give one of them")
    # the library's load_friction holds a back-EMF damping b_emf beside the coefficients: this
    # truth's law reads the actuator's torque alone (B_EMF = 0), and simulates no other
    mu_drive, mu_back, b_emf = effects.get("load_friction", (0.0, 0.0, B_EMF))
    stribeck = (0.0, 1.0, 1.0)
    if "friction_family_stribeck" in effects:
        mu_drive, mu_back, b_emf, *stribeck = effects["friction_family_stribeck"]
    if b_emf != B_EMF:
        raise ValueError(f"the servo truth's load law reads gear * actuator_force (b_emf {B_EMF}), not b_emf {b_emf}")
    (asymmetry,) = effects.get("asymmetric_friction", (0.0,))
    limit = effects.get("current_limit")
    return [measure(e, mu_drive=mu_drive, mu_back=mu_back, asymmetry_nm=asymmetry, seed=seed,
                    exact=exact, current_limit=None if limit is None else tuple(limit),
                    stribeck=tuple(stribeck), smooth_load=effects.get("load_friction_smooth")) for e in experiments]


# -- a truth of another form: the gear's efficiency law with a smooth sign -----------------------
# The geared-servo cases above hide the engine's own law (a Coulomb level mu |tau| set into
# MuJoCo's frictionloss, a hard stick).  This truth writes the same servo's gearbox losses in
# another form, in plain code of its own (neither omni_sim.device.DriveFriction nor MuJoCo's
# frictionloss carries them):
#
# * the mesh torque is what the motor's rotor passes to the first gear, reflected to the output:
#       tau_m = g u - c_e w - J_r a_prev
#   (``g`` = the actuator's gear [N*m/V] times its force, i.e. the winding's torque at zero
#   speed; ``c_e`` = kt^2/R the back-EMF [N*m*s/rad]; ``J_r`` the rotor's reflected inertia, the
#   model's joint armature; ``a_prev`` the joint's velocity change over the previous physics
#   step divided by the step, 0 before the first).  The library's law reads ``g u`` alone;
# * a lossy gear's efficiency (e.g. Modelica's LossyGear): while the motor drives the load
#   (tau_m w > 0) the load receives eta_drive tau_m, the mesh loses (1 - eta_drive) |tau_m|;
#   while the load back-drives the motor (tau_m w <= 0) the motor receives eta_back times the
#   load's torque, the mesh loses (1/eta_back - 1) |tau_m|;
# * the loss acts against the motion through a smooth sign, tanh(w / w_s): no stick (the loss
#   vanishes at rest, where the library's law holds the load up to its full level):
#       L(tau_m, w) = k |tau_m| tanh(w / w_s),  k = 1 - eta_drive if tau_m w > 0 else 1/eta_back - 1.
#   L is continuous (both branches vanish at tau_m = 0, the sign at w = 0).
#
# The joint's own friction (the nominal model's frictionloss Fc and bearing damping) stays as
# the nominal model has it.  The loss is applied linearly implicitly at every physics step
# (the joint force -L(w) + s w with s = dL/dw at the step's start velocity, and s added to the
# joint's damping, which MuJoCo's implicitfast integrator treats implicitly: the step sees
# -L(w) - s (w+ - w), stable for any w_s); at a steady velocity it is exactly -L(w).  With
# both efficiencies 1 the loop is the nominal model's bit for bit (tests/test_servo_truth.py).

#: The efficiencies [-]: the load_friction case's (eta_f = 1 - MU_DRIVE = 0.85: 4-5 spur
#: meshes at 0.96-0.97; eta_b = 1 / (1 + MU_BACK) = 0.69, an ESTIMATE of the larger
#: back-driving losses; provenance at MU_DRIVE, MU_BACK above and docs/method/servo-actuators.md,
#: "Typical geared servos"): the same gearbox, its law written in another form.
ETA_DRIVE = 1.0 - MU_DRIVE
ETA_BACK = 1.0 / (1.0 + MU_BACK)
#: The smooth sign's speed w_s [rad/s] at the output: 0.05 rad/s, 0.5 % of the servo's no-load
#: speed (12 V / kt 1.2 V*s/rad = 10 rad/s, models/servo_pendulum/servo_pendulum.xml), ~17 rad/s at the rotor
#: through ~350:1.  An ESTIMATE (a regularised Coulomb law's transition speed is a modelling
#: choice, not a datasheet figure): the loss reaches 76 % of its level at w_s and 99.9 % at
#: 4 w_s = 0.2 rad/s, below the bank runs' peak speeds (~1-3 rad/s), so the law is a Coulomb
#: law in motion and differs from a stick only near rest and at reversals.
SMOOTH_SPEED_RAD_S = 0.05
#: The servo's torque constant at the output [N*m/A] (models/servo_pendulum/servo_pendulum.xml's comment:
#: kt = 1.2 N*m/A, R = 4 ohm): the back-EMF c_e = kt^2/R = kt * gear = 0.36 N*m*s/rad, the part
#: of the joint's damping (0.37) that is the motor's, not the bearing's (0.01).
KT_NM_PER_A = 1.2


@dataclass
class EfficiencyTrajectory(Trajectory):
    """A run of the efficiency truth: :class:`Trajectory` (``frictionloss`` is the nominal
    Fc throughout, ``tau`` = ``g u``) plus, per step, the mesh torque ``tau_m`` [N*m], the loss
    level ``loss`` = L(tau_m, w) [N*m, signed as w] and its slope ``slope`` = dL/dw
    [N*m*s/rad] at the step's start velocity (the step applies -L - slope (w+ - w))."""

    tau_m: np.ndarray = None
    loss: np.ndarray = None
    slope: np.ndarray = None


def gear_loss(tau_m: float, w: float, eta_drive: float, eta_back: float,
              smooth_speed: float) -> tuple[float, float]:
    """The mesh's loss L = k |tau_m| tanh(w / w_s) [N*m] (it acts as -L on the joint) and its
    derivative in w at fixed tau_m [N*m*s/rad]; ``k = 1 - eta_drive`` while the motor drives
    (``tau_m w > 0``), ``1/eta_back - 1`` otherwise."""
    k = (1.0 - eta_drive) if tau_m * w > 0 else (1.0 / eta_back - 1.0)
    th = math.tanh(w / smooth_speed)
    level = k * abs(tau_m)
    return level * th, level * (1.0 - th * th) / smooth_speed


def _efficiency_setup(path, t_log, r_log, enabled_log):
    """The private model and the per-tick schedule of :func:`simulate_efficiency`."""
    m = mujoco.MjModel.from_xml_path(str(path or model_path()))
    jid, aid = m.joint(JOINT).id, m.actuator(ACTUATOR).id
    dof, qadr = int(m.jnt_dofadr[jid]), int(m.jnt_qposadr[jid])
    dt = float(m.opt.timestep)
    t_log = np.asarray(t_log, float)
    n = int(math.floor(t_log[-1] / dt + 1e-9)) + 1  # ticks up to and past the last log time
    t = np.arange(n + 1) * dt
    hold = held_index(t_log, t[:n])
    goal = np.asarray(r_log, float)[hold]
    on = np.asarray(enabled_log, float)[hold] != 0
    return m, aid, dof, qadr, n, t, goal, on


def simulate_efficiency(t_log, r_log, enabled_log, *, eta_drive: float = ETA_DRIVE,
                        eta_back: float = ETA_BACK, smooth_speed: float = SMOOTH_SPEED_RAD_S,
                        kt: float = KT_NM_PER_A, kp: float = KP,
                        command_limit: float = COMMAND_LIMIT, noise=None,
                        step_rad: float = ENCODER_STEP_RAD, theta0: float = 0.0,
                        path=None) -> EfficiencyTrajectory:
    """Run the efficiency truth's servo loop (the law above) from rest at ``theta0`` until the
    last log time; arguments as :func:`simulate` (``eta_drive``, ``eta_back`` [-] in (0, 1],
    ``smooth_speed`` [rad/s], ``kt`` [N*m/A] the torque constant giving the back-EMF
    ``kt * gear``)."""
    m, aid, dof, qadr, n, t, goal, on = _efficiency_setup(path, t_log, r_log, enabled_log)
    d = mujoco.MjData(m)
    gear = float(m.actuator_gear[aid, 0])
    lo, hi = (float(x) for x in m.actuator_ctrlrange[aid])  # the drive clips the volts there
    c_e, j_r = kt * gear, float(m.dof_armature[dof])
    base_damping, dt = float(m.dof_damping[dof]), float(m.opt.timestep)
    noise = np.zeros(n) if noise is None else np.asarray(noise, float)
    theta, omega = np.empty(n + 1), np.empty(n + 1)
    y, u, tau, tau_m, loss, slope = (np.empty(n) for _ in range(6))
    d.qpos[qadr] = theta0
    mujoco.mj_forward(m, d)
    theta[0], omega[0] = d.qpos[qadr], d.qvel[dof]
    acc = 0.0
    for k in range(n):
        y[k] = read_encoder(theta[k], noise[k], step_rad)
        u[k] = min(max(kp * (goal[k] - y[k]), -command_limit), command_limit) if on[k] else 0.0
        w = float(d.qvel[dof])
        tau[k] = gear * min(max(u[k], lo), hi)
        tau_m[k] = tau[k] - c_e * w - j_r * acc
        loss[k], slope[k] = gear_loss(tau_m[k], w, eta_drive, eta_back, smooth_speed)
        m.dof_damping[dof] = base_damping + slope[k]
        d.qfrc_applied[dof] = -loss[k] + slope[k] * w
        d.ctrl[aid] = u[k]
        mujoco.mj_step(m, d)
        theta[k + 1], omega[k + 1] = d.qpos[qadr], d.qvel[dof]
        acc = (omega[k + 1] - w) / dt
    if not np.all(np.isfinite(theta)):
        raise RuntimeError("servo efficiency truth diverged (non-finite angle)")
    fl = np.full(n, float(m.dof_frictionloss[dof]))
    return EfficiencyTrajectory(t, theta, omega, y, u, fl, tau, tau_m, loss, slope)


def measure_efficiency(e: Experiment, *, eta_drive: float = ETA_DRIVE, eta_back: float = ETA_BACK,
                       smooth_speed: float = SMOOTH_SPEED_RAD_S, seed: int = 1,
                       exact: bool = False, path=None) -> Run:
    """One run of the efficiency truth, logged as :func:`measure` logs the other cases' (the
    same log times, goal, encoder and noise streams for the same seed and run)."""
    def run(t_log, r, en, noise, step):
        return simulate_efficiency(t_log, r, en, eta_drive=eta_drive, eta_back=eta_back,
                                   smooth_speed=smooth_speed, noise=noise, step_rad=step, path=path)
    return _logged_run(e, run, seed, exact, "models/servo_pendulum/servo_pendulum.xml + a gear efficiency law with a "
                       "smooth sign")


def generate_efficiency(eta_drive: float = ETA_DRIVE, eta_back: float = ETA_BACK,
                        smooth_speed: float = SMOOTH_SPEED_RAD_S, seed: int = 1,
                        exact: bool = False, experiments=EXPERIMENTS) -> list[Run]:
    """The "measured" runs of the efficiency truth (the bank's ``gear_efficiency`` case: the
    load_friction case's experiments, log and encoder)."""
    return [measure_efficiency(e, eta_drive=eta_drive, eta_back=eta_back, smooth_speed=smooth_speed,
                               seed=seed, exact=exact) for e in experiments]


#: The bank's case on this truth (run by ``scripts/discrepancy_bank.py --gear-efficiency``,
#: tests/test_discrepancy_bank.py): its name, the truth's parameters and what a correct
#: workflow should do with it, stated before the case was run.
GEAR_EFFICIENCY_CASE = {
    "name": "gear_efficiency",
    "truth": {"eta_drive": ETA_DRIVE, "eta_back": ETA_BACK, "smooth_speed_rad_s": SMOOTH_SPEED_RAD_S,
              "kt_nm_per_a": KT_NM_PER_A},
    "equivalent": {"mu_drive": MU_DRIVE, "mu_back": MU_BACK},
    "expect": "load_friction named first (the library's load-dependent effect: the nearest form "
              "of a gear efficiency law), its fitted mu_back > mu_drive (the truth's back-driving "
              "efficiency is the lower), and the held-out gap shrunk >= 3x",
}


def assess_efficiency(report: dict) -> tuple[bool, str]:
    """What a correct workflow should do on the ``gear_efficiency`` case (:data:`GEAR_EFFICIENCY_CASE`
    ``expect``): name ``load_friction`` first, with ``mu_back > mu_drive``, and shrink the
    held-out gap >= 3x.  Other names after it are allowed (a stand-in for the part of the truth's
    form the library's law lacks); confidence is not required (the forms differ, so the gap left
    may stay above the noise)."""
    named = [e["name"] for e in report["effects"]]
    if not named or named[0] != "load_friction":
        return False, f"named {named}, not load_friction first"
    p = report["effects"][0]["parameters"]
    if not p["mu_back"] > p["mu_drive"]:
        return False, f"mu_back {p['mu_back']:.4g} <= mu_drive {p['mu_drive']:.4g}"
    shrink = report["shrink_factor"]
    if not shrink >= 3:
        return False, f"gap shrank only x{shrink:.1f}"
    return True, "ok"
