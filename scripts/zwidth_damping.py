#!/usr/bin/env python
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

Writes ``--out`` (JSON, default docs/studies/haptics/damping_prediction.json) and the figure beside it
(same stem, .png).

    python scripts/zwidth_damping.py
    python scripts/zwidth_damping.py --params lugre=docs/studies/friction/lugre/params.json,coulomb=...
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from identification.inertia import InertiaParameters
from identification.nonlinear import AlphaModel
from omni_studies import zwidth as zw

ROOT = Path(__file__).resolve().parents[1]

GAMMA_SET = (65.0, 90.0)
FAMILIES = ("lugre", "coulomb")
#: study case name -> (family, quantize, probe speed)
CASES = {f"{fam}_{enc}_{v}": (fam, enc == "quantised", speed)
         for fam in FAMILIES for enc in ("exact", "quantised")
         for v, speed in (("v002", 0.02), ("v1", 1.0))}
PREDICTORS = ("nominal", "linear", "alpha")


def identify(family: str, workdir: Path) -> Path:
    """Run ``omni reproduce --friction family`` into workdir/family; returns its params.json."""
    out = workdir / family
    workdir.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "omni_app", "reproduce", "--friction", family, "--out", str(out), "--force"]
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    print(f"identified {family} in {time.perf_counter() - t0:.1f} s ({' '.join(cmd[1:])})",
          flush=True)
    return out / "params.json"


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
    tau = res["trace"]["tau_wall"]
    n = tau.shape[1]
    k0 = int(round(zw.SETTLE_FRACTION * n))
    per = res["index_per_probe"]  # probes x damping x stiffness
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
                    "alpha_per_probe": alphas, "probe_periods": list(res["probe_periods"]),
                    "binding_probe": res["probe_periods"][binding],
                    "alpha": alphas[binding],
                    "index_per_probe": [float(x) for x in per[:, i, i]]})
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--study", default=str(ROOT / "docs/studies/haptics/study.json"),
                   help="the study's JSON with the measured boundaries (scripts/zwidth_study.py)")
    p.add_argument("--out", default=str(ROOT / "docs/studies/haptics/damping_prediction.json"),
                   help="output JSON; the figure is written beside it (.png)")
    p.add_argument("--params", default=None,
                   help="FAMILY=params.json[,FAMILY=...]: use these identifications instead of "
                        "running omni reproduce")
    p.add_argument("--keep", default=None,
                   help="folder to keep the omni reproduce outputs in (default: a temporary one)")
    args = p.parse_args(argv)

    study = json.loads(Path(args.study).read_text())
    damping = np.array(study["grid"]["damping"])
    missing = [c for c in CASES if c not in study["cases"]]
    if missing:
        p.error(f"{args.study} lacks the case(s) {missing}: run scripts/zwidth_study.py")
    given = {}
    if args.params:
        for item in args.params.split(","):
            fam, _, path = item.partition("=")
            given[fam.strip()] = Path(path.strip())
    tmp = tempfile.TemporaryDirectory() if args.keep is None else None
    workdir = Path(args.keep) if args.keep else Path(tmp.name)
    doc = {"study": str(Path(args.study).resolve().relative_to(ROOT))
           if Path(args.study).resolve().is_relative_to(ROOT) else args.study,
           "families": {}, "cases": {}}
    try:
        for fam in FAMILIES:
            src = given.get(fam) or identify(fam, workdir)
            params = json.loads(Path(src).read_text())
            info = pose_dampings(fam, params)
            am = params["alpha_model"]
            info["alpha_model"] = {k: am[k] for k in ("alpha_breaks", "C_k1")}
            info["params_source"] = (str(src) if fam in given
                                     else f"omni reproduce --friction {fam} (run by this script)")
            doc["families"][fam] = info
            print(f"{fam}: actual pose {info['gamma_actual_deg'][0]:.2f}/"
                  f"{info['gamma_actual_deg'][1]:.2f} deg, I_yaw {info['I_yaw']:.5g}, C_linear "
                  f"{info['C_linear']:.4g} 1/s -> b_id {info['b_linear']:.4g} "
                  f"(nominal {info['b_nominal']:.4g})", flush=True)
            info["_model"] = AlphaModel.from_dict(am)
    finally:
        if tmp is not None:
            tmp.cleanup()

    for case, (fam, quantize, speed) in CASES.items():
        info = doc["families"][fam]
        T = info["sample_period_s"]
        meas = study["cases"][case]["boundary_stiffness"]
        passive = np.array(study["cases"][case]["passive"], dtype=bool)
        t0 = time.perf_counter()
        rows = probe_alpha(case, meas, damping, info)
        model = info["_model"]
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
        doc["cases"][case] = {"family": fam, "quantize": quantize, "probe_speed": speed,
                              "elapsed_s": round(time.perf_counter() - t0, 2), "rows": rows,
                              "median_abs_error": {k: (float(np.median(np.abs(v))) if v else None)
                                                   for k, v in errs.items()},
                              "rows_compared": len(errs["nominal"])}
        me = doc["cases"][case]["median_abs_error"]
        print(f"{case:24s} alpha(B=0) {rows[0]['alpha']:.4g} (probe m={rows[0]['binding_probe']})"
              f"  median |err| " + ", ".join(f"{k} {'-' if v is None else f'{v:.0%}'}"
                                             for k, v in me.items()), flush=True)
    for info in doc["families"].values():
        info.pop("_model")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1) + "\n")
    plot(doc, damping, out.with_suffix(".png"))
    print(f"wrote {out}, {out.with_suffix('.png')}")
    return 0


def plot(doc: dict, damping: np.ndarray, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(CASES)
    fig, axes = plt.subplots(2, 4, figsize=(13, 6.4), sharey=True)
    style = {"nominal": ("k-", "nominal b"), "linear": ("b--", "b_id = C_linear I"),
             "alpha": ("r:", "C(alpha) I"), "coulomb_fc_over_v": ("g-.", "b + Fc/V")}
    kmax = 45.0
    for ax, case in zip(axes.ravel(), names):
        c = doc["cases"][case]
        rows = c["rows"]
        meas = np.array([np.nan if r["measured"] is None else r["measured"] for r in rows])
        capped = np.array([r["measured_capped_at_grid_end"] for r in rows])
        for k, (ls, lab) in style.items():
            if k not in rows[0]["predicted"]:
                continue
            pk = np.array([r["predicted"][k] for r in rows])
            ax.plot(np.minimum(pk, kmax), damping, ls, lw=1.4, label=lab)
            off = pk > kmax
            if off.any():
                ax.plot(np.full(off.sum(), kmax), damping[off], ls[0] + ">", ms=5)
        ax.plot(meas[~capped], damping[~capped], "ko", ms=5, mfc="none", label="measured")
        if capped.any():
            ax.plot(meas[capped], damping[capped], "k>", ms=6, mfc="none",
                    label="measured: passive to K = 40")
        fam, q, v = CASES[case]
        ax.set_title(f"{fam}, {'quantised' if q else 'exact'}, V = {v:g} rad/s", fontsize=9)
        ax.set_xlim(0, kmax + 1)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("K_max [N m/rad]")
    for ax in axes[:, 0]:
        ax.set_ylabel("wall damping B [N m s/rad]")
    h, lab = axes[1, 0].get_legend_handles_labels()
    seen = dict(zip(lab, h))
    for ax in axes.ravel():
        for hh, ll in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(ll, hh)
    fig.legend(seen.values(), seen.keys(), loc="lower center", ncol=6, fontsize=8)
    fig.suptitle("Z-width boundary: measured vs 2(b_x - |B|)/T (arrows: off the scale, > 45)",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
