"""The bank's fourth test half (bank/test_half_4): each truth's law against an independent check
(closed forms, scipy roots, scipy's ODE solvers on the law's own equations, limit cases where
the law becomes the first half's loop), the null case against the first half's loop, make.py's
determinism and the dataset contract, and score.py's extensions.

As in the earlier halves' tests: a constant command ``u`` is had by a huge gain clipped at
``command_limit = u`` with a goal far away; "flat" plants have ``mgl = 0``.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, fsolve

from bank.test_half import make as make1
from bank.test_half import truths as tr
from bank.test_half_2 import truths as tr2
from bank.test_half_3 import truths as tr3
from bank.test_half_4 import make, score
from bank.test_half_4 import truths as tr4
from tests import half_loops as loops
from tests import half_make

PLANT = tr.nominal_plant()
FLAT = replace(PLANT, mgl=0.0)
G, EMF, B, FC, J = PLANT.gear, PLANT.emf, PLANT.bearing, PLANT.coulomb, PLANT.inertia


def _constant(truth, u, seconds, theta0=0.0, sign=1.0, state=None):
    return loops.constant(tr4.simulate, truth, u, seconds, theta0, sign, state)


def _torque_off(truth, seconds, theta0, state=None):
    return loops.torque_off(tr4.simulate, truth, seconds, theta0, state)


_end_speed = loops.end_speed


def _campaign_run(index, seconds=6.0):
    """The goal and torque-on flag of one of the campaign's runs, per 1 ms period."""
    e = make1.campaign(seconds)[index]
    t = np.arange(int(round(seconds / tr.CONTROL_PERIOD_S))) * tr.CONTROL_PERIOD_S
    en = np.ones(len(t)) if e["off_s"] is None else (t < e["off_s"]).astype(float)
    return np.asarray(e["ref"](t), dtype=float), en


def _both(truth, run, seconds=2.0, state=None):
    """A campaign run on ``truth`` (this half's loop) and on the first half's null truth of the
    same plant (the first half's loop)."""
    goal, en = _campaign_run(run, seconds)
    state = truth.initial_state() if state is None else state
    a = tr4.simulate(truth, goal, en, 30.0, 12.0, float(goal[0]), state)
    b = tr.simulate(tr.Null(truth.p), goal, en, 30.0, 12.0, float(goal[0]), {})
    return a, b


def test_cases_are_new_and_documented():
    """Ten cases, a null among them; each expectation in known families, each law cited with
    its equation; no law's name is one of the earlier halves'."""
    assert len(tr4.CASES) == 10 and [n[0] for n, _ in tr4.CASES] == list("abcdefghij")
    earlier = {cls.name for _, cls in tr.CASES + tr2.CASES + tr3.CASES}
    for name, cls in tr4.CASES:
        truth = cls(PLANT)
        e = truth.expected()
        assert e["family"] in tr4.FAMILIES and set(e["accept"]) | set(e["partial"]) <= set(tr4.FAMILIES)
        assert truth.source and truth.equation and cls.__doc__, name
        assert truth.name not in earlier or name == "j_null", name
        json.dumps(truth.describe(), allow_nan=False)
    assert tr4.Null(PLANT).expected()["family"] == "none"
    assert set(tr3.FAMILIES) < set(tr4.FAMILIES)


def test_null_is_the_first_halfs_loop():
    """The null case runs the first half's loop bit for bit (a square wave with gravity and the
    torque-off run), and so do the supply sag without a source resistance, the coast law and
    the goal profile on runs that never exceed their limits, and the cable with no stiffness."""
    plant, _ = tr.perturbed(PLANT, 45 * 100 + 9)
    for run in (6, 11):
        (a, ua), (b, ub) = _both(tr4.Null(plant), run)
        assert np.array_equal(a, b) and np.array_equal(ua, ub)
        assert np.ptp(a) > 0.3
        (a, ua), (b, ub) = _both(tr4.SupplySag(plant, Rs=0.0), run)
        assert np.array_equal(a, b) and np.array_equal(ua, ub)
        (a, ua), (b, ub) = _both(tr4.CableHysteresis(plant, k=0.0), run)
        assert np.array_equal(a, b) and np.array_equal(ua, ub)
    (a, ua), (b, ub) = _both(tr4.CoastOff(plant), 6)            # torque on all along
    assert np.array_equal(a, b) and np.array_equal(ua, ub)
    (a, ua), (b, ub) = _both(tr4.GoalProfile(plant), 0)         # 0.5 Hz, 0.15 rad: 0.47 rad/s
    assert np.array_equal(a, b) and np.array_equal(ua, ub)


# --- (a) GMS ----------------------------------------------------------------------------------

def _gms_curve(w):
    return 0.06 + (0.11 - 0.06) / (1 + (w / 0.04) ** 2)


def test_gms_steady_sliding_is_its_curve():
    """Flat plant, every element slipping: G u = (kt^2/R + b + sigma2) w + s(w), s the
    Lorentzian curve (scipy root), either way, at two speeds."""
    truth = tr4.GMS(FLAT)
    for u in (0.6, 4.0):
        w_star = brentq(lambda w: G * u - (EMF + B + 0.02) * w - _gms_curve(w), 1e-6, 20.0)
        for sign in (1.0, -1.0):
            state = truth.initial_state()
            theta = _constant(truth, u, 1.0, sign=sign, state=state)
            assert _end_speed(theta) == pytest.approx(sign * w_star, rel=1e-3)
            assert state["slip"] == [sign] * 3
            assert sum(state["F"]) == pytest.approx(sign * _gms_curve(w_star), rel=1e-3)


def test_gms_presliding_is_a_spring_below_breakaway():
    """Flat plant, 0.02 N m from rest: no element reaches its share of the curve (the first
    breaks away at 0.5 mrad), so the friction is the springs' sum K x, K = 154 N m/rad: the
    truth's angle against scipy on J x'' = tau - (kt^2/R + b + sigma2) x' - K x, and its rest at
    tau / K."""
    truth = tr4.GMS(FLAT)
    tau, k = 0.02, 110.0 + 33.0 + 11.0
    state = truth.initial_state()
    theta = _constant(truth, tau / G, 1.5, state=state)
    assert state["slip"] == [0.0] * 3 and theta.max() < 0.5e-3
    c = EMF + B + 0.02
    t = np.arange(len(theta)) * tr.H
    sol = solve_ivp(lambda s, x: [x[1], (tau - c * x[1] - k * x[0]) / J], (0, t[-1]), [0, 0],
                    t_eval=t[::20], rtol=1e-10, atol=1e-14)
    err = np.abs(theta[::20] - sol.y[0]).max()
    assert err < 5e-3 * np.ptp(sol.y[0]), err
    assert theta[-1] == pytest.approx(tau / k, rel=1e-6)


def test_gms_element_slips_on_its_ode_and_sticks_back():
    """One element (alpha 0.5, k 110) driven by a prescribed falling speed while slipping: its
    force against scipy on dF/dt = C (1 - F / (alpha s(w(t)))); then the speed reverses and it
    sticks, unloading along its spring (F = F0 - k x) until it slips the other way at
    -alpha s(w)."""
    truth = tr4.GMS(FLAT)
    alpha, k, c = 0.5, 110.0, 20.0
    w_of = (lambda t: 0.2 * math.exp(-t / 0.05))
    f, slip = alpha * _gms_curve(0.2), 1.0
    n = 1000
    for i in range(n):
        f, slip = truth.element(f, slip, w_of((i + 1) * tr.H), k, alpha)
    sol = solve_ivp(lambda t, y: [c * (1 - y[0] / (alpha * _gms_curve(w_of(t))))], (0, n * tr.H),
                    [alpha * _gms_curve(0.2)], rtol=1e-10, atol=1e-14)
    assert slip == 1.0 and f == pytest.approx(sol.y[0, -1], rel=2e-3)
    assert f > alpha * _gms_curve(0.2) + 5e-3               # it rose along the curve
    f0, x = f, 0.0
    while slip >= 0.0:
        f, slip = truth.element(f, slip, -0.01, k, alpha)
        x += 0.01 * tr.H
        if slip == 0.0:
            assert f == pytest.approx(f0 - k * x, rel=1e-9)
    assert f == pytest.approx(-alpha * _gms_curve(-0.01)) and x == pytest.approx(
        (f0 + alpha * _gms_curve(0.01)) / k, abs=0.01 * tr.H)


# --- (b) dwell-time stiction ------------------------------------------------------------------

def _excess(t2):
    return 0.02 + (0.10 - 0.02) * t2 / (t2 + 0.4)


def test_dwell_holds_by_its_rest_and_breaks_away_lower_under_a_faster_ramp():
    """Flat plant.  0.11 N m applied after a rest t2: it holds when Fc + Fs(t2) >= 0.11, i.e.
    t2 >= gamma (tau - Fc - Fs_a) / (Fc + Fs_inf - tau) = 0.4 s (closed form), and slides at once
    after a shorter rest.  A torque ramped at rho from a fresh stop breaks it away where
    rho t = Fc + Fs(t) (scipy root): at a lower torque under the faster ramp (the rate effect
    of rising static friction)."""
    truth = tr4.DwellStiction(FLAT)
    t_star = 0.4 * (0.11 - 0.05 - 0.02) / (0.05 + 0.10 - 0.11)
    assert t_star == pytest.approx(0.4)
    held = _constant(truth, 0.11 / G, 0.3, state=dict(truth.initial_state(), dwell=1.02 * t_star))
    slid = _constant(truth, 0.11 / G, 0.3, state=dict(truth.initial_state(), dwell=0.98 * t_star))
    assert np.ptp(held) == 0.0 and slid[1] > 0.0
    levels = []
    for rho in (0.2, 1.0):
        n = 1000
        goal = rho * np.arange(n) * tr.CONTROL_PERIOD_S / (G * 30.0)
        state = dict(truth.initial_state(), dwell=0.0)
        theta, _ = tr4.simulate(truth, goal, np.ones(n), 30.0, 12.0, 0.0, state)
        t_r = brentq(lambda t: rho * t - 0.05 - _excess(t), 1e-6, 2.0)
        first = (np.flatnonzero(theta)[0] - 1) * tr.H
        assert t_r <= first <= t_r + tr.CONTROL_PERIOD_S + 2 * tr.H, (first, t_r)
        assert state["fs"] == pytest.approx(_excess(t_r), abs=1e-3)
        levels.append(rho * t_r)
    assert levels[0] > levels[1] + 0.02


def test_dwell_memory_and_steady_slide():
    """Flat plant after a 5 s rest, 0.25 N m: for the first tau_L = 10 ms of the slide the lagged
    speed is 0, so the friction stays at its static level Fc + Fs(5 s) (the closed form of
    J w' = tau - F - c w); without the memory (tau_L 0) it falls sooner and the joint is ahead;
    the steady speed solves G u = c w + Fc + Fs(5 s) / (1 + (w/vs)^2) (scipy root) with either."""
    u = 0.25 / G
    c = EMF + B + 0.02
    f = 0.05 + _excess(5.0)
    a = c / J
    t = 0.01
    closed = (0.25 - f) / c * (t - (1 - math.exp(-a * t)) / a)
    lag = _constant(tr4.DwellStiction(FLAT), u, 1.0)
    none = _constant(tr4.DwellStiction(FLAT, tau_L=0.0), u, 1.0)
    assert lag[100] == pytest.approx(closed, rel=2e-2)
    assert none[150] > lag[150] * 1.02
    w_star = brentq(lambda w: G * u - c * w - 0.05 - _excess(5.0) / (1 + (w / 0.03) ** 2), 0.1, 5.0)
    for theta in (lag, none):
        assert _end_speed(theta) == pytest.approx(w_star, rel=1e-3)


# --- (c) pinion friction ----------------------------------------------------------------------

def test_pinion_friction_holds_by_angle_and_slides_on_its_ode():
    """Flat plant: at the angle of the largest level (0.096 N m) and of the smallest (0.024) the
    joint holds at 98 % of it and moves at 102 %; 0.3 N m from rest: the truth's angle against
    scipy's Radau on J theta'' = G u - (kt^2/R + b) theta' - Fc0 (1 + a cos(3 theta + 0.5))."""
    truth = tr4.PinionFriction(FLAT)
    for theta0, level in ((-0.5 / 3, 0.096), ((math.pi - 0.5) / 3, 0.024)):
        assert truth.level(theta0) == pytest.approx(level)
        assert np.ptp(_constant(truth, 0.98 * level / G, 0.05, theta0=theta0)) == 0.0
        assert _constant(truth, 1.02 * level / G, 0.05, theta0=theta0)[-1] > theta0
    theta = _constant(truth, 1.0, 1.0)
    t = np.arange(len(theta)) * tr.H

    def f(s, x):
        return [x[1], (G - (EMF + B) * x[1] - 0.06 * (1 + 0.6 * math.cos(3 * x[0] + 0.5))) / J]
    sol = solve_ivp(f, (0, t[-1]), [0, 0], method="Radau", t_eval=t[::100], rtol=1e-10, atol=1e-13)
    err = np.abs(theta[::100] - sol.y[0]).max()
    assert err < 2e-3 * np.ptp(sol.y[0]), err
    assert np.ptp(np.diff(theta[5000:])) > 0.05 * np.mean(np.diff(theta[5000:]))   # the ripple


# --- (d) cable hysteresis (Bouc-Wen) ----------------------------------------------------------

def test_bouc_wen_advance_is_its_ode():
    """z(theta) from 0: forward 0.2 rad, then back 0.3 rad (through z = 0): against scipy on
    dz/dtheta = A - beta sgn(dtheta) z - gamma |z|, whatever the steps the travel is cut into;
    it saturates at A/(beta + gamma) = 0.05, and the torque's loop over a long swing is
    2 (1 - alpha) k z_max = 0.09 N m wide."""
    truth = tr4.CableHysteresis(FLAT)
    z = 0.0
    for dx in np.full(200, 1e-3):
        z = truth.advance(z, dx)
    assert truth.advance(0.0, 0.2) == pytest.approx(z, rel=1e-12)
    up = solve_ivp(lambda x, y: [1 - 15 * y[0] - 5 * abs(y[0])], (0, 0.2), [0.0], rtol=1e-12, atol=1e-15)
    assert z == pytest.approx(up.y[0, -1], rel=1e-9)
    back = truth.advance(z, -0.3)
    down = solve_ivp(lambda x, y: [-(1 + 15 * y[0] - 5 * abs(y[0]))], (0, 0.3), [z], rtol=1e-12, atol=1e-15)
    assert back == pytest.approx(down.y[0, -1], rel=1e-9) and back < 0
    zs = [truth.advance(0.0, 2.0), truth.advance(0.0, -2.0)]
    assert zs == pytest.approx([0.05, -0.05], rel=1e-9)
    width = truth.torque(0.1, zs[1]) - truth.torque(0.1, zs[0])
    assert width == pytest.approx(2 * 0.75 * 1.2 * 0.05)


def test_cable_spring_rest_angle():
    """With alpha = 1 the cable is a pure spring: without Coulomb friction, torque off, the
    pendulum rests where k (theta_c - theta) = m g l sin(theta) (scipy root); with the
    hysteresis it rests within the band the loop allows, (1 - alpha) k z_max about that of its
    elastic part."""
    plant = replace(PLANT, coulomb=0.0)
    rest = brentq(lambda x: 1.2 * (0.3 - x) - PLANT.mgl * math.sin(x), -1.0, 1.0)
    assert _torque_off(tr4.CableHysteresis(plant, alpha=1.0), 5.0, -0.4)[-1] == pytest.approx(rest, abs=1e-6)
    elastic = brentq(lambda x: 0.3 * (0.3 - x) - PLANT.mgl * math.sin(x), -1.0, 1.0)
    truth = tr4.CableHysteresis(plant)
    state = truth.initial_state()
    end = _torque_off(truth, 8.0, -0.4, state=state)[-1]
    assert PLANT.mgl * math.sin(end) + 0.3 * (end - 0.3) == pytest.approx(-0.9 * state["z"], abs=1e-6)
    assert abs(end - elastic) > 1e-3 and abs(state["z"]) <= 0.05


# --- (e) supply sag ---------------------------------------------------------------------------

def test_supply_sag_is_the_circuit():
    """The motor's torque is kt i where (scipy fsolve) V_bus = V0 - Rs d i and d V_bus = R i +
    kt w, at several (u, w); on the flat plant the steady speed is the closed form
    (G u - Fc (1 + rho d^2)) / (kt^2/R + b (1 + rho d^2)), rho = Rs/R, either way."""
    truth = tr4.SupplySag(PLANT)
    kt, r, v0, rs = PLANT.kt, PLANT.resistance, PLANT.supply, 2.0
    for u, w in ((12.0, 0.0), (6.0, 2.0), (-9.0, -1.0), (3.0, -4.0)):
        d = u / v0
        vb, i = fsolve(lambda x: [x[0] - (v0 - rs * d * x[1]), d * x[0] - r * x[1] - kt * w], [v0, 1.0],
                       xtol=1e-13)
        assert truth.motor(u, w, True) == pytest.approx(kt * i, rel=1e-9)
    assert truth.motor(12.0, 0.0, True) == pytest.approx(G * 12.0 / 1.5, rel=1e-12)
    truth = tr4.SupplySag(FLAT)
    for u in (6.0, 12.0):
        k = 1 + 0.5 * (u / 12.0) ** 2
        for sign in (1.0, -1.0):
            w = _end_speed(_constant(truth, u, 1.0, sign=sign))
            assert w == pytest.approx(sign * (G * u - FC * k) / (EMF + B * k), rel=1e-4)


# --- (f) goal profile -------------------------------------------------------------------------

def test_goal_profile_ramps_and_the_servo_follows_with_the_ramp_lag():
    """A step of the goal becomes a ramp of v_max T per period, reaching the goal after
    ceil(step / (v_max T)) periods; a sine slower than v_max is unchanged.  Flat plant, v_max 1
    rad/s, a 1 rad step: after the transient the servo follows the ramp lagging
    ((kt^2/R + b) v + Fc) / (G kp) (the type-0 loop's closed form), within the encoder's count."""
    truth = tr4.GoalProfile(PLANT)
    goal = np.r_[np.zeros(5), np.full(300, 0.5)]
    prof = truth.profile(goal, 0.0)
    assert np.allclose(np.diff(prof[4:88]), 0.006) and prof[4 + math.ceil(0.5 / 0.006)] == 0.5
    assert np.all(prof[:5] == 0) and np.all(prof[88:] == 0.5)
    slow, _ = _campaign_run(0, 2.0)
    assert np.array_equal(truth.profile(slow, 0.0), slow)
    flat = tr4.GoalProfile(FLAT, v_max=1.0)
    n = 1200
    theta, u = tr4.simulate(flat, np.full(n, 1.0), np.ones(n), 30.0, 12.0, 0.0, {})
    lag = ((EMF + B) * 1.0 + FC) / (G * 30.0)
    for k in (700, 900):
        assert (k + 1) * 1e-3 - theta[k * tr.SUBSTEPS] == pytest.approx(lag, abs=1.5 * tr.ENCODER_STEP_RAD)
    assert theta[-1] == pytest.approx(1.0, abs=3 * tr.ENCODER_STEP_RAD)


# --- (g) coast with torque off ----------------------------------------------------------------

def test_coast_swings_on_the_bearing_alone():
    """Torque off, no Coulomb friction, released at 0.5 rad: the truth's angle against scipy on
    J theta'' = -b theta' - m g l sin(theta) (the winding open: no back-EMF), 3 s; the first
    half's shorted winding creeps down instead."""
    plant = replace(PLANT, coulomb=0.0)
    theta = _torque_off(tr4.CoastOff(plant), 3.0, 0.5)
    t = np.arange(len(theta)) * tr.H
    sol = solve_ivp(lambda s, x: [x[1], (-B * x[1] - PLANT.mgl * math.sin(x[0])) / J], (0, t[-1]),
                    [0.5, 0.0], t_eval=t[::50], rtol=1e-10, atol=1e-13)
    assert np.abs(theta[::50] - sol.y[0]).max() < 1e-3
    assert theta.min() < -0.4
    shorted = _torque_off(tr.Null(plant), 3.0, 0.5)
    assert shorted.min() > 0 and np.abs(theta - shorted).max() > 0.5


# --- (h) transmission error -------------------------------------------------------------------

def _ratio(x):
    return 1 - 3e-3 * 48 * math.cos(48 * x + 0.4), 3e-3 * 48 ** 2 * math.sin(48 * x + 0.4)


def test_transmission_error_against_lagrange_and_its_rest():
    """Without an error (eps 0) the first half's loop (to 1e-12 rad); flat plant, no Coulomb,
    2 V from rest: the truth's angle against scipy on Lagrange's equation
    (J_l + J_a r^2) w' + J_a r r' w^2 = r (G u - (kt^2/R) r w) - b w; with gravity, 0.5 V held:
    it rests where r(theta) G u = m g l sin(theta) (scipy root), not at the rigid gear's angle."""
    (a, _), (b, _) = _both(tr4.TransmissionError(PLANT, eps=0.0), 6)
    assert np.abs(a - b).max() < 1e-12
    plant = replace(FLAT, coulomb=0.0)
    theta = _constant(tr4.TransmissionError(plant), 2.0, 0.3)
    ja, jl = plant.armature, plant.j_link

    def f(s, x):
        r, dr = _ratio(x[0])
        return [x[1], (r * (G * 2.0 - EMF * r * x[1]) - ja * r * dr * x[1] ** 2 - B * x[1]) / (jl + ja * r * r)]
    t = np.arange(len(theta)) * tr.H
    sol = solve_ivp(f, (0, t[-1]), [0, 0], method="Radau", t_eval=t[::50], rtol=1e-10, atol=1e-13)
    err = np.abs(theta[::50] - sol.y[0]).max()
    assert err < 2e-3 * np.ptp(sol.y[0]), err
    rigid = _constant(tr.Null(plant), 2.0, 0.3)
    assert np.abs(rigid[::50] - sol.y[0]).max() > 5 * err
    plant = replace(PLANT, coulomb=0.0)
    end = _constant(tr4.TransmissionError(plant), 0.5, 2.0)[-1]
    g = lambda x: _ratio(x)[0] * G * 0.5 - PLANT.mgl * math.sin(x)
    rest = brentq(g, 0.0, 0.3)
    assert end == pytest.approx(rest, abs=1e-6)
    assert abs(rest - math.asin(G * 0.5 / PLANT.mgl)) > 2 * tr.ENCODER_STEP_RAD


# --- (i) encoder filter -----------------------------------------------------------------------

def test_encoder_filter_lags_the_angle():
    """As tau_s -> 0 the first half's loop (to 1e-9 rad); flat plant, no Coulomb, 2 V from rest:
    the loop's reading against scipy on J w' = G u - (kt^2/R + b) w, tau_s y' = theta - y, and
    the true angle (the state) against the same; at steady speed the reading is theta - w tau_s."""
    (a, _), (b, _) = _both(tr4.EncoderFilter(PLANT, tau_s=1e-12), 6)
    assert np.abs(a - b).max() < 1e-9
    plant = replace(FLAT, coulomb=0.0)
    truth = tr4.EncoderFilter(plant)
    state = truth.initial_state()
    y = _constant(truth, 2.0, 0.5, state=state)
    c = EMF + B
    t = np.arange(len(y)) * tr.H
    sol = solve_ivp(lambda s, x: [x[1], (G * 2.0 - c * x[1]) / J, (x[0] - x[2]) / 1e-2], (0, t[-1]),
                    [0, 0, 0], t_eval=t[::50], rtol=1e-10, atol=1e-13)
    err = np.abs(y[::50] - sol.y[2]).max()
    assert err < 2e-3 * np.ptp(sol.y[2]), err
    assert np.abs(sol.y[0] - sol.y[2]).max() > 20 * err          # the unfiltered angle is not it
    assert state["theta"] == pytest.approx(sol.y[0, -1], rel=2e-3)
    w = state["w"]
    assert w == pytest.approx(G * 2.0 / c, rel=1e-3)
    assert state["theta"] - y[-1] == pytest.approx(w * 1e-2, rel=1e-3)


# --- make.py: determinism and the dataset contract --------------------------------------------

def test_make_is_deterministic_and_keeps_the_contract(tmp_path, capsys):
    """Same seed -> same bytes, another seed -> other bytes; the runs read back through the
    dataset contract with their metadata, jittered log intervals and encoder counts (the
    filtered reading too); cases.json holds each case's law, source, equation, plant factors and
    expectation; the default seed is 45."""
    half_make.check_make_keeps_the_contract(make, tmp_path, ("i_encoder_filter", "j_null"), 45)


def test_make_null_case_is_the_first_halfs_loop_and_logs_the_hosts_goal():
    """make's null case (seed 45, index 9) logs the first half's loop on its plant: its quick
    first run's encoder samples equal the first half's simulate at the logged ticks.  The goal
    profile's log holds the host's goal (the campaign's), not the profiled one."""
    truth, runs, record = make.run_case(9, "j_null", 45, quick=True)
    run = runs[0]
    ticks = np.round(run.t / tr.H).astype(int)
    n = 1500
    held = np.searchsorted(ticks, np.arange(n) * tr.SUBSTEPS, side="right") - 1
    theta, u = tr.simulate(tr.Null(truth.p), run.r[held], np.ones(n), make1.KP, make1.COMMAND_LIMIT,
                           float(run.r[0]), {})
    y = np.round(theta[ticks] / tr.ENCODER_STEP_RAD) * tr.ENCODER_STEP_RAD
    assert np.array_equal(y, run.theta) and record["expected"]["family"] == "none"
    _, runs, _ = make.run_case(5, "f_goal_profile", 45, quick=True)
    drop = runs[1]
    assert np.array_equal(drop.r, make1.campaign(1.5)[-1]["ref"](drop.t))


def test_make_refuses_unknown_case(tmp_path, capsys):
    assert make.main(["--out", str(tmp_path / "x"), "--only", "a_dahl"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown case 'a_dahl'")
    assert not (tmp_path / "x").exists()


# --- score.py ---------------------------------------------------------------------------------

NULL_REPORT = tr.ROOT / "bank" / "test_half" / "null_report.json"


def _case(name):
    return {"name": name, "expected": dict(tr4.CASES)[name](PLANT).expected()}


def _named(report, name, params):
    return dict(report, effects=[{"name": name, "parameters": params, "reason": ""}])


def test_score_families():
    """This half's keywords put names into its families; the earlier halves' names keep theirs."""
    assert score.family_of("generalized_maxwell_slip") == "friction: dynamic"
    assert score.family_of("dwell_stiction") == "friction: stribeck"
    assert score.family_of("position_dependent_friction") == "friction: position-dependent"
    assert score.family_of("cable_hysteresis") == "hysteretic stiffness"
    assert score.family_of("supply_sag") == "supply sag"
    assert score.family_of("goal_profile") == "goal rate limit"
    assert score.family_of("torque_off_coast") == "torque-off coast"
    assert score.family_of("transmission_error") == "transmission error"
    assert score.family_of("sensor_lag") == "sensor lag"
    for name, fam in (("encoder_eccentricity", "sensor error"), ("actuator_lag", "actuator lag"),
                      ("joint_stiffness", "joint stiffness"), ("load_friction", "friction: load-dependent"),
                      ("presliding_friction", "friction: dynamic"), ("time_delay", "time delay"),
                      ("cogging", "cogging"), ("torque_saturation", "torque saturation")):
        assert score.family_of(name) == fam


def test_score_null_and_unexpressible():
    """The first half's null report (names nothing, not flagged) scores the null case fully.  On
    the encoder filter with no candidate of its family the right answer is a flag with maps: the
    unflagged report fails, the flagged one passes, a named time delay is only partial; on GMS
    a presliding friction is right."""
    report = json.loads(NULL_REPORT.read_text())
    row = score.score_case(_case("j_null"), report)
    assert row["points"] == {"family": True, "no_spurious": True, "direction": True, "unexplained": True}
    lag = score.score_case(_case("i_encoder_filter"), report)
    assert lag["library_can_express"] is False and lag["points"]["family"] is False
    flagged = dict(report, unexplained=True)
    assert score.score_case(_case("i_encoder_filter"), flagged)["points"]["family"] is True
    assert score.score_case(_case("i_encoder_filter"), flagged)["points"]["unexplained"] is True
    delay = score.score_case(_case("i_encoder_filter"), _named(report, "time_delay", {"delay_s": 0.01}))
    assert delay["points"]["family"] is False and delay["partial_family"] is True
    gms = score.score_case(_case("a_gms"), _named(report, "presliding_friction", {"fs": 0.1, "fc": 0.07}))
    assert gms["points"]["family"] is True and gms["points"]["direction"] is True


def test_score_new_claims():
    """The claims this half adds, and the earlier ones it reuses, read from the named effect's
    parameters: unreadable is None (unchecked), a right value passes, a wrong one fails."""
    report = json.loads(NULL_REPORT.read_text())
    prof = _case("f_goal_profile")
    assert score.score_case(prof, _named(report, "goal_profile", {"rate_rad_s": 5.0}))["points"]["direction"] is True
    assert score.score_case(prof, _named(report, "goal_profile", {"slew": 1.0}))["points"]["direction"] is False
    none = score.score_case(prof, _named(report, "goal_profile", {"gain": 1.0}))
    assert none["points"]["direction"] is None and none["signs"]["rate_limit_rad_s"] is None
    sag = _case("e_supply_sag")
    assert score.score_case(sag, _named(report, "supply_sag", {"source_resistance": 1.5}))["points"]["direction"] is True
    assert score.score_case(sag, _named(report, "supply_sag", {"resistance_ohm": 9.0}))["points"]["direction"] is False
    mesh = score.score_case(_case("h_transmission_error"), _named(report, "transmission_error", {"teeth": 48}))
    assert mesh["points"]["family"] is True and mesh["points"]["direction"] is True
    pin = score.score_case(_case("c_pinion_friction"), _named(report, "position_friction", {"order": 2}))
    assert pin["points"]["family"] is True and pin["points"]["direction"] is False
    filt = score.score_case(_case("i_encoder_filter"), _named(report, "sensor_lag", {"time_constant_ms": 12.0}))
    assert filt["points"]["family"] is True and filt["points"]["direction"] is True
    cable = score.score_case(_case("d_cable_hysteresis"), _named(report, "joint_stiffness", {"stiffness": 0.4}))
    assert cable["points"]["family"] is True and cable["points"]["direction"] is True


# --- the one run's record (bank/README.md, "The fourth half's one run") ------------------------
RECORD = tr.ROOT / "bank" / "test_half_4" / "record"


def test_readme_fourth_half_run_is_its_record():
    """bank/README.md's table of the fourth half's one run is made from test_half_4/record (the
    score as run and each case's report), the commit it names is the score's, the record's
    scores are what score.py says of its reports, the wall times and physics steps it quotes
    are the reports' own, and so are the figures of its prose."""
    from tests.half_record import check_readme_run

    flat = check_readme_run(RECORD, "fourth test half", score.score_case)
    sc = json.loads((RECORD / "score.json").read_text())
    t = sc["totals"]
    assert f"family {t['family']}, no spurious second effect {t['no_spurious']}" in flat
    unchecked = sum(c["points"]["direction"] is None for c in sc["cases"])
    wrong = sum(c["points"]["direction"] is False for c in sc["cases"])
    assert wrong == 0 and f"no direction claim wrong ({t['direction']} right, {unchecked} unchecked" in flat
    rep = {c["case"]: json.loads((RECORD / c["case"] / "report.json").read_text()) for c in sc["cases"]}
    spring, hyst = rep["d_cable_hysteresis"]["effects"]
    p, u = spring["parameters"], spring["uncertainty"]
    assert (f"`joint_stiffness` {p['stiffness_nm_per_rad']:.3f} ± {u['stiffness_nm_per_rad']:.2g} N m/rad about a rest "
            f"of {p['rest_rad']:.3f} ± {u['rest_rad']:.2g} rad") in flat
    assert (f"(sigma0 {hyst['parameters']['sigma0_nm_per_rad']:.2f} N m/rad, level "
            f"{hyst['parameters']['fc_nm']:.3f} N m;") in flat
    (delay,) = rep["i_encoder_filter"]["effects"]
    assert delay["name"] == "time_delay" and f"{delay['parameters']['delay_s'] * 1e3:.1f} ms for a 10 ms lag" in flat
    for case in ("f_goal_profile", "g_coast_off"):
        r = rep[case]
        assert f"({r['gap_before']:.2e} → {r['gap_after']:.2e} rad)" in flat, case
    assert rep["g_coast_off"]["gap_after"] > rep["g_coast_off"]["gap_before"]  # "made ... worse"
    flags = [c for c in sc["cases"] if c["unexplained_flag"] and not [
        e for e in rep[c["case"]]["effects"] if e["name"] != "none"]]
    assert len(flags) == 5 and all(c["points"]["family"] for c in flags)
    assert "five of the nine family points are such flags" in flat
