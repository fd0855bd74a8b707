"""The bank's second test half (bank/test_half_2): each truth's law against an independent check
(closed forms, scipy roots, scipy's ODE solvers on the law's own equations), its loop against
the first half's, make.py's determinism and the dataset contract, and score.py's extensions.

As in the first half's tests: a constant command ``u`` is had by a huge gain clipped at
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

from bank.test_half import truths as tr
from bank.test_half_2 import make, score
from bank.test_half_2 import truths as tr2
from tests import half_make
from tests.half_record import check_readme_run

PLANT = tr.nominal_plant()
FLAT = replace(PLANT, mgl=0.0)
G, EMF, B, FC, J = PLANT.gear, PLANT.emf, PLANT.bearing, PLANT.coulomb, PLANT.inertia


def _constant(truth, u, seconds, theta0=0.0, sign=1.0, state=None):
    """Angle every 0.1 ms under a constant command ``sign * u`` [V]."""
    n = int(round(seconds / tr.CONTROL_PERIOD_S))
    state = truth.initial_state() if state is None else state
    theta, cmd = tr2.simulate(truth, np.full(n, sign * 1e3), np.ones(n), 1e6, u, theta0, state)
    assert np.allclose(cmd[truth.delay_periods if isinstance(truth, tr2.OwnLoop) else 0:], sign * u)
    return theta


def _torque_off(truth, seconds, theta0):
    n = int(round(seconds / tr.CONTROL_PERIOD_S))
    theta, u = tr2.simulate(truth, np.zeros(n), np.zeros(n), 30.0, 12.0, theta0, truth.initial_state())
    assert np.all(u == 0.0)
    return theta


def _end_speed(theta, periods=10):
    return (theta[-1] - theta[-1 - periods * tr.SUBSTEPS]) / (periods * tr.CONTROL_PERIOD_S)


def _initial_acceleration(truth, u, theta0):
    """theta_1 = theta0 + h^2 a: the semi-implicit Euler step from rest."""
    theta = _constant(truth, u, 0.001, theta0=theta0)
    return (theta[1] - theta0) / tr.H ** 2


def test_own_loop_is_the_first_halfs_loop():
    """An OwnLoop truth with the default step and no delay gives the first half's trajectory
    bit for bit (the same P law, encoder, hold and sub-step): a 0.3 rad step with gravity."""
    class Plain(tr2.OwnLoop):
        pass
    n = 800
    goal = np.full(n, 0.3)
    a = tr2.simulate(Plain(PLANT), goal, np.ones(n), 30.0, 12.0, 0.0, {})
    b = tr.simulate(tr.Null(PLANT), goal, np.ones(n), 30.0, 12.0, 0.0, {})
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert np.ptp(a[0]) > 0.25


# --- (a) LuGre --------------------------------------------------------------------------------

def _lugre_ode(truth, u):
    """The LuGre equations of Canudas de Wit et al. 1995 on the flat plant, constant u."""
    q = truth.params

    def g(w):
        return q["Fc"] + (q["Fs"] - q["Fc"]) * math.exp(-(w / q["vs"]) ** 2)

    def f(t, x):
        th, w, z = x
        zdot = w - q["sigma0"] * abs(w) * z / g(w)
        friction = q["sigma0"] * z + q["sigma1"] * zdot + q["sigma2"] * w
        return [w, (G * u - (EMF + B) * w - friction) / J, zdot]
    return f


@pytest.mark.parametrize("u", [0.25, 0.45])
def test_lugre_against_an_ode_solver(u):
    """From rest, a constant command below (0.075 N m < Fs 0.10: presliding only) and above
    the breakaway (0.135 N m): the truth's angle against scipy's Radau on the paper's three
    equations, 0.4 s, within 2e-5 rad (the Euler step's first-order error)."""
    truth = tr2.LuGre(FLAT)
    theta = _constant(truth, u, 0.4)
    t = np.arange(len(theta)) * tr.H
    sol = solve_ivp(_lugre_ode(truth, u), (0, t[-1]), [0, 0, 0], method="Radau", t_eval=t[::100],
                    rtol=1e-9, atol=1e-12, max_step=1e-3)
    err = np.abs(theta[::100] - sol.y[0]).max()
    assert err < max(2e-5, 2e-3 * np.ptp(sol.y[0])), err
    fs, s0 = truth.params["Fs"], truth.params["sigma0"]
    if G * u < fs:   # presliding: it stops; at least the quasi-static -(Fs/s0) ln(1 - tau/Fs)
        assert abs(_end_speed(theta)) < 1e-3
        creep = -(fs / s0) * math.log(1 - G * u / fs)
        assert creep <= theta[-1] <= 3 * creep and theta[-1] < 3 * tr.ENCODER_STEP_RAD
    else:
        assert theta[-1] > 0.05


def test_lugre_steady_sliding_is_its_stribeck_curve():
    """Steady sliding: dz/dt = 0 gives F = g(w) + sigma2 w; the speed under a constant command
    solves G u = g(w) + (sigma2 + kt^2/R + b) w (scipy root) at two speeds, one in the
    Stribeck dip."""
    truth = tr2.LuGre(FLAT)
    q = truth.params
    for u in (0.5, 1.5):
        w_star = brentq(lambda w: G * u - q["Fc"] - (q["Fs"] - q["Fc"]) * math.exp(-(w / q["vs"]) ** 2)
                        - (q["sigma2"] + EMF + B) * w, 1e-6, 20.0)
        w = _end_speed(_constant(truth, u, 1.0))
        assert w == pytest.approx(w_star, rel=1e-3), (u, w, w_star)
    assert brentq(lambda w: G * 0.5 - truth.g(w) - (q["sigma2"] + EMF + B) * w, 1e-6, 20.0) < 0.3


# --- (b) harmonic drive -----------------------------------------------------------------------

def test_harmonic_drive_quadrants_and_viscous():
    """Initial acceleration from rest at pi/2 (gravity 1.18 N m): lifting at 8 V,
    J a = G u - mgl - Fc - (1 - eta_f) G u; falling against 1 V (back-driven),
    J a = G u - mgl + Fc + (1/eta_b - 1) G u.  Steady speed on the flat plant (driving):
    the linear balance G u - (kt^2/R + b + Bv) w - Fc - (1 - eta_f)(G u - kt^2/R w) = 0."""
    truth = tr2.HarmonicDrive(PLANT)
    ef, eb, bv = 0.85, 0.70, 0.04
    up = _initial_acceleration(truth, 8.0, math.pi / 2)
    assert up == pytest.approx((G * 8 - PLANT.mgl - FC - (1 - ef) * G * 8) / J, rel=1e-6)
    down = _initial_acceleration(truth, 1.0, math.pi / 2)
    assert down == pytest.approx((G - PLANT.mgl + FC + (1 / eb - 1) * G) / J, rel=1e-6)
    flat = tr2.HarmonicDrive(FLAT)
    u = 3.0
    w_star = (G * u * ef - FC) / (EMF + B + bv - (1 - ef) * EMF)
    assert _end_speed(_constant(flat, u, 1.0)) == pytest.approx(w_star, rel=1e-3)


# --- (c) worm mesh ----------------------------------------------------------------------------

def test_worm_efficiencies_are_shigleys():
    """With a zero pressure angle the Shigley relations are the screw's tan forms:
    eta_f = tan(l) / tan(l + phi), eta_b = tan(l - phi) / tan(l), phi = atan(mu)."""
    lam, mu = math.radians(8.0), 0.08
    square = tr2.WormMesh(PLANT, pressure_deg=0.0).efficiencies()
    phi = math.atan(mu)
    assert square[0] == pytest.approx(math.tan(lam) / math.tan(lam + phi), rel=1e-12)
    assert square[1] == pytest.approx(math.tan(lam - phi) / math.tan(lam), rel=1e-12)
    ef, eb = tr2.WormMesh(PLANT).efficiencies()
    assert ef == pytest.approx(0.615, abs=1e-3) and eb == pytest.approx(0.390, abs=1e-3)


def test_worm_mesh_power_balance_from_rest():
    """At pi/2 from rest, each regime's acceleration is the root (scipy) of the mesh's power
    balance with the two inertias: lifting (rotor drives), eta_f (tau - J_a a) = J_l a + mgl;
    falling against 1 V (pendulum back-drives), tau - J_a a = eta_b (J_l a + mgl), tau the
    motor's torque with the gear train's Coulomb friction opposing the motion."""
    truth = tr2.WormMesh(PLANT)
    ef, eb = truth.efficiencies()
    ja, jl, mgl = PLANT.armature, PLANT.j_link, PLANT.mgl
    up = brentq(lambda a: ef * (G * 8 - FC - ja * a) - (jl * a + mgl), -1e3, 1e3)
    assert up > 0 and _initial_acceleration(truth, 8.0, math.pi / 2) == pytest.approx(up, rel=1e-9)
    down = brentq(lambda a: (G * 1 + FC - ja * a) - eb * (jl * a + mgl), -1e3, 1e3)
    assert down < 0 and _initial_acceleration(truth, 1.0, math.pi / 2) == pytest.approx(down, rel=1e-9)


def test_worm_mesh_holds_in_its_band():
    """Held at pi/2 by any motor torque in [eta_b mgl - Fc, mgl/eta_f + Fc] (it neither falls
    nor lifts), outside it moves; with torque off it back-drives (eta_b > 0)."""
    truth = tr2.WormMesh(PLANT)
    ef, eb = truth.efficiencies()
    lo, hi = (eb * PLANT.mgl - FC) / G, (PLANT.mgl / ef + FC) / G
    for u, moves in ((0.98 * lo, -1), (1.02 * lo, 0), (0.98 * hi, 0), (1.02 * hi, 1)):
        th = _constant(truth, u, 0.05, theta0=math.pi / 2)
        assert np.sign(th[-1] - math.pi / 2) == moves, (u, lo, hi)
    assert lo < 0.45 * PLANT.mgl / G      # holds with less than half of gravity's torque
    drop = _torque_off(truth, 0.3, math.pi / 2)
    assert drop[-1] < math.pi / 2 - 0.05


# --- (d) atan load friction -------------------------------------------------------------------

def test_load_atan_driving_steady_speed():
    """Flat plant, constant u (driving): G u - (kt^2/R + b) w - Fc
    - mu_drive |G u - kt^2/R w| (2/pi) atan(w/ws) = 0 (scipy root)."""
    truth = tr2.LoadAtan(FLAT)
    u = 2.0

    def balance(w):
        tau_m = G * u - EMF * w
        return tau_m - B * w - FC - 0.25 * abs(tau_m) * (2 / math.pi) * math.atan(w / 0.05)

    w_star = brentq(balance, 1e-6, 10.0)
    assert _end_speed(_constant(truth, u, 1.0)) == pytest.approx(w_star, rel=1e-3)


def test_load_atan_back_driven_fall_against_an_ode_solver():
    """At pi/2 against 1 V the pendulum falls, back-driving the motor (tau_m > 0, w < 0):
    the truth against scipy's LSODA on J w' = tau_m - b w - mgl sin + Fc
    - mu_back |tau_m| (2/pi) atan(w/ws), 0.3 s; the drive coefficient instead misses by far."""
    truth = tr2.LoadAtan(PLANT)
    theta = _constant(truth, 1.0, 0.3, theta0=math.pi / 2)

    def ode(mu):
        def f(t, x):
            th, w = x
            tau_m = G - EMF * w
            return [w, (tau_m - B * w - PLANT.mgl * math.sin(th) + FC
                        - mu * abs(tau_m) * (2 / math.pi) * math.atan(w / 0.05)) / J]
        return f

    t = np.arange(len(theta)) * tr.H
    sols = [solve_ivp(ode(mu), (0, t[-1]), [math.pi / 2, 0], method="LSODA", t_eval=t[::100],
                      rtol=1e-10, atol=1e-12) for mu in (0.08, 0.25)]
    assert np.all(np.diff(theta) < 0)                 # falling all along: back-driven
    err = np.abs(theta[::100] - sols[0].y[0]).max()
    assert err < 2e-4, err
    assert np.abs(theta[::100] - sols[1].y[0]).max() > 10 * err


# --- (e) dead zone ----------------------------------------------------------------------------

def test_dead_zone():
    """Flat plant: 0.5 V (0.15 N m, five times the Coulomb level) does not move it; 2 V either
    way runs at w = (G (|u| - 0.6) - Fc)/(kt^2/R + b)."""
    truth = tr2.DeadZone(FLAT)
    assert np.ptp(_constant(truth, 0.5, 0.3)) == 0.0
    for sign in (1.0, -1.0):
        w = _end_speed(_constant(truth, 2.0, 1.0, sign=sign))
        assert w == pytest.approx(sign * (G * 1.4 - FC) / (EMF + B), rel=1e-3)


# --- (f) cogging ------------------------------------------------------------------------------

def test_cogging_wells_and_initial_acceleration():
    """Flat plant, no Coulomb friction, torque off: released at 0.2 rad it settles in the well
    of A sin(n theta + phi) it starts in, theta* = (pi - phi)/n = 0.2368 rad.  With gravity,
    the acceleration at release is (A sin(n theta0 + phi) - mgl sin theta0)/J."""
    truth = tr2.Cogging(replace(FLAT, coulomb=0.0))
    th = _torque_off(truth, 10.0, 0.2)     # overdamped: time constant (kt^2/R + b)/(n A) = 0.77 s
    assert th[-1] == pytest.approx((math.pi - 0.3) / 12, abs=1e-5)
    truth = tr2.Cogging(replace(PLANT, coulomb=0.0))
    th = _torque_off(truth, 0.001, 0.5)
    a = (th[1] - 0.5) / tr.H ** 2
    assert a == pytest.approx((0.04 * math.sin(12 * 0.5 + 0.3) - PLANT.mgl * math.sin(0.5)) / J, rel=1e-9)


# --- (g) mass offset --------------------------------------------------------------------------

def test_mass_offset_hangs_at_phi0():
    """No Coulomb friction, torque off: released at 0.3 rad (or -0.3) it comes to rest at
    phi0 = 0.06 rad, where the centre of mass is under the pivot."""
    truth = tr2.MassOffset(replace(PLANT, coulomb=0.0))
    for start in (0.3, -0.3):
        assert _torque_off(truth, 5.0, start)[-1] == pytest.approx(0.06, abs=1e-6)


# --- (h) latency ------------------------------------------------------------------------------

def test_latency_holds_six_periods_then_the_step():
    """Flat plant at rest, goal 0.3 rad from t = 0 (P law 30 V/rad): the command applied is the
    start's hold (0 V) for six periods, then 9 V; the angle stays 0 for 60 sub-steps and then
    takes the first step h^2 (9 G - Fc)/J.  A torque-off is obeyed six periods late."""
    truth = tr2.Latency(FLAT)
    n = 30
    theta, u = tr2.simulate(truth, np.full(n, 0.3), np.ones(n), 30.0, 12.0, 0.0, {})
    assert np.all(u[:6] == 0.0) and np.all(u[6:12] == 9.0)
    assert np.all(theta[:61] == 0.0)
    assert theta[61] == pytest.approx(tr.H ** 2 * (9 * G - FC) / J, rel=1e-9)
    en = np.r_[np.ones(10), np.zeros(20)]
    _, u = tr2.simulate(truth, np.full(n, 0.3), en, 30.0, 12.0, 0.0, {})
    assert np.all(u[10:16] != 0.0) and np.all(u[16:] == 0.0)


# --- (i) compliance ---------------------------------------------------------------------------

def test_compliance_against_an_ode_solver():
    """Flat plant, no Coulomb friction, 2 V from rest: the pendulum's angle against scipy's
    Radau on Spong's two-mass equations (rotor J_a with the motor, spring and damper to the
    pendulum J_l), 0.2 s, within 3e-4 rad: the sub-step's first-order error (halving the
    sub-step halves it: 1.5e-4, 7.5e-5, 3.8e-5 rad at 0.1, 0.05, 0.025 ms, checked once); the
    rigid joint differs by far more, and the pendulum does not move in the first sub-step
    (the spring is unwound)."""
    truth = tr2.Compliance(replace(FLAT, coulomb=0.0))
    theta = _constant(truth, 2.0, 0.2)
    ja, jl, k, c = FLAT.armature, FLAT.j_link, 150.0, 0.2

    def f(t, x):
        qm, wm, q, w = x
        s = k * (qm - q) + c * (wm - w)
        return [wm, (G * 2.0 - EMF * wm - B * wm - s) / ja, w, s / jl]

    t = np.arange(len(theta)) * tr.H
    sol = solve_ivp(f, (0, t[-1]), [0, 0, 0, 0], method="Radau", t_eval=t[::50], rtol=1e-10, atol=1e-13)
    err = np.abs(theta[::50] - sol.y[2]).max()
    assert err < 3e-4, err
    assert theta[1] == 0.0
    rigid = _constant(tr.Null(replace(FLAT, coulomb=0.0)), 2.0, 0.2)
    assert np.abs(rigid[::50] - sol.y[2]).max() > 5 * err   # 1.4e-3 rad: the spring winding up


# --- make.py: determinism and the dataset contract --------------------------------------------

def test_make_is_deterministic_and_keeps_the_contract(tmp_path, capsys):
    """Same seed -> same bytes, another seed -> other bytes; the runs read back through the
    dataset contract with their metadata (kind, kp, command_limit, control_period_s,
    encoder_step_rad, units), jittered log intervals, encoder counts; cases.json holds each
    case's law, source, equation, plant factors and expectation."""
    half_make.check_make_keeps_the_contract(make, tmp_path, ("h_latency", "j_null"), 43)


def test_make_refuses_unknown_case(tmp_path, capsys):
    assert make.main(["--out", str(tmp_path / "x"), "--only", "a_stribeck"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown case 'a_stribeck'")
    assert not (tmp_path / "x").exists()


def test_cases_are_new_and_documented():
    """Ten cases, a null among them; each expectation in known families, each law cited with
    its equation; no law's name is one of the first half's."""
    assert len(tr2.CASES) == 10
    first = {cls.name for _, cls in tr.CASES}
    for name, cls in tr2.CASES:
        truth = cls(PLANT)
        e = truth.expected()
        assert e["family"] in tr2.FAMILIES and set(e["accept"]) | set(e["partial"]) <= set(tr2.FAMILIES), name
        assert truth.source and truth.equation and cls.__doc__, name
        assert truth.name not in first or name == "j_null", name
    assert tr2.Null(PLANT).expected()["family"] == "none"


# --- score.py ---------------------------------------------------------------------------------

NULL_REPORT = tr.ROOT / "bank" / "test_half" / "null_report.json"


def _case(name):
    return {"name": name, "expected": dict(tr2.CASES)[name](PLANT).expected()}


def test_score_families_and_new_claims():
    """The first half's null report (names nothing, not flagged) scores the null case fully and
    fails the dead zone (no candidate of its list is a dead zone: a flag was due); a report
    naming a cogging law with 12 periods per turn passes the cogging case's family and
    direction, with 7 its direction fails; a flagged report with maps and nothing named passes
    the dead zone."""
    report = json.loads(NULL_REPORT.read_text())
    row = score.score_case(_case("j_null"), report)
    assert row["points"] == {"family": True, "no_spurious": True, "direction": True, "unexplained": True}
    dz = score.score_case(_case("e_dead_zone"), report)
    assert dz["library_can_express"] is False and dz["points"]["family"] is False
    flagged = dict(report, unexplained=True)
    assert score.score_case(_case("e_dead_zone"), flagged)["points"]["family"] is True
    assert score.score_case(_case("e_dead_zone"), flagged)["points"]["unexplained"] is True
    report = dict(report, effects=[{"name": "cogging", "parameters": {"amplitude_nm": 0.04, "harmonic": 12},
                                    "reason": ""}])
    cog = score.score_case(_case("f_cogging"), report)
    assert cog["points"]["family"] is True and cog["points"]["direction"] is True
    report["effects"][0]["parameters"]["harmonic"] = 7
    assert score.score_case(_case("f_cogging"), report)["points"]["direction"] is False
    assert score.family_of("gravity_tilt") == "gravity offset"
    assert score.family_of("load_friction") == "friction: load-dependent"
    assert score.family_of("time_delay") == "time delay"
    report["effects"] = [{"name": "time_delay", "parameters": {"delay_s": 0.0055}, "reason": ""}]
    lat = score.score_case(_case("h_latency"), report)
    assert lat["points"]["family"] is True and lat["points"]["direction"] is True
    report["effects"] = [{"name": "load_friction", "parameters": {"mu_drive": 0.1, "mu_back": 0.3}, "reason": ""}]
    assert score.score_case(_case("c_worm_mesh"), report)["points"]["direction"] is True
    assert score.score_case(_case("d_load_atan"), report)["points"]["direction"] is False


# --- the one run's record (bank/README.md, "The second half's one run") -------------------------
RECORD = tr.ROOT / "bank" / "test_half_2" / "record"


def test_readme_second_half_run_is_its_record():
    """bank/README.md's table of the second half's one run is made from test_half_2/record (the
    score as run and each case's report), the commit it names is the score's and the reports',
    the record's scores are what score.py says of its reports, and the wall times it quotes
    are the reports' own."""
    flat = check_readme_run(RECORD, "second test half", score.score_case)
    lat = json.loads((RECORD / "h_latency" / "report.json").read_text())["effects"]
    assert [e["name"] for e in lat] == ["presliding_friction", "time_delay"]
    assert f"(`time_delay` {1e3 * lat[1]['parameters']['delay_s']:.2f} ms, {lat[1]['confidence']} confidence)" in flat
