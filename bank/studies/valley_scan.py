"""Why ``load_friction``'s coefficient is blended, and why the prescreen also starts from the
model's own values: the objective of the joint fit (the nominal's corrections +
``load_friction``) on the ``load_friction_nominal_off`` case's runs, with the law as the
library holds it (``blend``: the coefficient passes from mu_back to mu_drive over
``omni_sim.device.laws.LOAD_FRICTION_BLEND_RAD_S``) and as a switch (``switch``: on the sign of
tau*w, mu_back at rest: the blend speed set to 0, in the engine and in the case's truth alike,
so the truth's runs change with it).

:func:`record` is the record ``valley_scan.json`` (``scripts/valley_scan.py`` writes it) with,
per law:

* ``truth_gap``: the training gap [rad] at the truth (every parameter at its true value);
* ``mu_back_scan``: the training gap along mu_back (every other parameter at its truth);
* ``fits``: trust-region fits (``Problem.fit``, 30 evaluations at most) from three starts --
  the truth, the point CI reported with the switch (armature 0.002703, mu_drive 0.1919,
  mu_back 0.3644, the rest at the truth) and a far one (the nominal's values, mu_drive 0.04,
  mu_back 0.07): where each stops and its training gap;

and, with the blend, ``prescreen``: the corrections fitted without the effect (all runs), and
on the prescreen's 1 s records the gap of every point of load_friction's grid with the other
parameters at those corrections and at the nominal's own values, and where the prescreen
(:func:`discrepancy.select.prescreen`) ends.

The training gap is :func:`discrepancy.fit.gap` on all runs.  Deterministic (the
case's seed); a few minutes on 2 cores.  The scan sets the blend speed of
:mod:`omni_sim.device.laws` and :mod:`bank.servo_truth` for the switch and restores
it before it returns.
"""

from __future__ import annotations

import mujoco
import numpy as np

from omni_sim.device import laws as drive_laws
from omni_sim import model as om
from omni_sim.device import Device
from discrepancy import effects as fx
from discrepancy import fit as fitm
from discrepancy import select
from discrepancy import workflow as wf
from discrepancy.replay import Replayer, control_period_of, prepare_runs

from bank import hidden, servo_truth

CASE = "load_friction_nominal_off"
#: The point CI reported at 66d9989 with the switch (the failing test's message).
CI_POINT = {"armature_kgm2": 0.002703, "mu_drive": 0.1919, "mu_back": 0.3644}
#: The far start's coefficients (the corrections at the nominal's values).
FAR_START = {"mu_drive": 0.04, "mu_back": 0.07}
#: The blend speed that makes the law a switch on sign(tau w) (mu_back at rest).
SWITCH_SPEED = 0.0


def _scan(case, blend: float) -> dict:
    drive_laws.LOAD_FRICTION_BLEND_RAD_S = blend
    servo_truth.BLEND_SPEED_RAD_S = blend
    path, target = hidden.nominal(case)
    runs = hidden.generate(case)
    model = om.load_model(path, target=target)
    spec = mujoco.MjSpec.from_file(str(path))
    period = control_period_of(runs)
    rr = prepare_runs(runs, Device(model, period, target=target))
    builder = fx.ModelBuilder(spec, target)
    fixed = [builder.effect(n) for n in wf.correction_names("auto", spec, target, True)]
    effs = fixed + [builder.effect("load_friction")]
    names = [p.name for e in effs for p in e.params]
    x_nom = np.concatenate([builder.nominal_values(e) for e in fixed] + [np.zeros(2)])
    truth_joint = hidden.truth_joint(case)
    xt = x_nom.copy()
    for attr, _ in case.nominal_joint:
        xt[names.index(hidden.CORRECTED_BY[attr][1])] = truth_joint[attr]
    xt[names.index("mu_drive")], xt[names.index("mu_back")] = dict(case.effects)["load_friction"]
    starts = {"truth": xt.copy(), "ci_point": xt.copy(), "far": x_nom.copy()}
    for k, v in CI_POINT.items():
        starts["ci_point"][names.index(k)] = v
    for k, v in FAR_START.items():
        starts["far"][names.index(k)] = v
    out = {"parameters": names, "truth_x": xt.tolist()}
    with Replayer(None, target, period) as rep:
        prob = fitm.Problem(builder, [], effs, rr, rep)
        out["truth_gap"] = fitm.gap(prob.simulate([xt])[0])
        mus = np.round(np.linspace(0.35, 0.55, 21), 3)
        pts = []
        for m in mus:
            x = xt.copy()
            x[names.index("mu_back")] = m
            pts.append(x)
        out["mu_back_scan"] = {"mu_back": mus.tolist(), "gap": [fitm.gap(r) for r in prob.simulate(pts)]}
        out["fits"] = {}
        for label, x0 in starts.items():
            f = prob.fit(x0, max_nfev=30)
            out["fits"][label] = {"start": x0.tolist(), "x": f.x.tolist(), "gap": f.gap_train}
        if blend != SWITCH_SPEED:
            out["prescreen"] = _prescreen(builder, fixed, x_nom[:len(names) - 2], rr, rep)
    return out


def _prescreen(builder, fixed: list, x_own: np.ndarray, rr: list, rep) -> dict:
    corr = fitm.Problem(builder, [], fixed, rr, rep).fit(x_own, max_nfev=30)
    short = [r.first_seconds(select.PRESCREEN_S) for r in rr]
    eff = builder.effect("load_friction")
    grid = [eff.clip(np.asarray(g, float)) for g in eff.grid(np.zeros(2))]
    prob = fitm.Problem(builder, [], fixed + [eff], short, rep)
    gaps = {}
    for label, base in (("from_corrections", corr.x), ("from_own_values", x_own)):
        raws = prob.simulate([np.concatenate([base, g]) for g in grid])
        gaps[label] = [fitm.gap(r) for r in raws]
    (p,) = select.prescreen(builder, fixed, corr.x, ["load_friction"], rr, rep)
    return {"corrections_x": corr.x.tolist(), "grid": [g.tolist() for g in grid], "grid_gap": gaps,
            "prescreen_x": p.x.tolist(), "prescreen_gap": p.gap}


def record() -> dict:
    """The record: the case, the blend and switch speeds, the starts, and :func:`_scan` per law
    (the switch first, then the blend)."""
    case = hidden.case(CASE)
    blend = drive_laws.LOAD_FRICTION_BLEND_RAD_S
    out = {"case": CASE, "blend_rad_s": blend, "switch_rad_s": SWITCH_SPEED, "ci_point": CI_POINT,
           "far_start": FAR_START}
    try:
        out["switch"] = _scan(case, SWITCH_SPEED)
    finally:
        drive_laws.LOAD_FRICTION_BLEND_RAD_S = servo_truth.BLEND_SPEED_RAD_S = blend
    out["blend"] = _scan(case, blend)
    return out
