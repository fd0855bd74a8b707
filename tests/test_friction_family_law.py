"""The friction family (one law, nested variants), the rule that chooses among
the variants, and the current limit whose torque bound moves with the back-EMF.

Truths: closed-form steady sliding of a damped hinge (tau - F(tau, w) - b w = 0, solved here
with scipy where the Stribeck term keeps it implicit), the static level at rest, and MuJoCo 4's
own ``dcmotor`` with ``saturation`` for the current limit (an implementation that shares no
code with the engine's law)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.optimize import brentq

from discrepancy import effects as fx
from discrepancy.effects import family
from discrepancy.nesting import TIE_SHARE, choose_variant
from identification.errors import UserError
from omni_sim import model as om
from omni_sim.device import Device, Engine

TARGET = om.Target("hinge", "drive")
SERVO = om.Target("pivot", "servo")
FC, B, GEAR = 0.05, 0.02, 2.0  # Coulomb level [N*m], viscous damping [N*m*s/rad], motor gear


def _hinge(family_values=None, external=0.0, fc=FC):
    custom = (f'<custom><numeric name="friction_family" data="{" ".join(map(str, family_values))}"/></custom>'
              if family_values is not None else "")
    ext = (f'<general name="load" joint="hinge" gainprm="0" biastype="affine" biasprm="{external} 0 0" '
           'ctrllimited="false"/>') if external else ""
    return mujoco.MjModel.from_xml_string(f"""<mujoco><option timestep="0.001" gravity="0 0 0"/>
    <worldbody><body><joint name="hinge" axis="0 0 1" damping="{B}" frictionloss="{fc}"/>
    <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody>
    <actuator><motor name="drive" joint="hinge" gear="{GEAR}" ctrllimited="true" ctrlrange="-1 1"/>{ext}</actuator>
    <sensor><actuatorfrc actuator="drive"/></sensor>{custom}</mujoco>""")


def _run(model, v, periods=12000):  # 24 time constants J/b = 0.5 s
    eng = Engine([Device(model, 0.001, TARGET)], [0.0], [None])
    for _ in range(periods):
        eng.apply([v])
    return float(eng.yaw_velocity()[0]), float(eng.yaw()[0])


@pytest.mark.parametrize("v", [0.4, -0.4])
def test_family_law_slides_as_its_equation_when_the_motor_drives(v):
    """Motor torque tau = 2 v drives the joint: the steady velocity solves
    |tau| - Fc0 - k_drive |tau| - rise exp(-(|w|/ws)^delta) - b |w| = 0 (solved by brentq), with a
    Stribeck speed (10 rad/s, delta 1) where the rise still acts at the sliding speed (~27 rad/s:
    exp(-2.7) of the rise, 6.6 mN*m here, 0.33 rad/s of speed)."""
    kd, kb, rise, ws, delta = 0.25, 0.6, 0.1, 10.0, 1.0
    w, _ = _run(_hinge((kd, kb, rise, ws, delta)), v)
    tau = abs(GEAR * v)
    want = brentq(lambda s: tau - FC - kd * tau - rise * math.exp(-(s / ws) ** delta) - B * s, 1e-9, 100.0)
    assert w == pytest.approx(math.copysign(want, v), rel=1e-6)
    # the rise moved the speed: the same law without it slides faster by more than the tolerance
    w0, _ = _run(_hinge((kd, kb, 0.0, 0.0, 0.0)), v)
    assert abs(w0) - abs(w) > 1e-3 and abs(w0) == pytest.approx((tau * (1 - kd) - FC) / B, rel=1e-6)


def test_family_law_when_the_load_back_drives():
    """A constant external torque 0.9 N*m against a motor holding back with tau = -0.4 N*m: the
    load back-drives the motor, so the level uses k_back; the Stribeck speed 0.05 rad/s is far
    below the sliding speed (exp(-(w/ws)^2) = 0): w = (0.9 - 0.4 - Fc0 - k_back 0.4) / b."""
    kb = 0.6
    w, _ = _run(_hinge((0.25, kb, 0.1, 0.05, 2.0), external=0.9), -0.2)
    assert w == pytest.approx((0.9 - 0.4 - FC - kb * 0.4) / B, rel=1e-6)


def test_stribeck_rise_at_rest_and_far_above_its_speed():
    """At w = 0+ the level is Fc0 + k_mean |tau| + rise (k_drive = k_back = 0.2 here, so the
    blend's mean is 0.2): breakaway at tau* = (Fc0 + rise) / (1 - 0.2) = 0.1875 N*m.  Below it
    (0.9 tau*) the joint sticks: it creeps as MuJoCo's soft frictionloss creeps, as a plain
    joint whose constant frictionloss is that level (18 mrad in 1 s, both; in the first period
    the law reads tau = 0, level Fc0 + rise, a 2e-6 rad difference), while the same law without
    the rise slides away; above it the joint breaks
    away and, at w >> ws (0.5 rad/s, delta 2: exp(-(5/0.5)^2) = 4e-44 at the ~5 rad/s it
    reaches), slides as if the rise were not there: w = (0.8 tau - Fc0) / b."""
    law, no_rise = (0.2, 0.2, 0.1, 0.5, 2.0), (0.2, 0.2, 0.0, 0.0, 0.0)
    tau_star = (FC + 0.1) / 0.8
    hold = 0.9 * tau_star / GEAR
    _, q = _run(_hinge(law), hold, periods=1000)
    _, stuck = _run(_hinge(None, fc=FC + 0.1 + 0.2 * GEAR * hold), hold, periods=1000)
    assert abs(q - stuck) < 1e-5 and abs(q) < 0.03
    _, q0 = _run(_hinge(no_rise), hold, periods=1000)
    assert abs(q0) > 0.1
    slide = 1.05 * tau_star / GEAR
    w, _ = _run(_hinge(law), slide)
    assert w == pytest.approx((0.8 * GEAR * slide - FC) / B, rel=1e-6)


def test_family_values_that_are_not_a_law_are_refused():
    for bad in ((0.1, 0.2, 0.05, 0.0, 1.0), (0.1, -0.2, 0.0, 0.0, 0.0), (0.1, 0.2, 0.0, 0.0)):
        with pytest.raises(UserError, match="friction_family"):
            Device(_hinge(bad), 0.001, TARGET)


# --- the variants: nesting, write/read round trip -------------------------------------------
def test_the_variants_are_nested():
    """Each variant's parameters contain its parent's (names and order), one root (the library's
    load_friction), and the complexity is the parameter count, growing along the chain; the
    search confirms the Stribeck variant with load_friction (NESTED)."""
    by = {v.name: v for v in family.VARIANTS}
    roots = [n for n, p in family.PARENT.items() if p is None]
    assert roots == ["load_friction"] and set(family.PARENT) == set(by)
    for name, parent in family.PARENT.items():
        if parent is not None:
            mine, theirs = [p.name for p in by[name].params], [p.name for p in by[parent].params]
            assert mine[:len(theirs)] == theirs and len(mine) > len(theirs)
            assert family.COMPLEXITY[name] > family.COMPLEXITY[parent]
    assert family.COMPLEXITY == {"load_friction": 3, "friction_family_stribeck": 6, "load_friction_smooth": 4}
    assert family.NESTED == {"load_friction": ("friction_family_stribeck", "load_friction_smooth")}
    assert by["load_friction"] is fx.get("load_friction") and "load_friction" in fx.NAMES
    assert all(fx.get(e.name) is e for e in fx.STAGED) and not set(fx.NAMES) & {e.name for e in fx.STAGED}


def test_a_parent_is_its_child_with_the_extra_parameters_at_zero():
    """load_friction (its own numeric) and the Stribeck variant with its rise at 0 (the family's
    numeric) are one law: the engine replays them bit for bit alike; with a rise they differ."""
    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    mu = np.array([0.15, 0.45, 0.3])  # with a back-EMF damping b_emf: the net torque's path too
    a = fx.apply(spec, [(family.LOAD_FRICTION_EFFECT, mu)], SERVO).compile()
    b = fx.apply(spec, [(family.STRIBECK, np.array([*mu, 0.0, 0.2, 1.5]))], SERVO).compile()
    c = fx.apply(spec, [(family.STRIBECK, np.array([*mu, 0.05, 0.2, 1.5]))], SERVO).compile()
    assert "load_friction" in [a.numeric(i).name for i in range(a.nnumeric)]
    assert "friction_family" in [b.numeric(i).name for i in range(b.nnumeric)]

    def run(m):
        eng = Engine([Device(m, 0.001, SERVO)], [0.0], [None])
        out = []
        for k in range(1500):
            eng.apply([6.0 * math.sin(2 * math.pi * 1.3 * k * 1e-3)])
            out.append(float(eng.yaw()[0]))
        return np.array(out)
    ya, yb, yc = run(a), run(b), run(c)
    np.testing.assert_array_equal(ya, yb)
    assert np.max(np.abs(yc - ya)) > 1e-4


def test_the_smooth_variant_is_its_parent_in_the_limit_and_takes_its_place():
    """load_friction_smooth written over a nominal that holds load_friction replaces it (one load
    law, not two); as w_s -> 0 it is its parent while sliding: the missing torque both models
    leave on a run of the servo pendulum agrees to 1e-6 N*m at w_s = 1e-6 rad/s on the samples
    whose window sees one friction direction, the velocity's, above 0.4 rad/s (the parent's
    coefficients blend over 0.05 rad/s), and not at w_s = 0.3 (a truth: the
    parent's own sliding force).  Elsewhere they differ by MuJoCo's frictionloss: a soft
    constraint whose force opposes ``qdd + B qd`` (torque.py), which in a hard deceleration is
    not the velocity's sign (31 of this run's 199 steady samples differ by more than 1e-9)."""
    from discrepancy import torque as tq
    from discrepancy.replay import prepare_runs
    from bank import servo_truth as st
    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    mu = np.array([0.15, 0.45, 0.3])
    stick = fx.apply(spec, [(family.LOAD_FRICTION_EFFECT, mu)], SERVO)
    over = fx.apply(stick, [(family.SMOOTH, np.array([*mu, 0.05]))], SERVO)
    assert over.numeric("load_friction") is None and over.numeric("load_friction_smooth") is not None
    m_stick = stick.compile()
    prepared = prepare_runs(st.generate(experiments=st.EXPERIMENTS[:1]), Device(m_stick, target=SERVO))
    inv = tq.InverseModel(m_stick, SERVO)
    s_f, _ = inv.direction(tq.smooth(prepared[0], float(m_stick.opt.timestep)))
    a = tq.missing_torque(m_stick, prepared, SERVO)[0]
    # the window sees one friction direction only, the velocity's; at |qd| > 0.4 rad/s, where the
    # parent's blend of its coefficients (over 0.05 rad/s) is its quadrant's to 1 - tanh(8) = 2e-7
    ok = a.steady & a.trusted & (s_f * np.sign(a.qd) > 1 - 1e-12) & (np.abs(a.qd) > 0.4)
    assert ok.sum() > 30
    for w_s, agree in ((1e-6, True), (0.3, False)):
        b = tq.missing_torque(fx.apply(spec, [(family.SMOOTH, np.array([*mu, w_s]))], SERVO).compile(),
                              prepared, SERVO)[0]
        # 1e-6 N*m: that blend's 2e-7 share of (mu_back - mu_drive) |tau|, |tau| < 2 N*m here
        assert (np.max(np.abs(a.tau_miss[ok] - b.tau_miss[ok])) < 1e-6) == agree


@pytest.mark.parametrize("name", [e.name for e in fx.STAGED] + ["current_limit"])
def test_staged_effects_write_read_and_xml_round_trip(name):
    """As the library's effects (tests/test_discrepancy.py): written off the nominal, read back
    equal; the patched MJCF text compiles, keeps the contract's names and reads back the values
    to MjSpec.to_xml's 6 significant digits."""
    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    e = fx.for_model(fx.get(name), spec, SERVO)
    x = e.clip(fx.nominal_values(e, spec, SERVO) + 3 * e.scales())
    s2 = fx.apply(spec, [(e, x)], SERVO)
    np.testing.assert_allclose(fx.nominal_values(e, s2, SERVO), x, rtol=1e-12, atol=1e-15)
    back = mujoco.MjSpec.from_string(s2.to_xml())
    om.index(back.compile(), "back", SERVO)
    np.testing.assert_allclose(fx.nominal_values(e, back, SERVO), x, rtol=5e-6)


def test_the_family_needs_the_runtime():
    from omni_sim import runtime
    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    assert not runtime.runtime_note(spec)[0]
    needs, lines = runtime.runtime_note(fx.apply(spec, [(family.STRIBECK, np.array([0.2, 0.5, 0.0, 0.0, 0.0, 0.0]))], SERVO))
    assert needs and "friction_family (k_drive=0.2, k_back=0.5" in lines[0]
    needs, lines = runtime.runtime_note(fx.apply(spec, [(family.CURRENT_LIMIT_EFFECT, np.array([1.0, 0.3]))], SERVO))
    assert needs and "current_limit (torque_limit_nm=1, back_emf_nms_per_rad=0.3)" in lines[0]
    assert "force range at rest" in lines[1] and "constant friction" not in lines[1]


# --- the current limit ------------------------------------------------------------------------
#: A servo's datasheet numbers: torque constant kt [N*m/A] (= ke [V*s/rad] in SI), winding R
#: [ohm], supply V_s [V], the firmware's current limit i_max [A].
KT, R, VS, IMAX = 1.2, 4.0, 12.0, 0.9


def _servo_hinge(limit=True):
    """The motor as the servo pendulum writes it: gear kt/R, the back-EMF kt^2/R as damping."""
    custom = (f'<custom><numeric name="current_limit" data="{KT * IMAX} {KT * KT / R}"/></custom>'
              if limit else "")
    return mujoco.MjModel.from_xml_string(f"""<mujoco><option timestep="0.001" gravity="0 0 0"/>
    <worldbody><body><joint name="hinge" axis="0 0 1" damping="{KT * KT / R}"/>
    <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody>
    <actuator><motor name="drive" joint="hinge" gear="{KT / R}" ctrllimited="true" ctrlrange="-{VS} {VS}"/>
    </actuator><sensor><actuatorfrc actuator="drive"/></sensor>{custom}</mujoco>""")


def _motor_torque(model, w, v):
    """The net motor torque (gear x force - back-EMF damping x w) the engine applies in the first
    physics step of a period started at joint velocity ``w`` under command ``v``."""
    eng = Engine([Device(model, 0.001, TARGET)], [0.0], [None])
    eng.data.qvel[0] = w
    eng.apply([v])
    force = float(eng.data.sensordata[0])  # the actuator force of that step
    return KT / R * force - KT * KT / R * w


def _native_dcmotor(w, v):
    """MuJoCo 4's own dcmotor with the same numbers (saturation = "0 i_max V_s")."""
    m = mujoco.MjModel.from_xml_string(f"""<mujoco><option timestep="0.001" gravity="0 0 0"/>
    <worldbody><body><joint name="j" axis="0 0 1"/><geom size=".1" mass="1"/></body></worldbody>
    <actuator><dcmotor joint="j" motorconst="{KT}" resistance="{R}" saturation="0 {IMAX} {VS}"
    input="voltage"/></actuator></mujoco>""")
    assert m.actuator_forcerange[0].tolist() == pytest.approx([-KT * IMAX, KT * IMAX], rel=1e-12)
    assert m.actuator_dynprm[0, 1] == VS
    d = mujoco.MjData(m)
    d.qvel[0], d.ctrl[0] = w, v
    mujoco.mj_forward(m, d)
    return float(d.actuator_force[0])


@pytest.mark.parametrize("w,v,want", [
    (1.0, VS, KT * min(IMAX, (VS - KT * 1.0) / R)),     # current-limited: 1.08 N*m
    (8.0, VS, KT * min(IMAX, (VS - KT * 8.0) / R)),     # voltage-limited by the back-EMF: 0.72 N*m
    (-8.0, -VS, -KT * min(IMAX, (VS - KT * 8.0) / R)),  # the same, the other way
    (8.0, -VS, -KT * IMAX),                             # braking: the current limit bounds it too
])
def test_current_limit_bound_moves_with_the_back_emf(w, v, want):
    """tau_max(w) = kt min(i_max, (V_s - ke |w|)/R) in the direction of motion: the engine's law
    on a motor + damping model equals the closed form and MuJoCo's native dcmotor; without the
    numeric the bound at 1 rad/s is the voltage's, 2.7 A worth (a different model)."""
    assert _motor_torque(_servo_hinge(), w, v) == pytest.approx(want, rel=1e-12, abs=1e-12)
    assert _native_dcmotor(w, v) == pytest.approx(want, rel=1e-12, abs=1e-12)
    if w == 1.0:
        assert _motor_torque(_servo_hinge(limit=False), w, v) == pytest.approx(KT * (VS - KT * w) / R)


def test_current_limit_values_that_are_not_a_limit_are_refused():
    bad = _servo_hinge()
    bad.numeric_data[:2] = (0.0, 0.3)
    with pytest.raises(UserError, match="current_limit"):
        Device(bad, 0.001, TARGET)


def test_current_limit_at_zero_back_emf_is_torque_saturation():
    """Nested: the current limit with b = 0 writes the same forcerange as torque_saturation and
    a model without its numeric reads torque_saturation's limit and b = 0."""
    spec = mujoco.MjSpec.from_file(str(om.SERVO_PENDULUM))
    sat = fx.apply(spec, [(fx.get("torque_saturation"), np.array([1.5]))], SERVO)
    np.testing.assert_allclose(fx.nominal_values(family.CURRENT_LIMIT_EFFECT, sat, SERVO), [1.5, 0.0])
    cur = fx.apply(spec, [(family.CURRENT_LIMIT_EFFECT, np.array([1.5, 0.0]))], SERVO)
    a, b = sat.compile(), cur.compile()
    assert a.actuator_forcerange.tolist() == b.actuator_forcerange.tolist()
    assert not family.CURRENT_LIMIT_EFFECT.applies(
        mujoco.MjSpec.from_string('<mujoco><worldbody><body><joint name="pivot"/><geom size=".1"/></body>'
                                  '</worldbody><actuator><dcmotor name="servo" joint="pivot" motorconst="1" '
                                  'resistance="1"/></actuator></mujoco>'), SERVO)


# --- the selection rule, on synthetic scores ----------------------------------------------------
#: The rule is generic: a four-variant chain (the law's full nesting with its dry level and
#: viscous term as parameters of their own: 1, 3, 6, 7 parameters).
C = {"friction_family_coulomb": 1, "friction_family_load": 3, "friction_family_stribeck": 6,
     "friction_family_viscous": 7}
RNG = np.random.default_rng(41)
BASE = 1e-3 * (1 + 0.3 * RNG.random(12))  # 12 held-out runs of different difficulty [rad]


def _scores(**factor):
    """Each variant's per-run gaps: the base runs times a factor, plus 1 % run-to-run jitter."""
    jitter = {n: 1 + 0.01 * RNG.standard_normal(12) for n in C}
    return {f"friction_family_{k}": BASE * f * jitter[f"friction_family_{k}"] for k, f in factor.items()}


def test_rule_keeps_the_root_when_nothing_richer_helps():
    assert choose_variant(_scores(coulomb=1.0, load=0.99, stribeck=0.985, viscous=0.98), C) == "friction_family_coulomb"


def test_rule_takes_a_richer_variant_that_clearly_helps():
    assert choose_variant(_scores(coulomb=1.0, load=0.6, stribeck=0.59, viscous=0.58), C) == "friction_family_load"
    assert choose_variant(_scores(coulomb=1.0, load=0.8, stribeck=0.4, viscous=0.39), C) == "friction_family_stribeck"
    assert choose_variant(_scores(coulomb=1.0, load=0.9, stribeck=0.7, viscous=0.3), C) == "friction_family_viscous"


def test_rule_needs_more_than_a_consistent_sliver():
    """A richer variant better on every run by 5 % (many standard errors, but within the 10 %
    tie share) is not taken; by 15 % it is."""
    s = {"friction_family_coulomb": BASE, "friction_family_load": BASE * 0.95}
    assert choose_variant(s, C) == "friction_family_coulomb"
    s["friction_family_load"] = BASE * (1 - TIE_SHARE - 0.05)
    assert choose_variant(s, C) == "friction_family_load"


def test_rule_needs_more_than_the_run_to_run_spread():
    """A richer variant 20 % better on average but only by the luck of a few runs (its paired
    difference's standard error larger than the gain) is not taken."""
    better = BASE.copy()
    better[:2] *= 0.05  # two runs much better, the others 60 % better or worse in turn
    better[2:] *= 1 + 0.6 * (-1.0) ** np.arange(10)
    s = {"friction_family_coulomb": BASE, "friction_family_stribeck": better}
    d = better - BASE
    assert d.mean() < -TIE_SHARE * BASE.mean() and -d.mean() < d.std(ddof=1) / math.sqrt(12)
    assert choose_variant(s, C) == "friction_family_coulomb"


def test_rule_ignores_failed_variants_and_is_scale_and_order_free():
    s = _scores(coulomb=1.0, load=0.6, stribeck=0.59)
    s["friction_family_viscous"] = np.full(12, np.nan)
    assert choose_variant(s, C) == "friction_family_load"
    assert choose_variant({k: 1e3 * v for k, v in s.items()}, C) == "friction_family_load"
    assert choose_variant(dict(reversed(list(s.items()))), C) == "friction_family_load"
    one = {k: v[:1] for k, v in s.items()}  # one run: no standard error, the tie share alone
    assert choose_variant(one, C) == "friction_family_load"


def test_rule_refuses_what_it_cannot_judge():
    with pytest.raises(ValueError, match="no variant"):
        choose_variant({}, C)
    with pytest.raises(ValueError, match="same held-out runs"):
        choose_variant({"friction_family_coulomb": [1.0, 2.0], "friction_family_load": [1.0]}, C)
    with pytest.raises(ValueError, match="no complexity"):
        choose_variant({"other": [1.0]}, C)
    with pytest.raises(ValueError, match="non-finite"):
        choose_variant({"friction_family_coulomb": [np.inf]}, C)
