"""Fidelity screen: which single effect of the discrepancy library moves the virtual Omni's
linear-model step error towards the real Omni's, and at what cost on Table 3.

The virtual Omni is calibrated to the paper's Table 3, Table 9's resonance, Table 10 and
section 2.3, yet the linear model (26) follows its steps 3-4x better than it follows the real
Omni's (Table 11, linear column: median over the 25 Table 2 poses 11.2 mrad; lugre 3.1 mrad,
coulomb 2.9 mrad).  This study is a first *screen* for the missing effect: for each base scene
(``lugre`` = models/omni/scene.xml, ``coulomb`` = models/omni/scene_coulomb.xml) and each (effect,
magnitude) of :data:`CONFIGURATIONS`, one effect at a time is written into a copy of the base's
MjSpec (:func:`discrepancy.effects.apply`, target OMNI), the model is compiled and the
paper's campaign runs on it in memory (:func:`omni_studies.reproduce.simulate_campaign`).  Nothing
is re-calibrated: the friction and inertia stay the base scene's.

Measured, device-describing figures only:

* the linear model's step errors at the 25 Table 2 poses (per pose: median and p90 of
  |theta_linear - theta| over the whole record, as Table 11), their median over poses beside
  Table 11's linear column, and the poses within 40 % of Table 11's linear median;
* Table 3: the identified C_linear and beta~_linear at the 9 Table 1 poses against the paper's
  (worst relative errors) and the worst actual-angle error;
* the resonance sqrt(beta_linear)/(2 pi) at 65/90 (Table 9).

The alpha-invariant model is neither fitted nor simulated here: the identification stops after
the per-pose linear models and the inertia model (6), and only the linear model is simulated
on the steps.  Tables 8 and 11's alpha columns are the paper's validation; no choice of this
screen may look at them.  As a second guard, every key containing "alpha" is dropped from what
is recorded (:func:`strip_alpha`).

The magnitudes are data (:data:`CONFIGURATIONS`, each with its provenance in the library's
docstrings or models/omni/README.md), fixed before any result was seen.

:func:`run_configuration` (one configuration, a record row), :func:`new_record` (the record
around the rows), :func:`pending` (which configurations a run computes).
``scripts/fidelity_screen.py`` is the command; :mod:`omni_app.fidelity_screen_report` writes
``screen.json``, ``screen.md`` and ``screen.png``.
"""

from __future__ import annotations

import math
import platform
import time
from pathlib import Path

import numpy as np

from omni_studies.calibration import STEP_BAND_REL
from omni_sim.device import ENCODER_STEP_RAD

ROOT = Path(__file__).resolve().parents[1]

#: The Omni's encoder count [rad] (the device's, 15000 counts/rev), for the backlash magnitudes.
COUNT_RAD = ENCODER_STEP_RAD
#: A pose "matches" Table 11 when its linear median step error is within this fraction of it
#: (the table-level targets' band, omni_studies.calibration.STEP_BAND_REL).
WITHIN = STEP_BAND_REL
#: The bases: scene file (relative to the project) per friction family.
BASES = {"lugre": "models/omni/scene.xml", "coulomb": "models/omni/scene_coulomb.xml"}
#: The scene's calibrated LuGre element ``yaw_friction`` (models/omni/scene_lugre.xml): sigma0
#: [N*m/rad], Fc, Fs [N*m], vs [rad/s]; the lugre base's presliding_friction values start here.
LUGRE = (3.20549, 0.012916, 0.0316457, 0.615182)

# -- the configurations (fixed before any result) -----------------------------------------------
#: ``(effect, label, values, provenance)`` per base; values in the effect's parameter order
#: (discrepancy/effects).  Every magnitude lies inside the library's bounds and its
#: documented plausible range (the provenance says where).
_SHARED = [
    ("coulomb_friction", "10mNm", [0.010],
     "joint frictionloss 10 mN*m: middle of models/omni/README.md's waist Coulomb estimate 5-20 mN*m; "
     "library grid value (effects/joint.py). lugre base: a hard stick added to the LuGre element "
     "(its frictionloss is 0); coulomb base: replaces the calibrated 3.85 mN*m"),
    ("coulomb_friction", "20mNm", [0.020],
     "joint frictionloss 20 mN*m: top of models/omni/README.md's 5-20 mN*m estimate; library grid value"),
    ("stribeck_friction", "Fc5_Fs15_vs0.1", [0.005, 0.015, 0.1],
     "added stiff LuGre (Stribeck) element Fc 5, Fs 15 mN*m, vs 0.1 rad/s: the example of "
     "effects/friction.py's docstring (realistic Fc 5-20, Fs up to 35 mN*m); stacks on the base's friction"),
    ("stribeck_friction", "Fc10_Fs30_vs0.1", [0.010, 0.030, 0.1],
     "added Stribeck element Fc 10, Fs 30 mN*m, vs 0.1 rad/s: library grid value (effects/friction.py), "
     "inside its realistic Fc 5-20 / Fs <= 35 mN*m; stacks on the base's friction"),
    ("cogging", "1mNm", [0.001, 0.0],
     "cogging 1 mN*m, 45 periods per turn, phase 0: bottom of effects/friction.py's 1-3 mN*m estimate"),
    ("cogging", "3mNm", [0.003, 0.0],
     "cogging 3 mN*m, 45 periods per turn, phase 0: top of effects/friction.py's 1-3 mN*m estimate"),
    ("backlash", "1count", [1 * COUNT_RAD],
     "half-width 1 encoder count (0.42 mrad): effects/two_mass.py, a slack cable or loose coupling "
     "gives a few counts (1 count: 8x the noise floor)"),
    ("backlash", "3counts", [3 * COUNT_RAD],
     "half-width 3 encoder counts (1.26 mrad): effects/two_mass.py's 'a few counts' (19x the floor)"),
    ("drive_compliance", "k20", [20.0, 0.0, 1e-4],
     "capstan cable 20 N*m/rad, no cable damping, rotor = the scene's armature 1e-4 kg*m^2: "
     "effects/two_mass.py's soft-drive range 0.5-100 N*m/rad (k = 20: 160x the floor)"),
    ("drive_compliance", "k5", [5.0, 0.0, 1e-4],
     "capstan cable 5 N*m/rad (a loose or stretched cable), rotor 1e-4 kg*m^2: effects/two_mass.py "
     "(k = 5: 600x the floor; grid 2, 5, 15, 40)"),
    ("armature", "5e-5", [5e-5],
     "reflected rotor inertia 5e-5 kg*m^2: bottom of models/omni/README.md's estimate 5e-5-2e-4 (nominal 1e-4)"),
    ("armature", "2e-4", [2e-4],
     "reflected rotor inertia 2e-4 kg*m^2: top of models/omni/README.md's estimate 5e-5-2e-4"),
    ("actuator_lag", "2ms", [0.002],
     "first-order drive lag 2 ms (amplifier/current loop): library scale and grid value (effects/actuator.py)"),
    ("actuator_lag", "5ms", [0.005],
     "first-order drive lag 5 ms: library grid value (effects/actuator.py)"),
    ("time_delay", "2ms", [0.002],
     "pure loop delay 2 ms: 'a USB servo loop's few ms' (effects/actuator.py; models/omni/README.md: "
     "servo loop 1 kHz nominal, 700-900 Hz on some USB units); library grid value"),
    ("time_delay", "5ms", [0.005],
     "pure loop delay 5 ms: the upper end of 'a few ms' (effects/actuator.py); library grid value"),
    ("joint_stiffness", "0.03", [0.03, 0.0],
     "torsional spring 0.03 N*m/rad at the yaw, rest at 0 (cables, wiring through the turret): "
     "library grid value (effects/joint.py; scale 0.02)"),
    ("joint_stiffness", "0.1", [0.1, 0.0],
     "torsional spring 0.1 N*m/rad (a tenth of the P loop's kp * gear = 1 N*m/rad): library grid value"),
]

_PRESLIDING = {
    "lugre": [
        ("presliding_friction", "sigma0x0.3", [0.3 * LUGRE[0], *LUGRE[1:]],
         "yaw_friction's bristles weaker, sigma0 x 0.3 (0.96 N*m/rad), levels kept: library grid "
         "factor (effects/friction.py; bounds 0.3-100 N*m/rad)"),
        ("presliding_friction", "sigma0x3", [3.0 * LUGRE[0], *LUGRE[1:]],
         "yaw_friction's bristles stiffer, sigma0 x 3 (9.6 N*m/rad), levels kept: library grid "
         "factor; its docstring: sigma0 3.2 -> 10 is 54x the floor"),
        ("presliding_friction", "Fc19_Fs35", [LUGRE[0], 0.0194, 0.0348, LUGRE[3]],
         "yaw_friction's levels at the top of the documented ranges, Fc 19.4 mN*m (x1.5, estimate "
         "5-20) and Fs 34.8 mN*m (x1.1, below the 35 mN*m back-drive bound, models/omni/README.md)"),
    ],
    "coulomb": [
        ("presliding_friction", "s3_Fc5_Fs10", [3.0, 0.005, 0.010, 0.5],
         "an added LuGre element sigma0 3, Fc 5, Fs 10 mN*m, vs 0.5 rad/s (the hard stick kept): "
         "library grid for a model without one (effects/friction.py)"),
        ("presliding_friction", "s10_Fc10_Fs20", [10.0, 0.010, 0.020, 0.5],
         "an added LuGre element sigma0 10, Fc 10, Fs 20 mN*m, vs 0.5 rad/s: library grid value"),
    ],
}


def configurations() -> list[dict]:
    """Every configuration: the two bases unchanged, then each base's (effect, magnitude)s."""
    out = []
    for base in BASES:
        out.append({"id": f"{base}/none/base", "base": base, "effect": None, "label": "base",
                    "values": [], "provenance": f"{BASES[base]} as calibrated"})
        for eff, label, values, prov in _PRESLIDING[base] + _SHARED:
            out.append({"id": f"{base}/{eff}/{label}", "base": base, "effect": eff, "label": label,
                        "values": [float(v) for v in values], "provenance": prov})
    return out


CONFIGURATIONS = configurations()


# -- the paper's reference (linear columns only) -------------------------------------------------
def paper_reference() -> dict:
    """Table 11's linear columns (per pose and their median over poses), Table 9's resonance."""
    from identification import paper

    rows = paper.table11()
    med = [r["median_linear_rad"] for r in rows]
    p90 = [r["p90_linear_rad"] for r in rows]
    beta = paper.table9()["beta_linear"]["fitted"]
    return {"step_linear_median_over_poses_rad": float(np.median(med)),
            "step_linear_p90_median_over_poses_rad": float(np.median(p90)),
            "n_poses": len(rows),
            "resonance_hz_65_90": math.sqrt(beta) / (2 * math.pi),
            "table11_linear": {f"{int(r['gamma1_set_deg'])}/{int(r['gamma2_set_deg'])}":
                               [r["median_linear_rad"], r["p90_linear_rad"]] for r in rows}}


# -- one configuration ---------------------------------------------------------------------------
def build_model(cfg: dict):
    """The base's MjSpec with the configuration's effect written in, compiled."""
    import mujoco

    from discrepancy import effects

    spec = mujoco.MjSpec.from_file(str(ROOT / BASES[cfg["base"]]))
    if cfg["effect"] is not None:
        eff = effects.get(cfg["effect"])
        spec = effects.apply(spec, [(eff, np.asarray(cfg["values"], float))], effects.OMNI)
    return spec.compile()


def _linear_step_errors(runs, inertia_params) -> list[dict]:
    """The linear model (26) on every step run (:func:`omni_studies.calibration.linear_step_errors`),
    in this screen's row layout."""
    from omni_studies.calibration import linear_step_errors

    return [{"set_deg": r["set"], "median_linear_rad": r["median_rad"], "p90_linear_rad": r["p90_rad"]}
            for r in linear_step_errors(runs, inertia_params)]


def measure_model(model, jobs=None) -> dict:
    """The screen's figures of one compiled model (see the module docstring)."""
    from identification.identify import Identification, identify_runs
    from identification.inertia import MIN_POSES, fit_inertia_model
    from omni_studies.comparison import DETAIL_POSE, pose_of, resonance_hz, table3_errors
    from omni_sim.device import Device
    from omni_studies.reproduce import simulate_campaign

    runs = list(simulate_campaign(Device(model), jobs).runs)
    lin = identify_runs(runs, linear_only=True)  # per-pose linear models: stops before any alpha fit
    usable = [p for p in lin.poses if p.physical]
    out: dict = {"warnings": list(lin.warnings)}
    t3 = table3_errors(lin)
    out["table3"] = {k: t3[k] for k in ("n_poses", "C_linear_worst_rel_error",
                                       "beta_tilde_linear_worst_rel_error", "angle_worst_error_deg")}
    out["table3"]["poses"] = [{k: r[k] for k in ("set_deg", "C_linear_rel_error",
                                                "beta_tilde_linear_rel_error", "angle_error_deg")}
                              for r in t3["poses"]]
    detail = pose_of(lin, DETAIL_POSE)
    out["resonance_hz_65_90"] = (resonance_hz(detail.beta_linear) if detail is not None and detail.physical
                                 else None)
    if len(usable) < MIN_POSES:
        out["ok"] = False
        out["error"] = f"only {len(usable)} physical poses: no inertia model (6), no step prediction"
        return out
    inertia = fit_inertia_model([p.gamma1_deg for p in usable], [p.gamma2_deg for p in usable],
                                [p.C_linear for p in usable], [p.beta_tilde_linear for p in usable])
    if inertia.poorly_determined:
        out["warnings"].append("inertia model: poorly determined " + ", ".join(inertia.poorly_determined))
    ident = Identification(lin.poses, inertia, out["warnings"], lin.ignored_runs)
    steps = _linear_step_errors(runs, ident.inertia.params)
    out["step_linear"] = summarise_steps(steps)
    out["ok"] = True
    return out


def summarise_steps(rows: list[dict]) -> dict:
    """Per-pose linear step errors beside Table 11's linear column, and their summaries."""
    from identification import paper

    t11 = paper.by_set_pose(paper.table11())
    within = 0
    for r in rows:
        t = t11.get(tuple(r["set_deg"]))
        r["paper_median_linear_rad"] = t["median_linear_rad"] if t else None
        r["paper_p90_linear_rad"] = t["p90_linear_rad"] if t else None
        r["ratio_to_paper"] = r["median_linear_rad"] / t["median_linear_rad"] if t else None
        if t and abs(r["ratio_to_paper"] - 1) <= WITHIN:
            within += 1
    med = [r["median_linear_rad"] for r in rows]
    p90 = [r["p90_linear_rad"] for r in rows]
    return {"n_poses": len(rows),
            "median_over_poses_rad": float(np.median(med)),
            "p90_median_over_poses_rad": float(np.median(p90)),
            "median_p90_over_poses_rad": float(np.percentile(med, 90)),
            "poses_within_40pct": within,
            "statistic": "per pose: median (p90) of |theta_linear - theta| over the whole record "
                         "(Table 11); summaries: median over poses",
            "poses": rows}


def strip_alpha(x):
    """``x`` without any dict key that mentions "alpha" (recursively)."""
    if isinstance(x, dict):
        return {k: strip_alpha(v) for k, v in x.items() if "alpha" not in str(k).lower()}
    if isinstance(x, list):
        return [strip_alpha(v) for v in x]
    return x


def run_configuration(cfg: dict, jobs=None) -> dict:
    """Build, simulate and measure one configuration; a failure is recorded, never dropped."""
    t0 = time.perf_counter()
    try:
        model = build_model(cfg)
        fig = measure_model(model, jobs)
    except Exception as exc:  # noqa: BLE001  (a configuration that fails is a result)
        fig = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
    fig["wall_s"] = time.perf_counter() - t0
    return strip_alpha({**cfg, **fig})


# -- the record ----------------------------------------------------------------------------------
def new_record(jobs: int | None, code_commit: str | None) -> dict:
    """The screen's record without configurations: settings, code commit, machine, the paper's
    reference."""
    return {"description": "fidelity screen: one library effect at a time on the calibrated "
                           "scenes; linear-model step errors and Table 3 (no alpha model)",
            "settings": {"bases": BASES, "campaign": "paper", "within_fraction": WITHIN,
                         "jobs": jobs, "target": "OMNI (joint yaw, actuator yaw_motor)"},
            "code_commit": code_commit,
            "machine": {"python": platform.python_version(), "processor": platform.machine()},
            "paper": paper_reference(),
            "configurations": []}


def pending(chosen: list[str], done: dict, rerun: bool) -> list[dict]:
    """The configurations of ``chosen`` to compute, in :data:`CONFIGURATIONS`' order: every one
    with ``rerun``, else those without a successful row in ``done``."""
    return [c for c in CONFIGURATIONS if c["id"] in chosen
            and (rerun or not done.get(c["id"], {}).get("ok"))]
