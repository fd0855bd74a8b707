"""Truths of the second test half: the same geared servo pendulum, ten more laws from the
literature, in other forms than the first half's.

Written WITHOUT reading the discrepancy library (its effects, search, shapes, fits, or the
device's drive laws), under the first half's rule: only the nominal model's file
(``models/servo_pendulum/``), the servo page (``docs/method/servo-actuators.md``), the dataset
contract, the CLI's help and the first test half (``bank/test_half/``: its truths, make, score
and tests) were read.  Each law is written from its source's equation, cited in its class's
docstring; where an equation is recalled rather than re-read, the docstring says so.

The plant, the servo and the integration are the first half's (``bank.test_half.truths``,
imported, not copied): :func:`~bank.test_half.truths.nominal_plant` reads the constants from
the MJCF file, :func:`~bank.test_half.truths.perturbed` puts them 5-15 % off per seed,
``Truth``'s hooks (``motor``, ``dry``, ``smooth``) carry the laws that fit them, and
:func:`~bank.test_half.truths.simulate` integrates them (semi-implicit Euler at 0.1 ms, ten
sub-steps per 1 ms control period, the time-stepping stick rule for dry friction, the
two-mass loop for a compliant drive).  Three laws need what those hooks cannot say: a friction
with a state integrated per sub-step (LuGre), a mesh whose loss depends on which side drives
it and on both sides' inertia (the worm-type gear), and a command delayed inside the servo.
They subclass :class:`OwnLoop`, whose :func:`simulate` is the first half's loop (the same P
law, encoder, hold and sub-steps) with a per-sub-step ``step`` hook and a command FIFO.

Each truth carries ``expected``, in the physics families of :data:`FAMILIES` (the first
half's, plus the four this half needs: ``cogging``, ``gravity offset``, ``position offset``,
``dead zone``).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from bank.test_half import truths as tr
from bank.test_half.truths import H, SUBSTEPS, Plant, Truth, nominal_plant, perturbed  # noqa: F401

#: The first half's families and the ones this half's laws need.
FAMILIES = tr.FAMILIES + ("cogging", "gravity offset", "position offset", "dead zone")


def _expect(family, accept=None, partial=(), unexplained_ok=False, signs=None, note="",
            families=FAMILIES):
    """The first half's expectation record (``family``, ``accept``, ``partial``,
    ``unexplained_ok``, ``signs``, ``note``) over ``families`` (this half's :data:`FAMILIES`;
    a later half passes its own)."""
    accept = list(accept or [family])
    for f in (family, *accept, *partial):
        assert f in families, f
    return {"family": family, "accept": accept, "partial": list(partial),
            "unexplained_ok": unexplained_ok, "signs": signs or {}, "note": note}


def _sign(x: float) -> float:
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


class OwnLoop(Truth):
    """A truth integrated by :func:`simulate`'s own loop: the first half's loop with a
    ``step`` hook (the speed after one sub-step, given the angle, the speed and the motor's
    torque) and ``delay_periods`` (the command applied that many 1 ms periods after the P law
    computed it).  The default ``step`` is the first half's sub-step exactly."""

    delay_periods = 0

    def step(self, theta: float, w: float, tau_m: float, state: dict) -> float:
        p = self.p
        tau = tau_m - p.bearing * w - p.mgl * math.sin(theta) + self.smooth(theta, w, tau_m)
        return tr._dry_step(w + H * tau / p.inertia, p.inertia, self.dry(w, tau_m, state))


def simulate(truth: Truth, goal: np.ndarray, enabled: np.ndarray, kp: float,
             command_limit: float, theta0: float, state: dict) -> tuple[np.ndarray, np.ndarray]:
    """The servo's P loop on the truth (the signature and returns of the first half's
    :func:`bank.test_half.truths.simulate`, which runs every truth that is not an
    :class:`OwnLoop`).

    For an :class:`OwnLoop`: each period the P law ``clip(kp (goal - y), +-limit)`` on the
    encoder angle ``y``; the pair (command, torque-on) enters a FIFO of ``delay_periods``
    periods (pre-filled with the command that held ``theta0`` before t = 0) and the pair
    leaving it is applied and returned; each of the ten sub-steps calls ``truth.step``.
    """
    if not isinstance(truth, OwnLoop):
        return tr.simulate(truth, goal, enabled, kp, command_limit, theta0, state)
    p = truth.p
    lim = min(command_limit, p.supply)
    n = len(goal)
    theta = np.empty(n * SUBSTEPS + 1)
    u_out = np.empty(n)
    th, w = float(theta0), 0.0
    theta[0] = th
    q = tr.ENCODER_STEP_RAD
    d = int(truth.delay_periods)
    hold0 = min(lim, max(-lim, kp * (float(theta0) - round(theta0 / q) * q)))
    fifo = deque([(hold0, True)] * d)
    i = 0
    for k in range(n):
        on = bool(enabled[k])
        y = round(th / q) * q
        u = min(lim, max(-lim, kp * (float(goal[k]) - y))) if on else 0.0
        if d:
            fifo.append((u, on))
            u, on = fifo.popleft()
        u_out[k] = u
        for _ in range(SUBSTEPS):
            tau_m = truth.motor(u, w, on)
            w = truth.step(th, w, tau_m, state)
            th += H * w
            i += 1
            theta[i] = th
    return theta, u_out


# ---------------------------------------------------------------------------------------------
# The truths


class LuGre(OwnLoop):
    """(a) LuGre dynamic friction, replacing the gear train's Coulomb level.

    Source: C. Canudas de Wit, H. Olsson, K. J. Astrom, P. Lischinsky, "A new model for
    control of systems with friction", IEEE Trans. Automatic Control 40(3), 419-425, 1995,
    eqs. (1)-(3) (the bristle model; g with the Gaussian Stribeck curve of their eq. (4))::

        dz/dt = w - sigma0 |w| z / g(w),   g(w) = Fc + (Fs - Fc) exp(-(w/vs)^2),
        F     = sigma0 z + sigma1 dz/dt + sigma2 w,

    the friction ``F`` opposing the joint (``J w' = ... - F``).  Steady sliding gives
    ``F = g(w) sign(w) + sigma2 w`` (a Stribeck curve); near rest it is a spring of stiffness
    sigma0 (presliding: z up to Fs/sigma0 = 2 mrad; under a steady torque tau < Fs the joint
    creeps at least -(Fs/sigma0) ln(1 - tau/Fs), a few encoder counts, and stops).  Integration: over a
    sub-step the speed is advanced with F at the sub-step's start, then z exactly for the new
    (constant) speed, ``z <- z_ss + (z - z_ss) exp(-sigma0 |w| h / g)``, ``z_ss = g sign(w) /
    sigma0`` (the bristle equation is stiff at speed: its rate sigma0 |w| / g reaches 1e4/s).
    z carries over from run to run (the pendulum rests between them).
    """

    name = "lugre"
    title = "LuGre dynamic friction (bristle state, Gaussian Stribeck curve)"
    source = "Canudas de Wit, Olsson, Astrom, Lischinsky, IEEE TAC 40(3) 1995, eqs. (1)-(4)"
    equation = ("dz/dt = w - sigma0 |w| z / g(w), g = Fc + (Fs-Fc) exp(-(w/vs)^2); "
                "F = sigma0 z + sigma1 dz/dt + sigma2 w")

    def defaults(self):
        return {"Fc": 0.05, "Fs": 0.10, "vs": 0.1, "sigma0": 50.0, "sigma1": 0.4, "sigma2": 0.02}

    def initial_state(self):
        return {"z": 0.0}

    def g(self, w: float) -> float:
        q = self.params
        return q["Fc"] + (q["Fs"] - q["Fc"]) * math.exp(-(w / q["vs"]) ** 2)

    def force(self, w: float, z: float) -> float:
        """The friction torque opposing the joint at speed ``w`` and bristle state ``z``."""
        q = self.params
        zdot = w - q["sigma0"] * abs(w) * z / self.g(w)
        return q["sigma0"] * z + q["sigma1"] * zdot + q["sigma2"] * w

    def step(self, theta, w, tau_m, state):
        p, q = self.p, self.params
        z = state["z"]
        tau = tau_m - p.bearing * w - p.mgl * math.sin(theta) - self.force(w, z)
        w = w + H * tau / p.inertia
        a = q["sigma0"] * abs(w) / self.g(w)
        if a > 0:
            z_ss = _sign(w) * self.g(w) / q["sigma0"]
            z = z_ss + (z - z_ss) * math.exp(-a * H)
        state["z"] = z
        return w

    def expected(self):
        return _expect("friction: dynamic", accept=["friction: dynamic", "friction: stribeck"],
                       partial=["friction: coulomb", "friction: viscous"],
                       signs={"static_above_kinetic": True},
                       note="Fs 0.10 > Fc 0.05 N m (nominal Coulomb 0.03), vs 0.1 rad/s, "
                            "presliding stiffness 50 N m/rad, extra viscous 0.02")


class HarmonicDrive(Truth):
    """(b) A gearbox loss written as two efficiencies, with a load-independent and a viscous
    part: the loss model of harmonic-drive and planetary transmissions.

    Sources: T. D. Tuttle, W. P. Seering, "A nonlinear model of a harmonic drive gear
    transmission", IEEE Trans. Robotics and Automation 12(3), 368-374, 1996, and H. D.
    Taghirad, P. R. Belanger, "Modeling and parameter identification of harmonic drive
    systems", ASME J. Dyn. Sys. Meas. Control 120(4), 439-444, 1998: a transmission loss with
    a Coulomb part, a viscous part, and a part that grows with the transmitted torque, whose
    forward and backward efficiencies differ (the equations below are as we recall the
    papers' structure, not re-read; the efficiency form of the load term is the usual one of
    gearbox catalogues)::

        tau_loss = Fc + c_q |tau_m| + Bv w,   opposing w,
        c_drive = 1 - eta_f        (motor drives the load, tau_m w > 0),
        c_back  = 1/eta_b - 1      (the load back-drives the motor, tau_m w < 0),

    with ``tau_m = (kt/R) u - (kt^2/R) w`` the motor's net torque at the output.  eta_f =
    0.85, eta_b = 0.70 (independent numbers, not ``eta_b = 2 - 1/eta``): 0.15 and 0.4286 per
    N m; Bv = 0.04 N m s/rad.  The dry part (Fc + c_q |tau_m|) holds at rest by the stick rule.
    """

    name = "harmonic_drive"
    title = "efficiency loss eta_f 0.85 / eta_b 0.70 with Coulomb and viscous parts"
    source = ("Tuttle & Seering, IEEE TRA 12(3) 1996; Taghirad & Belanger, ASME JDSMC 120(4) "
              "1998 (structure recalled)")
    equation = ("tau_loss = Fc + c_q |tau_m| + Bv w opposing w; c_drive = 1 - eta_f if "
                "tau_m w > 0, c_back = 1/eta_b - 1 if tau_m w < 0")

    def defaults(self):
        return {"eta_f": 0.85, "eta_b": 0.70, "Bv": 0.04}

    def coefficients(self) -> tuple[float, float]:
        """(driving, back-driven) loss per N m of motor torque."""
        q = self.params
        return 1 - q["eta_f"], 1 / q["eta_b"] - 1

    def dry(self, w, tau_m, state):
        drive, back = self.coefficients()
        c, a = self.p.coulomb, abs(tau_m)
        pos = c + (drive if tau_m > 0 else back) * a     # motion w > 0
        neg = c + (drive if tau_m < 0 else back) * a     # motion w < 0
        return pos, neg, pos, neg

    def smooth(self, theta, w, tau_m):
        return -self.params["Bv"] * w

    def expected(self):
        drive, back = self.coefficients()
        return _expect("friction: load-dependent",
                       partial=["friction: coulomb", "friction: viscous", "torque gain"],
                       signs={"driving_vs_back_driven": "back-driven larger"},
                       note=f"driving {drive:.3f}, back-driven {back:.3f} per N m; viscous 0.04")


class WormMesh(OwnLoop):
    """(c) A self-locking-leaning (worm-type) gear: the mesh passes a fraction of the torque
    it transmits, by the direction the power flows, between the rotor's inertia and the
    pendulum's.

    Source: the worm-gear (and power-screw) efficiencies of J. E. Shigley, C. R. Mischke,
    *Mechanical Engineering Design* (worm gearing; power screws), as we recall them:
    lead angle lambda, friction coefficient mu, normal pressure angle phi_n::

        eta_f = (cos phi_n - mu tan lambda) / (cos phi_n + mu cot lambda)   (worm drives)
        eta_b = (cos phi_n - mu cot lambda) / (cos phi_n + mu tan lambda)   (gear drives worm)

    lambda = 8 deg, mu = 0.08, phi_n = 20 deg: eta_f = 0.615, eta_b = 0.390 (eta_b <= 0 would
    lock).  The mesh torque ``T_in`` the gear takes from the rotor side and ``T_out`` it puts on
    the pendulum::

        J_a w' = tau_m - b w - Fc sign(w) - T_in,    J_l w' = T_out - m g l sin(theta),
        T_out = eta_f T_in   if the rotor side drives (T_in w > 0),
        T_in  = eta_b T_out  if the pendulum back-drives (T_out w < 0),

    one rigid speed w.  Eliminating the mesh: driving ``(eta_f J_a + J_l) w' = eta_f tau -
    mgl sin(theta)``, back-driven ``(J_a + eta_b J_l) w' = tau - eta_b mgl sin(theta)``
    (``tau`` the rotor side's net torque); which holds is the sign of ``J_l tau + J_a m g l
    sin(theta)`` against w (the two meet where it is 0).  At rest the joint moves the way one
    of them accelerates it, else it sticks: held against gravity ``g`` by any motor torque in
    ``[eta_b g - Fc, g/eta_f + Fc]``; with torque off it back-drives with 39 % of gravity.
    This loss scales with the torque the mesh carries (gravity's, when back-driven), not with
    the motor's: the first half's gear laws scaled with ``|tau_m|``.
    """

    name = "worm_mesh"
    title = "worm-type mesh: eta_f 0.615, eta_b 0.390 by power flow, inertia on both sides"
    source = "Shigley & Mischke, Mechanical Engineering Design (worm gear efficiency; recalled)"
    equation = ("T_out = eta_f T_in if T_in w > 0; T_in = eta_b T_out if T_out w < 0; "
                "eta = (cos phi_n -+ mu tan/cot lambda)/(cos phi_n +- mu cot/tan lambda)")

    def defaults(self):
        return {"lead_deg": 8.0, "mu": 0.08, "pressure_deg": 20.0}

    def efficiencies(self) -> tuple[float, float]:
        """(eta_f, eta_b) of the Shigley relations."""
        q = self.params
        lam, cn, mu = math.radians(q["lead_deg"]), math.cos(math.radians(q["pressure_deg"])), q["mu"]
        eta_f = (cn - mu * math.tan(lam)) / (cn + mu / math.tan(lam))
        eta_b = (cn - mu / math.tan(lam)) / (cn + mu * math.tan(lam))
        return eta_f, eta_b

    def acceleration(self, tau: float, grav: float, s: float) -> float:
        """The joint's acceleration for a motion of sign ``s``: ``tau`` the rotor side's net
        torque (its Coulomb friction included), ``grav`` = m g l sin(theta)."""
        ef, eb = self.efficiencies()
        ja, jl = self.p.armature, self.p.j_link
        if (jl * tau + ja * grav) * s > 0:       # the rotor side puts power into the mesh
            return (ef * tau - grav) / (ef * ja + jl)
        return (tau - eb * grav) / (ja + eb * jl)

    def step(self, theta, w, tau_m, state):
        p = self.p
        tau = tau_m - p.bearing * w
        grav = p.mgl * math.sin(theta)
        if w != 0.0:
            s = _sign(w)
            w_new = w + H * self.acceleration(tau - p.coulomb * s, grav, s)
            return w_new if w_new * s > 0 else 0.0      # never reverses in a sub-step
        for s in (1.0, -1.0):
            a = self.acceleration(tau - p.coulomb * s, grav, s)
            if a * s > 0:
                return H * a
        return 0.0

    def expected(self):
        ef, eb = self.efficiencies()
        return _expect("friction: load-dependent",
                       partial=["friction: coulomb", "torque gain", "inertia"],
                       signs={"driving_vs_back_driven": "back-driven larger"},
                       note=f"eta_f {ef:.3f}, eta_b {eb:.3f}: loss per N m carried {1 - ef:.3f} "
                            f"driving, {1 / eb - 1:.3f} back-driven (of the motor side's torque)")


class LoadAtan(Truth):
    """(d) Load-dependent friction larger when the motor drives, with an arctangent sign.

    Sources: the quadrant-dependent load friction of P. Hamon, M. Gautier, P. Garrec (IROS
    2010, ICRA 2011; recalled), here with the driving coefficient larger, and the arctangent
    regularisation of the sign function listed by S. Andersson, A. Soderberg, S. Bjorklund,
    "Friction models for sliding dry, boundary and mixed lubricated contacts", Tribology
    International 40(4), 580-587, 2007 (``(2/pi) arctan(k v)``; recalled)::

        tau_f = -mu_q |tau_m| (2/pi) atan(w / ws),   mu_q = mu_drive if tau_m w > 0 else mu_back,

    on top of the gear train's Coulomb level (stick rule).  mu_drive = 0.25, mu_back = 0.08,
    ws = 0.05 rad/s (at 0.05 rad/s half the level, at 0.5 rad/s 94 %).
    """

    name = "load_atan"
    title = "load-dependent friction, driving 0.25 > back-driven 0.08, (2/pi) atan(w/0.05)"
    source = ("Hamon, Gautier, Garrec, IROS 2010 / ICRA 2011 (quadrants); Andersson, Soderberg, "
              "Bjorklund, Tribology Int. 40 (2007) (atan sign)")
    equation = "tau_f = -mu_q |tau_m| (2/pi) atan(w/ws); mu_q = mu_drive if tau_m w > 0 else mu_back"

    def defaults(self):
        return {"mu_drive": 0.25, "mu_back": 0.08, "ws": 0.05}

    def smooth(self, theta, w, tau_m):
        q = self.params
        mu = q["mu_drive"] if tau_m * w > 0 else q["mu_back"]
        return -mu * abs(tau_m) * (2 / math.pi) * math.atan(w / q["ws"])

    def expected(self):
        return _expect("friction: load-dependent", partial=["friction: coulomb", "torque gain"],
                       signs={"driving_vs_back_driven": "driving larger"},
                       note="mu_drive 0.25 > mu_back 0.08 per N m of motor torque, smooth sign")


class DeadZone(Truth):
    """(e) A dead band of the motor driver: commands below 0.6 V give no torque.

    Source: the dead-zone nonlinearity of G. Tao, P. V. Kokotovic, "Adaptive control of plants
    with unknown dead-zones", IEEE Trans. Automatic Control 39(1), 59-68, 1994 (their dead-zone
    model with unit slopes and symmetric break points), the minimum duty below which an
    H-bridge's PWM does not move a motor::

        u_eff = 0              if |u| <= d,
        u_eff = u - d sign(u)  if |u| > d,     d = 0.6 V,

    so ``tau_m = (kt/R) u_eff - (kt^2/R) w`` (the back-EMF stays: the winding is driven at 0 V).
    A torque band of 0.18 N m in the command, not in the speed: it resembles a Coulomb friction
    only while the command and the motion share a sign.
    """

    name = "dead_zone"
    title = "driver dead band: |u| < 0.6 V gives no torque, u - 0.6 sign(u) outside"
    source = "Tao & Kokotovic, IEEE TAC 39(1) 1994 (dead-zone model)"
    equation = "u_eff = 0 if |u| <= d else u - d sign(u), d = 0.6 V; tau_m = (kt/R) u_eff - (kt^2/R) w"

    def defaults(self):
        return {"d": 0.6}

    def effective(self, u: float) -> float:
        d = self.params["d"]
        return 0.0 if abs(u) <= d else u - d * _sign(u)

    def motor(self, u, w, enabled):
        return (self.p.gear * self.effective(u) if enabled else 0.0) - self.p.emf * w

    def expected(self):
        return _expect("dead zone", accept=["dead zone"],
                       partial=["friction: coulomb", "torque gain", "torque saturation",
                                "friction: load-dependent"],
                       note="0.6 V dead band (0.18 N m of drive torque): a law of the command, "
                            "not of the motion; a library without one should flag it")


class Cogging(Truth):
    """(f) A position-periodic torque ripple at the output (a gear-mesh / cogging ripple).

    Sources: the Fourier model of position-dependent torque ripple of J. Holtz, L. Springob,
    "Identification and compensation of torque ripple in high-precision permanent magnet
    motor drives", IEEE Trans. Industrial Electronics 43(2), 309-320, 1996, and the review of
    T. M. Jahns, W. L. Soong, "Pulsating torque minimization techniques for permanent magnet AC
    motor drives -- a review", same issue, 321-330 (one harmonic kept; recalled)::

        tau_r = A sin(n theta + phi),   n = 12 per output turn, A = 0.04 N m, phi = 0.3 rad.

    The motor's own cogging (tooth count times the 350:1 ratio per output turn) is far above
    the log's bandwidth; a 12-per-turn ripple is what an output stage's mesh leaves.
    """

    name = "cogging"
    title = "output torque ripple 0.04 sin(12 theta + 0.3) N m"
    source = "Holtz & Springob, IEEE TIE 43(2) 1996; Jahns & Soong, IEEE TIE 43(2) 1996 (recalled)"
    equation = "tau_r = A sin(n theta + phi), A = 0.04 N m, n = 12, phi = 0.3 rad"

    def defaults(self):
        return {"A": 0.04, "n": 12, "phi": 0.3}

    def smooth(self, theta, w, tau_m):
        q = self.params
        return q["A"] * math.sin(q["n"] * theta + q["phi"])

    def expected(self):
        return _expect("cogging", partial=["gravity offset", "position offset"],
                       signs={"ripple_order": self.params["n"]},
                       note="12 periods per turn (period 0.524 rad), 0.04 N m")


class MassOffset(Truth):
    """(g) The pendulum's centre of mass off the arm's line by phi0 = 0.06 rad.

    Source: the rigid pendulum (gravity torque of a body whose centre of mass lies at angle
    phi0 from the arm: ``-m g l sin(theta - phi0)``), e.g. the gravity term of a link whose
    mass centre is not on its axis in J. J. Craig, *Introduction to Robotics*, 3rd ed., ch. 6
    (the link's centre-of-mass vector); the encoder still reads the arm (theta = 0 is the arm
    hanging)::

        tau_g = -m g l sin(theta - phi0),   phi0 = 0.06 rad,

    i.e. the truth adds ``m g l [sin(theta) - sin(theta - phi0)]`` to the nominal's gravity.
    The pendulum hangs at rest at theta = phi0 (a bias of -m g l phi0 = -0.071 N m at 0).
    """

    name = "mass_offset"
    title = "centre of mass off the arm by 0.06 rad: gravity -mgl sin(theta - 0.06)"
    source = "rigid-body gravity of an off-axis centre of mass (Craig, Introduction to Robotics, ch. 6)"
    equation = "tau_g = -m g l sin(theta - phi0), phi0 = 0.06 rad"

    def defaults(self):
        return {"phi0": 0.06}

    def smooth(self, theta, w, tau_m):
        mgl = self.p.mgl
        return mgl * math.sin(theta) - mgl * math.sin(theta - self.params["phi0"])

    def expected(self):
        return _expect("gravity offset", partial=["position offset", "torque bias"],
                       signs={"offset_rad": self.params["phi0"]},
                       note="gravity's zero at +0.06 rad while the encoder's is at 0")


class Latency(OwnLoop):
    """(h) A bus / firmware latency: the command is applied 6 ms after the P law computes it.

    Source: the transport delay (dead time) ``e^{-s T_d}`` of a sampled control loop, e.g.
    G. F. Franklin, J. D. Powell, M. Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
    1998 (the delay of a computation and of a bus in the loop, whole sample periods)::

        u_applied[k] = u[k - 6],   u[k] = clip(kp (r[k] - y[k]), +-limit),

    with the torque-on flag delayed with it (it travels on the same bus).  The logged ``v`` is
    the command applied (what the drive reports as its present voltage); before t = 0 the
    servo held its start.
    """

    name = "latency"
    title = "command latency 6 ms (6 control periods) inside the servo"
    source = "transport delay of a sampled loop (Franklin, Powell, Workman, Digital Control, 1998)"
    equation = "u_applied[k] = u[k - 6] (1 ms periods)"
    delay_periods = 6

    def defaults(self):
        return {"delay_s": 0.006}

    def expected(self):
        return _expect("time delay", partial=["drive compliance", "inertia"],
                       signs={"delay_s": self.params["delay_s"]},
                       note="6 ms between the P law and the torque")


class Compliance(Truth):
    """(i) A compliant gear train: the rotor behind a torsional spring (flexible joint).

    Source: M. W. Spong, "Modeling and control of elastic joint robots", ASME J. Dyn. Sys.
    Meas. Control 109(4), 310-319, 1987 (the flexible-joint model; with a damper in parallel
    with the spring)::

        J_r q_m'' = tau_m - b q_m' - Fc sign(q_m') - k (q_m - q) - c (q_m' - q'),
        J_l q''   = k (q_m - q) + c (q_m' - q') - m g l sin(q),

    ``J_r`` the reflected rotor inertia (the armature), ``J_l`` the pendulum; the encoder reads
    the pendulum ``q``.  k = 150 N m/rad, c = 0.2 N m s/rad: the gravity of the pendulum at 90
    deg winds the spring 7.9 mrad (five encoder counts); its mode is near 41 Hz.  Integrated by
    the first half's two-mass loop (``shaft``: the spring and damper, which may pull).
    """

    name = "compliance"
    title = "compliant drive: rotor behind k = 150 N m/rad, c = 0.2 N m s/rad"
    source = "Spong, ASME JDSMC 109(4) 1987 (flexible-joint model)"
    equation = ("J_r q_m'' = tau_m - b q_m' - Fc sign - k (q_m - q) - c (q_m' - q'); "
                "J_l q'' = k (q_m - q) + c (q_m' - q') - mgl sin q")
    two_mass = True

    def defaults(self):
        return {"k": 150.0, "c": 0.2}

    def shaft(self, x: float, xd: float) -> float:
        return self.params["k"] * x + self.params["c"] * xd

    def expected(self):
        return _expect("drive compliance", partial=["backlash", "time delay"],
                       signs={"stiffness_nm_per_rad": self.params["k"]},
                       note="torsional spring 150 N m/rad between rotor and pendulum")


class Null(tr.Null):
    """(j) Nothing missing: the nominal's own laws with its constants 5-15 % off (a new seed:
    the first half's null case, ``bank.test_half.truths.Null``)."""


#: The cases of the second test half, in order: (name, class).
CASES = (("a_lugre", LuGre), ("b_harmonic_drive", HarmonicDrive), ("c_worm_mesh", WormMesh),
         ("d_load_atan", LoadAtan), ("e_dead_zone", DeadZone), ("f_cogging", Cogging),
         ("g_mass_offset", MassOffset), ("h_latency", Latency), ("i_compliance", Compliance),
         ("j_null", Null))
