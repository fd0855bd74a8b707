"""What the documentation's figures come from: the records the tools write, read from the checkout,
and the formats the pages print them in (:mod:`tools.docs_tables` renders the generated tables,
:mod:`tools.docs_claims` the figures quoted in the prose; both read :func:`load_sources`)."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

from identification import paper

ROOT = Path(__file__).resolve().parents[1]

#: The pages that hold generated tables or quoted figures, by short name (paths from the root).
PAGES = {"results": "docs/studies/reproduce/results.md", "model": "docs/reference/model.md",
         "calibration": "docs/studies/calibration/calibration.md",
         "friction": "docs/method/friction-families.md", "errata": "docs/method/paper-errata.md",
         "performance": "docs/reference/performance.md", "gymnasium": "docs/usage/gymnasium.md",
         "sweeps": "docs/usage/sweeps.md", "readme": "README.md",
         "real_servo": "examples/real_servo/README.md"}
#: The targets the tables state (the report's: omni_app/report.py).
TARGET_INERTIA_REL = 0.02
TARGET_STEP_RATIO = 3.0
TARGET_RTF = 50.0
TARGET_C_REL = 0.10             # calibration: C_linear, beta~_linear within 10 % of Table 3
TARGET_ANGLE_DEG = 1.5
TARGET_RESONANCE_HZ = (3.4, 0.3)
TARGET_FALL = 3.0
TARGET_GENERATE_RTF = 100.0     # omni bench (omni_studies/bench.py)
TARGET_ROLLOUT_RATIO = 0.8
TARGET_ALPHA_LSIM = 3.0
TARGET_REPRODUCE_RATIO = 6.0
TARGET_VECTOR_RATIO = 0.3
TARGET_SWEEP_SPEEDUP = 1.7
TARGET_COLD_RATIO = 1.3         # omni reproduce's first run after an install / a later one (bench.py)
#: docs/studies/calibration/calibration.md's "close" candidates of the table-level search: a step error (Table 11's
#: linear column, median over poses) within this share of the real Omni's.
CLOSE_STEP_REL = 0.25
MINUS = "\u2212"


# -- sources ------------------------------------------------------------------------------------
def _json(rel):
    return json.loads((ROOT / rel).read_text())


def _servo_model(rel) -> dict:
    """The real-servo example's nominal model: its hinge's and its actuator's attributes."""
    import xml.etree.ElementTree as ET

    root = ET.parse(ROOT / rel).getroot()
    return {"joint": root.find(".//joint[@name='servo_axis']").attrib,
            "actuator": root.find("./actuator/*[@name='servo']").attrib}


def load_sources() -> dict:
    """Every file the pages' results quote, parsed."""
    with open(ROOT / "docs" / "studies" / "sweep" / "results.csv") as fh:
        sweep = list(csv.DictReader(fh))
    return {"summary": _json("docs/studies/reproduce/summary.json"),
            "comparison": _json("docs/studies/friction/comparison.json"),
            "lugre_params": _json("docs/studies/friction/lugre/params.json"),
            "study": _json("docs/studies/friction/friction_study.json"),
            "cal": _json("models/omni/calibration.json"),
            "cal_coulomb": _json("models/omni/calibration_coulomb.json"),
            "cal_hard_stick": _json("docs/studies/calibration/calibration_coulomb_run.json"),
            "cal_coulomb_all_free": _json("docs/studies/fidelity/coulomb_all_free.json"),
            "cal_weighted": _json("docs/studies/calibration/calibration_weighted_run.json"),
            "cal_matched": _json("models/omni/calibration_matched.json"),
            "matched_summary": _json("docs/studies/friction/matched/summary.json"),
            "search": _json("docs/studies/fidelity/search.json"),
            "bench": _json("docs/reference/bench.json"),
            "zwidth_ideal": _json("docs/studies/haptics/zwidth_ideal.json"),
            "real_servo": _json("examples/real_servo/report/report.json"),
            "real_servo_model": _servo_model("examples/real_servo/model.xml"),
            "sweep": sweep}


# -- formatting ---------------------------------------------------------------------------------
def _s(x: float, nd: int = 1) -> str:
    """Signed, with a true minus sign: +2.2, −7.3."""
    return f"{x:+.{nd}f}".replace("-", MINUS)


def _m(x: float, nd: int = 1) -> str:
    """A number with a true minus sign."""
    return f"{x:.{nd}f}".replace("-", MINUS)


def _sci(x: float, nd: int = 1) -> str:
    """6.8e-4 (no zero-padded exponent)."""
    mant, exp = f"{x:.{nd}e}".split("e")
    return f"{mant}e{int(exp)}"


def _int(n: int) -> str:
    """686 000 (a space between thousands)."""
    return f"{n:,}".replace(",", " ")


def _met(ok: bool) -> str:
    return "met" if ok else "**not met**"


def _pose(p) -> str:
    return f"{round(p[0])}/{round(p[1])}"


def _mrad(x: float, nd: int = 1) -> str:
    return f"{1e3 * x:.{nd}f}"


# -- the α model of the reproduction at 65/90 ------------------------------------------------------
def _beta_tilde_65_90(params: dict) -> dict:
    """beta~(alpha) of the reproduction's alpha model at 65/90 (inertia model (6)) at alpha = 0,
    the highest alpha fitted there (frequencies up to resonance), alpha at resonance and the
    right edge of Fig. 10 (twice the highest alpha of the pose's data)."""
    import numpy as np

    from identification.inertia import InertiaParameters
    from identification.nonlinear import AlphaModel, pose_resonance_hz

    pose = next(p for p in params["poses"] if (round(p["gamma1_set_deg"]), round(p["gamma2_set_deg"]))
                == paper.TABLE9_10_SET_POSE)
    am = AlphaModel.from_dict(params["alpha_model"])
    I = float(InertiaParameters.from_dict(params["inertia_model"]).inertia(pose["gamma1_deg"],
                                                                          pose["gamma2_deg"]))
    f_res = pose_resonance_hz({"beta_linear": pose["beta_linear"]})
    freqs = pose["frequencies"]
    fitted = [q["alpha"] for q in freqs if q["used"] and q["frequency_hz"] <= f_res]
    at_res = max(q["alpha"] for q in freqs)
    edge = 2 * max(q["alpha"] for q in freqs)
    bt = lambda a: float(am.beta_tilde(np.array([a]), I)[0])  # noqa: E731
    return {"alpha_fitted": max(fitted), "alpha_resonance": at_res, "alpha_edge": edge,
            "at_0": bt(0.0), "at_fitted": bt(max(fitted)), "at_resonance": bt(at_res),
            "at_edge": bt(edge)}


def _cal_detail(rec: dict) -> dict:
    return next(p for p in rec["poses"] if tuple(round(x) for x in p["set"]) == paper.TABLE9_10_SET_POSE)


#: A count in words, as the prose writes it up to twelve.
_WORDS = {2: "two", 3: "three", 4: "four", 5: "five", 6: "six", 7: "seven", 8: "eight", 9: "nine",
          10: "ten", 11: "eleven", 12: "twelve"}


def _count(n: int) -> str:
    """A count as the prose writes it: in words up to twelve."""
    return _WORDS.get(n, str(n))


def _norm(text: str) -> str:
    return re.sub(r"\s+", " ", text)
