"""Truths of the third test half: the same geared servo pendulum, ten more laws from the
literature, in other forms than the first and second halves'.

Written WITHOUT reading the discrepancy library (its effects, search, shapes, fits, or the
device's drive laws), under the first half's rule: only the nominal model's file
(``models/servo_pendulum/``), the servo page (``docs/method/servo-actuators.md``), the dataset
contract, the CLI's help and the two earlier test halves (``bank/test_half/``,
``bank/test_half_2/``: truths, make, score, tests and their README sections) were read.  Each
law is written from its source's equation, cited in its class's docstring; where an equation
is recalled rather than re-read, the docstring says "(recalled)".

The plant, the servo and the integration are the first half's (``bank.test_half.truths``,
imported, not copied): :func:`~bank.test_half.truths.nominal_plant` reads the constants from
the MJCF file, :func:`~bank.test_half.truths.perturbed` puts them 5-15 % off per seed, the
``Truth`` hooks (``motor``, ``dry``, ``smooth``) carry the laws that fit them, and the first
half's ``simulate`` integrates them.  Laws with a state of their own per sub-step (Dahl's
friction force, Karnopp's velocity band, the winding current, the encoder's eccentric reading)
subclass the second half's :class:`~bank.test_half_2.truths.OwnLoop` and run in its loop
(:func:`simulate` here is the second half's, re-exported).

Inside an ``OwnLoop.step`` the winding's voltage is read back from the motor hook's torque,
``v = (tau_m + (kt^2/R) w) / (kt/R)`` (:func:`_volts`): 0 V while torque is off, the shorted
winding of the first half's reading.

Each truth carries ``expected``, in the physics families of :data:`FAMILIES` (the second
half's, plus the five this half needs: ``friction: nonlinear viscous``, ``actuator lag``,
``sensor error``, ``joint stiffness``, ``inertia and gravity``).
"""

from __future__ import annotations

import math
from dataclasses import replace

from bank.test_half import truths as tr
from bank.test_half.truths import H, Plant, Truth, nominal_plant, perturbed  # noqa: F401
from bank.test_half_2 import truths as tr2
from bank.test_half_2.truths import OwnLoop, simulate  # noqa: F401

#: The second half's families and the ones this half's laws need.
FAMILIES = tr2.FAMILIES + ("friction: nonlinear viscous", "actuator lag", "sensor error",
                           "joint stiffness", "inertia and gravity")
#: Standard gravity [m/s^2] (MuJoCo's default, the nominal file's).
GRAVITY = 9.81


def _expect(family, accept=None, partial=(), unexplained_ok=False, signs=None, note=""):
    """The second half's expectation record (:func:`bank.test_half_2.truths._expect`) over this
    half's :data:`FAMILIES`."""
    return tr2._expect(family, accept, partial, unexplained_ok, signs, note, families=FAMILIES)


_sign = tr2._sign


def _volts(p: Plant, tau_m: float, w: float) -> float:
    """The winding's voltage behind the motor hook's torque ``(kt/R) v - (kt^2/R) w``."""
    return (tau_m + p.emf * w) / p.gear


# ---------------------------------------------------------------------------------------------
# Friction and transmission laws


class Dahl(OwnLoop):
    """(a) Dahl's solid friction, replacing the gear train's Coulomb level: a friction force
    that is a function of the travelled distance (presliding, rate-independent hysteresis), with
    no Stribeck rise (its only level is Fc).

    Source: P. R. Dahl, "A solid friction model", The Aerospace Corporation, TOR-0158(3107-18)-1,
    1968, and "Solid friction damping of mechanical vibrations", AIAA J. 14(12), 1675-1682,
    1976; in the form of Olsson, Astrom, Canudas de Wit, Gafvert, Lischinsky, "Friction models
    and friction compensation", Eur. J. Control 4, 1998, sect. 3 (recalled)::

        dF/dx = sigma |1 - F/Fc sgn(w)|^i sgn(1 - F/Fc sgn(w)),   x the travelled angle,

    the friction ``F`` opposing the joint (``J w' = ... - F``).  i = 2 (Dahl's "ductile"
    exponent; i = 1 would be LuGre's special case without a Stribeck curve): from F = 0 at
    a constant sign of motion ``F(x) = Fc sigma x / (Fc + sigma x)`` (a hyperbola, half the
    level at x = Fc/sigma = 1.3 mrad, 90 % at 12 mrad).  Fc = 0.08 N m, sigma = 60 N m/rad.
    Integration: the speed is advanced with F at the sub-step's start, then F exactly over the
    sub-step's travel ``dx = h w`` (:meth:`advance`: ``y = 1 - F sgn(dx)/Fc``,
    ``y^(1-i) += (i-1) sigma |dx| / Fc``).  F carries over from run to run.
    """

    name = "dahl"
    title = "Dahl friction, i = 2 (presliding hysteresis, no Stribeck rise)"
    source = ("Dahl, Aerospace Corp. TOR-0158(3107-18)-1 1968; Dahl, AIAA J. 14(12) 1976; "
              "Olsson et al., Eur. J. Control 4 1998, sect. 3 (recalled)")
    equation = "dF/dx = sigma |1 - F/Fc sgn w|^i sgn(1 - F/Fc sgn w); Fc 0.08 N m, sigma 60 N m/rad, i 2"

    def defaults(self):
        return {"Fc": 0.08, "sigma": 60.0, "i": 2.0}

    def initial_state(self):
        return {"F": 0.0}

    def advance(self, f: float, dx: float) -> float:
        """The friction after a travel ``dx`` at a constant sign of motion (exact)."""
        if dx == 0.0:
            return f
        q = self.params
        s, fc, i = _sign(dx), q["Fc"], q["i"]
        y0 = 1.0 - s * f / fc
        rate = q["sigma"] * abs(dx) / fc
        if i == 1.0:
            y = y0 * math.exp(-rate)
        else:
            y = (y0 ** (1.0 - i) + (i - 1.0) * rate) ** (1.0 / (1.0 - i))
        return s * fc * (1.0 - y)

    def step(self, theta, w, tau_m, state):
        p = self.p
        tau = tau_m - p.bearing * w - p.mgl * math.sin(theta) - state["F"]
        w = w + H * tau / p.inertia
        state["F"] = self.advance(state["F"], H * w)
        return w

    def expected(self):
        return _expect("friction: dynamic", accept=["friction: dynamic"],
                       partial=["friction: coulomb", "friction: stribeck", "friction: viscous"],
                       signs={"coulomb_level_nm": self.params["Fc"]},
                       note="presliding over a few mrad (sigma 60 N m/rad, i = 2), a single level "
                            "Fc 0.08 N m (nominal Coulomb 0.03), no static peak")


class Karnopp(OwnLoop):
    """(b) Karnopp's stick-slip model: a band of speeds counted as rest, inside which the
    friction balances the other torques up to a static level clearly above the kinetic one.

    Source: D. Karnopp, "Computer simulation of stick-slip friction in mechanical dynamic
    systems", ASME J. Dyn. Sys. Meas. Control 107(1), 100-103, 1985 (as recalled, and as
    reviews describe it: a small speed is treated as zero and the friction compensates the
    external torque)::

        F = clip(tau_e, -Fs, Fs)   if |w| < DV,
        F = Fc sign(w)             if |w| >= DV,

    ``tau_e`` every other torque on the joint (motor, bearing, gravity), ``F`` opposing the
    joint (``J w' = tau_e - F``).  Fs = 0.12 N m, Fc = 0.05 N m, DV = 1 mrad/s.  Inside the band
    a stuck joint keeps the small speed it entered with (Karnopp's model does not zero it: it
    creeps at most DV, 1 mrad per second of stick).  Integrated explicitly per sub-step (the
    kinetic level changes the speed by at most h Fc/J = 0.24 mrad/s per sub-step, less than
    the band, so sliding always lands in it).
    """

    name = "karnopp"
    title = "Karnopp stick-slip: static 0.12 > kinetic 0.05 N m, rest band 1 mrad/s"
    source = "Karnopp, ASME J. Dyn. Sys. Meas. Control 107(1) 1985 (recalled)"
    equation = "F = clip(tau_e, +-Fs) if |w| < DV else Fc sign w; Fs 0.12, Fc 0.05 N m, DV 1e-3 rad/s"

    def defaults(self):
        return {"Fs": 0.12, "Fc": 0.05, "DV": 1e-3}

    def friction(self, w: float, tau_e: float) -> float:
        q = self.params
        if abs(w) < q["DV"]:
            return min(q["Fs"], max(-q["Fs"], tau_e))
        return q["Fc"] * _sign(w)

    def step(self, theta, w, tau_m, state):
        p = self.p
        tau_e = tau_m - p.bearing * w - p.mgl * math.sin(theta)
        return w + H * (tau_e - self.friction(w, tau_e)) / p.inertia

    def expected(self):
        return _expect("friction: stribeck", accept=["friction: stribeck", "friction: dynamic"],
                       partial=["friction: coulomb"], signs={"static_above_kinetic": True},
                       note="Fs 0.12 > Fc 0.05 N m (nominal Coulomb 0.03): a jump at breakaway, "
                            "no curve; a Stribeck or a dynamic friction with Fs > Fc is right")


class ChurningDrag(Truth):
    """(c) Quadratic (churning / windage) drag in the gearbox: a loss torque that grows with
    the square of the speed, on top of the nominal's viscous and Coulomb terms.

    Source: the churning-loss model of geared transmissions, P. Changenet, P. Velex, "A model
    for the prediction of churning losses in geared transmissions -- preliminary results",
    ASME J. Mech. Des. 129(1), 128-133, 2007 (recalled): ``C_ch = 1/2 rho omega^2 S_m R_p^3
    C_m``, with ``C_m`` taken constant over the speed range (it varies only weakly with the
    Reynolds number), i.e. a drag ``c omega^2`` opposing the motion::

        tau_d = -c w |w|,   c = 0.015 N m s^2/rad^2

    (0.015 N m at 1 rad/s, 0.375 N m at 5 rad/s; the back-EMF gives 1.8 N m there).
    """

    name = "churning_drag"
    title = "quadratic churning drag -0.015 w|w| N m"
    source = "Changenet & Velex, ASME J. Mech. Des. 129(1) 2007 (churning torque ~ omega^2; recalled)"
    equation = "tau_d = -c w |w|, c = 0.015 N m s^2/rad^2"

    def defaults(self):
        return {"c": 0.015}

    def smooth(self, theta, w, tau_m):
        return -self.params["c"] * w * abs(w)

    def expected(self):
        return _expect("friction: nonlinear viscous", accept=["friction: nonlinear viscous"],
                       partial=["friction: viscous", "friction: coulomb"], unexplained_ok=True,
                       signs={"speed_exponent_vs_1": "above"},
                       note="a drag in w^2: a viscous term fits it only at one speed; if the "
                            "library has no such law, nothing named and the gap flagged "
                            "unexplained is the right answer")


class HertzLoad(Truth):
    """(d) Load-dependent dry friction that grows as the 2/3 power of the transmitted torque
    (a Hertzian contact's real area), the same in both quadrants.

    Sources: the adhesion theory of friction, F. P. Bowden, D. Tabor, *The Friction and
    Lubrication of Solids*, Oxford 1950 (friction = shear strength x real contact area), with
    the Hertz contact of K. L. Johnson, *Contact Mechanics*, Cambridge 1985, ch. 4 (a contact
    radius ``a = (3 N R / 4 E*)^(1/3)``, so an area ``pi a^2`` growing as ``N^(2/3)``; both
    recalled).  The gear mesh's normal force is proportional to the torque it carries, taken as
    the motor's torque at the output, ``N ~ |tau_m|``::

        tau_f = -(Fc + k |tau_m|^(2/3)) sign(w),   |tau_f| <= Fc + k |tau_m|^(2/3) at rest,

    k = 0.10 N m^(1/3) (0.022 N m at 0.1 N m of motor torque, 0.10 at 1 N m, 0.21 at 3 N m),
    on top of the gear train's Coulomb level (stick rule).  Sub-linear: the earlier halves'
    load laws were linear in ``|tau_m|``.
    """

    name = "hertz_load"
    title = "load friction 0.10 |tau_m|^(2/3) (Hertzian contact area), both quadrants equal"
    source = ("Bowden & Tabor 1950 (adhesion: F = shear strength x real area); Johnson, Contact "
              "Mechanics 1985, ch. 4 (Hertz area ~ N^(2/3); recalled)")
    equation = "tau_f = -(Fc + k |tau_m|^(2/3)) sign w, k = 0.10 N m^(1/3)"

    def defaults(self):
        return {"k": 0.10, "p": 2.0 / 3.0}

    def level(self, tau_m: float) -> float:
        q = self.params
        return self.p.coulomb + q["k"] * abs(tau_m) ** q["p"]

    def dry(self, w, tau_m, state):
        f = self.level(tau_m)
        return f, f, f, f

    def expected(self):
        return _expect("friction: load-dependent", partial=["friction: coulomb", "torque gain"],
                       signs={"driving_vs_back_driven": "equal", "load_exponent_vs_1": "below"},
                       note="0.10 |tau_m|^(2/3) N m in both quadrants: sub-linear in the load")


class Palmgren(Truth):
    """(e) The speed-dependent friction torque of the gearbox's rolling bearings (Palmgren):
    a drag growing as the 2/3 power of the speed, constant below a threshold.

    Source: A. Palmgren, *Ball and Roller Bearing Engineering*, 3rd ed., SKF 1959, and T. A.
    Harris, *Rolling Bearing Analysis*, ch. on friction (recalled): the load-independent
    moment::

        M0 = 1e-7 f0 (nu n)^(2/3) dm^3 [N mm]   for nu n >= 2000,
        M0 = 160e-7 f0 dm^3                     for nu n < 2000,

    (``nu`` [mm^2/s], ``n`` [rpm], ``dm`` [mm]).  Summed over the motor-side bearings and
    reflected through the gear it reads, at the output speed ``w``::

        tau_b = -c_p max(|w|, w_t)^(2/3) sign(w),   c_p = 0.12 N m (s/rad)^(2/3),  w_t = 6 mrad/s

    (nu n = 2000 at the motor is w_t at the output, for nu = 100 mm^2/s and the 350:1 gear;
    0.12 N m at 1 rad/s, 0.35 N m at 5 rad/s).  It holds at rest up to ``c_p w_t^(2/3)``
    (4 mN m), with the gear train's Coulomb level (stick rule).
    """

    name = "palmgren"
    title = "bearing drag 0.12 |w|^(2/3) N m (Palmgren, constant below 6 mrad/s)"
    source = "Palmgren, Ball and Roller Bearing Engineering, SKF 1959; Harris, Rolling Bearing Analysis (recalled)"
    equation = "tau_b = -c_p max(|w|, w_t)^(2/3) sign w, c_p 0.12 N m (s/rad)^(2/3), w_t 6e-3 rad/s"

    def defaults(self):
        return {"c_p": 0.12, "w_t": 6e-3, "p": 2.0 / 3.0}

    def level(self, w: float) -> float:
        q = self.params
        return self.p.coulomb + q["c_p"] * max(abs(w), q["w_t"]) ** q["p"]

    def dry(self, w, tau_m, state):
        s = self.level(0.0)
        f = self.level(w)
        return s, s, f, f

    def expected(self):
        return _expect("friction: nonlinear viscous", accept=["friction: nonlinear viscous"],
                       partial=["friction: viscous", "friction: coulomb", "friction: stribeck"],
                       unexplained_ok=True,
                       signs={"speed_exponent_vs_1": "below"},
                       note="a drag in |w|^(2/3): steeper than linear at low speed, flatter at "
                            "high; a Coulomb + viscous pair fits it only in part")


# ---------------------------------------------------------------------------------------------
# Actuator, plant and sensor laws


class Inductance(OwnLoop):
    """(f) The winding's inductance: the current lags the voltage by the electrical time
    constant L/R, with the back-EMF in the voltage equation.

    Source: the DC motor's electrical equation, as on a motor datasheet (e.g. the Maxon
    catalogue's "terminal inductance" and "terminal resistance"; the electrical time constant
    L/R, a fraction of a ms for coreless motors and up to a few ms for iron-cored gearmotors;
    values recalled)::

        L di/dt = v - R i - kt w,   tau_m = kt i,

    at the output (``kt = 1.2`` N m/A, ``R = 4`` ohm at the nominal), L/R = 3 ms.  Integrated
    per sub-step exactly for a constant ``v`` and ``w``: ``i <- i_ss + (i - i_ss)
    exp(-h R/L)``, ``i_ss = (v - kt w)/R``.  Torque off: the bridge shorts the winding, ``v``
    = 0 (the first half's reading), and the current decays.  Each run starts with the current
    of its start (steady).
    """

    name = "inductance"
    title = "winding inductance: current lag L/R = 3 ms"
    source = "DC motor electrical equation, motor datasheets (Maxon catalogue: L, R; values recalled)"
    equation = "L di/dt = v - R i - kt w, tau_m = kt i; L/R = 3 ms"

    def defaults(self):
        return {"tau_e": 3e-3}

    def initial_state(self):
        return {"i": None}

    def rest(self, seconds, state):
        state["i"] = None

    def current(self, v: float, w: float, i: float | None) -> float:
        """The current after one sub-step at voltage ``v`` and speed ``w`` (exact)."""
        p = self.p
        i_ss = (v - p.kt * w) / p.resistance
        if i is None:
            return i_ss
        return i_ss + (i - i_ss) * math.exp(-H / self.params["tau_e"])

    def step(self, theta, w, tau_m, state):
        p = self.p
        state["i"] = self.current(_volts(p, tau_m, w), w, state["i"])
        tau_i = p.kt * state["i"]
        tau = tau_i - p.bearing * w - p.mgl * math.sin(theta)
        return tr._dry_step(w + H * tau / p.inertia, p.inertia, self.dry(w, tau_i, state))

    def expected(self):
        return _expect("actuator lag", accept=["actuator lag", "time delay"],
                       partial=["drive compliance", "inertia", "torque gain"],
                       signs={"time_constant_s": self.params["tau_e"]},
                       note="first-order current lag of 3 ms between the command and the torque")


class Payload(Truth):
    """(g) A payload at the tip: a 0.2 kg point mass clamped 0.18 m below the pivot.  Inertia
    and gravity both grow, by the same added mass (rigid body, parallel-axis theorem; e.g.
    Meriam & Kraige, *Engineering Mechanics: Dynamics*, the pendulum's equation)::

        J' = J + m_p l_p^2,   (m g l)' = m g l + m_p g l_p:   +6.5e-3 kg m^2, +0.353 N m (x1.30).

    The pendulum's equation divided by ``k = (m g l)'/(m g l)`` is the nominal's with the gain,
    back-EMF, bearing loss and Coulomb friction divided by ``k`` and the armature at ``J'/k -
    J_link``: a payload is exactly a change of the nominal's constants (trajectory for
    trajectory, ``test_payload_is_the_nominal_scaled``).  The right answer is therefore
    nothing named, the constants' corrections taking it (the torque gain about 1/1.30 of the
    truth's), or a law of added mass.
    """

    name = "payload"
    title = "payload 0.2 kg at 0.18 m: inertia and gravity x1.30 together"
    source = "rigid-body pendulum with a point mass (parallel-axis theorem; Meriam & Kraige, Dynamics)"
    equation = "J' = J + m_p l_p^2, mgl' = mgl + m_p g l_p; m_p 0.2 kg, l_p 0.18 m"

    def __init__(self, plant: Plant, **params):
        super().__init__(plant, **params)
        q = self.params
        self.base = plant
        self.p = replace(plant, j_link=plant.j_link + q["m_p"] * q["l_p"] ** 2,
                         mgl=plant.mgl + q["m_p"] * GRAVITY * q["l_p"])

    def defaults(self):
        return {"m_p": 0.2, "l_p": 0.18}

    def scale(self) -> float:
        """``k``: the gravity torque's factor."""
        return self.p.mgl / self.base.mgl

    def expected(self):
        return _expect("none", accept=["none", "inertia and gravity"],
                       partial=["inertia", "torque gain"],
                       signs={"torque_gain_vs_nominal": "lower"},
                       note=f"equal to the nominal with gain, damping and Coulomb /{self.scale():.2f} "
                            "and the armature moved: corrections, or a payload law, are right")


class Eccentricity(OwnLoop):
    """(h) An eccentric encoder: the servo's angle reading (the one its P law closes on and the
    host logs) carries a once-per-turn error.

    Source: the eccentricity error of a graduated disc mounted off its bearing's axis,
    HEIDENHAIN, "Angle encoders" brochure (the error ``+-412 e/D`` arcsec for an eccentricity
    ``e`` [um] on a graduation of diameter ``D`` [mm], i.e. an amplitude ``2 e/D`` rad;
    recalled)::

        y = theta + a sin(theta + phi),   a = 2 e/D = 0.015 rad (e = 0.15 mm on D = 20 mm),
        phi = 0.6 rad,

    then rounded to 4096 counts per turn.  The pendulum hanging (theta = 0) reads 8.5 mrad.
    Integrated in the loop's angle variable: the loop's ``theta`` is the reading ``y``, the
    true angle is ``y``'s inverse (Newton) and the true speed a state; each sub-step advances
    the true joint and returns the reading's rate (``state["theta"]``, ``state["w"]`` the true
    angle and speed).
    """

    name = "eccentricity"
    title = "eccentric encoder: y = theta + 0.015 sin(theta + 0.6)"
    source = "HEIDENHAIN, Angle encoders brochure (eccentricity error 412 e/D arcsec; recalled)"
    equation = "y = theta + a sin(theta + phi), a = 0.015 rad, phi = 0.6 rad"

    def defaults(self):
        return {"a": 0.015, "phi": 0.6}

    def initial_state(self):
        return {"w": 0.0}

    def rest(self, seconds, state):
        state["w"] = 0.0

    def reading(self, theta: float) -> float:
        q = self.params
        return theta + q["a"] * math.sin(theta + q["phi"])

    def true_angle(self, y: float) -> float:
        """The angle whose reading is ``y`` (Newton; the reading is monotone for a < 1)."""
        q = self.params
        x = y - q["a"] * math.sin(y + q["phi"])
        for _ in range(30):
            dx = (self.reading(x) - y) / (1.0 + q["a"] * math.cos(x + q["phi"]))
            x -= dx
            if abs(dx) < 1e-15:
                break
        return x

    def step(self, theta, w, tau_m, state):
        p = self.p
        th = self.true_angle(theta)
        wt = state["w"]
        tau_d = p.gear * _volts(p, tau_m, w) - p.emf * wt
        tau = tau_d - p.bearing * wt - p.mgl * math.sin(th)
        wt = tr._dry_step(wt + H * tau / p.inertia, p.inertia, self.dry(wt, tau_d, state))
        state["w"], state["theta"] = wt, th + H * wt
        return (self.reading(th + H * wt) - theta) / H

    def expected(self):
        return _expect("sensor error", accept=["sensor error"],
                       partial=["position offset", "cogging", "gravity offset"],
                       unexplained_ok=True, signs={"sensor_amplitude_rad": self.params["a"]},
                       note="a once-per-turn reading error of 0.015 rad (10 counts); a constant "
                            "position offset takes only its mean over the range swept")


class TorsionSpring(Truth):
    """(i) A gravity-compensation torsion spring at the pivot.

    Source: Hooke's law of a helical torsion spring, ``M = k' theta`` with ``k' = d^4 E /
    (10.8 D N)`` (J. E. Shigley, C. R. Mischke, *Mechanical Engineering Design*, torsion
    springs; recalled), mounted as a preloaded balancing spring (e.g. the spring
    gravity-balancing of N. Ulrich, V. Kumar, "Passive mechanical gravity compensation for
    robot manipulators", IEEE ICRA 1991; recalled)::

        tau_s = -k (theta - theta0),   k = 0.6 N m/rad,   theta0 = 0.25 rad,

    its neutral angle on the side the arm is lifted to: it pushes the arm up by k theta0 =
    0.15 N m at the hanging angle and adds half of gravity's slope (1.18 N m/rad) about it.
    The pendulum hangs at rest where ``k (theta0 - theta) = m g l sin(theta)`` (0.084 rad).
    """

    name = "torsion_spring"
    title = "torsion spring at the pivot: -0.6 (theta - 0.25) N m"
    source = ("Hooke's law of a torsion spring (Shigley & Mischke, torsion springs; recalled); "
              "spring gravity balancing (Ulrich & Kumar, ICRA 1991; recalled)")
    equation = "tau_s = -k (theta - theta0), k = 0.6 N m/rad, theta0 = 0.25 rad"

    def defaults(self):
        return {"k": 0.6, "theta0": 0.25}

    def smooth(self, theta, w, tau_m):
        q = self.params
        return -q["k"] * (theta - q["theta0"])

    def expected(self):
        return _expect("joint stiffness", accept=["joint stiffness"],
                       partial=["gravity offset", "torque bias", "position offset"],
                       signs={"stiffness_nm_per_rad": self.params["k"]},
                       note="0.6 N m/rad about 0.25 rad: linear in the angle where gravity is "
                            "a sine; a tilt or bias takes only its offset")


class Null(tr.Null):
    """(j) Nothing missing: the nominal's own laws with its constants 5-15 % off (seed 44;
    the first half's null case, ``bank.test_half.truths.Null``)."""


#: The cases of the third test half, in order: (name, class).
CASES = (("a_dahl", Dahl), ("b_karnopp", Karnopp), ("c_churning_drag", ChurningDrag),
         ("d_hertz_load", HertzLoad), ("e_palmgren", Palmgren), ("f_inductance", Inductance),
         ("g_payload", Payload), ("h_eccentricity", Eccentricity),
         ("i_torsion_spring", TorsionSpring), ("j_null", Null))
