"""Does the identified damping predict the Z-width boundary better than the nominal b?

For each friction family (lugre, coulomb) the paper's identification runs on the virtual Omni
(``omni reproduce --friction F``, or a given params.json).  At the wall maps' pose (servo set
points gamma_set = (65, 90) deg; the actual, sagged angles from ``Device.equilibrium``, as
:func:`omni_studies.zwidth.passivity_map` uses them) three physical dampings [N*m*s/rad] are formed:

* ``nominal``: the yaw's joint damping b (:func:`omni_studies.zwidth.physical_damping`);
* ``linear``: b_id = C_linear * I_yaw, C_linear [1/s] of the identified pose nearest to the actual
  angles (beta_bar = 1 units: C = damping / inertia), I_yaw MuJoCo's yaw inertia there
  (``Device.inertia``);
* ``alpha``: C(alpha, I) * I_yaw, the identified alpha model (params.json ``alpha_model``, I the
  identified inertia model (6) at the actual angles) evaluated at the alpha of the wall's command
  voltage during the probe.  That alpha comes from a recorded map run at the measured boundary
  cell (K = the row's measured K_max, B) of every damping row: v = tau_wall / torque_constant per
  servo period, over the energy window; alpha is the cycle average (34) over whole cycles, 2 <v'^2>
  (the end term cancels), with v' the backward difference of the period samples; the probe taken is the binding one (the smallest energy index at that cell).
  np.interp holds C at its end values outside the identified [alpha0, alpha3]; the JSON says
  whether alpha was outside.

Each is turned into Colgate & Schenkel's boundary 2(b_x - |B|)/T and compared with the measured
boundary of docs/studies/haptics/study.json (``scripts/zwidth_study.py``) for the lugre and coulomb maps,
exact and quantised encoder, probe speeds 0.02 and 1 rad/s.

:func:`family_dampings` (one family's pose and its three dampings), :func:`case_prediction`
(one map case: the alpha of the recorded runs, the predicted and measured boundaries).
``scripts/zwidth_damping.py`` is the command (it runs the identifications);
:mod:`omni_app.zwidth` writes the record and its figure.
"""

from __future__ import annotations

import math
import time

import numpy as np

from identification.inertia import InertiaParameters
from omni_studies import zwidth as zw

GAMMA_SET = (65.0, 90.0)
FAMILIES = ("lugre", "coulomb")
#: study case name -> (family, quantize, probe speed)
CASES = {f"{fam}_{enc}_{v}": (fam, enc == "quantised", speed)
         for fam in FAMILIES for enc in ("exact", "quantised")
         for v, speed in (("v002", 0.02), ("v1", 1.0))}
PREDICTORS = ("nominal", "linear", "alpha")


def pose_dampings(family: str, params: dict) -> dict:
    dev, _ = zw.map_device(None, family)
    g1, g2 = dev.equilibrium(*GAMMA_SET)
    I_yaw = dev.inertia(g1, g2)
    poses = params["poses"]
    d = [math.hypot(p["gamma1_deg"] - g1, p["gamma2_deg"] - g2) for p in poses]
    i = int(np.argmin(d))
    C_lin = float(poses[i]["C_linear"])
    inertia_model = InertiaParameters.from_dict(params["inertia_model"])
    return {"family": family, "gamma_set_deg": list(GAMMA_SET), "gamma_actual_deg": [g1, g2],
            "identified_pose_deg": [poses[i]["gamma1_deg"], poses[i]["gamma2_deg"]],
            "identified_pose_distance_deg": d[i],
            "I_yaw": I_yaw, "torque_constant": dev.torque_constant,
            "I_paper": float(inertia_model.inertia(g1, g2)),
            "C_linear": C_lin, "C_linear_inertia_model": float(inertia_model.C(g1, g2)),
            "b_nominal": zw.physical_damping(dev), "b_linear": C_lin * I_yaw,
            "friction": dev.friction(), "sample_period_s": dev.control_period_s}


def probe_alpha(case: str, measured: list, damping: np.ndarray, pose: dict) -> dict:
    """Record the map's run at each row's measured boundary cell; alpha of the wall's command."""
    family, quantize, speed = CASES[case]
    dev, tlim = zw.map_device(None, family)
    T, kt = dev.control_period_s, dev.torque_constant
    K = np.array([0.0 if x is None else x for x in measured])  # None: not passive even at K = 0
    res = zw.passivity_map(dev, K, damping, torque_limit=tlim, quantize=quantize,
                           probe_speed=speed, record=True)
    nB, nK = len(damping), len(K)
    tau = res.trace["tau_wall"]
    n = tau.shape[1]
    k0 = int(round(zw.SETTLE_FRACTION * n))
    per = res.index_per_probe  # probes x damping x stiffness
    out = []
    for i in range(nB):
        alphas = []
        for p in range(per.shape[0]):
            v = tau[p * nB * nK + i * nK + i, k0:] / kt
            # (34) over whole cycles: 2 <v'^2> (the end term [v v'] cancels; the wall's command
            # carries the push's large DC part K p0, which makes the end term of a window that
            # is not a whole number of cycles large)
            alphas.append(float(2.0 * np.mean((np.diff(v) / T) ** 2)))
        binding = int(np.argmin(per[:, i, i]))
        out.append({"K": float(K[i]), "B": float(damping[i]),
                    "alpha_per_probe": alphas, "probe_periods": list(res.probe_periods),
                    "binding_probe": res.probe_periods[binding],
                    "alpha": alphas[binding],
                    "index_per_probe": [float(x) for x in per[:, i, i]]})
    return out


def family_dampings(family: str, params: dict, source: str) -> dict:
    """The family's entry of the record: :func:`pose_dampings`, the identified alpha model's
    breaks and slopes, and where the identification (``params``, a params.json) came from."""
    info = pose_dampings(family, params)
    am = params["alpha_model"]
    info["alpha_model"] = {k: am[k] for k in ("alpha_breaks", "C_k1")}
    info["params_source"] = source
    return info


def case_prediction(case: str, study: dict, damping: np.ndarray, info: dict, model) -> dict:
    """One case of :data:`CASES`: the alpha at each row's measured boundary cell
    (:func:`probe_alpha`), the dampings b_x, their boundaries 2(b_x - |B|)/T against the
    measured one of ``study`` (the Z-width study's record), and their errors; ``info`` the
    family's :func:`family_dampings`, ``model`` its identified
    :class:`identification.nonlinear.AlphaModel`."""
    fam, quantize, speed = CASES[case]
    T = info["sample_period_s"]
    meas = study["cases"][case]["boundary_stiffness"]
    passive = np.array(study["cases"][case]["passive"], dtype=bool)
    t0 = time.perf_counter()
    rows = probe_alpha(case, meas, damping, info)
    lo, hi = model.alpha_breaks[0], model.alpha_breaks[-1]
    for i, r in enumerate(rows):
        a = r["alpha"]
        r["alpha_outside_identified_range"] = bool(a < lo or a > hi)
        C_a = float(model.C(a, info["I_paper"]))
        r["C_alpha"] = C_a
        b = {"nominal": info["b_nominal"], "linear": info["b_linear"],
             "alpha": C_a * info["I_yaw"]}
        if fam == "coulomb":
            b["coulomb_fc_over_v"] = info["b_nominal"] + info["friction"]["frictionloss"] / speed
        r["b"] = b
        r["predicted"] = {k: float(zw.colgate_limit(v, damping[i], T)) for k, v in b.items()}
        m = meas[i]
        capped = bool(passive[i].all())  # passive to the grid's end: only K_max >= 40 known
        r["measured"] = m
        r["measured_capped_at_grid_end"] = capped
        r["b_implied_by_measured"] = (None if m is None or capped
                                      else m * T / 2 + abs(damping[i]))
        r["error"] = {k: (None if m is None or capped or m <= 0 else (v - m) / m)
                      for k, v in r["predicted"].items()}
    errs = {k: [r["error"][k] for r in rows if r["error"][k] is not None]
            for k in rows[0]["error"]}
    return {"family": fam, "quantize": quantize, "probe_speed": speed,
            "elapsed_s": round(time.perf_counter() - t0, 2), "rows": rows,
            "median_abs_error": {k: (float(np.median(np.abs(v))) if v else None)
                                 for k, v in errs.items()},
            "rows_compared": len(errs["nominal"])}
