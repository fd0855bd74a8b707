"""Servo actuators as nominal models: MuJoCo 4's ``dcmotor`` and a ``motor`` with the back-EMF
as joint damping, closed in the device's P loop and held to hand-derived closed forms
(docs/method/servo-actuators.md).

The plant is one hinge about a vertical axis (gravity puts no torque on it), inertia ``J``, no
friction, driven by a DC motor with torque constant ``K`` [N*m/A] and winding resistance ``R``
[Ohm] at the joint.  A voltage ``u`` held over a control period gives the joint torque
``(K/R) u - (K^2/R) w``, so the plant is linear:

    J th'' = g u - c th',    g = K/R [N*m/V],   c = K^2/R [N*m*s/rad].

Two exact solutions are used:

* the sampled loop (the device's time convention: ``u_k = clip(kp (r - th_k))`` held over
  ``[kT, (k+1)T)``): one period maps ``(th, w)`` by the zero-order-hold matrices ``Ad, Bd``
  written out below by hand (checked against ``scipy.linalg.expm``);
* the continuous constant-command solution ``th(t) = th0 + (g u / c) (t - (1 - e^{-at}) / a)``
  (``a = c/J``), exact at every sample while the P law is saturated (the command does not change).

MuJoCo's integrators on this linear plant (checked by hand-written one-step recurrences below):

* ``RK4`` approximates ``exp(hA)`` to 4th order: local error ``(h a)^5 / 120`` per step.  With
  ``h = 0.1 ms`` (10 physics steps per 1 ms control period) and ``a = 41.7 1/s`` that is
  1.1e-14 per step, so 5000 steps stay below ~1e-10 of the step size (observed 8e-13): the tight
  tests use RK4 at 0.1 ms with a tolerance of 1e-9 of the step size.  A 1 % error in ``R``
  moves the trajectory by ~3e-3 of the step size, six orders above that.
* ``implicitfast`` (and ``implicit``) is semi-implicit Euler with the velocity derivative of the
  damping *and* of the dcmotor's back-EMF in the implicit part:
  ``w+ = w + h (g u - c w) / (J + h c)``, ``th+ = th + h w+``.  It is first order: at
  ``h = 1 ms`` its trajectory is 0.6 % of the step size from the exact one, more than the 0.3 %
  a 1 % resistance error makes, so it cannot carry a tight test; MuJoCo matches the recurrence
  itself to round-off.
* ``Euler`` treats joint ``damping`` implicitly but the dcmotor's back-EMF explicitly
  (``w+ = w + h (g u - c w) / J``): there the two forms of the same motor differ by O(h a).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.linalg import expm

from omni_sim.device import Device, Engine, run_p_loop
from omni_sim.model import Target

#: Hinge inertia about the vertical axis [kg*m^2] (a geared servo's output with its rotor).
J = 2e-3
#: Torque constant [N*m/A] and winding resistance [Ohm], both as seen at the joint.
KT = 0.5
R = 3.0
#: Torque per volt [N*m/V] and back-EMF damping [N*m*s/rad] at the joint.
GAIN = KT / R
DAMPING = KT ** 2 / R
#: Supply voltage [V] (the drive's ctrlrange).
SUPPLY = 12.0
#: Control period [s] and the RK4 physics timestep [s] of the tight tests.
PERIOD = 1e-3
H = 1e-4
#: Relative tolerance (of the step size) of MuJoCo RK4 at H against the exact sampled loop:
#: the local RK4 error (H*a)^5/120 = 1.1e-14 summed over 5000 steps is < 1e-10 (see above).
TIGHT = 1e-9
#: Two computations of one recurrence by different arithmetic (MuJoCo's C against numpy, the
#: dcmotor's (K/R)(u - K w) against a motor's gear*u - damping*w): round-off only.
ROUNDOFF = 1e-12

TARGET = Target(joint="j", actuator="a")


# -- models ------------------------------------------------------------------------------------

def mjcf(actuator: str, damping: float = 0.0, integrator: str = "RK4", timestep: float = H) -> str:
    """A hinge ``j`` about z with inertia ``J`` (no gravity torque, no friction), actuator ``a``."""
    return f"""
<mujoco>
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{timestep!r}" integrator="{integrator}"/>
  <worldbody>
    <body>
      <joint name="j" type="hinge" axis="0 0 1" damping="{damping!r}"/>
      <inertial pos="0 0 0" mass="0.1" diaginertia="{J!r} {J!r} {J!r}"/>
    </body>
  </worldbody>
  <actuator>{actuator}</actuator>
</mujoco>"""


def dcmotor_xml(kt=KT, r=R, gear=1.0, limit=SUPPLY, **kw) -> str:
    """The servo as MuJoCo's dcmotor: control = terminal voltage [V], clipped by ctrlrange."""
    act = (f'<dcmotor name="a" joint="j" motorconst="{kt!r}" resistance="{r!r}" gear="{gear!r}" '
           f'ctrlrange="{-limit!r} {limit!r}"/>')
    return mjcf(act, **kw)


def motor_xml(kt=KT, r=R, limit=SUPPLY, **kw) -> str:
    """The same servo as a motor (gear = K/R, torque per volt) and joint damping K^2/R."""
    act = f'<motor name="a" joint="j" gear="{kt / r!r}" ctrlrange="{-limit!r} {limit!r}"/>'
    return mjcf(act, damping=kt ** 2 / r, **kw)


FORMS = {
    "dcmotor": dcmotor_xml,
    "motor+damping": motor_xml,
    # the constants of the motor itself behind a 25:1 gear: K_joint = 25 * 0.02 = 0.5
    "geared dcmotor": lambda **kw: dcmotor_xml(kt=KT / 25, gear=25.0, **kw),
}


def device(xml: str) -> Device:
    return Device(mujoco.MjModel.from_xml_string(xml), PERIOD, target=TARGET)


def closed_loop(xml: str, kp: float, r: float, theta0: float, n: int, command_limit=None) -> dict:
    """The device's P loop on one row: ``theta`` (n,) and the applied command ``v`` (n,)."""
    eng = device(xml).engine([theta0], [None])
    out = run_p_loop(eng, np.full((1, n), r), kp, command_limit=command_limit)
    return {k: out[k][0] for k in ("theta", "v")}


# -- closed forms --------------------------------------------------------------------------------

def zoh(gain: float, damping: float, T: float = PERIOD):
    """The exact map of one period of ``J th'' = gain u - damping th'`` with u held:
    ``x+ = Ad x + Bd u``, ``x = (th, w)``; by hand, with ``a = damping / J``, ``E = e^{-aT}``."""
    a = damping / J
    E = math.exp(-a * T)
    Ad = np.array([[1.0, (1 - E) / a], [0.0, E]])
    Bd = (gain / J) * np.array([(T - (1 - E) / a) / a, (1 - E) / a])
    return Ad, Bd


def sampled_loop(gain, damping, kp, r, theta0, n, limit=math.inf):
    """The exact sampled P loop: angles ``th_k`` (n,), commands ``u_k`` (n,) and velocities
    ``w_k`` (n + 1,) at the sample times."""
    Ad, Bd = zoh(gain, damping)
    x = np.array([theta0, 0.0])
    th, u, w = np.empty(n), np.empty(n), np.empty(n + 1)
    for k in range(n):
        th[k], w[k] = x
        u[k] = min(max(kp * (r - x[0]), -limit), limit)
        x = Ad @ x + Bd * u[k]
    w[n] = x[1]
    return th, u, w


def constant_command(gain, damping, u, theta0, t):
    """From rest at ``theta0``, a constant command ``u``: the angle at times ``t``."""
    a = damping / J
    return theta0 + gain * u / damping * (t - (1 - np.exp(-a * t)) / a)


def continuous_step(gain, damping, kp, r, theta0, t):
    """The continuous (unsampled) linear loop ``J th'' + c th' + G th = G r``, ``G = gain kp``,
    from rest at ``theta0`` (underdamped): the angle at times ``t``."""
    G = gain * kp
    alpha, wn2 = damping / (2 * J), G / J
    assert wn2 > alpha ** 2, "underdamped loop expected"
    wd = math.sqrt(wn2 - alpha ** 2)
    return r + (theta0 - r) * np.exp(-alpha * t) * (np.cos(wd * t) + alpha / wd * np.sin(wd * t))


def impulse_l1(gain, damping, kp) -> float:
    """``int_0^inf |h(t)| dt`` of ``h`` the impulse response of ``1 / (J s^2 + c s + G)``."""
    G = gain * kp
    alpha = damping / (2 * J)
    wd = math.sqrt(G / J - alpha ** 2)
    t = np.linspace(0.0, 40.0 / alpha, 400_001)
    h = np.abs(np.exp(-alpha * t) * np.sin(wd * t) / (J * wd))
    return float(np.sum((h[1:] + h[:-1]) / 2) * (t[1] - t[0]))


# -- what MuJoCo's dcmotor is --------------------------------------------------------------------

def test_dcmotor_compiles_to_R_and_K_in_gainprm():
    m = mujoco.MjModel.from_xml_string(dcmotor_xml(gear=3.0))
    assert m.actuator_gaintype[0] == mujoco.mjtGain.mjGAIN_DCMOTOR
    assert m.actuator_biastype[0] == mujoco.mjtBias.mjBIAS_DCMOTOR
    assert m.actuator_dyntype[0] == mujoco.mjtDyn.mjDYN_DCMOTOR
    assert m.na == 0  # no inductance, thermal or LuGre state: the current is algebraic
    assert list(m.actuator_gainprm[0, :2]) == [R, KT]  # gainprm = (R, K, ...)
    assert not np.any(m.actuator_biasprm[0, :3])  # back-EMF comes from gainprm, not biasprm
    assert m.actuator_gear[0, 0] == 3.0
    assert m.actuator_ctrllimited[0] and list(m.actuator_ctrlrange[0]) == [-SUPPLY, SUPPLY]
    # motorconst="Kt Ke": one constant K = sqrt(Kt Ke) for both torque and back-EMF
    xml = mjcf('<dcmotor name="a" joint="j" motorconst="0.5 0.4" resistance="2"/>')
    m = mujoco.MjModel.from_xml_string(xml)
    assert m.actuator_gainprm[0, 1] == pytest.approx(math.sqrt(0.5 * 0.4), rel=1e-15)
    # nominal="V stall_torque no_load_speed": K = V / no_load_speed, R = K V / stall_torque
    m = mujoco.MjModel.from_xml_string(mjcf('<dcmotor name="a" joint="j" nominal="12 3 24"/>'))
    assert list(m.actuator_gainprm[0, :2]) == pytest.approx([0.5 * 12 / 3, 12 / 24], rel=1e-15)


@pytest.mark.parametrize("kt_ke, r, gear, limit", [
    ("0.5", 3.0, 1.0, 12.0), ("0.02", 3.0, 25.0, 12.0), ("0.5 0.4", 2.0, 3.0, 6.0)])
@pytest.mark.parametrize("u, w", [(1.0, 0.0), (0.0, 2.0), (5.0, -3.0), (20.0, 1.0), (-30.0, -0.5)])
def test_dcmotor_torque(kt_ke, r, gear, limit, u, w):
    """Joint torque = gear (K/R) (clip(u) - K gear w): ctrlrange clips the voltage, the
    back-EMF sees the motor's speed gear*w, and actuator_force is the motor-side torque."""
    xml = mjcf(f'<dcmotor name="a" joint="j" motorconst="{kt_ke}" resistance="{r}" gear="{gear}" '
               f'ctrlrange="{-limit} {limit}"/>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.ctrl[0], d.qvel[0] = u, w
    mujoco.mj_forward(m, d)
    consts = [float(x) for x in kt_ke.split()]
    K = math.sqrt(consts[0] * consts[1]) if len(consts) == 2 else consts[0]
    motor_side = K / r * (min(max(u, -limit), limit) - K * gear * w)
    assert d.actuator_force[0] == pytest.approx(motor_side, rel=1e-13, abs=1e-15)
    assert d.qfrc_actuator[0] == pytest.approx(gear * motor_side, rel=1e-13, abs=1e-15)


@pytest.mark.parametrize("form, brakes", [("dcmotor", True), ("motor+damping", True), ("motor", False)])
def test_zero_command_brakes_a_shorted_winding(form, brakes):
    """u = 0 V is a shorted winding: the back-EMF drives a current that brakes the joint,
    w(t) = w0 e^{-at}, th(t) = w0 (1 - e^{-at}) / a.  A motor without the damping coasts (an open
    winding, what neither form gives at zero command)."""
    xml = {"dcmotor": dcmotor_xml(), "motor+damping": motor_xml(),
           "motor": mjcf(f'<motor name="a" joint="j" gear="{GAIN!r}"/>')}[form]
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    w0, n = 3.0, 2000
    d.qvel[0] = w0
    th = np.empty(n)
    for k in range(n):
        mujoco.mj_step(m, d)
        th[k] = d.qpos[0]
    t = H * np.arange(1, n + 1)
    a = DAMPING / J
    expected = w0 * (1 - np.exp(-a * t)) / a if brakes else w0 * t
    np.testing.assert_allclose(th, expected, rtol=0, atol=TIGHT * np.max(np.abs(expected)))


def test_dcmotor_with_K_zero_is_an_open_winding():
    """Setting K (gainprm[1]) to 0 in a compiled model removes the torque and the back-EMF
    together: the joint coasts whatever the command -- the open winding of a servo whose torque
    is disabled, which a zero command (a shorted winding) is not."""
    m = mujoco.MjModel.from_xml_string(dcmotor_xml())
    m.actuator_gainprm[0, 1] = 0.0
    d = mujoco.MjData(m)
    w0, n = 3.0, 2000
    d.qvel[0], d.ctrl[0] = w0, 5.0
    for _ in range(n):
        mujoco.mj_step(m, d)
    assert d.qvel[0] == w0
    assert d.qpos[0] == pytest.approx(w0 * n * H, rel=1e-12)


# -- the closed loop against the closed forms ---------------------------------------------------

def test_hand_zoh_is_the_matrix_exponential():
    A = np.array([[0.0, 1.0], [0.0, -DAMPING / J]])
    B = np.array([0.0, GAIN / J])
    aug = np.zeros((3, 3))
    aug[:2, :2], aug[:2, 2] = A, B
    E = expm(aug * PERIOD)
    Ad, Bd = zoh(GAIN, DAMPING)
    np.testing.assert_allclose(Ad, E[:2, :2], rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(Bd, E[:2, 2], rtol=1e-13)


@pytest.mark.parametrize("form", FORMS)
def test_volts_law_is_the_sampled_closed_form(form):
    """A 50 mrad step under u = kp (r - th) [V], kp = 20 V/rad (loop 6.5 Hz, damping ratio
    0.51, never saturating): MuJoCo's trajectory is the exact sampled solution within TIGHT."""
    kp, r, n = 20.0, 0.05, 500
    run = closed_loop(FORMS[form](), kp, r, 0.0, n)
    th, u, _ = sampled_loop(GAIN, DAMPING, kp, r, 0.0, n)
    assert np.max(np.abs(u)) < SUPPLY
    np.testing.assert_allclose(run["theta"], th, rtol=0, atol=TIGHT * r)
    np.testing.assert_allclose(run["v"], u, rtol=0, atol=TIGHT * kp * r)


def test_batch_engine_steps_both_forms_alike():
    """The replay's batch path (mujoco.rollout over rows of different models): one row a
    dcmotor, one a motor with damping, both the sampled closed form."""
    kp, r, n = 20.0, 0.05, 300
    devs = [device(dcmotor_xml()), device(motor_xml())]
    with Engine(devs, [0.0, 0.0], [None, None], nthread=1) as eng:
        out = run_p_loop(eng, np.full((2, n), r), kp)
    th, _, _ = sampled_loop(GAIN, DAMPING, kp, r, 0.0, n)
    for row in out["theta"]:
        np.testing.assert_allclose(row, th, rtol=0, atol=TIGHT * r)


@pytest.mark.parametrize("wrong", [{"r": R * 1.01}, {"kt": KT * 1.01}])
def test_a_one_percent_error_fails_the_closed_form(wrong):
    """The tight check sees a 1 % error in R or K: the model's trajectory leaves the nominal
    closed form by more than 1000 times TIGHT (~3e-3 of the step size for R)."""
    kp, r, n = 20.0, 0.05, 500
    run = closed_loop(dcmotor_xml(**wrong), kp, r, 0.0, n)
    th, _, _ = sampled_loop(GAIN, DAMPING, kp, r, 0.0, n)
    assert np.max(np.abs(run["theta"] - th)) > 1000 * TIGHT * r


def test_sampled_loop_is_near_the_continuous_closed_form():
    """The 1 ms zero-order hold against the continuous loop J th'' + c th' + G th = G r.

    The difference e = th_sampled - th_continuous obeys J e'' + c e' + G e = G (th(t) - th(t_k))
    with |th(t) - th(t_k)| <= T max|w|, so |e| <= G T max|w| ||h||_1 (h the impulse response
    of 1/(J s^2 + c s + G)); between samples w relaxes monotonically under a held command, so
    max|w| is the largest sampled |w_k|.  That bound (a few % of the step here) is the
    tolerance; the comparison of MuJoCo with the continuous form is only this loose because of
    the hold, not of MuJoCo."""
    kp, r, n = 20.0, 0.05, 500
    run = closed_loop(dcmotor_xml(), kp, r, 0.0, n)
    _, _, w = sampled_loop(GAIN, DAMPING, kp, r, 0.0, n)
    bound = GAIN * kp * PERIOD * np.max(np.abs(w)) * impulse_l1(GAIN, DAMPING, kp)
    cont = continuous_step(GAIN, DAMPING, kp, r, 0.0, PERIOD * np.arange(n))
    err = np.max(np.abs(run["theta"] - cont))
    assert err <= bound + TIGHT * r
    assert bound < 0.1 * r  # the closed form is still a meaningful check of the physics
    assert err > 100 * TIGHT * r  # the hold is visible: this is why the tight tests are sampled


@pytest.mark.parametrize("form", ["dcmotor", "motor+damping"])
def test_duty_cycle_law_with_a_saturating_step(form):
    """A servo's P law in duty cycle: duty = clip(kp_duty (r - th), -duty_max, duty_max), volts =
    supply * duty; the device runs it as kp = supply * kp_duty [V/rad] and command_limit =
    supply * duty_max [V].  A 1 rad step saturates the command at 6 V: while saturated the
    angle is the continuous constant-command solution (exact at the samples: the command does
    not change), then the linear regime; the whole run is the sampled closed form."""
    supply, kp_duty, duty_max = SUPPLY, 2.0, 0.5  # duty per rad; a 50 % duty clip
    r, n = 1.0, 400
    kp, limit = supply * kp_duty, supply * duty_max
    run = closed_loop(FORMS[form](), kp, r, 0.0, n, command_limit=limit)
    duty = np.clip(kp_duty * (r - run["theta"]), -duty_max, duty_max)
    np.testing.assert_allclose(run["v"], supply * duty, rtol=0, atol=1e-12)
    # the saturated phase: u = +limit for k < m
    t = PERIOD * np.arange(n)
    sat = constant_command(GAIN, DAMPING, limit, 0.0, t)
    m = int(np.argmax(kp_duty * (r - sat) < duty_max))  # first sample out of saturation
    assert 50 < m < n // 2
    assert np.all(run["v"][:m] == limit) and run["v"][m] < limit
    np.testing.assert_allclose(run["theta"][: m + 1], sat[: m + 1], rtol=0, atol=TIGHT * r)
    # the whole run, saturation and linear regime
    th, u, _ = sampled_loop(GAIN, DAMPING, kp, r, 0.0, n, limit)
    np.testing.assert_allclose(run["theta"], th, rtol=0, atol=TIGHT * r)
    np.testing.assert_allclose(run["v"], u, rtol=0, atol=TIGHT * kp * r)


def test_drive_ctrlrange_clips_the_voltage():
    """Without command_limit the law saturates at the drive's ctrlrange (the supply: duty_max
    = 1); a command_limit above the ctrlrange is still clipped there by the drive."""
    kp, r, n = 24.0, 1.0, 300
    dev = device(dcmotor_xml())
    assert dev.voltage_limit == SUPPLY
    th, u, _ = sampled_loop(GAIN, DAMPING, kp, r, 0.0, n, SUPPLY)
    assert u[0] == SUPPLY
    for command_limit in (None, 2 * SUPPLY):
        run = closed_loop(dcmotor_xml(), kp, r, 0.0, n, command_limit=command_limit)
        assert np.max(run["v"]) == SUPPLY
        np.testing.assert_allclose(run["theta"], th, rtol=0, atol=TIGHT * r)


# -- the two forms and the integrators -----------------------------------------------------------

def semi_implicit_loop(gain, damping, kp, r, theta0, n, h, implicit_damping=True):
    """MuJoCo's Euler-family step by hand, ``PERIOD / h`` steps per period: ``w+ = w + h (g u -
    c w) / (J + h c)`` (damping implicit) or ``/ J`` (explicit), then ``th+ = th + h w+``."""
    sub = round(PERIOD / h)
    denom = J + h * damping if implicit_damping else J
    q, w, th = theta0, 0.0, np.empty(n)
    for k in range(n):
        th[k] = q
        u = kp * (r - q)
        for _ in range(sub):
            w = w + h * (gain * u - damping * w) / denom
            q = q + h * w
    return th


@pytest.mark.parametrize("integrator, timestep", [("RK4", H), ("RK4", PERIOD), ("implicitfast", PERIOD),
                                                  ("implicit", PERIOD)])
def test_dcmotor_and_motor_damping_are_one_model(integrator, timestep):
    """RK4 and the implicit integrators give the dcmotor and the equivalent motor + damping
    the same trajectory (to round-off)."""
    kp, r, n = 20.0, 0.05, 500
    kw = dict(integrator=integrator, timestep=timestep)
    a = closed_loop(dcmotor_xml(**kw), kp, r, 0.0, n)["theta"]
    b = closed_loop(motor_xml(**kw), kp, r, 0.0, n)["theta"]
    np.testing.assert_allclose(a, b, rtol=0, atol=ROUNDOFF * r)


@pytest.mark.parametrize("integrator", ["implicitfast", "implicit"])
def test_implicit_integrators_are_semi_implicit_euler(integrator):
    """At a 1 ms timestep MuJoCo's implicit integrators are the hand recurrence with the
    back-EMF implicit (to round-off), first order: 0.6 % of the step size from the exact
    solution, more than a 1 % error in R moves it (0.3 %)."""
    kp, r, n = 20.0, 0.05, 500
    run = closed_loop(dcmotor_xml(integrator=integrator, timestep=PERIOD), kp, r, 0.0, n)["theta"]
    np.testing.assert_allclose(run, semi_implicit_loop(GAIN, DAMPING, kp, r, 0.0, n, PERIOD),
                               rtol=0, atol=ROUNDOFF * r)
    exact, _, _ = sampled_loop(GAIN, DAMPING, kp, r, 0.0, n)
    wrong_r, _, _ = sampled_loop(KT / (1.01 * R), KT ** 2 / (1.01 * R), kp, r, 0.0, n)
    assert np.max(np.abs(run - exact)) > np.max(np.abs(wrong_r - exact)) > 1e-3 * r


def test_euler_integrates_the_dcmotor_back_emf_explicitly():
    """Euler: joint damping implicit, the dcmotor's back-EMF explicit, so the two forms part
    by O(h c / J) (about 1 % of the step size at 1 ms here)."""
    kp, r, n = 20.0, 0.05, 500
    kw = dict(integrator="Euler", timestep=PERIOD)
    dc = closed_loop(dcmotor_xml(**kw), kp, r, 0.0, n)["theta"]
    mo = closed_loop(motor_xml(**kw), kp, r, 0.0, n)["theta"]
    np.testing.assert_allclose(dc, semi_implicit_loop(GAIN, DAMPING, kp, r, 0.0, n, PERIOD, False),
                               rtol=0, atol=ROUNDOFF * r)
    np.testing.assert_allclose(mo, semi_implicit_loop(GAIN, DAMPING, kp, r, 0.0, n, PERIOD, True),
                               rtol=0, atol=ROUNDOFF * r)
    assert np.max(np.abs(dc - mo)) > 5e-3 * r


# -- what the device layer reads from a servo actuator ------------------------------------------

def torque_per_volt(model: mujoco.MjModel, act: int) -> float:
    """Joint torque per volt at rest [N*m/V]: gear * K / R for a dcmotor, gear * gainprm[0]
    for a fixed-gain motor."""
    gear = float(model.actuator_gear[act, 0])
    if model.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_DCMOTOR:
        return gear * float(model.actuator_gainprm[act, 1] / model.actuator_gainprm[act, 0])
    return gear * float(model.actuator_gainprm[act, 0])


@pytest.mark.parametrize("form", FORMS)
def test_torque_per_volt_of_each_form(form):
    m = mujoco.MjModel.from_xml_string(FORMS[form]())
    d = mujoco.MjData(m)
    d.ctrl[0] = 1.0
    mujoco.mj_forward(m, d)
    assert torque_per_volt(m, 0) == pytest.approx(GAIN, rel=1e-14)
    assert d.qfrc_actuator[0] == pytest.approx(GAIN, rel=1e-14)
    assert device(FORMS[form]()).voltage_limit == SUPPLY  # ctrlrange is the voltage limit


def test_device_torque_constant_of_a_dcmotor():
    """The torque per volt at rest, gear*K/R (not the dcmotor's gear ratio)."""
    assert device(dcmotor_xml()).torque_constant == pytest.approx(GAIN, rel=1e-14)
