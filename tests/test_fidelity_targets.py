"""The table-level targets (omni_studies.calibration, targets="tables"): the published tables that
describe the real Omni -- Table 3, Table 9's resonance, Table 10, section 2.3 and Table 11's
*linear* column -- and never the paper's validation of the alpha model (Tables 8 and 11's alpha
columns).  The guard is behavioural: in a fresh process whose copy of the paper's data holds
nonsense in Tables 8 and 11's alpha columns, with a profiler recording every Python function that
runs, the evaluation runs none of the alpha model's code and gives the same residuals, bit for bit.
"""

import csv
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from identification import paper
from omni_studies import calibration as cal
from omni_sim import model as om

from omni_studies.fidelity import N_RESIDUALS

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def evaluation():
    fig = cal.evaluate(om.load_model(), cal.ex.SINE_AMPLITUDE_RAD, steps=True)
    return fig


def test_residual_sets(evaluation):
    """'calibration' = Table 3 (4 x 9), Table 10 (3 + the fall), section 2.3 (1); 'tables' adds
    Table 9's resonance and Table 11's linear median and p90 at its 25 poses."""
    cal_terms = cal.residual_terms(evaluation, "calibration")
    tab_terms = cal.residual_terms(evaluation, "tables")
    assert len(cal_terms) == 36 + 4 + 1
    assert tab_terms[:len(cal_terms)] == cal_terms
    extra = [label for label, _ in tab_terms[len(cal_terms):]]
    assert extra[0] == "table9 resonance"
    assert len(extra) == 1 + 2 * len(paper.table11()) == 51
    assert len(tab_terms) == N_RESIDUALS  # what the search returns for a failed candidate
    assert all(label.startswith(("table3", "table10", "section2.3", "table9", "table11 linear"))
               for label, _ in tab_terms)
    assert np.array_equal(cal.residuals(evaluation), np.array([v for _, v in cal_terms]))
    with pytest.raises(cal.UserError):
        cal.residual_terms(evaluation, "table8")


def test_table11_residuals_are_the_log_ratios(evaluation):
    """Each step residual is log(virtual / real) over half the 40 % band, per pose."""
    steps = evaluation["steps"]
    by_label = dict(cal.residual_terms(evaluation, "tables"))
    rows = paper.by_set_pose(paper.table11())
    for s in steps["poses"]:
        real = rows[tuple(s["set"])]
        key = f"{s['set'][0]}/{s['set'][1]}"
        assert by_label[f"table11 linear median {key}"] == pytest.approx(
            math.log(s["median_rad"] / real["median_linear_rad"]) / (math.log(1.4) / 2), rel=1e-12)
        assert s["paper_p90_rad"] == real["p90_linear_rad"]
    assert len(steps["poses"]) == 25


# -- the alpha model never enters a residual -------------------------------------------------------
# The guard runs the table-level evaluation in a fresh Python process (i) on a copy of the
# identification package whose paper data hold nonsense in every alpha column of Tables 8 and 11
# (and PAPER_STEP_RATIO = nan): any reader of those numbers -- paper.table11(), paper.table(),
# table11_summary(), a csv reader of its own -- gets the nonsense, so a residual that used them
# would change; and (ii) with a profiler (sys.setprofile, every thread) recording every Python
# function that runs, from the first import on: none of the alpha model's code below may run, and
# the compiled alpha loop may not even be imported.  Residuals compared bit for bit with
# the ordinary in-process evaluation (same machine, same code: the same bytes).

#: The alpha model's code (qualified names per file; nested functions included): its simulation,
#: the validation that scores it, the summaries that compare it with the linear model, the
#: paper's alpha model and the paper accessors of Tables 8 and 11's alpha figures.  Fitting the
#: alpha model to the virtual Omni's sine data is *not* here: Table 10's fall of C(alpha) is a
#: target (identification.nonlinear.fit_alpha_model runs in every evaluation).
ALPHA_CODE = {
    "identification/simulate.py": ("simulate_alpha", "simulate_alpha_batch", "_model_constants",
                                   "batch_loop_numpy", "_tolerance", "_bisect_fallback",
                                   "bench_simulation"),
    "identification/validation.py": ("simulate_runs", "_reference_derivatives", "score",
                                     "validate_runs", "write_predictions", "read_params"),
    "identification/scoring.py": ("step_scores", "step_summary", "sine_summary"),
    "identification/nonlinear.py": ("paper_alpha_model",),
    "identification/paper.py": ("table8", "table8_average", "table11_medians_row", "table11_summary"),
}
#: Files of which no code may run, and modules that may not be imported: the compiled alpha loop.
ALPHA_FILES = ("omni_studies/alpha_kernel.py", "omni_studies/accel.py")
ALPHA_MODULES = ("omni_studies.alpha_kernel", "omni_studies.accel")
#: The data files of the paper's validation of the alpha model; every column naming alpha is
#: replaced by nonsense (signs alternating, magnitudes 1e3..1e5: comparisons flip, sums explode).
ALPHA_DATA = ("table8_sine_errors.csv", "table8_sine_errors_average.csv",
              "table11_step_errors.csv", "table11_step_errors_medians.csv")

_PROBE = r"""
import json, sys, threading
seen = set()
def profile(frame, event, arg):
    if event == "call":
        seen.add(frame.f_code)
sys.setprofile(profile)
threading.setprofile(profile)
before = set(sys.modules)
from identification import paper
from omni_studies import calibration as cal
from omni_sim import model as om
exec(sys.argv[1])  # an injected alpha route (the guard's own test); empty otherwise
fig = cal.evaluate(om.load_model(), cal.ex.SINE_AMPLITUDE_RAD, steps=True)
res = [float(x).hex() for x in cal.residuals(fig, "tables")]
sys.setprofile(None)
threading.setprofile(None)
print(json.dumps({
    "residuals": res,
    "called": sorted({(c.co_filename, c.co_qualname) for c in seen}),
    "imported": sorted(set(sys.modules) - before),
    "paper_file": paper.__file__,
    "step_ratio": repr(paper.PAPER_STEP_RATIO),
    "table11_alpha": [r["median_alpha_rad"] for r in paper.table11()],
}))
"""


def _nonsense(i: int, k: int) -> str:
    return repr((-1) ** i * 1e3 * (i + 1) * (k + 1))


def _scrambled_identification(dest: Path) -> Path:
    """A copy of the identification package in ``dest`` whose Tables 8 and 11 alpha columns
    (:data:`ALPHA_DATA`) are nonsense and whose PAPER_STEP_RATIO is nan."""
    pkg = dest / "identification"
    shutil.copytree(Path(paper.__file__).resolve().parent, pkg,
                    ignore=shutil.ignore_patterns("__pycache__"))
    for name in ALPHA_DATA:
        path = pkg / "data" / name
        rows = list(csv.reader(path.read_text().splitlines()))
        cols = [k for k, h in enumerate(rows[0]) if "alpha" in h]
        assert cols, f"{name}: no alpha column"
        for i, row in enumerate(rows[1:]):
            for k in cols:
                row[k] = _nonsense(i, k)
        path.write_text("".join(",".join(r) + "\n" for r in rows))
    src = pkg / "paper.py"
    text, n = re.subn(r"^PAPER_STEP_RATIO = .*$", 'PAPER_STEP_RATIO = float("nan")', src.read_text(),
                      flags=re.M)
    assert n == 1
    src.write_text(text)
    return dest


def _scratch_evaluation(tmp: Path, inject: str = "") -> dict:
    """The table-level evaluation in a fresh process on the scrambled copy (``inject``: code run
    before it, with ``cal``, ``om`` and ``paper`` imported)."""
    root = _scrambled_identification(tmp)
    env = dict(os.environ, PYTHONPATH=str(root))  # the copy before the editable install
    out = subprocess.run([sys.executable, "-c", _PROBE, inject], cwd=root, env=env,
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.splitlines()[-1])
    # the scramble reached the readers
    assert Path(got["paper_file"]).resolve().is_relative_to(root.resolve()), got["paper_file"]
    assert got["step_ratio"] == "nan"
    assert got["table11_alpha"] == [float(_nonsense(i, 4)) for i in range(25)]
    got["root"] = str(root.resolve())
    return got


def _alpha_routes(got: dict, reference: np.ndarray) -> list[str]:
    """Every sign that the alpha model entered the evaluation ``got``; [] when none."""
    found = []
    for filename, qualname in got["called"]:
        path = Path(filename).resolve()
        rel = next((str(path.relative_to(r)) for r in (got["root"], ROOT) if path.is_relative_to(r)),
                   None)
        if rel is None:
            continue
        names = ALPHA_CODE.get(rel, ())
        if rel in ALPHA_FILES or any(qualname == n or qualname.startswith(n + ".") for n in names):
            found.append(f"ran {rel}:{qualname}")
    found += [f"imported {m}" for m in got["imported"]
              if any(m == a or m.startswith(a + ".") for a in ALPHA_MODULES)]
    res = np.array([float.fromhex(x) for x in got["residuals"]])
    if not np.array_equal(res, reference):
        found.append("residuals changed with the alpha columns scrambled")
    return found


def test_the_alpha_code_list_names_real_functions():
    """:data:`ALPHA_CODE` names functions that exist (a renamed one would leave the guard blind)."""
    import importlib

    for rel, names in ALPHA_CODE.items():
        mod = importlib.import_module(rel[:-3].replace("/", "."))
        for name in names:
            assert callable(getattr(mod, name, None)), f"{rel}: {name}"
    for rel in ALPHA_FILES:
        assert (ROOT / rel).is_file(), rel
    for name in ALPHA_DATA:
        assert any("alpha" in k for k in paper.table(name)[0]), name


@pytest.mark.slow  # 14 s CPU: the whole evaluation again in a fresh process, under a profiler (end to end)
def test_no_alpha_model_output_enters_any_residual(evaluation, tmp_path):
    """With Tables 8 and 11's alpha columns nonsense in the data files and a profiler watching,
    the table-level evaluation runs none of the alpha model's code, imports no compiled alpha
    loop, and gives the same residuals, bit for bit.

    Shown to fail (test_the_guard_catches_each_alpha_route, slow): an alpha route injected
    into the evaluation -- the simulator imported by name, paper.table() read for an alpha
    column, table11_summary(), the compiled loop (omni_studies.accel / alpha_kernel), the paper's
    step ratio -- each gives a non-empty list of routes."""
    got = _scratch_evaluation(tmp_path)
    assert _alpha_routes(got, cal.residuals(evaluation, "tables")) == []
    # the profiler saw the evaluation: the linear step model and the alpha *fit* (Table 10) ran
    called = {q for _, q in got["called"]}
    assert {"linear_step_errors", "simulate_linear", "fit_alpha_model", "table11"} <= called


#: Alpha routes injected into the evaluation (code run before it), each with the sign the guard
#: must find.  Each perturbs a step figure by what it read, so that only the guard can tell.
_ROUTES = {
    "simulator imported by name": ("""
from identification.validation import simulate_alpha_batch as sab
from identification.nonlinear import AlphaModel
_orig = cal.step_errors
def step_errors(*a, **k):
    out = _orig(*a, **k)
    m = AlphaModel(alpha_breaks=[0.0, 2.2, 25.0, 250.0], C_k1=[13.5, 21.6, 35.3, 61.7],
                   beta_k1=[0.8558, 1.3405], alpha_bar=[0.0, 250.0])
    th = sab(m, 0.004, [[0.0, 0.01, 0.01]], 0.001, 2.0, C_linear=6.0, beta_tilde_linear=229.0)
    out["poses"][0]["median_rad"] += 0 * float(th[0].theta[-1])
    return out
cal.step_errors = step_errors
""", "ran identification/simulate.py:simulate_alpha_batch"),
    "paper.table() read for an alpha column": ("""
_orig = cal.step_errors
def step_errors(*a, **k):
    out = _orig(*a, **k)
    rows = paper.table("table11_step_errors.csv")
    out["poses"][0]["median_rad"] *= 1 + 1e-12 * rows[0]["median_alpha_rad"]
    return out
cal.step_errors = step_errors
""", "residuals changed with the alpha columns scrambled"),
    "table11_summary()": ("""
_orig = cal.step_errors
def step_errors(*a, **k):
    out = _orig(*a, **k)
    out["poses"][0]["median_rad"] += 0 * paper.table11_summary()["ratio_of_medians"]
    return out
cal.step_errors = step_errors
""", "ran identification/paper.py:table11_summary"),
    "the compiled loop": ("""
_orig = cal.step_errors
def step_errors(*a, **k):
    from omni_studies.alpha_kernel import loop
    out = _orig(*a, **k)
    out["poses"][0]["median_rad"] += 0 * id(loop)
    return out
cal.step_errors = step_errors
""", "imported omni_studies.alpha_kernel"),
    "the paper's step ratio": ("""
_orig = cal.step_errors
def step_errors(*a, **k):
    out = _orig(*a, **k)
    out["poses"][0]["median_rad"] *= paper.PAPER_STEP_RATIO / 2.6
    return out
cal.step_errors = step_errors
""", "residuals changed with the alpha columns scrambled"),
}


@pytest.mark.slow
@pytest.mark.parametrize("route", sorted(_ROUTES))
def test_the_guard_catches_each_alpha_route(evaluation, tmp_path, route):
    """Each injected alpha route is found (the guard of the test above can fail)."""
    inject, sign = _ROUTES[route]
    found = _alpha_routes(_scratch_evaluation(tmp_path, inject), cal.residuals(evaluation, "tables"))
    assert sign in found, found


#: The committed record of `omni reproduce --friction all`.
COMPARISON = ROOT / "docs" / "studies" / "friction" / "comparison.json"
#: Relative tolerance of a step figure against that record.  Measured (this AMD EPYC against the
#: machine or library build the record was written on): the record's sine figures (Table 3, 18
#: numbers) are met to 7e-16, its step figures to 3.4e-7 at worst (pose 55/60; 2e-8 typical).
#: The square waves start from rest and stick after every edge: stick-slip amplifies last-bit
#: differences there (numpy's SIMD dispatch cut to its baseline moves the step figures by 4e-13
#: only).  1e-5 is 30x the largest; a change of the model or the route moves them far more (the
#: yaw damping 0.1 % higher: up to 0.7 %).
STEP_RECORD_RTOL = 1e-5


def test_step_figures_match_the_reproduction(evaluation):
    """The calibration's Table 11 linear column (its own route,
    :func:`omni_studies.calibration.linear_step_errors`) is the reproduction's (``omni reproduce``'s
    validation; the committed record's family ``lugre``, the default scene): every pose's median
    and p90 and the median over poses (3.10 mrad; the paper's 11.2 mrad, 3.6x more).

    Shown to fail: the same evaluation with the yaw damping 0.1 % higher (every figure within
    the 2.5-4.5x band the test had before) misses by up to 0.7 %."""
    record = json.loads(COMPARISON.read_text())["families"]["lugre"]
    assert record["friction"] == "lugre" == om.builtin_family(om.DEFAULT_SCENE)
    rec = record["step_linear_vs_table11"]
    steps = evaluation["steps"]
    assert [list(s["set"]) for s in steps["poses"]] == [p["set_deg"] for p in rec["poses"]]
    for s, p in zip(steps["poses"], rec["poses"]):
        assert s["median_rad"] == pytest.approx(p["median_linear_rad"], rel=STEP_RECORD_RTOL), s["set"]
        assert s["p90_rad"] == pytest.approx(p["p90_linear_rad"], rel=STEP_RECORD_RTOL), s["set"]
        assert s["paper_median_rad"] == p["paper_median_linear_rad"]
    assert steps["median_over_poses_rad"] == pytest.approx(rec["median_over_poses_rad"],
                                                           rel=STEP_RECORD_RTOL)
    real = float(np.median([r["median_linear_rad"] for r in paper.table11()]))
    assert real == rec["paper_median_over_poses_rad"] == pytest.approx(0.0112, abs=5e-5)


# -- the matched scene ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def matched():
    record = json.loads((om.OMNI_DIR / "calibration_matched.json").read_text())
    fig = cal.evaluate(om.load_model(friction="matched"), cal.ex.SINE_AMPLITUDE_RAD, steps=True)
    return record, fig


def test_matched_scene_is_both_families_on_the_shared_robot():
    """scene_matched.xml: the LuGre drive *and* a hard stick, on the robot every family shares
    (same masses, inertias, servo gains as the lugre scene)."""
    from omni_sim.device import Device

    m, lug = om.load_model(friction="matched"), om.load_model(friction="lugre")
    f = Device(m).friction()
    assert f["frictionloss"] > 0 and f["lugre_Fc"] > 0
    for field in ("body_mass", "body_inertia", "actuator_gainprm", "dof_armature"):
        assert np.array_equal(getattr(m, field)[:len(getattr(lug, field))], getattr(lug, field)), field
    assert "matched" in om.FRICTION_FAMILIES and om.builtin_family(om.scene_path("matched")) == "matched"


@pytest.mark.slow  # 12 s CPU: the matched scene's calibration record re-measured end to end
def test_matched_scene_meets_its_record(matched):
    """The matched scene, re-measured here with the table-level targets, gives its record's
    figures (tolerance: 1 % of each figure or 0.2 mrad; the record was measured on one CPU, and
    stick-slip amplifies last-bit differences of other CPUs), and keeps the published tables it
    met: Table 11's linear column (median within 25 % of 11.2 mrad, >= 20 of 25 poses within
    40 %), Table 9's resonance, the angles, Table 10's fall >= 3x, section 2.3."""
    record, fig = matched
    rec = record["achieved"]
    steps = fig["steps"]
    assert steps["median_over_poses_rad"] == pytest.approx(rec["step_median_rad"], rel=0.01, abs=2e-4)
    assert abs(steps["within_40pct"] - rec["poses_within_40pct"]) <= 1
    assert abs(steps["median_over_poses_rad"] / 0.0112 - 1) <= 0.25
    assert steps["within_40pct"] >= 20
    worst_c = max((p["C_linear"] / p["C_paper"] - 1 for p in fig["poses"]), key=abs)
    assert worst_c == pytest.approx(rec["table3_C_worst_rel"], abs=0.01)
    assert abs(fig["detail"]["resonance_hz"] - cal.TABLE9_RESONANCE_HZ) <= 0.3
    assert fig["C_alpha_fall"] >= 3.0 and cal.min_margin(fig) <= cal.MARGIN_TARGET
    assert 0.5 * float(cal.residuals(fig, "tables") @ cal.residuals(fig, "tables")) == pytest.approx(
        record["cost"], rel=0.05)
    tried = {c["id"] for c in record["candidates_tried"]}
    assert record["from_candidate"] in tried and len(tried) >= 30
