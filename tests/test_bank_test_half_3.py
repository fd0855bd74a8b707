"""The bank's third test half (bank/test_half_3): each truth's law against an independent check
(closed forms, scipy roots, scipy's ODE solvers on the law's own equations, limit cases), the
null case against the first half's loop, make.py's determinism and the dataset contract, and
score.py's extensions.

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
from scipy.optimize import brentq

from bank.test_half import make as make1
from bank.test_half import truths as tr
from bank.test_half_2 import truths as tr2
from bank.test_half_3 import make, score
from bank.test_half_3 import truths as tr3
from tests import half_loops as loops
from tests import half_make
from tests.half_record import check_readme_run

PLANT = tr.nominal_plant()
FLAT = replace(PLANT, mgl=0.0)
G, EMF, B, FC, J = PLANT.gear, PLANT.emf, PLANT.bearing, PLANT.coulomb, PLANT.inertia


def _constant(truth, u, seconds, theta0=0.0, sign=1.0, state=None):
    return loops.constant(tr3.simulate, truth, u, seconds, theta0, sign, state)


def _torque_off(truth, seconds, theta0, state=None):
    return loops.torque_off(tr3.simulate, truth, seconds, theta0, state)


_end_speed = loops.end_speed


def _initial_acceleration(truth, u, theta0):
    """theta_1 = theta0 + h^2 a: the semi-implicit Euler step from rest."""
    theta = _constant(truth, u, 0.001, theta0=theta0)
    return (theta[1] - theta0) / tr.H ** 2


def _campaign_run(index, seconds=6.0):
    """The goal and torque-on flag of one of the campaign's runs, per 1 ms period."""
    e = make1.campaign(seconds)[index]
    t = np.arange(int(round(seconds / tr.CONTROL_PERIOD_S))) * tr.CONTROL_PERIOD_S
    en = np.ones(len(t)) if e["off_s"] is None else (t < e["off_s"]).astype(float)
    return np.asarray(e["ref"](t), dtype=float), en


def test_cases_are_new_and_documented():
    """Ten cases, a null among them; each expectation in known families, each law cited with
    its equation; no law's name is one of the earlier halves'."""
    assert len(tr3.CASES) == 10 and [n[0] for n, _ in tr3.CASES] == list("abcdefghij")
    earlier = {cls.name for _, cls in tr.CASES + tr2.CASES}
    for name, cls in tr3.CASES:
        truth = cls(PLANT)
        e = truth.expected()
        assert e["family"] in tr3.FAMILIES and set(e["accept"]) | set(e["partial"]) <= set(tr3.FAMILIES)
        assert truth.source and truth.equation and cls.__doc__, name
        assert truth.name not in earlier or name == "j_null", name
        json.dumps(truth.describe(), allow_nan=False)
    assert tr3.Null(PLANT).expected()["family"] == "none"
    assert set(tr2.FAMILIES) < set(tr3.FAMILIES)


def test_null_is_the_first_halfs_loop():
    """The null case runs the first half's loop bit for bit (a square wave with gravity and a
    torque-off run), and so does an OwnLoop without a law of its own."""
    plant, _ = tr.perturbed(PLANT, 44 * 100 + 9)
    for run in (6, 11):
        goal, en = _campaign_run(run, 2.0)
        a = tr3.simulate(tr3.Null(plant), goal, en, 30.0, 12.0, float(goal[0]), {})
        b = tr.simulate(tr.Null(plant), goal, en, 30.0, 12.0, float(goal[0]), {})
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        assert np.ptp(a[0]) > 0.3


# --- (a) Dahl ---------------------------------------------------------------------------------

def test_dahl_advance_is_the_hyperbola_and_the_ode():
    """From F = 0 at a constant sign of motion, i = 2: F(x) = Fc sigma x / (Fc + sigma x),
    whatever the steps the travel is cut into (the update is exact); against scipy on
    dF/dx = sigma (1 - F/Fc)^2 too; moving back, F leaves +Fc towards -Fc along the mirrored
    law; i = 1 gives the exponential Fc (1 - exp(-sigma x / Fc))."""
    truth = tr3.Dahl(FLAT)
    fc, sig = 0.08, 60.0
    f = 0.0
    for dx in np.full(300, 1e-4):
        f = truth.advance(f, dx)
    x = 0.03
    assert f == pytest.approx(fc * sig * x / (fc + sig * x), rel=1e-12)
    assert truth.advance(0.0, x) == pytest.approx(f, rel=1e-12)
    sol = solve_ivp(lambda s, y: [sig * (1 - y[0] / fc) ** 2], (0, x), [0.0], rtol=1e-12, atol=1e-15)
    assert f == pytest.approx(sol.y[0, -1], rel=1e-8)
    back = truth.advance(f, -0.01)
    sol = solve_ivp(lambda s, y: [-sig * (1 + y[0] / fc) ** 2], (0, 0.01), [f], rtol=1e-12, atol=1e-15)
    assert back == pytest.approx(sol.y[0, -1], rel=1e-8) and -fc < back < 0
    one = tr3.Dahl(FLAT, i=1.0)
    assert one.advance(0.0, x) == pytest.approx(fc * (1 - math.exp(-sig * x / fc)), rel=1e-12)


def _dahl_ode(u):
    """Dahl's law in time on the flat plant, constant u: dF/dt = sigma w |1 - F sgn(w)/Fc|^2
    sgn(1 - F sgn(w)/Fc)."""
    fc, sig = 0.08, 60.0

    def f(t, x):
        th, w, fr = x
        y = 1 - fr * np.sign(w) / fc
        return [w, (G * u - (EMF + B) * w - fr) / J, sig * w * abs(y) ** 2 * np.sign(y)]
    return f


@pytest.mark.parametrize("u", [0.2, 0.5])
def test_dahl_against_an_ode_solver(u):
    """From rest, a constant command below (0.06 N m < Fc 0.08: presliding, it stops a few
    mrad on, its friction then balancing the motor, beyond the virgin curve's travel: the swing
    overshoots and comes back on another branch of the hysteresis) and above the level (0.15 N m:
    it slides at (G u - F(x))/(kt^2/R + b), F on the virgin hyperbola, a little behind it): the truth's angle against scipy's Radau on Dahl's
    equation in time, 0.6 s."""
    truth = tr3.Dahl(FLAT)
    state = truth.initial_state()
    theta = _constant(truth, u, 0.6, state=state)
    t = np.arange(len(theta)) * tr.H
    sol = solve_ivp(_dahl_ode(u), (0, t[-1]), [0, 0, 0], method="Radau", t_eval=t[::100],
                    rtol=1e-10, atol=1e-13, max_step=1e-3)
    err = np.abs(theta[::100] - sol.y[0]).max()
    assert err < max(2e-5, 2e-3 * np.ptp(sol.y[0])), err
    if G * u < 0.08:   # at rest the friction balances the motor; past the virgin curve's x
        x = G * u * 0.08 / (60.0 * (0.08 - G * u))
        assert abs(_end_speed(theta)) < 1e-3 and state["F"] == pytest.approx(G * u, abs=1e-3)
        assert x < theta[-1] < 2 * x
    else:
        x = theta[-51]       # the middle of the end speed's 10 ms; forward all along
        fx = 0.08 * 60.0 * x / (0.08 + 60.0 * x)
        assert np.all(np.diff(theta) >= 0)
        c = EMF + B          # quasi-steady speed, plus the lag J/c behind F's slow rise
        w_qs = (G * u - fx) / c
        w_lag = J * 60.0 * w_qs * (1 - fx / 0.08) ** 2 / c ** 2
        assert _end_speed(theta) == pytest.approx(w_qs + w_lag, rel=1e-3) and w_lag > 1e-3 * w_qs


# --- (b) Karnopp ------------------------------------------------------------------------------

def _karnopp_run(truth, torques, steps):
    """Karnopp's step on the flat plant under a motor torque held for ``steps`` sub-steps each."""
    w, th, out = 0.0, 0.0, []
    for tau_m, n in zip(torques, steps):
        for _ in range(n):
            w = truth.step(th, w, tau_m - EMF * w, {})
            th += tr.H * w
        out.append((th, w))
    return out


def test_karnopp_sticks_breaks_away_and_slides_on_its_kinetic_level():
    """Flat plant: 0.105 N m (< Fs 0.12) does not move it at all; 0.15 N m breaks away with
    J a = 0.15 - Fs in the first sub-step (the friction at its static level inside the band),
    and slides at (tau - Fc)/(kt^2/R + b); brought down to 0.09 N m (between Fc and Fs) it
    keeps sliding at (0.09 - Fc)/(kt^2/R + b), where from rest 0.09 N m holds it."""
    truth = tr3.Karnopp(FLAT)
    assert np.ptp(_constant(truth, 0.35, 0.5)) == 0.0
    assert _initial_acceleration(truth, 0.5, 0.0) == pytest.approx((G * 0.5 - 0.12) / J, rel=1e-9)
    assert _end_speed(_constant(truth, 0.5, 1.0)) == pytest.approx((G * 0.5 - 0.05) / (EMF + B), rel=1e-3)
    (th1, w1), (th2, w2) = _karnopp_run(truth, (0.15, 0.09), (10000, 10000))
    assert w1 == pytest.approx((0.15 - 0.05) / (EMF + B), rel=1e-6)
    assert w2 == pytest.approx((0.09 - 0.05) / (EMF + B), rel=1e-6)
    assert _karnopp_run(truth, (0.09,), (10000,)) == [(0.0, 0.0)]
    assert _end_speed(_constant(truth, 0.5, 1.0, sign=-1.0)) == pytest.approx(-(G * 0.5 - 0.05) / (EMF + B), rel=1e-3)


# --- (c) churning drag ------------------------------------------------------------------------

def test_churning_drag_steady_speed_is_the_quadratic_root():
    """Flat plant: G u = c w^2 + (kt^2/R + b) w + Fc, the positive root, either way."""
    truth = tr3.ChurningDrag(FLAT)
    c = 0.015
    for u in (2.0, 8.0):
        a = EMF + B
        w_star = (-a + math.sqrt(a * a + 4 * c * (G * u - FC))) / (2 * c)
        for sign in (1.0, -1.0):
            assert _end_speed(_constant(truth, u, 1.0, sign=sign)) == pytest.approx(sign * w_star, rel=1e-3)
    assert w_star < (G * 8.0 - FC) / (EMF + B) - 0.5     # 0.9 rad/s below the viscous law's


# --- (d) Hertzian load friction ---------------------------------------------------------------

def test_hertz_load_speed_fall_and_holding_band():
    """Flat plant, driving: G u - (kt^2/R + b) w - Fc - k (G u - kt^2/R w)^(2/3) = 0 (scipy
    root); at pi/2 against 1 V (back-driven, the same law): J a = G - mgl + Fc + k G^(2/3); held
    at pi/2 by the motor torques tau with |tau - mgl| <= Fc + k tau^(2/3) (scipy roots for the
    band's two ends), moving just outside them."""
    k = 0.10
    truth = tr3.HertzLoad(FLAT)
    u = 3.0
    w_star = brentq(lambda w: G * u - (EMF + B) * w - FC - k * abs(G * u - EMF * w) ** (2 / 3), 1e-6, 20.0)
    assert _end_speed(_constant(truth, u, 1.0)) == pytest.approx(w_star, rel=1e-3)
    truth = tr3.HertzLoad(PLANT)
    down = _initial_acceleration(truth, 1.0, math.pi / 2)
    assert down == pytest.approx((G - PLANT.mgl + FC + k * G ** (2 / 3)) / J, rel=1e-9)
    mgl = PLANT.mgl
    lo = brentq(lambda tau: mgl - tau - FC - k * tau ** (2 / 3), 0.1, mgl)
    hi = brentq(lambda tau: tau - mgl - FC - k * tau ** (2 / 3), mgl, 3.0)
    for tau, moves in ((0.98 * lo, -1), (1.02 * lo, 0), (0.98 * hi, 0), (1.02 * hi, 1)):
        th = _constant(truth, tau / G, 0.05, theta0=math.pi / 2)
        assert np.sign(th[-1] - math.pi / 2) == moves, (tau, lo, hi)


# --- (e) Palmgren -----------------------------------------------------------------------------

def test_palmgren_steady_speed_and_threshold():
    """Flat plant: G u = (kt^2/R + b) w + Fc + c_p w^(2/3) (scipy root) at two speeds; it
    starts only above Fc + c_p w_t^(2/3); the docstring's sizes (0.12 N m at 1 rad/s, 0.35 at
    5 rad/s)."""
    truth = tr3.Palmgren(FLAT)
    cp, wt = 0.12, 6e-3
    for u in (1.0, 6.0):
        w_star = brentq(lambda w: G * u - (EMF + B) * w - FC - cp * w ** (2 / 3), wt, 30.0)
        assert _end_speed(_constant(truth, u, 1.5)) == pytest.approx(w_star, rel=1e-3)
    static = FC + cp * wt ** (2 / 3)
    assert np.ptp(_constant(truth, 0.98 * static / G, 0.3)) == 0.0
    assert _constant(truth, 1.05 * static / G, 0.3)[-1] > 0.0
    assert truth.level(1.0) - FC == pytest.approx(0.12) and truth.level(-5.0) - FC == pytest.approx(0.351, abs=1e-3)


# --- (f) inductance ---------------------------------------------------------------------------

def test_inductance_against_an_ode_solver_and_its_limit():
    """Flat plant, no Coulomb friction, 2 V from rest with no current: the truth's angle
    against scipy's Radau on L di/dt = v - R i - kt w, J w' = kt i - b w (0.2 s, within the
    sub-step's first-order error); without the lag (L/R -> 0) the first half's loop to 1e-12;
    a run starting with its steady current has no lag at t = 0; torque off, the current of a
    shorted winding (v = 0) decays towards -kt w / R."""
    plant = replace(FLAT, coulomb=0.0)
    truth = tr3.Inductance(plant)
    kt, r, tau_e = plant.kt, plant.resistance, 3e-3
    theta = _constant(truth, 2.0, 0.2, state={"i": 0.0})

    def f(t, x):
        th, w, i = x
        return [w, (kt * i - B * w) / J, (2.0 - r * i - kt * w) / (tau_e * r)]

    t = np.arange(len(theta)) * tr.H
    sol = solve_ivp(f, (0, t[-1]), [0, 0, 0], method="Radau", t_eval=t[::50], rtol=1e-10, atol=1e-13)
    err = np.abs(theta[::50] - sol.y[0]).max()
    assert err < 2e-4, err
    rigid = _constant(tr.Null(plant), 2.0, 0.2)
    assert np.abs(rigid[::50] - sol.y[0]).max() > 5 * err
    fast = _constant(tr3.Inductance(plant, tau_e=1e-12), 2.0, 0.2)
    assert np.allclose(fast, rigid, rtol=0, atol=1e-12)
    steady = _constant(tr3.Inductance(plant), 2.0, 0.001)
    assert steady[1] == pytest.approx(rigid[1], rel=1e-9)
    state = {"i": 0.5}
    th = _torque_off(truth, 0.05, 0.0, state=state)
    w_end = (th[-1] - th[-2]) / tr.H
    assert th[-1] > 1e-3 and state["i"] == pytest.approx(-kt * w_end / r, rel=0.1)


# --- (g) payload ------------------------------------------------------------------------------

def test_payload_is_the_nominal_scaled():
    """The payload adds m l^2 and m g l; the truth's trajectories (a 1.5 Hz sine and the
    lift-and-drop with torque off) equal, to 1e-9 rad, those of the nominal's laws with the
    gain, back-EMF, bearing loss and Coulomb friction divided by k = mgl'/mgl and the armature
    at J'/k - J_link: the corrections can take it, nothing is missing."""
    plant, _ = tr.perturbed(PLANT, 44 * 100 + 6)
    truth = tr3.Payload(plant)
    assert truth.p.j_link - plant.j_link == pytest.approx(0.2 * 0.18 ** 2, rel=1e-12)
    assert truth.p.mgl - plant.mgl == pytest.approx(0.2 * 9.81 * 0.18, rel=1e-12)
    k = truth.scale()
    assert k == pytest.approx(1.30, abs=0.01)
    same = replace(plant, armature=truth.p.inertia / k - plant.j_link, gear=plant.gear / k,
                   emf=plant.emf / k, bearing=plant.bearing / k, coulomb=plant.coulomb / k)
    for run in (3, 11):
        goal, en = _campaign_run(run)
        a = tr3.simulate(truth, goal, en, 30.0, 12.0, float(goal[0]), {})
        b = tr3.simulate(tr.Null(same), goal, en, 30.0, 12.0, float(goal[0]), {})
        assert np.abs(a[0] - b[0]).max() < 1e-9 and np.allclose(a[1], b[1], atol=1e-6)
        assert np.abs(a[0] - tr3.simulate(tr.Null(plant), goal, en, 30.0, 12.0,
                                          float(goal[0]), {})[0]).max() > 0.02


# --- (h) eccentric encoder --------------------------------------------------------------------

def test_eccentricity_reading_and_rest():
    """With a = 0 the truth is the first half's loop (to 1e-12 rad); torque off and without
    Coulomb friction the pendulum comes to rest hanging (true angle 0), which reads a sin(phi);
    on the flat plant the P loop brings the reading to the goal, the true angle to the root
    (scipy) of theta + a sin(theta + phi) = goal; the reading returned is the true angle's."""
    goal, en = _campaign_run(6, 1.0)
    a = tr3.simulate(tr3.Eccentricity(PLANT, a=0.0), goal, en, 30.0, 12.0, float(goal[0]), {"w": 0.0})[0]
    b = tr.simulate(tr.Null(PLANT), goal, en, 30.0, 12.0, float(goal[0]), {})[0]
    assert np.abs(a - b).max() < 1e-12
    truth = tr3.Eccentricity(replace(PLANT, coulomb=0.0))
    state = truth.initial_state()
    th = _torque_off(truth, 5.0, 0.3, state=state)
    assert th[-1] == pytest.approx(0.015 * math.sin(0.6), abs=1e-7)
    assert state["theta"] == pytest.approx(0.0, abs=1e-7)
    flat = tr3.Eccentricity(replace(FLAT, coulomb=0.0))
    state = flat.initial_state()
    n = 3000
    y, _ = tr3.simulate(flat, np.full(n, 0.5), np.ones(n), 30.0, 12.0, 0.0, state)
    x_star = brentq(lambda x: x + 0.015 * math.sin(x + 0.6) - 0.5, 0.3, 0.7)
    assert abs(y[-1] - 0.5) <= tr.ENCODER_STEP_RAD
    assert state["theta"] == pytest.approx(x_star, abs=1.5 * tr.ENCODER_STEP_RAD)
    assert y[-1] == pytest.approx(flat.reading(state["theta"]), abs=1e-12)
    assert abs(x_star - 0.5) > 8 * tr.ENCODER_STEP_RAD


# --- (i) torsion spring -----------------------------------------------------------------------

def test_torsion_spring_rest_and_acceleration():
    """Without Coulomb friction, torque off: released at -0.3 or 0.5 rad it rests where
    k (theta0 - theta) = mgl sin(theta) (scipy root, 0.084 rad); with it, the acceleration at
    release from 0.5 rad is (-k (0.5 - theta0) - mgl sin 0.5 + Fc)/J (falling)."""
    truth = tr3.TorsionSpring(replace(PLANT, coulomb=0.0))
    rest = brentq(lambda x: 0.6 * (0.25 - x) - PLANT.mgl * math.sin(x), -1.0, 1.0)
    assert rest == pytest.approx(0.084, abs=1e-3)
    for start in (-0.3, 0.5):
        assert _torque_off(truth, 5.0, start)[-1] == pytest.approx(rest, abs=1e-6)
    th = _torque_off(tr3.TorsionSpring(PLANT), 0.001, 0.5)
    a = (th[1] - 0.5) / tr.H ** 2
    assert a == pytest.approx((-0.6 * 0.25 - PLANT.mgl * math.sin(0.5) + FC) / J, rel=1e-9)


# --- make.py: determinism and the dataset contract --------------------------------------------

def test_make_is_deterministic_and_keeps_the_contract(tmp_path, capsys):
    """Same seed -> same bytes, another seed -> other bytes; the runs read back through the
    dataset contract with their metadata, jittered log intervals and encoder counts (the
    eccentric encoder's reading too); cases.json holds each case's law, source, equation,
    plant factors and expectation; the default seed is 44."""
    half_make.check_make_keeps_the_contract(make, tmp_path, ("h_eccentricity", "j_null"), 44)


def test_make_null_case_is_the_first_halfs_loop():
    """make's null case (seed 44, index 9) logs the first half's loop on its plant: its quick
    first run's encoder samples equal the first half's simulate at the logged ticks."""
    truth, runs, record = make.run_case(9, "j_null", 44, quick=True)
    run = runs[0]
    ticks = np.round(run.t / tr.H).astype(int)
    n = 1500
    held = np.searchsorted(ticks, np.arange(n) * tr.SUBSTEPS, side="right") - 1
    theta, u = tr.simulate(tr.Null(truth.p), run.r[held], np.ones(n), make1.KP, make1.COMMAND_LIMIT,
                           float(run.r[0]), {})
    y = np.round(theta[ticks] / tr.ENCODER_STEP_RAD) * tr.ENCODER_STEP_RAD
    assert np.array_equal(y, run.theta) and record["expected"]["family"] == "none"


def test_make_refuses_unknown_case(tmp_path, capsys):
    assert make.main(["--out", str(tmp_path / "x"), "--only", "a_lugre"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown case 'a_lugre'")
    assert not (tmp_path / "x").exists()


# --- score.py ---------------------------------------------------------------------------------

NULL_REPORT = tr.ROOT / "bank" / "test_half" / "null_report.json"


def _case(name):
    return {"name": name, "expected": dict(tr3.CASES)[name](PLANT).expected()}


def _named(report, name, params):
    return dict(report, effects=[{"name": name, "parameters": params, "reason": ""}])


def test_score_families():
    """This half's keywords put names into its families; the earlier halves' names keep theirs."""
    assert score.family_of("inductance_lag") == "actuator lag"
    assert score.family_of("encoder_eccentricity") == "sensor error"
    assert score.family_of("joint_stiffness") == "joint stiffness"
    assert score.family_of("quadratic_drag") == "friction: nonlinear viscous"
    assert score.family_of("payload_mass") == "inertia and gravity"
    assert score.family_of("drive_compliance") == "drive compliance"
    assert score.family_of("mass_offset") == "gravity offset"
    assert score.family_of("time_delay") == "time delay"
    assert score.family_of("load_friction") == "friction: load-dependent"


def test_score_null_payload_and_unexpressible():
    """The first half's null report (names nothing, not flagged) scores the null case fully;
    on the payload its family point passes and its direction is read from the corrections
    (the torque gain's ratio: > 1 fails, < 1 passes); naming a payload law passes the family,
    naming a gravity tilt fails it.  On the churning drag with no candidate of its family the
    right answer is a flag with maps: the unflagged report fails, the flagged one passes."""
    report = json.loads(NULL_REPORT.read_text())
    row = score.score_case(_case("j_null"), report)
    assert row["points"] == {"family": True, "no_spurious": True, "direction": True, "unexplained": True}
    pay = score.score_case(_case("g_payload"), report)
    gain = [c for c in report["corrections"] if "gain" in c["effect"]][0]["ratio_to_nominal"]
    assert pay["points"]["family"] is True and pay["points"]["direction"] is (gain < 1)
    lower = dict(report, corrections=[dict(c, ratio_to_nominal=0.78) if "gain" in c["effect"] else c
                                      for c in report["corrections"]])
    assert score.score_case(_case("g_payload"), lower)["points"]["direction"] is True
    assert score.score_case(_case("g_payload"), _named(lower, "payload_mass", {}))["points"]["family"] is True
    assert score.score_case(_case("g_payload"), _named(lower, "gravity_tilt", {}))["points"]["family"] is False
    drag = score.score_case(_case("c_churning_drag"), report)
    assert drag["library_can_express"] is False and drag["points"]["family"] is False
    flagged = dict(report, unexplained=True)
    assert score.score_case(_case("c_churning_drag"), flagged)["points"]["family"] is True
    assert score.score_case(_case("c_churning_drag"), flagged)["points"]["unexplained"] is True


def test_score_new_claims():
    """The claims this half adds, read from the named effect's parameters: unreadable is None
    (unchecked), a right value passes, a wrong one fails."""
    report = json.loads(NULL_REPORT.read_text())
    lag = score.score_case(_case("f_inductance"), _named(report, "actuator_lag", {"tau_s": 0.0035}))
    assert lag["points"]["family"] is True and lag["points"]["direction"] is True
    ms = score.score_case(_case("f_inductance"), _named(report, "actuator_lag", {"time_constant_ms": 2.5}))
    assert ms["points"]["direction"] is True
    slow = score.score_case(_case("f_inductance"), _named(report, "actuator_lag", {"tau_s": 0.02}))
    assert slow["points"]["direction"] is False
    none = score.score_case(_case("f_inductance"), _named(report, "actuator_lag", {"gain": 1.0}))
    assert none["points"]["direction"] is None and none["signs"]["time_constant_s"] is None
    ecc = score.score_case(_case("h_eccentricity"), _named(report, "encoder_eccentricity",
                                                           {"eccentricity_rad": -0.012, "phase": 0.6}))
    assert ecc["points"]["family"] is True and ecc["points"]["direction"] is True
    spring = score.score_case(_case("i_torsion_spring"), _named(report, "joint_stiffness",
                                                                 {"stiffness": 0.5, "angle": 0.2}))
    assert spring["points"]["family"] is True and spring["points"]["direction"] is True
    hertz = _case("d_hertz_load")
    ok = score.score_case(hertz, _named(report, "load_friction", {"mu_drive": 0.1, "mu_back": 0.11,
                                                                   "exponent": 0.7}))
    assert ok["points"]["direction"] is True
    lin = score.score_case(hertz, _named(report, "load_friction", {"mu_drive": 0.1, "mu_back": 0.3}))
    assert lin["signs"] == {"driving_vs_back_driven": False, "load_exponent_vs_1": None}
    assert lin["points"]["direction"] is False
    dahl = score.score_case(_case("a_dahl"), _named(report, "presliding_friction", {"fc": 0.09, "sigma0": 40}))
    assert dahl["points"]["family"] is True and dahl["points"]["direction"] is True
    kar = score.score_case(_case("b_karnopp"), _named(report, "stribeck_friction", {"fs": 0.11, "fc": 0.05}))
    assert kar["points"]["family"] is True and kar["points"]["direction"] is True


# --- the one run's record (bank/README.md, "The third half's one run") -------------------------
RECORD = tr.ROOT / "bank" / "test_half_3" / "record"


def test_readme_third_half_run_is_its_record():
    """bank/README.md's table of the third half's one run is made from test_half_3/record (the
    score as run and each case's report), the commit it names is the score's, the record's
    scores are what score.py says of its reports, and the wall times and physics steps it
    quotes are the reports' own."""
    flat = check_readme_run(RECORD, "third test half", score.score_case)
    hertz = json.loads((RECORD / "d_hertz_load" / "report.json").read_text())
    v = next(r["variants"] for r in hertz["rounds"] if "variants" in r)
    assert v["chosen"] == "load_friction"
    assert (f"(`d_hertz_load`: {v['load_friction']['heldout_gap_rad']:.2e} rad held out against the smooth "
            f"variant's {v['load_friction_smooth']['heldout_gap_rad']:.2e})").replace("e-03", "e-3") in flat
    spring = json.loads((RECORD / "i_torsion_spring" / "report.json").read_text())
    assert f"the spring's gap stays at {spring['gap_after']:.2e} rad" in flat
