"""The bank's test half (bank/test_half): each truth's law against an independent check
(closed forms, MuJoCo, scipy roots), and make.py's determinism.

The truths run the servo's P loop (``truths.simulate``); a constant command ``u`` is had by a
huge gain clipped at ``command_limit = u`` with a goal far away.  "Horizontal" plants have
``mgl = 0`` (no gravity), so that a constant command gives a steady speed.
"""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest
from scipy.optimize import brentq

from bank.test_half import make, score
from bank.test_half import truths as tr
from tests import half_make

PLANT = tr.nominal_plant()
FLAT = replace(PLANT, mgl=0.0)


def _constant(truth, u, seconds, theta0=0.0, sign=1.0):
    """Angle every 0.1 ms under a constant command ``sign * u`` [V]."""
    n = int(round(seconds / tr.CONTROL_PERIOD_S))
    goal = np.full(n, sign * 1e3)
    theta, cmd = tr.simulate(truth, goal, np.ones(n), 1e6, u, theta0, truth.initial_state())
    assert np.allclose(cmd, sign * u)
    return theta


def _end_speed(theta, periods=10):
    return (theta[-1] - theta[-1 - periods * tr.SUBSTEPS]) / (periods * tr.CONTROL_PERIOD_S)


def test_plant_is_the_nominal_file():
    """The plant read from the file matches its README's hand figures (m g l = 1.18 N m,
    pendulum inertia 1.82e-2 kg m^2) and its stated constants."""
    assert PLANT.mgl == pytest.approx(1.18, rel=0.01)
    assert PLANT.j_link == pytest.approx(1.82e-2, rel=0.01)
    assert PLANT.gear == 0.30 and PLANT.armature == 2.5e-3 and PLANT.coulomb == 0.03
    assert PLANT.emf + PLANT.bearing == pytest.approx(0.37)
    assert PLANT.kt == pytest.approx(1.2) and PLANT.resistance == pytest.approx(4.0)


def test_integration_matches_mujoco_rk4():
    """The truth's own integration (0.1 ms semi-implicit Euler) against MuJoCo's RK4 on the
    file itself (frictionloss 0, the same P loop closed by hand): a 0.3 rad step under
    gravity, 1 s.  Semi-implicit Euler is first order: its error is about h/2 times the
    largest speed change per second; here below 1e-3 rad."""
    truth = tr.Null(replace(PLANT, coulomb=0.0))
    n = 1000
    goal = np.full(n, 0.3)
    theta, u = tr.simulate(truth, goal, np.ones(n), 30.0, 12.0, 0.0, {})
    m = mujoco.MjModel.from_xml_path(str(tr.NOMINAL))
    m.dof_frictionloss[:] = 0.0
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    m.opt.timestep = 1e-4
    d = mujoco.MjData(m)
    q = tr.ENCODER_STEP_RAD
    ref = [0.0]
    for k in range(n):
        y = round(d.qpos[0] / q) * q
        d.ctrl[0] = min(12.0, max(-12.0, 30.0 * (0.3 - y)))
        for _ in range(tr.SUBSTEPS):
            mujoco.mj_step(m, d)
        ref.append(d.qpos[0])
    err = np.abs(theta[:: tr.SUBSTEPS] - np.array(ref))
    assert err.max() < 1e-3, err.max()
    assert abs(theta[-1] - ref[-1]) < 2e-4
    assert np.ptp(theta) > 0.3   # it moved


def test_stribeck_steady_speed_at_two_speeds():
    """Steady sliding on a flat plant: (kt/R) u = F(w) + (Fv + kt^2/R + b) w with the
    exponential Stribeck curve; the command for w* = 0.3 and 1.0 rad/s in closed form gives
    back w* (each above the breakaway Fs, and the balance has one root: the curve's steepest
    fall, 0.3 N m s/rad, is less than the damping, 0.4).  At 0.3 rad/s the curve adds
    7.4 mN m over Coulomb (0.018 rad/s of speed)."""
    truth = tr.Stribeck(FLAT)
    q = truth.params
    c = q["Fv"] + FLAT.emf + FLAT.bearing
    for w_star in (0.3, 1.0):
        f = q["Fc"] + (q["Fs"] - q["Fc"]) * math.exp(-(w_star / q["ws"]) ** 2)
        u = (f + c * w_star) / FLAT.gear
        w = _end_speed(_constant(truth, u, 1.5))
        assert w == pytest.approx(w_star, rel=2e-3), (w_star, w)
    coulomb_only = (q["Fc"] + c * 0.3) / FLAT.gear
    w = _end_speed(_constant(truth, coulomb_only, 1.5))
    assert w < 0.3 - 0.01   # the Stribeck hump is felt


def test_stribeck_breakaway_at_static_level():
    """At rest a torque just below Fs sticks, just above it moves."""
    truth = tr.Stribeck(FLAT)
    fs = truth.params["Fs"]
    assert np.ptp(_constant(truth, 0.99 * fs / FLAT.gear, 0.3)) == 0.0
    assert np.ptp(_constant(truth, 1.01 * fs / FLAT.gear, 0.3)) > 0.0


def test_asymmetric_coulomb_steady_speeds():
    """w+- = ((kt/R) |u| - F+-) / (kt^2/R + b) for each direction."""
    truth = tr.AsymmetricCoulomb(FLAT)
    c = FLAT.emf + FLAT.bearing
    u = 1.0
    w_pos = _end_speed(_constant(truth, u, 1.0, sign=1.0))
    w_neg = _end_speed(_constant(truth, u, 1.0, sign=-1.0))
    assert w_pos == pytest.approx((FLAT.gear * u - 0.07) / c, rel=1e-3)
    assert w_neg == pytest.approx(-(FLAT.gear * u - 0.025) / c, rel=1e-3)


def _initial_acceleration(truth, u, theta0):
    """The acceleration from rest over the first sub-step: theta_1 = theta0 + h^2 a (the
    semi-implicit Euler step from rest), i.e. the law's torque at rest, before any speed."""
    theta = _constant(truth, u, 0.001, theta0=theta0)
    return (theta[1] - theta0) / tr.H ** 2


@pytest.mark.parametrize("cls", [tr.LoadQuadrant, tr.GearEfficiency])
def test_load_friction_in_both_quadrants(cls):
    """Initial acceleration from rest, gravity acting (theta0 = pi/2, sin = 1):
    driving (lifting, u = 8 V): J a = G u - mgl - (Fc + mu_drive G u);
    back-driven (u = 1 V, the load falls against the motor): J a = G u - mgl + (Fc + mu_back G u).
    Each quadrant's coefficient is the law's (Hamon's F_drive/F_back; 1 - eta and
    1/(2 - 1/eta) - 1)."""
    truth = cls(PLANT)
    if cls is tr.LoadQuadrant:
        mu_d, mu_b = truth.params["F_drive"], truth.params["F_back"]
    else:
        eta = truth.params["eta"]
        mu_d, mu_b = 1 - eta, 1 / (2 - 1 / eta) - 1
    g, fc, j = PLANT.gear, PLANT.coulomb, PLANT.inertia
    up = _initial_acceleration(truth, 8.0, math.pi / 2)
    assert up == pytest.approx((g * 8 - PLANT.mgl - fc - mu_d * g * 8) / j, rel=1e-6)
    down = _initial_acceleration(truth, 1.0, math.pi / 2)
    assert down == pytest.approx((g * 1 - PLANT.mgl + fc + mu_b * g * 1) / j, rel=1e-6)
    # the two quadrants differ by more than the tolerance
    assert abs(mu_d - mu_b) * g * 8 / j > 0.05 * abs(up)


def test_users_friction_steady_speed():
    """Flat plant, constant u: G u - (kt^2/R + b) w - Fc - 0.2 |G u - kt^2/R w| tanh(w/0.02) = 0
    (root by scipy)."""
    truth = tr.UsersPendulum(FLAT)
    g, emf, b, fc = FLAT.gear, FLAT.emf, FLAT.bearing, FLAT.coulomb
    u = 2.0

    def balance(w):
        tau_m = g * u - emf * w
        return tau_m - b * w - fc - 0.2 * abs(tau_m) * math.tanh(w / 0.02)

    w_star = brentq(balance, 1e-6, 10.0)
    assert _end_speed(_constant(truth, u, 1.0)) == pytest.approx(w_star, rel=1e-3)
    free = (g * u - fc) / (emf + b)            # the speed without the law
    assert free - w_star > 10 * 1e-3 * w_star   # the law is felt, 10x the tolerance


def test_end_stop_equilibrium_beyond_the_limit():
    """The servo pushes the pendulum towards 0.6 rad, beyond the stop at 0.35: at rest the
    angle solves kp G (0.6 - y) = mgl sin(theta) + k (theta - 0.35)^1.5 +- Fc (scipy root,
    y within an encoder count of theta); without the stop it would sit near 0.51 rad."""
    truth = tr.EndStop(PLANT)
    n = 3000
    theta, _ = tr.simulate(truth, np.full(n, 0.6), np.ones(n), 30.0, 12.0, 0.0, {})
    k, n_exp, ts = truth.params["k"], truth.params["n"], truth.params["theta_stop"]
    g, fc = PLANT.gear, PLANT.coulomb
    q = tr.ENCODER_STEP_RAD

    def balance(th, friction, dy):
        return 30.0 * g * (0.6 - th - dy) - PLANT.mgl * math.sin(th) - k * (th - ts) ** n_exp + friction

    lo = brentq(balance, ts, 0.6, args=(-fc, q))
    hi = brentq(balance, ts, 0.6, args=(fc, -q))
    assert lo <= theta[-1] <= hi, (lo, theta[-1], hi)
    assert theta[-1] - ts > 1e-3          # it presses into the stop
    assert hi - ts < 0.05                 # and is held near it
    # the contact torque itself: k d^n (1 + 1.5 alpha d'), never pulling
    assert truth.contact(ts + 0.01, 0.0) == pytest.approx(-2000 * 0.01 ** 1.5)
    assert truth.contact(ts + 0.01, -10.0) == 0.0
    assert truth.contact(ts - 0.01, 0.0) == 0.0


def test_backlash_dead_zone():
    """Flat plant, pendulum at rest, rotor and pendulum centred in the gap: under a constant
    command the pendulum does not move until the rotor has crossed the half gap alpha, at
    t1 from the rotor's free motion J_m w' = G u - (kt^2/R + b) w - Fc in closed form:
    theta_m(t) = (tau/c) (t - (1 - e^{-a t})/a), a = c/J_m."""
    truth = tr.Backlash(FLAT)
    u = 2.0
    theta = _constant(truth, u, 0.05)
    c, jm = FLAT.emf + FLAT.bearing, FLAT.armature
    a, tau = c / jm, FLAT.gear * u - FLAT.coulomb
    t1 = brentq(lambda t: tau / c * (t - (1 - math.exp(-a * t)) / a) - truth.params["alpha"], 1e-6, 1.0)
    i1 = int(t1 / tr.H)
    assert np.all(theta[: i1 - 5] == 0.0)
    assert theta[i1 + 50] > 0.0
    # the dead-zone shaft torque (Nordin & Gutman): k (x - alpha sign x) + c x' outside, 0 inside
    assert truth.shaft(0.009, 5.0) == 0.0
    assert truth.shaft(0.015, 0.0) == pytest.approx(300 * 0.005)
    assert truth.shaft(-0.015, 0.0) == pytest.approx(-300 * 0.005)


def test_current_limit_torque_bound_at_speed():
    """Flat plant, 12 V applied: the motor torque read off the trajectory,
    J w' + b w + Fc, equals kt min(i_max, (Vs - ke w)/R) at every speed: the current bound
    at low speed, the voltage's above w = (Vs - R i_max)/ke = 6.67 rad/s."""
    truth = tr.CurrentLimit(FLAT)
    theta = _constant(truth, 12.0, 1.0)
    w = np.diff(theta) / tr.H
    acc = np.diff(w) / tr.H
    ws = w[:-1]
    motor = FLAT.inertia * acc + FLAT.bearing * ws + FLAT.coulomb
    kt, r = FLAT.kt, FLAT.resistance
    bound = kt * np.minimum(truth.params["i_max"], (12.0 - kt * ws) / r)
    moving = ws > 0.01
    assert np.abs(motor[moving] - bound[moving]).max() < 2e-3 * kt
    assert ws.max() > 7.0 and ws.min() < 1.0   # both regimes were crossed
    assert truth.bound(2.0) == pytest.approx(1.2) and truth.bound(8.0) == pytest.approx(1.2 * (12 - 9.6) / 4)


def test_thermal_first_order_and_linear_friction():
    """A constant current i for t: T = Ta + R i^2 Rth (1 - e^{-t/(Rth C)}) (closed form; the
    sub-step Euler is within 1e-3 K); the rest between runs cools exponentially; the
    friction is linear in T."""
    truth = tr.ThermalFriction(PLANT)
    q = truth.params
    state = truth.initial_state()
    i = 1.5
    steps = 200000  # 20 s
    for _ in range(steps):
        truth.heat(i * PLANT.kt, state)
    tau_th = q["Rth"] * q["C"]
    expect = q["T_amb"] + PLANT.resistance * i * i * q["Rth"] * (1 - math.exp(-20.0 / tau_th))
    assert state["T"] == pytest.approx(expect, abs=1e-2)
    hot = state["T"]
    truth.rest(10.0, state)
    assert state["T"] - q["T_amb"] == pytest.approx((hot - q["T_amb"]) * math.exp(-10.0 / tau_th))
    assert truth.level(q["T_amb"] + 10) == pytest.approx(q["Fc0"] * (1 + 10 * q["beta"]))
    assert truth.level(q["T_amb"] + 1e3) == 0.0


def test_torque_off_is_a_shorted_winding():
    """Torque off: no drive, the back-EMF brakes: from rest at 0.5 rad the pendulum creeps
    down without a swing (the nominal's damping over-damps it: zeta > 1) and the logged
    command is 0."""
    truth = tr.Null(PLANT)
    n = 2000
    theta, u = tr.simulate(truth, np.full(n, 0.5), np.zeros(n), 30.0, 12.0, 0.5, {})
    assert np.all(u == 0.0)
    assert np.all(np.diff(theta) <= 0.0) and theta[-1] < 0.05
    zeta = (PLANT.emf + PLANT.bearing) / (2 * math.sqrt(PLANT.mgl * PLANT.inertia))
    assert zeta > 1.0


def test_make_is_deterministic(tmp_path, capsys):
    """Same seed -> same bytes; another seed -> other bytes (jitter and the plant's offsets)."""
    args = ["--only", "j_null,h_current_limit", "--quick"]
    assert make.main(["--out", str(tmp_path / "a"), *args]) == 0
    assert make.main(["--out", str(tmp_path / "b"), *args]) == 0
    assert make.main(["--out", str(tmp_path / "c"), "--seed", "7", *args]) == 0
    a, b, c = (half_make.digest(tmp_path / x) for x in "abc")
    assert a == b and len(a) == 2 * 4 + 1
    assert a["j_null/lift_and_drop.csv"] != c["j_null/lift_and_drop.csv"]
    from identification.dataset import read_dataset
    runs = read_dataset(tmp_path / "a" / "j_null", require_pose=False, uniform=False)
    assert len(runs) == 2 and all(np.all(np.diff(r.t) >= 3.5e-3 - 1e-12) for r in runs)
    drop = [r for r in runs if r.name == "lift_and_drop"][0]
    off = np.flatnonzero(drop.extra["enabled"] == 0)
    # the servo obeys torque-off from its next 1 ms period: the period under way at the
    # first disabled sample may still drive
    assert len(off) > 10 and np.all(drop.v[off[1:]] == 0.0)
    assert np.allclose(np.round(drop.theta / tr.ENCODER_STEP_RAD) * tr.ENCODER_STEP_RAD, drop.theta)


def test_make_refuses_unknown_case(tmp_path, capsys):
    assert make.main(["--out", str(tmp_path / "x"), "--only", "nope"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown case 'nope'")
    assert not (tmp_path / "x").exists()


def test_expectations_use_known_families():
    for name, cls in tr.CASES:
        e = cls(PLANT).expected()
        assert e["family"] in tr.FAMILIES and set(e["accept"]) <= set(tr.FAMILIES), name


# --- score.py on the one pre-freeze report (the null case, seed 41, commit db86d6b) ---------

NULL_REPORT = tr.ROOT / "bank" / "test_half" / "null_report.json"


def _case(name):
    return {"name": name, "expected": dict(tr.CASES)[name](PLANT).expected()}


def test_score_reads_the_null_report():
    """The null case's real report names nothing and its ``unexplained`` key is false: every
    point is earned; its reason text nevertheless says UNEXPLAINED, which the score records."""
    import json
    report = json.loads(NULL_REPORT.read_text())
    row = score.score_case(_case("j_null"), report)
    assert row["named"] == [] and row["points"] == {"family": True, "no_spurious": True,
                                                    "direction": True, "unexplained": True}
    assert row["flag_and_text_disagree"] is True
    # the same report for a case whose law the library lacks (no end-stop candidate among
    # its 12 + 4 names): the right answer is a flag with maps, which this report lacks
    stop = score.score_case(_case("d_end_stop"), report)
    assert stop["library_can_express"] is False
    assert stop["points"]["family"] is False and stop["points"]["unexplained"] is False


def test_score_directions_of_a_load_friction():
    """A report naming load_friction with mu_drive < mu_back passes case c's direction and
    fails case b's; an equal pair passes the user's case."""
    import json
    report = json.loads(NULL_REPORT.read_text())
    report["unexplained"] = False
    report["effects"] = [{"name": "load_friction", "parameters": {"mu_drive": 0.1, "mu_back": 0.3},
                          "reason": ""}]
    c = score.score_case(_case("c_gear_efficiency"), report)
    b = score.score_case(_case("b_load_quadrant"), report)
    assert c["points"]["family"] and c["points"]["direction"] is True
    assert b["points"]["family"] and b["points"]["direction"] is False
    report["effects"][0]["parameters"] = {"mu_drive": 0.2, "mu_back": 0.21}
    assert score.score_case(_case("i_users_pendulum"), report)["points"]["direction"] is True
    report["effects"].append({"name": "backlash", "parameters": {}, "reason": ""})
    assert score.score_case(_case("c_gear_efficiency"), report)["points"]["no_spurious"] is False
    assert score.family_of("cogging") == "other"


# --- the one run's record (bank/README.md, "The one run") -------------------------------------
def test_readme_one_run_is_its_record():
    """bank/README.md's table of the one run is made from test_half/record (the score as frozen
    and each case's report), the commit it names is the score's, the record's scores are what
    score.py says of its reports, and the times and memory it quotes are the outputs'."""
    import json
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    record = root / "bank" / "test_half" / "record"
    text = (root / "bank" / "README.md").read_text()
    a = text.index("<!-- test half table:")
    table = text[text.index("\n", a) + 1:text.index("<!-- end of test half table -->")]
    assert table == score.record_table(record)
    sc = json.loads((record / "score.json").read_text())
    assert f"after the rules froze at commit {sc['commit']}" in text and f"score.py --commit {sc['commit']}" in text
    cases = json.loads((record / "cases.json").read_text())["cases"]
    for case, row in zip(cases, sc["cases"], strict=True):
        rep = json.loads((record / case["name"] / "report.json").read_text())
        assert score.score_case(case, rep)["points"] == row["points"], case["name"]
    wall, rss = [], []
    for case in cases:
        out = (record / case["name"] / "output.txt").read_text()
        m, s = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\d+):([\d.]+)", out).groups()
        wall.append(int(m) + float(s) / 60)
        rss.append(int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", out).group(1)) / 1024)
    flat = " ".join(text.split())
    assert (f"{min(wall):.1f} to {max(wall):.1f} min a case, peak memory {min(rss):.0f} to "
            f"{max(rss):.0f} MiB") in flat


def test_readme_one_run_prose_is_its_record():
    """The figures bank/README.md's prose quotes about the one run are the reports': the load law's
    screen shares on the three load-dependent cases, the current limit case's gap, armature ratio
    and screen share, the armature at its lower bound in the backlash case, the Stribeck case's
    Coulomb correction and fitted kinetic level."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    record = root / "bank" / "test_half" / "record"
    flat = " ".join((root / "bank" / "README.md").read_text().split())

    def rep(case):
        return json.loads((record / case / "report.json").read_text())

    def share(case, name):
        return next(c["share"] for c in rep(case)["candidates"][0] if c["name"] == name)

    def minus(x, fmt):  # the page writes a minus sign
        return format(x, fmt).replace("-", "−")

    shares = [minus(share(c, "load_friction"), ".2f") for c in ("b_load_quadrant", "c_gear_efficiency", "i_users_pendulum")]
    assert f"(shares {shares[0]}, {shares[1]} and {shares[2]} of it)" in flat
    h = rep("h_current_limit")
    armature = {c["effect"]: c for c in h["corrections"]}["armature"]["ratio_to_nominal"]
    assert (f"gap at {h['gap_after']:.2e} rad with the armature correction at {armature:.1f} times the nominal's "
            f"(the current limit screened at {minus(share('h_current_limit', 'current_limit'), '.2f')})"
            ).replace("e-02", "e-2") in flat
    assert {c["effect"]: c for c in rep("f_backlash")["corrections"]}["armature"]["at_bound"] == "lower"
    a = rep("a_stribeck")
    coulomb = {c["effect"]: c for c in a["corrections"]}["coulomb_friction"]["ratio_to_nominal"]
    assert f"below the nominal's ({coulomb:.3f} of it)" in flat
    assert f"its `fc_nm` {a['effects'][0]['parameters']['fc_nm']:.4f} N m" in flat
