"""Truths of the fourth test half: the same geared servo pendulum, ten more laws from the
literature, in forms none of the three earlier halves used.

Written WITHOUT reading the discrepancy library (its effects, search, shapes, fits, or the
device's drive laws), under the first half's rule: only the nominal model's file
(``models/servo_pendulum/``), the servo page (``docs/method/servo-actuators.md``), the dataset
contract (``identification/dataset.py``), the CLI's help and the three earlier test halves
(``bank/test_half/``, ``bank/test_half_2/``, ``bank/test_half_3/``: truths, make, score, tests and
their README sections, without the records of their runs) were read.  Each law is written from
its source's equation, cited in its class's docstring; where an equation is recalled rather
than re-read, the docstring says "(recalled)".  Where a size is our choice and not a source's,
the docstring says so.

The plant, the servo and the integration are the first half's (``bank.test_half.truths``,
imported, not copied): :func:`~bank.test_half.truths.nominal_plant` reads the constants from
the MJCF file, :func:`~bank.test_half.truths.perturbed` puts them 5-15 % off per seed, the
``Truth`` hooks (``motor``, ``dry``, ``smooth``) carry the laws that fit them, and the first
half's ``simulate`` integrates them (semi-implicit Euler at 0.1 ms, ten sub-steps per 1 ms
period, the stick rule ``_dry_step`` for dry friction).  Laws with a state of their own per
sub-step, or a friction level that depends on the angle (the ``dry`` hook sees no angle),
subclass the second half's :class:`~bank.test_half_2.truths.OwnLoop` and run in its loop.
Inside an ``OwnLoop.step`` the winding's voltage is read back from the motor hook's torque by
the third half's :func:`~bank.test_half_3.truths._volts` (0 V while torque is off: the
shorted winding of the first half's reading).  One law acts on the goal before the servo's P
law (the firmware's goal profile): :func:`simulate` here hands the profiled goal to the second
half's loop; every other truth runs in that loop unchanged.

Each truth carries ``expected``, in the physics families of :data:`FAMILIES` (the third
half's, plus the seven this half needs).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from bank.test_half import truths as tr
from bank.test_half.truths import CONTROL_PERIOD_S, H, Plant, Truth, nominal_plant, perturbed  # noqa: F401
from bank.test_half_2 import truths as tr2
from bank.test_half_2.truths import OwnLoop
from bank.test_half_3 import truths as tr3

#: The third half's families and the ones this half's laws need.
FAMILIES = tr3.FAMILIES + ("friction: position-dependent", "hysteretic stiffness", "supply sag",
                           "goal rate limit", "torque-off coast", "transmission error",
                           "sensor lag")


def _expect(family, accept=None, partial=(), unexplained_ok=False, signs=None, note=""):
    """The second half's expectation record (:func:`bank.test_half_2.truths._expect`) over this
    half's :data:`FAMILIES`."""
    return tr2._expect(family, accept, partial, unexplained_ok, signs, note, families=FAMILIES)


_sign = tr2._sign
_volts = tr3._volts


def _flow(p: Plant, theta: float, w: float, tau_m: float) -> float:
    """The torque on the rigid joint without friction: motor, bearing viscous loss, gravity."""
    return tau_m - p.bearing * w - p.mgl * math.sin(theta)


# ---------------------------------------------------------------------------------------------
# Friction laws


class GMS(OwnLoop):
    """(a) Generalized Maxwell-slip (GMS) friction, replacing the gear train's Coulomb level:
    N elastoplastic elements in parallel, each a spring that sticks until its force reaches its
    share of a Stribeck curve and then slips, following that curve.  Presliding is hysteretic
    with non-local memory (the elements saturate one after another); sliding follows the curve.

    Source: F. Al-Bender, V. Lampaert, J. Swevers, "The generalized Maxwell-slip model: a novel
    model for friction simulation and compensation", IEEE Trans. Automatic Control 50(11),
    1883-1887, 2005, and V. Lampaert, F. Al-Bender, J. Swevers, "A generalized Maxwell-slip
    friction model appropriate for control purposes", IEEE PhysCon 2003 (recalled)::

        F = sum_i F_i + sigma2 w,
        element i sticking:  dF_i/dt = k_i w,                       until F_i = alpha_i s(w) sgn(w),
        element i slipping:  dF_i/dt = sgn(w) C (1 - F_i / (alpha_i s(w) sgn(w))),
                             until the speed goes through zero,
        s(w) = Fc + (Fs - Fc) / (1 + (w/vs)^2)        (the Lorentzian curve of the GMS papers),

    ``sum alpha_i = 1``, so steady sliding gives ``F = s(w) sgn(w) + sigma2 w``.  The friction
    ``F`` opposes the joint (``J w' = ... - F``).  Sizes (ours, the second half's LuGre's
    order): Fc 0.06, Fs 0.11 N m, vs 0.04 rad/s, sigma2 0.02 N m s/rad; three elements, alpha
    (0.5, 0.3, 0.2), k (110, 33, 11) N m/rad, so they break away at 0.5, 1.0 and 2.0 mrad of
    travel (one encoder count is 1.5 mrad); C 20 N m/s, so a slipping element follows the curve
    with a time constant alpha_i s / C of 0.6-2.8 ms.  Integration: the speed is advanced with F at the
    sub-step's start, then each element over the sub-step at the new speed (:meth:`element`: a
    sticking element by ``k_i h w``, capped where it breaks away; a slipping one exactly,
    ``F_i <- T + (F_i - T) exp(-C h / |T|)``, ``T = alpha_i s(w) sgn(w)``).  The elements'
    forces carry over from run to run (the pendulum rests between them).
    """

    name = "gms"
    title = "generalized Maxwell-slip friction: 3 elements, Lorentzian Stribeck curve"
    source = ("Al-Bender, Lampaert, Swevers, IEEE TAC 50(11) 2005; Lampaert, Al-Bender, Swevers, "
              "PhysCon 2003 (recalled)")
    equation = ("F = sum F_i + sigma2 w; stick: dF_i/dt = k_i w until F_i = alpha_i s(w) sgn w; "
                "slip: dF_i/dt = sgn(w) C (1 - F_i/(alpha_i s(w) sgn w)); "
                "s(w) = Fc + (Fs - Fc)/(1 + (w/vs)^2)")

    def defaults(self):
        return {"Fc": 0.06, "Fs": 0.11, "vs": 0.04, "sigma2": 0.02, "alpha": [0.5, 0.3, 0.2],
                "k": [110.0, 33.0, 11.0], "C": 20.0}

    def initial_state(self):
        n = len(self.params["k"])
        return {"F": [0.0] * n, "slip": [0.0] * n}

    def s(self, w: float) -> float:
        """The Stribeck curve's magnitude at speed ``w``."""
        q = self.params
        return q["Fc"] + (q["Fs"] - q["Fc"]) / (1.0 + (w / q["vs"]) ** 2)

    def element(self, f: float, slip: float, w: float, k: float, alpha: float) -> tuple[float, float]:
        """One element after a sub-step at the (constant) speed ``w``: its force and its state
        (0 sticking, +-1 slipping in that direction)."""
        if slip and _sign(w) != slip:          # the speed went through zero: it sticks
            slip = 0.0
        if not slip:
            f += k * H * w
            cap = alpha * self.s(w)
            if w != 0.0 and f * _sign(w) >= cap:
                return cap * _sign(w), _sign(w)
            return f, 0.0
        target = alpha * self.s(w) * slip
        return target + (f - target) * math.exp(-self.params["C"] * H / abs(target)), slip

    def step(self, theta, w, tau_m, state):
        p, q = self.p, self.params
        tau = _flow(p, theta, w, tau_m) - sum(state["F"]) - q["sigma2"] * w
        w = w + H * tau / p.inertia
        for i, (k, a) in enumerate(zip(q["k"], q["alpha"])):
            state["F"][i], state["slip"][i] = self.element(state["F"][i], state["slip"][i], w, k, a)
        return w

    def expected(self):
        return _expect("friction: dynamic", accept=["friction: dynamic", "friction: stribeck"],
                       partial=["friction: coulomb", "friction: viscous"],
                       signs={"static_above_kinetic": True, "coulomb_level_nm": self.params["Fc"]},
                       note="Fs 0.11 > Fc 0.06 N m (nominal Coulomb 0.03), presliding over "
                            "0.5-2 mrad in three elements, extra viscous 0.02")


class DwellStiction(OwnLoop):
    """(b) Armstrong's seven-parameter friction without its presliding spring: a Lorentzian
    Stribeck curve whose static level rises with the time the joint has rested (dwell), and
    whose speed is read with a lag (frictional memory).  It replaces the gear train's Coulomb
    level.

    Source: B. Armstrong-Helouvry, P. Dupont, C. Canudas de Wit, "A survey of models, analysis
    tools and compensation methods for the control of machines with friction", Automatica
    30(7), 1083-1138, 1994, the seven-parameter model (recalled), after Armstrong-Helouvry,
    *Control of Machines with Friction*, Kluwer 1991; rising static friction after Kato, Sato,
    Matsubayashi, ASME J. Lubr. Technol. 94, 1972, and the frictional lag of Hess & Soom, ASME
    J. Tribology 112, 1990 (both recalled)::

        F = [Fc + Fs(t2) / (1 + (w(t - tau_L) / vs)^2)] sgn(w) + Fv w        (sliding),
        Fs(t2) = Fs_a + (Fs_inf - Fs_a) t2 / (t2 + gamma),                    t2 the dwell,
        |F| <= Fc + Fs(t2) at rest (the stick rule, in place of the model's presliding spring),

    ``Fs`` the Stribeck *excess* over Coulomb, fixed at its value when the joint breaks away
    and used for the whole slide.  Sizes (ours, the earlier Stribeck cases' order): Fc 0.05,
    Fs_a 0.02, Fs_inf 0.10 N m (static 0.07 N m just after a reversal, 0.15 N m after a long
    rest), gamma 0.4 s (a dwell of 0.4 s gives half the rise; Armstrong-Helouvry reports rises
    over fractions of a second to seconds, recalled), vs 0.03 rad/s, tau_L 10 ms (Hess & Soom
    measured lags of a few ms, recalled), Fv 0.02 N m s/rad.  The first run starts after a rest
    of 5 s (as between runs, make's ``REST_S``); the dwell carries over from run to run.
    """

    name = "dwell_stiction"
    title = "rising static friction with dwell time, Lorentzian Stribeck curve, 10 ms memory"
    source = ("Armstrong-Helouvry, Dupont, Canudas de Wit, Automatica 30(7) 1994 (seven-parameter "
              "model); Kato et al. 1972; Hess & Soom 1990 (recalled)")
    equation = ("F = [Fc + Fs(t2)/(1 + (w(t - tau_L)/vs)^2)] sgn w + Fv w; "
                "Fs(t2) = Fs_a + (Fs_inf - Fs_a) t2/(t2 + gamma); |F| <= Fc + Fs(t2) at rest")

    def defaults(self):
        return {"Fc": 0.05, "Fs_a": 0.02, "Fs_inf": 0.10, "gamma": 0.4, "vs": 0.03,
                "tau_L": 0.01, "Fv": 0.02, "dwell0": 5.0}

    def lag_steps(self) -> int:
        return int(round(self.params["tau_L"] / H))

    def initial_state(self):
        n = self.lag_steps()
        return {"dwell": self.params["dwell0"], "fs": self.excess(self.params["dwell0"]),
                "hist": deque([0.0] * n, maxlen=n)}

    def excess(self, dwell: float) -> float:
        """The Stribeck excess after a rest of ``dwell`` seconds."""
        q = self.params
        return q["Fs_a"] + (q["Fs_inf"] - q["Fs_a"]) * dwell / (dwell + q["gamma"])

    def sliding_level(self, w_lagged: float, fs: float) -> float:
        q = self.params
        return q["Fc"] + fs / (1.0 + (w_lagged / q["vs"]) ** 2)

    def step(self, theta, w, tau_m, state):
        p, q = self.p, self.params
        fs = self.excess(state["dwell"]) if w == 0.0 else state["fs"]
        w_lag = state["hist"][0] if state["hist"] else w
        static = q["Fc"] + fs
        slide = self.sliding_level(w_lag, fs)
        tau = _flow(p, theta, w, tau_m) - q["Fv"] * w
        w_new = tr._dry_step(w + H * tau / p.inertia, p.inertia, (static, static, slide, slide))
        if w_new == 0.0:
            state["dwell"] += H
        else:
            if w == 0.0:                  # breakaway: the excess of this dwell, for the slide
                state["fs"] = fs
            state["dwell"] = 0.0
        if state["hist"].maxlen:
            state["hist"].append(w_new)
        return w_new

    def rest(self, seconds, state):
        state["dwell"] += seconds
        state["hist"].extend([0.0] * self.lag_steps())

    def expected(self):
        return _expect("friction: stribeck", accept=["friction: stribeck", "friction: dynamic"],
                       partial=["friction: coulomb", "friction: viscous"], unexplained_ok=True,
                       signs={"static_above_kinetic": True},
                       note="static 0.07-0.15 N m by the dwell, kinetic 0.05 (nominal Coulomb "
                            "0.03); a Stribeck or dynamic friction with Fs > Fc is right, and so "
                            "is a flag (a dwell-dependent level may be beyond the library)")


class PinionFriction(OwnLoop):
    """(c) Coulomb friction whose level depends on the angle: the last stage's pinion runs
    eccentric, so the mesh's friction rises and falls once per pinion turn, three times per
    output turn.

    Source: position-dependent friction measured on robot joints by Armstrong-Helouvry,
    *Control of Machines with Friction*, Kluwer 1991 (the PUMA 560's joints; recalled); the
    form, one harmonic of the pinion's rotation, is ours::

        Fc(theta) = Fc0 (1 + a cos(n theta + phi)),   |F| <= Fc(theta) at rest (stick rule),

    replacing the gear train's Coulomb level.  n = 3: a 16-tooth pinion driving the 48-tooth
    output gear (the same gear as case (h); tooth counts ours); Fc0 0.06 N m, a 0.6 (0.024 to
    0.096 N m), phi 0.5 rad (ours).
    """

    name = "pinion_friction"
    title = "Coulomb friction 0.06 (1 + 0.6 cos(3 theta + 0.5)) N m (eccentric pinion)"
    source = ("Armstrong-Helouvry, Control of Machines with Friction, 1991 (position-dependent "
              "friction; recalled); one harmonic of the pinion's turn (ours)")
    equation = "Fc(theta) = Fc0 (1 + a cos(n theta + phi)); Fc0 0.06 N m, a 0.6, n 3, phi 0.5"

    def defaults(self):
        return {"Fc0": 0.06, "a": 0.6, "n": 3, "phi": 0.5}

    def level(self, theta: float) -> float:
        q = self.params
        return q["Fc0"] * (1.0 + q["a"] * math.cos(q["n"] * theta + q["phi"]))

    def step(self, theta, w, tau_m, state):
        p = self.p
        f = self.level(theta)
        return tr._dry_step(w + H * _flow(p, theta, w, tau_m) / p.inertia, p.inertia, (f, f, f, f))

    def expected(self):
        return _expect("friction: position-dependent", accept=["friction: position-dependent"],
                       partial=["friction: coulomb", "cogging", "gravity offset"],
                       unexplained_ok=True, signs={"ripple_order": self.params["n"]},
                       note="a Coulomb level from 0.024 to 0.096 N m, three periods per turn; a "
                            "constant level takes its mean only")


class CableHysteresis(OwnLoop):
    """(d) A cable harness across the pivot (the lead of a sensor on the bob): a spring with
    hysteresis, written as a Bouc-Wen element.

    Source: R. Bouc, "Forced vibration of mechanical systems with hysteresis", Proc. 4th Conf.
    Nonlinear Oscillations, Prague 1967; Y.-K. Wen, "Method for random vibration of hysteretic
    systems", ASCE J. Eng. Mech. Div. 102(2), 249-263, 1976; in the form of M. Ismail,
    F. Ikhouane, J. Rodellar, "The hysteresis Bouc-Wen model, a survey", Arch. Comput. Methods
    Eng. 16, 161-188, 2009 (recalled)::

        tau_c = -k [alpha (theta - theta_c) + (1 - alpha) z],
        dz/dt = A w - beta |w| |z|^(n-1) z - gamma w |z|^n,

    n = 1, so in the travelled angle ``dz/dtheta = A - (beta sgn(dtheta) + gamma sgn(z)) z``,
    piecewise linear, integrated exactly over each sub-step's travel (:meth:`advance`, through
    z = 0 where it crosses); ``z`` saturates at ``A/(beta + gamma)``.  Sizes (ours): k 1.2 N m/rad,
    alpha 0.25 (an elastic 0.3 N m/rad about theta_c 0.3 rad, where the cable hangs slack), A 1,
    beta 15, gamma 5 (z up to 0.05 rad: a hysteretic torque of +-0.045 N m, approached with
    an e-fold of 1/(beta + gamma) = 0.05 rad of travel).  On top of the gear train's Coulomb level (stick rule); z carries
    over from run to run.
    """

    name = "cable_hysteresis"
    title = "cable harness: Bouc-Wen spring, 0.3 N m/rad elastic + 0.045 N m hysteretic"
    source = ("Bouc 1967; Wen, ASCE J. Eng. Mech. Div. 102(2) 1976; Ismail, Ikhouane, Rodellar, "
              "Arch. Comput. Methods Eng. 16 2009 (recalled)")
    equation = ("tau_c = -k [alpha (theta - theta_c) + (1 - alpha) z]; dz/dt = A w - beta |w| z - "
                "gamma w |z| (n = 1)")

    def defaults(self):
        return {"k": 1.2, "alpha": 0.25, "theta_c": 0.3, "A": 1.0, "beta": 15.0, "gamma": 5.0}

    def initial_state(self):
        return {"z": 0.0}

    def torque(self, theta: float, z: float) -> float:
        q = self.params
        return -q["k"] * (q["alpha"] * (theta - q["theta_c"]) + (1.0 - q["alpha"]) * z)

    def advance(self, z: float, dx: float) -> float:
        """``z`` after a travel ``dx`` of one sign (exact; needs beta > gamma)."""
        if dx == 0.0:
            return z
        q = self.params
        a, s = q["A"], _sign(dx)
        if z * s < 0:                    # moving back towards z = 0: kappa = s (beta - gamma)
            kap = s * (q["beta"] - q["gamma"])
            to_zero = math.log((a / kap - z) / (a / kap)) / kap
            if abs(dx) < abs(to_zero):
                return a / kap + (z - a / kap) * math.exp(-kap * dx)
            dx, z = dx - to_zero, 0.0
        kap = s * (q["beta"] + q["gamma"])
        return a / kap + (z - a / kap) * math.exp(-kap * dx)

    def step(self, theta, w, tau_m, state):
        p = self.p
        tau = _flow(p, theta, w, tau_m) + self.torque(theta, state["z"])
        w = tr._dry_step(w + H * tau / p.inertia, p.inertia, self.dry(w, tau_m, state))
        state["z"] = self.advance(state["z"], H * w)
        return w

    def expected(self):
        q = self.params
        return _expect("hysteretic stiffness", accept=["hysteretic stiffness", "joint stiffness"],
                       partial=["friction: dynamic", "friction: coulomb", "gravity offset",
                                "torque bias", "position offset"],
                       unexplained_ok=True,
                       signs={"stiffness_nm_per_rad": q["alpha"] * q["k"]},
                       note="a spring 0.3 N m/rad about 0.3 rad with a hysteretic +-0.045 N m; a "
                            "joint stiffness takes the spring, a presliding friction the loop")


# ---------------------------------------------------------------------------------------------
# Actuator, transmission and sensor laws


class SupplySag(Truth):
    """(e) The supply sags with the current the servo draws: a source resistance in front of
    the PWM bridge.

    Source: the averaged model of a PWM-driven DC motor (N. Mohan, T. Undeland, W. Robbins,
    *Power Electronics*, the DC-DC converter's averaged switch: ``v = d V_bus``, ``i_bus = d i``;
    recalled) and a source with an internal resistance (Thevenin)::

        V_bus = V0 - Rs i_bus,  v = d V_bus,  i_bus = d i,  v = R i + kt w,   d = u / V0,
        so  i = (u - kt w) / (R + Rs d^2)  and  tau_m = (kt/R)(u - kt w) / (1 + (Rs/R) d^2).

    The torque per volt and the back-EMF's damping both fall by ``1/(1 + (Rs/R) d^2)``: little
    at the holding duty (d 0.1-0.2: 0.5-2 %), by a third at full duty.  Rs 2 ohm (an estimate: an unregulated
    plug-in adapter's internal resistance, a few ohms for a 1 A adapter that reads 16 V open and
    12 V at 1 A (recalled), with a thin daisy-chain lead); V0 the 12 V supply.
    Torque off (d = 0): the shorted winding, ``-kt^2/R w``, as in the first half.
    """

    name = "supply_sag"
    title = "supply sag: source resistance 2 ohm before the PWM bridge"
    source = ("averaged PWM bridge (Mohan, Undeland, Robbins, Power Electronics; recalled) fed by "
              "a Thevenin source")
    equation = "tau_m = (kt/R)(u - kt w) / (1 + (Rs/R) d^2), d = u/V0; Rs 2 ohm, V0 12 V"

    def defaults(self):
        return {"Rs": 2.0}

    def factor(self, u: float) -> float:
        """``1/(1 + (Rs/R) d^2)``: the share of the nominal's torque at command ``u``."""
        d = u / self.p.supply
        return 1.0 / (1.0 + self.params["Rs"] / self.p.resistance * d * d)

    def motor(self, u, w, enabled):
        if not enabled:
            return -self.p.emf * w
        return (self.p.gear * u - self.p.emf * w) * self.factor(u)

    def expected(self):
        return _expect("supply sag", accept=["supply sag"],
                       partial=["torque saturation", "torque gain", "friction: viscous"],
                       unexplained_ok=True, signs={"source_resistance_ohm": self.params["Rs"]},
                       note="torque per volt and back-EMF damping fall together with the duty's "
                            "square, by a third at full duty")


class GoalProfile(Truth):
    """(f) The servo's firmware profiles the goal: the goal its P law tracks moves towards the
    host's goal at no more than a profile velocity.

    Source: the "Profile Velocity" register of ROBOTIS Dynamixel X-series servos (with "Profile
    Acceleration" 0 the velocity profile is rectangular: the goal moves at the profile velocity
    until it is reached; ROBOTIS e-Manual, recalled)::

        r_s[k] = r_s[k-1] + clip(r[k] - r_s[k-1], -v_max T, v_max T),   r_s[-1] = theta0,

    each 1 ms period ``T``; the P law is ``clip(kp (r_s - y), +-limit)``.  The host logs its own
    goal ``r`` and the command the servo applied.  v_max 6 rad/s (57 rpm, 250 units of
    0.229 rpm; ours): the steps and the staircase are slowed, and the 2.5 Hz, 0.4 rad sine (6.3
    rad/s at its peak) at its fastest; the slower runs are not.
    """

    name = "goal_profile"
    title = "firmware goal profile: the goal moves at most 6 rad/s"
    source = "ROBOTIS Dynamixel X e-Manual, Profile Velocity register (rectangular profile; recalled)"
    equation = "r_s[k] = r_s[k-1] + clip(r[k] - r_s[k-1], +-v_max T); u = clip(kp (r_s - y)); v_max 6 rad/s"

    def defaults(self):
        return {"v_max": 6.0}

    def profile(self, goal: np.ndarray, theta0: float) -> np.ndarray:
        """The goal the P law tracks, one entry per 1 ms period."""
        step = self.params["v_max"] * CONTROL_PERIOD_S
        out = np.empty(len(goal))
        prev = float(theta0)
        for k, g in enumerate(goal):
            g = float(g)
            prev = g if abs(g - prev) <= step else prev + math.copysign(step, g - prev)
            out[k] = prev
        return out

    def expected(self):
        return _expect("goal rate limit", accept=["goal rate limit"],
                       partial=["time delay", "actuator lag", "torque saturation"],
                       unexplained_ok=True, signs={"rate_limit_rad_s": self.params["v_max"]},
                       note="the goal slewed at 6 rad/s inside the servo: the logged goal is not "
                            "the one tracked")


class CoastOff(Truth):
    """(g) Torque off opens the bridge: the winding coasts instead of being shorted.

    Source: the DC motor with an open winding carries no current, so no torque and no back-EMF
    braking (the servo page's "Torque off" section, ``docs/method/servo-actuators.md``: "a servo
    whose torque is disabled usually opens its bridge ... the joint coasts"; the motor
    equation ``tau = (kt/R) u - (kt^2/R) w`` holds only while the bridge closes the winding)::

        tau_m = (kt/R) u - (kt^2/R) w   torque on,
        tau_m = 0                        torque off (open winding),

    where the nominal file's back-EMF is joint damping, on in both states (the first half's
    shorted reading).  Only the lift-and-drop run turns the torque off (from 3 s, the pendulum at
    -1 rad): it then swings on the bearing's 0.01 N m s/rad and the gear train's Coulomb level,
    where a shorted winding lets it creep down.
    """

    name = "coast_off"
    title = "torque off opens the winding: the pendulum coasts (no back-EMF braking)"
    source = ("DC motor with an open winding; docs/method/servo-actuators.md, Torque off (a "
              "disabled servo coasts)")
    equation = "tau_m = (kt/R) u - (kt^2/R) w with torque on; tau_m = 0 with torque off"

    def motor(self, u, w, enabled):
        if not enabled:
            return 0.0
        return self.p.gear * u - self.p.emf * w

    def expected(self):
        return _expect("torque-off coast", accept=["torque-off coast"],
                       partial=["friction: viscous", "friction: coulomb"], unexplained_ok=True,
                       note="with torque off the back-EMF's 0.36 N m s/rad is gone: the "
                            "dropped pendulum swings instead of creeping down")


class TransmissionError(OwnLoop):
    """(h) The output gear's kinematic transmission error: the output turns with the motor
    through a ratio that ripples at the tooth-passing frequency.

    Source: the transmission error of a gear pair, ``TE = theta_out - theta_in / N`` (D. B.
    Welbourn, "Fundamental knowledge of gear noise -- a survey", IMechE Conf. Noise and Vibration
    of Engines and Transmissions, 1979; J. D. Smith, *Gear Noise and Vibration*, Dekker 2003;
    recalled), one harmonic at the mesh frequency.  At the output's angle scale the motor
    (rotor) angle is ``phi = theta - eps sin(n theta + psi)``, so the ratio ``r = dphi/dtheta =
    1 - eps n cos(n theta + psi)`` and, by Lagrange's equation with the rotor's reflected
    inertia ``J_a``::

        (J_l + J_a r^2) w' + J_a r r' w^2 = r tau_m(u, r w) - b w - m g l sin(theta) - F_c,
        r' = eps n^2 sin(n theta + psi),

    ``tau_m(u, w_m) = (kt/R) u - (kt^2/R) w_m`` the motor at the rotor's speed; bearing loss
    and Coulomb friction at the output (stick rule).  n 48 (the output gear's teeth, as in case
    (c); ours), eps 3 mrad (30 um at a 10 mm pitch radius: a moulded plastic gear's error,
    estimate), psi 0.4 rad (ours): the ratio ripples by +-14.4 %.
    """

    name = "transmission_error"
    title = "kinematic transmission error 3 mrad at 48 per turn: ratio ripple +-14.4 %"
    source = ("gear transmission error (Welbourn 1979; Smith, Gear Noise and Vibration, 2003; "
              "recalled); Lagrange's equation with a position-dependent ratio")
    equation = ("(J_l + J_a r^2) w' + J_a r r' w^2 = r tau_m(u, r w) - b w - mgl sin(theta) - Fc sgn w; "
                "r = 1 - eps n cos(n theta + psi)")

    def defaults(self):
        return {"eps": 3e-3, "n": 48, "psi": 0.4}

    def ratio(self, theta: float) -> tuple[float, float]:
        """``(r, dr/dtheta)`` at the output angle ``theta``."""
        q = self.params
        x = q["n"] * theta + q["psi"]
        return 1.0 - q["eps"] * q["n"] * math.cos(x), q["eps"] * q["n"] ** 2 * math.sin(x)

    def step(self, theta, w, tau_m, state):
        p = self.p
        r, dr = self.ratio(theta)
        tau_rotor = p.gear * _volts(p, tau_m, w) - p.emf * r * w
        inertia = p.j_link + p.armature * r * r
        tau = (r * tau_rotor - p.armature * r * dr * w * w - p.bearing * w
               - p.mgl * math.sin(theta))
        return tr._dry_step(w + H * tau / inertia, inertia, self.dry(w, tau_rotor, state))

    def expected(self):
        return _expect("transmission error", accept=["transmission error"],
                       partial=["cogging", "torque gain", "inertia"], unexplained_ok=True,
                       signs={"ripple_order": self.params["n"]},
                       note="the ratio ripples +-14.4 % at 48 per turn: a ripple of the motor's "
                            "torque, not a fixed cogging torque")


class EncoderFilter(OwnLoop):
    """(i) The angle reading passes an RC low-pass before the ADC: the P law closes on, and the
    host logs, a lagged angle.

    Source: a first-order RC low-pass, ``tau_s y' = theta - y`` (P. Horowitz, W. Hill, *The
    Art of Electronics*, ch. 1; recalled), as an anti-aliasing filter on a servo's position
    potentiometer; R 10 kOhm, C 1 uF (ours), tau_s = R C = 10 ms.  The filtered reading is
    then rounded to 4096 counts per turn (a 12-bit ADC).  Integrated in the loop's angle
    variable (as the third half's eccentric encoder): the loop's ``theta`` is the reading ``y``;
    the true angle and speed are a state (``state["theta"]``, ``state["w"]``); each sub-step
    advances the true joint, then ``y`` exactly for the true angle's ramp over the sub-step::

        y <- theta1 - w tau_s (1 - e) + (y - theta0) e,   e = exp(-h / tau_s),

    and returns the reading's rate.  Each run starts at rest with the reading equal to the angle.
    """

    name = "encoder_filter"
    title = "RC low-pass on the angle reading: tau_s = 10 ms"
    source = "first-order RC low-pass (Horowitz & Hill, The Art of Electronics; recalled)"
    equation = "tau_s y' = theta - y, y rounded to 4096 counts/rev; tau_s = RC = 10 ms"

    def defaults(self):
        return {"tau_s": 1e-2}

    def initial_state(self):
        return {"theta": None, "w": 0.0}

    def rest(self, seconds, state):
        state["theta"], state["w"] = None, 0.0

    def step(self, theta, w, tau_m, state):
        p = self.p
        if state["theta"] is None:          # a run's start: at rest, the reading is the angle
            state["theta"] = theta
        th, wt = state["theta"], state["w"]
        tau_d = p.gear * _volts(p, tau_m, w) - p.emf * wt
        wt = tr._dry_step(wt + H * _flow(p, th, wt, tau_d) / p.inertia, p.inertia,
                          self.dry(wt, tau_d, state))
        th1 = th + H * wt
        e = math.exp(-H / self.params["tau_s"])
        y1 = th1 - wt * self.params["tau_s"] * (1.0 - e) + (theta - th) * e
        state["theta"], state["w"] = th1, wt
        return (y1 - theta) / H

    def expected(self):
        return _expect("sensor lag", accept=["sensor lag"],
                       partial=["time delay", "actuator lag", "sensor error"], unexplained_ok=True,
                       signs={"time_constant_s": self.params["tau_s"]},
                       note="the reading lags the angle by 10 ms (first order); the torque does "
                            "not")


class Null(tr.Null):
    """(j) Nothing missing: the nominal's own laws with its constants 5-15 % off (seed 45; the
    first half's null case, ``bank.test_half.truths.Null``)."""


#: The cases of the fourth test half, in order: (name, class).
CASES = (("a_gms", GMS), ("b_dwell_stiction", DwellStiction), ("c_pinion_friction", PinionFriction),
         ("d_cable_hysteresis", CableHysteresis), ("e_supply_sag", SupplySag),
         ("f_goal_profile", GoalProfile), ("g_coast_off", CoastOff),
         ("h_transmission_error", TransmissionError), ("i_encoder_filter", EncoderFilter),
         ("j_null", Null))


def simulate(truth: Truth, goal: np.ndarray, enabled: np.ndarray, kp: float,
             command_limit: float, theta0: float, state: dict) -> tuple[np.ndarray, np.ndarray]:
    """The servo's P loop on the truth (the first half's signature and returns): the second
    half's loop (:func:`bank.test_half_2.truths.simulate`), on the goal the firmware profiles
    (:meth:`GoalProfile.profile`) for the goal-profile case, on ``goal`` for every other."""
    if isinstance(truth, GoalProfile):
        goal = truth.profile(goal, theta0)
    return tr2.simulate(truth, goal, enabled, kp, command_limit, theta0, state)
