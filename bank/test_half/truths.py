"""Truth simulators of a geared servo pendulum, each with one law from the literature.

Written WITHOUT reading the discrepancy library (its effects, search, shapes, fits, or the
device's drive laws): only the nominal model's file (``models/servo_pendulum/``), the servo
page (``docs/method/servo-actuators.md``), the dataset contract and the CLI's help were read.
Each law is written from its source's equation, cited in its class's docstring.

The plant
---------
The nominal file ``models/servo_pendulum/servo_pendulum.xml`` is compiled with MuJoCo only to
read the plant it describes (:func:`nominal_plant`, in :mod:`bank.test_half.plant`): the pendulum's inertia about the pivot
(the mass matrix without the armature), its gravity torque ``m g l`` (MuJoCo's bias force at
90 deg), the reflected rotor inertia (armature), the torque per volt ``kt/R`` (the motor's
gear), the joint damping (back-EMF ``kt^2/R`` = 0.36 of the file's 0.37, the rest bearing
viscous loss, as the file's comment splits it), the gear train's Coulomb friction
(frictionloss) and the supply (ctrlrange).  The truth then **integrates the joint itself**
(our choice, not MuJoCo's step): one degree of freedom (two for backlash: rotor and load),

    (J_link + J_a) w' = tau_m - b w - m g l sin(theta) + tau_law + tau_dry,

with ``tau_m = (kt/R) u - (kt^2/R) w`` (the motor at the output shaft), semi-implicit Euler at
0.1 ms (ten sub-steps per 1 ms control period), and the dry friction ``tau_dry`` by a
time-stepping stick rule (:func:`_dry_step`): over a sub-step the friction takes any value
inside its static bounds that stops the joint, else it slides at its kinetic level.  This
stands in for continuous reality: it is neither MuJoCo's ``implicitfast`` step at 1 ms nor
its frictionloss constraint, so the nominal replay differs from the truth by integration too
(as from a real device).  ``tests/test_bank_test_half.py`` checks the integration against
MuJoCo's RK4 on the frictionless plant.

The servo (``docs/method/servo-actuators.md``): the P law ``u = clip(kp (r - y), +-limit)``
on the encoder angle ``y`` (4096 counts per revolution, rounded), held for the 1 ms control
period, clipped again at the 12 V supply.  Torque off (``enabled`` 0): the bridge stops
driving and **shorts** the winding (a braking driver), so the back-EMF torque ``-(kt^2/R) w``
stays and the motor's drive torque is 0.  This is the reading of the nominal file (its
back-EMF is joint damping, present at 0 V) chosen so that no case is about the torque-off
reading; a coasting driver (open winding) would be another case.

Each truth perturbs the nominal's armature, gear, damping and Coulomb friction by 5-15 %
(sign and size drawn from the case's seed, :func:`perturbed`): the nominal is a bit off
everywhere, as a user's model is.

Each truth carries ``expected``: the verdict a correct method should give, in physics
families (:data:`FAMILIES`) and signs, not in any library's names.
"""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np

from .plant import (  # noqa: F401
    ACTUATOR,
    CONTROL_PERIOD_S,
    COUNTS_PER_REV,
    EMF_SHARE,
    ENCODER_STEP_RAD,
    JOINT,
    NOMINAL,
    NOMINAL_REL,
    ROOT,
    SUBSTEPS,
    H,
    Plant,
    nominal_plant,
    perturbed,
)

#: The physics families the expectations use (a method's names are mapped onto them by
#: ``score.py``).
FAMILIES = (
    "none", "friction: coulomb", "friction: viscous", "friction: stribeck",
    "friction: dynamic", "friction: load-dependent", "friction: asymmetric",
    "friction: drifting", "end_stop", "backlash", "drive compliance", "torque saturation",
    "torque gain", "time delay", "torque bias", "inertia", "unexplained",
)


# ---------------------------------------------------------------------------------------------
# The truths


class Truth:
    """A truth: the plant plus one law.  Subclasses override the hooks below.

    Hooks (all at the output shaft, torques in N m, speeds in rad/s):

    * :meth:`motor` -- the motor's torque at command ``u`` [V] and speed ``w``;
    * :meth:`dry` -- the dry friction's bounds ``(static_pos, static_neg, slide_pos,
      slide_neg)``: the largest friction opposing a positive (negative) motion at rest, and
      while sliding at ``w``;
    * :meth:`smooth` -- any other torque (viscous terms, a smooth friction, a contact);
    * :meth:`heat` -- a state update per sub-step (the thermal case).
    """

    name = "truth"
    title = ""
    source = ""
    equation = ""
    two_mass = False

    def __init__(self, plant: Plant, **params):
        self.p = plant
        self.params = dict(self.defaults(), **params)

    def defaults(self) -> dict:
        return {}

    def motor(self, u: float, w: float, enabled: bool) -> float:
        """DC motor at the output: ``(kt/R) u - (kt^2/R) w``; torque off shorts the winding."""
        return (self.p.gear * u if enabled else 0.0) - self.p.emf * w

    def dry(self, w: float, tau_m: float, state: dict) -> tuple[float, float, float, float]:
        c = self.p.coulomb
        return c, c, c, c

    def smooth(self, theta: float, w: float, tau_m: float) -> float:
        return 0.0

    def heat(self, tau_m: float, state: dict) -> None:
        return None

    def initial_state(self) -> dict:
        return {}

    def rest(self, seconds: float, state: dict) -> None:
        """What happens between two runs (``seconds`` at rest, torque on, no load)."""
        return None

    def expected(self) -> dict:
        raise NotImplementedError

    def describe(self) -> dict:
        """The case's record for ``cases.json``."""
        return {"law": self.name, "title": self.title, "source": self.source,
                "equation": self.equation, "params": self.params, "plant": asdict(self.p),
                "expected": self.expected()}


def _expect(family, accept=None, partial=(), unexplained_ok=False, signs=None, note=""):
    """An expectation record: ``family`` the right answer, ``accept`` every family that counts
    as right, ``partial`` families that are only partly right, ``signs`` the direction
    claims (``score.py``), ``unexplained_ok`` whether an 'unexplained' flag is also right."""
    accept = list(accept or [family])
    for f in (family, *accept, *partial):
        assert f in FAMILIES, f
    return {"family": family, "accept": accept, "partial": list(partial),
            "unexplained_ok": unexplained_ok, "signs": signs or {}, "note": note}


class Null(Truth):
    """(j) Nothing missing: the nominal's own laws (DC motor, viscous, Coulomb) with its
    constants 5-15 % off.  A correct method names nothing (the corrections absorb the
    constants)."""

    name = "null"
    title = "null: nothing missing, the nominal a bit off"
    source = "the nominal file itself (models/servo_pendulum/servo_pendulum.xml)"
    equation = "J w' = (kt/R) u - (kt^2/R + b) w - m g l sin(theta) - Fc sign(w)"

    def expected(self):
        return _expect("none", note="the nominal's constants are off by 5-15 %: corrections, "
                                    "not an effect")


class Stribeck(Truth):
    """(a) Stribeck friction with a viscous term, replacing the gear train's Coulomb level.

    Source: B. Armstrong-Helouvry, P. Dupont, C. Canudas de Wit, "A survey of models,
    analysis tools and compensation methods for the control of machines with friction",
    Automatica 30(7), 1994 (after Armstrong-Helouvry, *Control of Machines with Friction*,
    Kluwer 1991), the exponential Stribeck curve; in the form of Olsson, Astrom, Canudas de
    Wit, Gafvert, Lischinsky, "Friction models and friction compensation", Eur. J. Control
    4, 1998, eq. (5)/(9)::

        F(v) = [Fc + (Fs - Fc) exp(-|v / vs|^delta)] sign(v) + Fv v

    At rest the friction holds up to ``Fs`` (static); sliding it follows the curve.
    """

    name = "stribeck"
    title = "Stribeck friction (exponential curve) with a viscous term"
    source = ("Armstrong-Helouvry 1991 (book); Armstrong-Helouvry, Dupont, Canudas de Wit, "
              "Automatica 30(7) 1994; Olsson et al., Eur. J. Control 4 1998, eq. (9)")
    equation = "F(w) = [Fc + (Fs - Fc) exp(-|w/ws|^delta)] sign(w) + Fv w; |F| <= Fs at rest"

    def defaults(self):
        return {"Fc": 0.05, "Fs": 0.12, "ws": 0.2, "delta": 2.0, "Fv": 0.03}

    def level(self, w: float) -> float:
        q = self.params
        return q["Fc"] + (q["Fs"] - q["Fc"]) * math.exp(-abs(w / q["ws"]) ** q["delta"])

    def dry(self, w, tau_m, state):
        fs = self.params["Fs"]
        f = self.level(w)
        return fs, fs, f, f

    def smooth(self, theta, w, tau_m):
        return -self.params["Fv"] * w

    def expected(self):
        return _expect("friction: stribeck", accept=["friction: stribeck", "friction: dynamic"],
                       partial=["friction: coulomb", "friction: viscous"],
                       signs={"static_above_kinetic": True, "coulomb_vs_nominal": "higher"},
                       note="Fs 0.12 > Fc 0.05 N m (nominal Coulomb 0.03); extra viscous 0.03")


class LoadQuadrant(Truth):
    """(b) Load-dependent dry friction with separate coefficients in the driving and the
    back-driven quadrants.

    Source: P. Hamon, M. Gautier, P. Garrec, "Dynamic identification of robots with a dry
    friction model depending on load and velocity", IEEE/RSJ IROS 2010, and "New dry
    friction model with load- and velocity-dependence and dynamic identification of
    multi-DOF robots", IEEE ICRA 2011 (equations as we recall them, not re-read): the dry
    friction is affine in the absolute transmitted torque, with its constants depending on
    the quadrant of (speed, torque), i.e. on whether the motor drives the load
    (``tau_m w > 0``) or the load back-drives the motor (``tau_m w < 0``)::

        tau_f = -(Fc + F_tau,q |tau_m|) sign(w) - Fv w,   q = drive if tau_m w > 0 else back

    The coefficients here make the DRIVING one larger (0.15 against 0.05): the quadrant
    model allows either order; the other direction is case (c).
    """

    name = "load_quadrant"
    title = "load-dependent friction, driving coefficient > back-driven (Hamon et al.)"
    source = "Hamon, Gautier, Garrec, IROS 2010 / ICRA 2011 (quadrant-dependent dry friction)"
    equation = ("tau_f = -(Fc + F_q |tau_m|) sign(w) - Fv w; F_q = F_drive if tau_m w > 0 "
                "else F_back")

    def defaults(self):
        return {"F_drive": 0.15, "F_back": 0.05, "Fv": 0.02}

    def _levels(self, tau_m):
        q, c = self.params, self.p.coulomb
        a = abs(tau_m)
        pos = c + (q["F_drive"] if tau_m > 0 else q["F_back"]) * a   # motion w > 0
        neg = c + (q["F_drive"] if tau_m < 0 else q["F_back"]) * a   # motion w < 0
        return pos, neg

    def dry(self, w, tau_m, state):
        pos, neg = self._levels(tau_m)
        return pos, neg, pos, neg

    def smooth(self, theta, w, tau_m):
        return -self.params["Fv"] * w

    def expected(self):
        return _expect("friction: load-dependent", partial=["friction: coulomb"],
                       signs={"driving_vs_back_driven": "driving larger"},
                       note="F_drive 0.15 > F_back 0.05 (per N m of motor torque)")


class GearEfficiency(Truth):
    """(c) Power-flow dependent gear efficiency.

    Sources: the mesh-efficiency reading of gear losses (E. Pennestri, P. P. Valentini,
    "A review of formulas for the mechanical efficiency analysis of two degrees-of-freedom
    epicyclic gear trains", J. Mech. Des. 125, 2003; A. Wolf's power-flow method), where the
    torque the gear delivers is the input torque times the efficiency in the direction the
    power flows: motor driving (``tau_m w > 0``) ``tau_out = eta tau_m``; load back-driving
    (``tau_m w < 0``) the load must overcome ``tau_m / eta_b``.  The back-driving efficiency
    of the same mesh is the classical ``eta_b = 2 - 1/eta`` (same friction angle both ways;
    e.g. Shigley's *Mechanical Engineering Design*, power screws and worm gears), which makes
    the back-driven loss larger::

        tau_loss = (1 - eta) |tau_m|         motor drives
        tau_loss = (1/eta_b - 1) |tau_m|     load back-drives,   opposing w,

    on top of the gear train's Coulomb level.  With eta = 0.80: 0.20 and 0.333 per N m.
    """

    name = "gear_efficiency"
    title = "gear efficiency by power flow (back-driven loss larger)"
    source = ("Pennestri & Valentini, J. Mech. Des. 125 (2003); Wolf's power-flow method; "
              "eta_b = 2 - 1/eta (Shigley, power screws/worm gears)")
    equation = ("tau_loss = (1-eta)|tau_m| if tau_m w > 0 else (1/eta_b - 1)|tau_m|, "
                "eta_b = 2 - 1/eta, opposing w, + Fc")

    def defaults(self):
        return {"eta": 0.80}

    def coefficients(self) -> tuple[float, float]:
        """(driving, back-driven) loss per N m of motor torque."""
        eta = self.params["eta"]
        eta_b = 2 - 1 / eta
        return 1 - eta, 1 / eta_b - 1

    def dry(self, w, tau_m, state):
        drive, back = self.coefficients()
        c, a = self.p.coulomb, abs(tau_m)
        pos = c + (drive if tau_m > 0 else back) * a
        neg = c + (drive if tau_m < 0 else back) * a
        return pos, neg, pos, neg

    def expected(self):
        drive, back = self.coefficients()
        return _expect("friction: load-dependent", partial=["torque gain", "friction: coulomb"],
                       signs={"driving_vs_back_driven": "back-driven larger"},
                       note=f"driving {drive:.3f}, back-driven {back:.3f} per N m")


class EndStop(Truth):
    """(d) A mechanical end stop beyond +0.35 rad: a Hunt-Crossley contact.

    Source: K. H. Hunt, F. R. E. Crossley, "Coefficient of restitution interpreted as
    damping in vibroimpact", ASME J. Appl. Mech. 42(2), 440-445, 1975::

        tau = -k d^n (1 + 3/2 alpha d'),   d = theta - theta_stop > 0,   n = 3/2,

    never pulling (``tau <= 0``); zero below the stop.
    """

    name = "end_stop"
    title = "end stop at +0.35 rad (Hunt-Crossley contact)"
    source = "Hunt & Crossley, ASME J. Appl. Mech. 42 (1975)"
    equation = "tau = -k d^n (1 + 1.5 alpha d'), d = theta - theta_stop > 0, tau <= 0"

    def defaults(self):
        return {"theta_stop": 0.35, "k": 2000.0, "n": 1.5, "alpha": 0.5}

    def contact(self, theta: float, w: float) -> float:
        q = self.params
        d = theta - q["theta_stop"]
        if d <= 0:
            return 0.0
        return min(0.0, -q["k"] * d ** q["n"] * (1 + 1.5 * q["alpha"] * w))

    def smooth(self, theta, w, tau_m):
        return self.contact(theta, w)

    def expected(self):
        return _expect("end_stop", signs={"side": "positive", "angle_rad": 0.35},
                       note="one-sided stop at +0.35 rad")


class AsymmetricCoulomb(Truth):
    """(e) Direction-dependent Coulomb friction.

    Source: the asymmetric Coulomb model of robot joint identification, e.g. W. Khalil,
    E. Dombre, *Modeling, Identification and Control of Robots*, 2002, sect. 12.x (an offset
    term with the Coulomb one), and Olsson et al. 1998, sect. 2 ("the friction may be
    different in the two directions")::

        tau_f = -F+   for w > 0,    +F-   for w < 0,    |tau_f| <= F+- at rest.

    Here F+ = 0.07 N m, F- = 0.025 N m (the nominal 0.03 both ways).
    """

    name = "asymmetric_coulomb"
    title = "asymmetric Coulomb friction (F+ > F-)"
    source = "Khalil & Dombre 2002 (asymmetric Coulomb/offset); Olsson et al. 1998, sect. 2"
    equation = "tau_f = -F+ if w > 0, +F- if w < 0; stick within [-F+, F-]"

    def defaults(self):
        return {"F_pos": 0.07, "F_neg": 0.025}

    def dry(self, w, tau_m, state):
        q = self.params
        return q["F_pos"], q["F_neg"], q["F_pos"], q["F_neg"]

    def expected(self):
        return _expect("friction: asymmetric", accept=["friction: asymmetric"],
                       partial=["friction: coulomb", "torque bias"],
                       signs={"direction_larger": "positive"},
                       note="0.07 N m moving +, 0.025 N m moving -")


class Backlash(Truth):
    """(f) Backlash between the rotor side and the load: a dead zone with impacts.

    Source: M. Nordin, P.-O. Gutman, "Controlling mechanical systems with backlash -- a
    survey", Automatica 38(10), 1633-1649, 2002, the "dead-zone model" (their eq. for the
    shaft torque)::

        tau_s = k (x - alpha sign(x)) + c x'   if |x| > alpha   (x = theta_m - theta_l)
        tau_s = 0                              if |x| <= alpha

    (the contact never pulls).  Two bodies: the rotor side (reflected armature; motor,
    back-EMF, bearing viscous loss and the gear train's Coulomb friction) and the pendulum
    (gravity).  The encoder reads the pendulum (the output shaft).  Half gap alpha = 0.01
    rad (1.15 deg of total play), mesh stiffness 300 N m/rad, contact damping 0.3 N m s/rad.
    """

    name = "backlash"
    title = "backlash 0.02 rad total (dead-zone model with impacts)"
    source = "Nordin & Gutman, Automatica 38 (2002), dead-zone model"
    equation = "tau_s = k (x - alpha sign x) + c x' for |x| > alpha else 0, x = theta_m - theta"
    two_mass = True

    def defaults(self):
        return {"alpha": 0.01, "k": 300.0, "c": 0.3}

    def shaft(self, x: float, xd: float) -> float:
        q = self.params
        a = q["alpha"]
        if x > a:
            return max(0.0, q["k"] * (x - a) + q["c"] * xd)
        if x < -a:
            return min(0.0, q["k"] * (x + a) + q["c"] * xd)
        return 0.0

    def expected(self):
        return _expect("backlash", partial=["drive compliance"],
                       signs={"gap_rad": 2 * self.params["alpha"]},
                       note="total play 0.02 rad between rotor and pendulum")


class ThermalFriction(Truth):
    """(g) Coulomb friction that drifts with the winding/gear temperature.

    Sources: a first-order thermal model of a DC motor heated by its copper losses (e.g.
    the Maxon / Faulhaber datasheet thermal model, one thermal resistance and capacity:
    ``C dT/dt = R i^2 - (T - T_amb)/R_th``) and a friction linear in temperature (the
    temperature dependence of robot joint friction reported by Bittencourt & Gunnarsson,
    "Static friction in a robot joint -- modeling and identification of load and
    temperature effects", J. Dyn. Sys. Meas. Control 134, 2012, where friction falls as the
    grease warms)::

        Fc(T) = Fc0 (1 + beta (T - T_amb)),   beta < 0,   i = tau_m / kt.

    The temperature carries over from run to run (in the order ``make.py`` runs them, with
    a rest of 5 s between runs cooling it), so the friction level drifts across the
    dataset.
    """

    name = "thermal_friction"
    title = "Coulomb friction falling with temperature (I^2 R heating, first order)"
    source = ("first-order motor thermal model (Maxon/Faulhaber datasheets); Bittencourt & "
              "Gunnarsson, J. Dyn. Sys. Meas. Control 134 (2012)")
    equation = ("C dT/dt = R i^2 - (T - Ta)/Rth, i = tau_m/kt; Fc(T) = Fc0 (1 + beta (T - Ta)), "
                "floored at 0")

    def defaults(self):
        return {"Fc0": 0.10, "beta": -0.03, "C": 2.0, "Rth": 15.0, "T_amb": 25.0}

    def initial_state(self):
        return {"T": self.params["T_amb"]}

    def level(self, temperature: float) -> float:
        q = self.params
        return max(0.0, q["Fc0"] * (1 + q["beta"] * (temperature - q["T_amb"])))

    def dry(self, w, tau_m, state):
        f = self.level(state["T"])
        return f, f, f, f

    def heat(self, tau_m, state):
        q = self.params
        i = tau_m / self.p.kt
        power = self.p.resistance * i * i
        state["T"] += H * (power - (state["T"] - q["T_amb"]) / q["Rth"]) / q["C"]

    def rest(self, seconds, state):
        q = self.params
        state["T"] = q["T_amb"] + (state["T"] - q["T_amb"]) * math.exp(-seconds / (q["Rth"] * q["C"]))

    def expected(self):
        return _expect("friction: drifting",
                       accept=["friction: drifting", "friction: coulomb", "unexplained"],
                       unexplained_ok=True, signs={"coulomb_vs_nominal": "higher"},
                       note="Coulomb 0.10 N m cold (nominal 0.03), falling as the motor warms; "
                            "a constant higher level is the best a drift-free law can do")


class CurrentLimit(Truth):
    """(h) A firmware current limit: the torque bound moves with the back-EMF.

    Source: the DC motor's operating range on a servo datasheet (e.g. the Dynamixel
    X-series "current limit" register and the speed-torque curve of the Maxon catalogue):
    the winding current ``i = (V - ke w)/R`` is clipped at ``i_max`` by the firmware and
    the voltage at the supply, so::

        tau_m = kt clip((u - ke w)/R, -i_max, i_max),   |u| <= V_s,
        bound: tau_m <= kt min(i_max, (V_s - ke w)/R).

    i_max = 1.0 A (a third of the 3 A stall current); ``ke = kt`` (SI units).
    """

    name = "current_limit"
    title = "firmware current limit 1.0 A (torque bound kt min(i_max, (Vs - ke w)/R))"
    source = ("DC motor speed-torque range with a current limit (Maxon catalogue; Dynamixel X "
              "current limit register)")
    equation = "tau_m = kt clip((u - ke w)/R, -i_max, i_max), |u| <= Vs"

    def defaults(self):
        return {"i_max": 1.0}

    def motor(self, u, w, enabled):
        if not enabled:
            return -self.p.emf * w
        kt, r = self.p.kt, self.p.resistance
        i = (u - kt * w) / r
        i = min(self.params["i_max"], max(-self.params["i_max"], i))
        return kt * i

    def bound(self, w: float) -> float:
        """The largest positive torque at speed ``w`` (the supply's voltage applied)."""
        kt, r = self.p.kt, self.p.resistance
        return kt * min(self.params["i_max"], (self.p.supply - kt * w) / r)

    def expected(self):
        return _expect("torque saturation", partial=["torque gain"],
                       signs={"torque_bound_nm": self.p.kt * self.params["i_max"],
                              "bound_vs_stall": "below"},
                       note="the torque saturates at kt i_max, far below the 12 V stall torque")


class UsersPendulum(Truth):
    """(i) The user's pendulum: an extra friction proportional to the motor torque, the same
    in both directions, smooth in speed.

    Source: the user's own description of their servo (the project's requests), a smooth
    (tanh-regularised) load-dependent Coulomb law, as in the regularised friction models of
    Makkar, Dixon, Sawyer, Hu, "A new continuously differentiable friction model for
    control systems design", IEEE/ASME AIM 2005::

        tau_f = -0.2 |tau_m| tanh(w / 0.02)   (+ the gear train's Coulomb level)
    """

    name = "users_pendulum"
    title = "the user's pendulum: 0.2 |tau_m| tanh(w/0.02), both directions equal"
    source = "the user's description; tanh regularisation as in Makkar et al., AIM 2005"
    equation = "tau_f = -mu |tau_m| tanh(w/w0), mu = 0.2, w0 = 0.02 rad/s"

    def defaults(self):
        return {"mu": 0.2, "w0": 0.02}

    def smooth(self, theta, w, tau_m):
        q = self.params
        return -q["mu"] * abs(tau_m) * math.tanh(w / q["w0"])

    def expected(self):
        return _expect("friction: load-dependent", partial=["friction: coulomb"],
                       signs={"driving_vs_back_driven": "equal"},
                       note="0.2 per N m of motor torque in both quadrants")


#: The cases of the test half, in order: (name, class).
CASES = (("a_stribeck", Stribeck), ("b_load_quadrant", LoadQuadrant),
         ("c_gear_efficiency", GearEfficiency), ("d_end_stop", EndStop),
         ("e_asymmetric_coulomb", AsymmetricCoulomb), ("f_backlash", Backlash),
         ("g_thermal_friction", ThermalFriction), ("h_current_limit", CurrentLimit),
         ("i_users_pendulum", UsersPendulum), ("j_null", Null))


# ---------------------------------------------------------------------------------------------
# Integration


def _dry_step(w_free: float, inertia: float, bounds) -> float:
    """The speed after a sub-step with dry friction, given the speed ``w_free`` it would
    reach without it: stick (0) if a friction inside the static bounds stops the joint in
    the sub-step, else slide with the kinetic level opposing the motion (never reversing
    it)."""
    s_pos, s_neg, f_pos, f_neg = bounds
    if -H * s_neg / inertia <= w_free <= H * s_pos / inertia:
        return 0.0
    if w_free > 0:
        return max(0.0, w_free - H * f_pos / inertia)
    return min(0.0, w_free + H * f_neg / inertia)


def simulate(truth: Truth, goal: np.ndarray, enabled: np.ndarray, kp: float,
             command_limit: float, theta0: float, state: dict) -> tuple[np.ndarray, np.ndarray]:
    """Run the servo's P loop on the truth: one control period per entry of ``goal``.

    Parameters
    ----------
    goal, enabled : ndarray, shape (n,)
        The goal angle [rad] and torque-on flag the servo holds over each 1 ms period.
    kp, command_limit : float
        The P law [V/rad] and its clip [V] (the supply clips too).
    theta0 : float
        The angle at rest at t = 0 [rad].
    state : dict
        The truth's state carried from run to run (temperature); updated in place.

    Returns
    -------
    theta : ndarray, shape (n * SUBSTEPS + 1,)
        The pendulum's angle every 0.1 ms from t = 0.
    u : ndarray, shape (n,)
        The command held over each period [V] (0 while torque is off).
    """
    if truth.two_mass:
        return _simulate_two_mass(truth, goal, enabled, kp, command_limit, theta0)
    p = truth.p
    inertia, mgl, b = p.inertia, p.mgl, p.bearing
    lim = min(command_limit, p.supply)
    n = len(goal)
    theta = np.empty(n * SUBSTEPS + 1)
    u_out = np.empty(n)
    th, w = float(theta0), 0.0
    theta[0] = th
    q = ENCODER_STEP_RAD
    i = 0
    for k in range(n):
        on = bool(enabled[k])
        y = round(th / q) * q
        u = min(lim, max(-lim, kp * (float(goal[k]) - y))) if on else 0.0
        u_out[k] = u
        for _ in range(SUBSTEPS):
            tau_m = truth.motor(u, w, on)
            tau = tau_m - b * w - mgl * math.sin(th) + truth.smooth(th, w, tau_m)
            w = _dry_step(w + H * tau / inertia, inertia, truth.dry(w, tau_m, state))
            th += H * w
            truth.heat(tau_m, state)
            i += 1
            theta[i] = th
    return theta, u_out


def _simulate_two_mass(truth: Backlash, goal, enabled, kp, command_limit, theta0):
    """:func:`simulate` with the rotor side and the pendulum as two bodies (backlash)."""
    p = truth.p
    jm, jl, mgl, b, fc = p.armature, p.j_link, p.mgl, p.bearing, p.coulomb
    lim = min(command_limit, p.supply)
    n = len(goal)
    theta = np.empty(n * SUBSTEPS + 1)
    u_out = np.empty(n)
    th, w = float(theta0), 0.0         # pendulum
    thm, wm = float(theta0), 0.0       # rotor side (at the output's angle scale)
    theta[0] = th
    q = ENCODER_STEP_RAD
    bounds = (fc, fc, fc, fc)
    i = 0
    for k in range(n):
        on = bool(enabled[k])
        y = round(th / q) * q
        u = min(lim, max(-lim, kp * (float(goal[k]) - y))) if on else 0.0
        u_out[k] = u
        for _ in range(SUBSTEPS):
            tau_m = truth.motor(u, wm, on)
            ts = truth.shaft(thm - th, wm - w)
            wm = _dry_step(wm + H * (tau_m - b * wm - ts) / jm, jm, bounds)
            w = w + H * (ts - mgl * math.sin(th)) / jl
            thm += H * wm
            th += H * w
            i += 1
            theta[i] = th
    return theta, u_out
