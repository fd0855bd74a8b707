"""The sweep engine: studies of many model variants on Dask (``dask.distributed``); the command
``omni sweep`` and its figures are :mod:`omni_app.sweep`.

A study file (TOML, ``omni sweep --example``) names a base model, the pipeline every variant
runs and the parameters to vary (a grid, a list of rows, or seeded random samples).  Each variant
is one Dask task (``client.submit(..., retries=2)``) on a ``LocalCluster`` of one-thread worker
processes listening on 127.0.0.1 (default) or on an existing cluster (``--scheduler``); its
rollouts run on one thread.  The client writes each finished variant atomically into
``DIR/variants/<id>/`` (``result.json`` plus the pipeline's own files), so a killed study resumes
where it stopped; ``DIR/results.csv`` is rebuilt from the variants' ``result.json`` in id order.
Results are frozen objects: a variant's :class:`VariantResult` (``result.json``, its figures a
typed record per pipeline), :func:`run_sweep`'s :class:`SweepSummary`; the writers take them.

Pipelines:

* ``reproduce``: the reproduce job's stages in memory (generate the campaign, identify, validate
  both models, inertia against MuJoCo's mass matrix) with the variant's run settings; the
  summary figures.
* ``discrepancy``: "measured" data of the variant with a hidden effect of the validation
  bank's cases, ``bank.hidden`` (installed from the source checkout: :mod:`.bank_link`; the
  compact experiment set of :mod:`discrepancy.experiment_set`, quantised, noisy encoder), the
  discrepancy workflow with the variant as the nominal model; the effects it names, whether the
  bank's criteria (``bank.hidden.assess``) pass, the gap's shrink factor.
* ``simulate``: the campaign only; tracking errors (cheap: for checking a study file).
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import itertools
import json
import math
import os
import shutil
import sys
import time
import tomllib
import typing
import uuid
from dataclasses import dataclass
from pathlib import Path

from identification.errors import UserError
from identification.records import Record

PIPELINES = ("reproduce", "discrepancy", "simulate")
TIMING_COLUMNS = ("wall_s",)
#: Seconds to wait for an existing scheduler (--scheduler).
CONNECT_TIMEOUT_S = 20
_TOP_KEYS = ("description", "seed", "base", "pipeline", "fixed", "grid", "list", "random")
_PIPELINE_KEYS = {"reproduce": ("name", "campaign"), "simulate": ("name", "campaign"),
                  "discrepancy": ("name", "hidden", "duration_s")}


# -- results as objects --------------------------------------------------------------------------
@dataclass(frozen=True)
class ReproduceFigures(Record):
    """The ``reproduce`` pipeline's figures of one variant (``result.json``'s ``figures``; the
    reproduce job's ``summary.json`` figures of the same names; None: not computed)."""

    inertia_max_rel_error: float | None  #: largest inertia parameter error vs MuJoCo's mass matrix [-]
    #: median step error linear / α, whole record (> 1: the α model better) [-]
    step_ratio_of_medians_whole_record: float | None
    step_ratio_of_medians_after_edges: float | None  #: the same, first second after each edge [-]
    sine_phase_p90_linear_deg: float | None  #: Table 8 phase error, linear model [deg]
    sine_phase_p90_alpha_deg: float | None  #: the same, α-invariant model [deg]
    sine_magnitude_p90_linear: float | None  #: Table 8 magnitude error |theta|/A_r, linear model [-]
    sine_magnitude_p90_alpha: float | None  #: the same, α-invariant model [-]


@dataclass(frozen=True)
class DiscrepancyFigures(Record):
    """The ``discrepancy`` pipeline's figures of one variant (from its ``report.json``)."""

    effects: str  #: the effects named, joined by "+" ("": none)
    passed: int  #: 1 when the bank's criteria pass (``bank.hidden.assess``), else 0
    assessment: str  #: why, in words
    shrink_factor: float  #: held-out gap before / after [-]
    gap_before_rad: float  #: the nominal model's replay gap [rad]
    gap_after_rad: float  #: the held-out gap with the named effects [rad]
    unexplained: int  #: 1 when the gap left stands well above the noise floor, else 0


@dataclass(frozen=True)
class SimulateFigures(Record):
    """The ``simulate`` pipeline's figures of one variant: the tracking error theta - r."""

    rms_error_rad: float  #: RMS over every run [rad]
    max_abs_error_rad: float  #: largest |theta - r| [rad]
    rms_error_sine_rad: float  #: RMS over the sine runs (NaN: none) [rad]
    rms_error_step_rad: float  #: RMS over the step runs (NaN: none) [rad]


#: Each pipeline's figures record (its fields: :data:`FIGURES`' columns, in order).
FIGURE_TYPES = {"reproduce": ReproduceFigures, "discrepancy": DiscrepancyFigures,
                "simulate": SimulateFigures}
Figures = ReproduceFigures | DiscrepancyFigures | SimulateFigures
#: The figures of each pipeline, in results.csv's column order.
FIGURES = {name: tuple(f.name for f in dataclasses.fields(cls)) for name, cls in FIGURE_TYPES.items()}


@dataclass(frozen=True)
class VariantResult(Record):
    """One variant's result: ``variants/<id>/result.json``, a row of ``results.csv``."""

    id: str  #: ``v0000``, ``v0001``, ... in expansion order
    seed: int  #: from the study's seed and the id (:func:`variant_seed`)
    params: dict[str, float]  #: the varied parameters' values
    fixed: dict[str, float]  #: the study's ``[fixed]`` values
    pipeline: str  #: reproduce | discrepancy | simulate
    status: str  #: "ok" or "failed"
    error: str  #: a failed variant's error, ``Type: message`` ("" when ok)
    figures: Figures | None  #: the pipeline's figures (None: failed; ``{}`` in the file)
    wall_s: float  #: the variant's wall time on its worker [s] (measured: varies)

    def to_json(self) -> dict:
        return {**super().to_json(), "figures": {} if self.figures is None else self.figures.to_json()}

    @classmethod
    def from_json(cls, d: dict) -> VariantResult:
        figs = FIGURE_TYPES[d["pipeline"]](**d["figures"]) if d["figures"] else None
        return cls(**{**d, "figures": figs})


@dataclass(frozen=True)
class VariantOutput:
    """What :func:`run_variant` returns (from a worker): the result and the variant's files."""

    result: VariantResult  #: ``result.json``
    files: dict[str, str]  #: the pipeline's own files (``summary.json``, ``report.json``, ...): name -> text


@dataclass(frozen=True)
class SweepSummary:
    """What :func:`run_sweep` returns: every variant's result and what this call did."""

    variants: tuple[VariantResult, ...]  #: every variant of the study, in id order
    ran: int  #: variants run by this call
    skipped: int  #: variants already finished in the folder (a resume)
    wall_s: float  #: this call's wall time, cluster start-up included [s] (measured: varies)

    @property
    def n(self) -> int:
        """The study's variants."""
        return len(self.variants)

    @property
    def failed(self) -> int:
        """Variants whose status is ``failed``."""
        return sum(v.status == "failed" for v in self.variants)

EXAMPLE = '''\
# omni sweep study: the reproduce figures against the yaw drive's dry-friction level and its
# viscous damping, on a small campaign (6 variants, a few minutes on 2 cores).
description = "reproduce figures vs dry-friction scale and yaw damping (small campaign)"
seed = 0                          # variant seeds derive from it and the variant id

[base]
friction = "lugre"                # a built-in friction family, or: model = "my_omni.xml"

[pipeline]
name = "reproduce"                # reproduce | discrepancy | simulate
# campaign: "paper", "sine", "step", a campaign file (path relative to this file), or inline:
[pipeline.campaign]
[[pipeline.campaign.sine]]
poses_deg = [[25, 70], [25, 115], [45, 90], [65, 70], [65, 90], [65, 115]]
frequencies_hz = [2.0, 2.5, 3.0, 3.5, 4.0, 5.0]
amplitude_rad = 0.05
settle_s = 2.0
record_s = 2.0
[[pipeline.campaign.step]]
poses_deg = [[45, 90], [65, 90]]
frequency_hz = 0.25
amplitude_rad = 0.07
duration_s = 4.0

[fixed]                           # values every variant gets (optional)
kp = 2.0                          # yaw P gain [V/rad] (the paper's)

[grid]                            # cartesian product; or [list] params/rows, or [random]
friction_scale = [0.5, 1.0, 1.5]
"joint.yaw.damping" = [0.004, 0.0069]
'''


# -- the study file ----------------------------------------------------------------------------
def _err(source: str, key: str, problem: str) -> UserError:
    return UserError(f"{source}: {key}: {problem}")


def _num(source: str, key: str, v, param: str | None = None) -> float:
    if param == "quantize" and isinstance(v, bool):
        return float(v)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _err(source, key, f"must be a finite number, got {v!r}")
    if param == "quantize" and v not in (0, 1):
        raise _err(source, key, f"quantize is 0 or 1 (or true/false), got {v!r}")
    return float(v)


def _check_keys(source: str, where: str, table: dict, known) -> None:
    for k in table:
        if k not in known:
            raise _err(source, f"{where}{k}", f"unknown key (known: {', '.join(known)})")


def _campaign_toml(camp: dict) -> str:
    """An inline campaign table back to campaign-file text (numbers and arrays: JSON is TOML)."""
    out = []
    for k, v in camp.items():
        if not isinstance(v, (list, dict)):
            out.append(f"{k} = {json.dumps(v)}")
    for k, v in camp.items():
        groups = v if isinstance(v, list) else [v] if isinstance(v, dict) else []
        for g in groups:
            if not isinstance(g, dict):
                continue
            out.append(f"[[{k}]]")
            out += [f"{gk} = {json.dumps(gv)}" for gk, gv in g.items()]
    return "\n".join(out) + "\n"


class Study:
    """A parsed study file: base model, pipeline, fixed values, variants.

    Attributes
    ----------
    source : str
    text : str
        The file's text (copied into the output folder; a resume must match it).
    base : dict
        ``{"friction": ..., "model": absolute path or None}``.
    pipeline : dict
        ``name`` and its options; ``campaign_text`` / ``campaign_source`` for reproduce and simulate.
    fixed : dict
    params : list of str
        The varied parameters, in column order.
    variants : list of (id, dict)
    seed : int
    """

    def __init__(self, source, text, base, pipeline, fixed, params, rows, seed):
        self.source, self.text, self.base, self.pipeline = source, text, base, pipeline
        self.fixed, self.params, self.seed = fixed, params, seed
        self.variants = [(f"v{i:04d}", dict(zip(params, row))) for i, row in enumerate(rows)]

    def jobs(self) -> list[dict]:
        return [{"id": vid, "seed": variant_seed(self.seed, vid), "values": values,
                 "fixed": self.fixed, "base": self.base, "pipeline": self.pipeline}
                for vid, values in self.variants]


def variant_seed(seed: int, vid: str) -> int:
    """The variant's seed: from the study's seed and the variant id only."""
    return int.from_bytes(hashlib.sha256(f"{seed}/{vid}".encode()).digest()[:4], "little")


def _values(source: str, key: str, v, param: str) -> list[float]:
    if not isinstance(v, list) or not v:
        raise _err(source, key, "must be a non-empty array of numbers")
    return [_num(source, f"{key}[{i}]", x, param) for i, x in enumerate(v)]


def _random_rows(source: str, table: dict) -> tuple[list[str], list[list[float]]]:
    import numpy as np

    for k in ("n", "seed"):
        if k not in table:
            raise _err(source, f"random.{k}", "missing (random: n, seed and PARAM = {uniform = [lo, hi]} "
                                              "or {log_uniform = [lo, hi]})")
    n, seed = table["n"], table["seed"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise _err(source, "random.n", f"must be an integer >= 1, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise _err(source, "random.seed", f"must be an integer >= 0, got {seed!r}")
    params, dists = [], []
    for p, d in table.items():
        if p in ("n", "seed"):
            continue
        key = f"random.{p}"
        if not isinstance(d, dict) or len(d) != 1 or next(iter(d)) not in ("uniform", "log_uniform"):
            raise _err(source, key, "must be {uniform = [lo, hi]} or {log_uniform = [lo, hi]}")
        kind, rng = next(iter(d.items()))
        if not isinstance(rng, list) or len(rng) != 2:
            raise _err(source, f"{key}.{kind}", "must be [lo, hi]")
        lo, hi = (_num(source, f"{key}.{kind}", x) for x in rng)
        if not lo < hi:
            raise _err(source, f"{key}.{kind}", f"needs lo < hi, got [{lo}, {hi}]")
        if kind == "log_uniform" and lo <= 0:
            raise _err(source, f"{key}.{kind}", f"needs lo > 0, got {lo}")
        if p == "quantize":
            raise _err(source, key, "quantize is 0 or 1; vary it in a grid or list")
        params.append(p)
        dists.append((kind, lo, hi))
    if not params:
        raise _err(source, "random", "names no parameter")
    rs = np.random.default_rng(seed)
    u = rs.random((n, len(params)))
    rows = []
    for row in u:
        vals = []
        for x, (kind, lo, hi) in zip(row, dists):
            vals.append(float(lo + x * (hi - lo)) if kind == "uniform"
                        else float(math.exp(math.log(lo) + x * (math.log(hi) - math.log(lo)))))
        rows.append(vals)
    return params, rows


def parse_study(text: bytes | str, source: str, base_dir: Path | None = None) -> Study:
    """Parse and check a study file (UserError ``SOURCE: KEY: problem`` on the first problem;
    the model is opened to check every model parameter names an existing numeric attribute)."""
    from omni_sim import variants as va

    base_dir = Path(base_dir) if base_dir is not None else Path(".")
    text = text.decode() if isinstance(text, bytes) else text
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{source}: not a valid TOML file ({exc})") from None
    _check_keys(source, "", doc, _TOP_KEYS)
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise _err(source, "seed", f"must be an integer >= 0, got {seed!r}")
    base, spec = _parse_base(doc, source, base_dir)
    pipe = _parse_pipeline(doc, source, base_dir)

    def check(key: str, param: str) -> None:
        try:
            va.check_param(spec, param)
        except ValueError as exc:
            raise _err(source, key, str(exc)) from None

    fixed = _parse_fixed(doc, source, check)
    params, rows, mode = _parse_variants(doc, source)
    for k in params:
        check(f"{mode}.{k}", k)
        if k in fixed:
            raise _err(source, f"{mode}.{k}", "also in [fixed]")
    return Study(source, text, base, pipe, fixed, params, rows, seed)


def _parse_base(doc: dict, source: str, base_dir: Path) -> tuple[dict, object]:
    """``[base]``: a friction family or a model file; returns it and the model's spec."""
    from omni_sim import model as om
    from omni_sim import variants as va
    from omni_sim.device import Device

    b = doc.get("base", {})
    if not isinstance(b, dict):
        raise _err(source, "base", "must be a table")
    _check_keys(source, "base.", b, ("friction", "model"))
    if "friction" in b and "model" in b:
        raise _err(source, "base", "give friction or model, not both")
    friction, model = b.get("friction"), None
    if friction is not None and friction not in om.FRICTION_FAMILIES:
        raise _err(source, "base.friction", f"must be one of {', '.join(om.FRICTION_FAMILIES)}, got {friction!r}")
    if "model" in b:
        if not isinstance(b["model"], str):
            raise _err(source, "base.model", "must be a path (string)")
        model = (base_dir / b["model"]).resolve()
        if not model.is_file():
            raise _err(source, "base.model", om.model_not_found(model))
        model = str(model)
    try:
        spec = va.base_spec(model, friction)
        Device(spec.compile(), source=model or "built-in scene")
    except (UserError, ValueError) as exc:
        raise _err(source, "base", str(exc)) from None
    base = {"friction": friction, "model": model}
    return base, spec


def _parse_pipeline(doc: dict, source: str, base_dir: Path) -> dict:
    """``[pipeline]``: reproduce or simulate a campaign, or the discrepancy workflow on a
    hidden case of the validation bank (which must be installed: :mod:`.bank_link`)."""
    from omni_sim import experiments as ex
    from discrepancy import experiment_set

    from .bank_link import load as load_bank

    p = doc.get("pipeline")
    if not isinstance(p, dict):
        raise _err(source, "pipeline", "missing table [pipeline] (name = " + " | ".join(PIPELINES) + ")")
    name = p.get("name")
    if name not in PIPELINES:
        raise _err(source, "pipeline.name", f"must be one of {', '.join(PIPELINES)}, got {name!r}")
    _check_keys(source, "pipeline.", p, _PIPELINE_KEYS[name])
    pipe = {"name": name}
    if name in ("reproduce", "simulate"):
        camp = p.get("campaign", "paper")
        try:
            if isinstance(camp, dict):
                ctext, csource = _campaign_toml(camp), f"{source} [pipeline.campaign]"
            elif isinstance(camp, str) and camp in ex.CAMPAIGNS:
                ctext, csource = None, camp
            elif isinstance(camp, str):
                path = (base_dir / camp)
                if not path.is_file():
                    raise UserError(f"{path}: campaign file not found")
                ctext, csource = path.read_text(), str(path)
            else:
                raise UserError(f"must be a name ({', '.join(ex.CAMPAIGNS)}), a file or a table, got {camp!r}")
            c = ex.parse_campaign(ctext, csource) if ctext is not None else ex.load_campaign(csource)
            c.experiments()
        except UserError as exc:
            raise _err(source, "pipeline.campaign", str(exc)) from None
        pipe.update(campaign_text=ctext, campaign_source=csource)
    else:
        try:
            hidden = load_bank("omni sweep's discrepancy pipeline").hidden
        except UserError as exc:
            raise _err(source, "pipeline", str(exc)) from None
        case_name = p.get("hidden", "viscous_damping")
        # the sweep writes a case's truth on the study's Omni variants: the Omni's cases only
        # (a geared-servo case simulates a device of its own)
        names = [c.name for c in hidden.CASES if c.truth == "omni"]
        if case_name not in names:
            raise _err(source, "pipeline.hidden", f"must be one of the bank's Omni cases ({', '.join(names)}), "
                       f"got {case_name!r}")
        dur = _num(source, "pipeline.duration_s", p.get("duration_s", experiment_set.DURATION_S))
        if not 1.0 <= dur <= 60:
            raise _err(source, "pipeline.duration_s", f"must be in [1, 60] s, got {dur}")
        pipe.update(hidden=case_name, duration_s=dur)
    return pipe


def _parse_fixed(doc: dict, source: str, check) -> dict:
    """``[fixed]``: parameters set in every variant."""
    fixed = doc.get("fixed", {})
    if not isinstance(fixed, dict):
        raise _err(source, "fixed", "must be a table")
    fixed = dict(fixed)
    for k, v in fixed.items():
        check(f"fixed.{k}", k)
        fixed[k] = _num(source, f"fixed.{k}", v, k)
        _check_setting(source, f"fixed.{k}", k, fixed[k])
    return fixed


#: Run settings that cannot be negative; ``kp`` must be > 0 (the simulator refuses a zero gain).
_NONNEGATIVE = ("kp", "friction_scale", "amplitude_rad", "noise_rad")


def _check_setting(source: str, key: str, param: str, v: float) -> None:
    if param == "kp" and not v > 0:
        raise _err(source, key, f"must be > 0 (the yaw P gain), got {v}")
    if param in _NONNEGATIVE and v < 0:
        raise _err(source, key, f"must be >= 0, got {v}")


def _parse_variants(doc: dict, source: str) -> tuple[list, list, str]:
    """The variants: exactly one of ``[grid]``, ``[list]``, ``[random]``; returns the varied
    parameters, the rows of values and the mode."""
    modes = [m for m in ("grid", "list", "random") if m in doc]
    if len(modes) != 1:
        raise _err(source, "grid", "give exactly one of [grid], [list], [random] (found "
                   f"{', '.join(modes) or 'none'})")
    mode, table = modes[0], doc[modes[0]]
    if not isinstance(table, dict):
        raise _err(source, mode, "must be a table")
    if mode == "grid":
        if not table:
            raise _err(source, "grid", "names no parameter")
        params = list(table)
        cols = [_values(source, f"grid.{k}", v, k) for k, v in table.items()]
        rows = [list(r) for r in itertools.product(*cols)]
    elif mode == "list":
        _check_keys(source, "list.", table, ("params", "rows"))
        params = table.get("params")
        if not isinstance(params, list) or not params or not all(isinstance(x, str) for x in params):
            raise _err(source, "list.params", "must be a non-empty array of parameter names")
        rows_in = table.get("rows")
        if not isinstance(rows_in, list) or not rows_in:
            raise _err(source, "list.rows", "must be a non-empty array of rows")
        rows = []
        for i, r in enumerate(rows_in):
            if not isinstance(r, list) or len(r) != len(params):
                raise _err(source, f"list.rows[{i}]", f"must be an array of {len(params)} numbers")
            rows.append([_num(source, f"list.rows[{i}][{j}]", x, params[j]) for j, x in enumerate(r)])
    else:
        params, rows = _random_rows(source, table)
    if len(set(params)) != len(params):
        raise _err(source, mode, "a parameter is named twice")
    for r in rows:
        for k, v in zip(params, r):
            _check_setting(source, f"{mode}.{k}", k, v)
    return params, rows, mode


def load_study(path: str | os.PathLike) -> Study:
    p = Path(path)
    if not p.is_file():
        raise UserError(f"{p}: study file not found")
    return parse_study(p.read_bytes(), str(p), p.parent)


# -- one variant (runs on a Dask worker) ---------------------------------------------------
def _settings(values: dict, seed: int, pipeline: str):
    from omni_sim import experiments as ex
    from discrepancy import experiment_set

    disc = pipeline == "discrepancy"
    return ex.Settings(kp=values.get("kp", ex.KP_DEFAULT),
                       quantize=bool(values.get("quantize", 1.0 if disc else 0.0)),
                       noise_rad=values.get("noise_rad", experiment_set.NOISE_RAD if disc else 0.0),
                       seed=seed)


def _campaign(pipe: dict):
    from omni_sim import experiments as ex

    if pipe["campaign_text"] is None:
        return ex.load_campaign(pipe["campaign_source"])
    return ex.parse_campaign(pipe["campaign_text"], pipe["campaign_source"])


def _reproduce(spec, model, values: dict, settings, pipe: dict) -> tuple[ReproduceFigures, dict]:
    """The reproduce job's stages (:func:`omni_studies.reproduce.run_reproduce`) with run settings."""
    from identification.identify import identify_runs
    from identification.validation import Params, validate_runs
    from omni_sim import experiments as ex
    from omni_sim import truth
    from omni_sim.device import Device

    from .accel import install
    install()  # the compiled α loop (loaded at its first use)
    exps = _campaign(pipe).experiments(values.get("amplitude_rad"))
    device = Device(model, settings.control_period_s)
    runs = ex.simulate(device, exps, settings, jobs=1)
    ident = identify_runs(runs)
    if ident.inertia is None or ident.alpha_model is None:
        raise UserError("identification failed: " + "; ".join(w for w in ident.warnings if "not fitted" in w))
    params_dict = ident.to_params()
    params = Params(ident.inertia.params, ident.alpha_model, params_dict["poses"])
    s = {**validate_runs(runs, params).summary.to_json(),  # "inertia" (null) stays the first key
         "inertia": truth.inertia_truth(device, ident.inertia.params)}
    win = s["step"]["windows"]
    fig = ReproduceFigures(
        inertia_max_rel_error=s["inertia"]["max_rel_error"],
        step_ratio_of_medians_whole_record=win["whole_record"]["ratio_of_medians"],
        step_ratio_of_medians_after_edges=win["after_edges"]["ratio_of_medians"],
        **{f"sine_{k}": s["sine"][k] for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg",
                                               "magnitude_p90_linear", "magnitude_p90_alpha")})
    return fig, {"summary.json": json.dumps(s, indent=2) + "\n",
                 "params.json": json.dumps(params_dict, indent=2) + "\n"}


def _simulate(spec, model, values, settings, pipe) -> tuple[SimulateFigures, dict]:
    import numpy as np

    from omni_sim import experiments as ex
    from omni_sim.device import Device

    exps = _campaign(pipe).experiments(values.get("amplitude_rad"))
    runs = ex.simulate(Device(model), exps, settings, jobs=1)
    err = {r.name: np.asarray(r.theta) - np.asarray(r.r) for r in runs}
    if not all(np.all(np.isfinite(e)) for e in err.values()):
        raise UserError("the simulation diverged (non-finite yaw angle)")
    kinds = {e.name: e.kind for e in exps}

    def rms(names):
        names = list(names)
        if not names:
            return float("nan")
        return float(np.sqrt(np.mean(np.concatenate([err[n] ** 2 for n in names]))))

    fig = SimulateFigures(rms_error_rad=rms(err),
                          max_abs_error_rad=float(max(np.max(np.abs(e)) for e in err.values())),
                          rms_error_sine_rad=rms(n for n in err if kinds[n] == "sine"),
                          rms_error_step_rad=rms(n for n in err if kinds[n] == "step"))
    return fig, {}


def _discrepancy(spec, model, values, settings, pipe) -> tuple[DiscrepancyFigures, dict]:
    import tempfile

    from omni_sim import experiments as ex
    from omni_sim.device import Device
    from discrepancy import experiment_set
    from discrepancy.workflow import run_discrepancy

    from .bank_link import load as load_bank

    hidden = load_bank("omni sweep's discrepancy pipeline").hidden
    case = hidden.case(pipe["hidden"])
    amp = values.get("amplitude_rad")
    exps = experiment_set.experiments(amplitudes_rad=experiment_set.AMPLITUDES_RAD if amp is None else (amp,),
                                      duration_s=pipe["duration_s"])
    truth_model = hidden.truth_spec(case, base=spec.copy()).compile()
    runs = ex.simulate(Device(truth_model), exps, settings, jobs=1)
    xml = spec.to_xml()
    with tempfile.TemporaryDirectory(prefix="omni-sweep-") as d:
        nominal = Path(d) / "nominal.xml"
        nominal.write_text(xml)
        out = run_discrepancy(runs, nominal, jobs=1)
    rep = out.report
    # the nominal model is written beside report.json, which names it there (not the temporary
    # folder's path: the same study gives the same bytes)
    rep = {**rep, "settings": {**rep["settings"], "model": "nominal.xml"}}
    ok, why = hidden.assess(case, rep)
    fig = DiscrepancyFigures(effects="+".join(e["name"] for e in rep["effects"]), passed=int(ok),
                             assessment=why, shrink_factor=rep["shrink_factor"],
                             gap_before_rad=rep["gap_before"], gap_after_rad=rep["gap_after"],
                             unexplained=int(rep["unexplained"]))
    rep = {k: v for k, v in rep.items() if k != "timings"}
    return fig, {"report.json": json.dumps(rep, indent=2, default=float) + "\n", "nominal.xml": xml}


_PIPELINE_FUNCS = {"reproduce": _reproduce, "simulate": _simulate, "discrepancy": _discrepancy}


def run_variant(job: dict) -> VariantOutput:
    """Run one variant (on a worker, one thread); never raises for a failing variant: its error
    is the result.  Returns a frozen :class:`VariantOutput` (``.result``: ``result.json``'s
    :class:`VariantResult`, ``.files``: the pipeline's files, name -> text)."""
    from omni_sim import variants as va

    t0 = time.perf_counter()
    values = {**job["fixed"], **job["values"]}
    name = job["pipeline"]["name"]
    figures, files, error = None, {}, ""
    try:
        spec = va.base_spec(job["base"]["model"], job["base"]["friction"])
        spec, model = va.build(spec, values)
        settings = _settings(values, job["seed"], name)
        figures, files = _PIPELINE_FUNCS[name](spec, model, values, settings, job["pipeline"])
    except Exception as exc:  # a variant that fails is a result, not a lost task
        error = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    result = VariantResult(id=job["id"], seed=job["seed"], params=job["values"], fixed=job["fixed"],
                           pipeline=name, status="failed" if error else "ok", error=error,
                           figures=figures, wall_s=time.perf_counter() - t0)
    return VariantOutput(result, files)


# -- the output folder ---------------------------------------------------------------------
def _write_variant(out: Path, res: VariantOutput) -> None:
    """``out/variants/<id>/`` atomically: a temporary folder renamed into place."""
    vdir = out / "variants"
    final = vdir / res.result.id
    tmp = vdir / f".{res.result.id}.{uuid.uuid4().hex}.tmp"
    tmp.mkdir(parents=True)
    for name, text in res.files.items():
        (tmp / name).write_text(text)
    (tmp / "result.json").write_text(json.dumps(res.result.to_json(), indent=2, default=float) + "\n")
    if final.exists():
        shutil.rmtree(final)
    os.rename(tmp, final)


def finished(out: Path) -> set[str]:
    """Ids of the variants with a complete output folder."""
    vdir = out / "variants"
    if not vdir.is_dir():
        return set()
    return {d.name for d in vdir.iterdir() if not d.name.startswith(".") and (d / "result.json").is_file()}


def cell_text(v) -> str:
    """A value as ``results.csv`` writes it: "" for None, a float's ``repr`` (it reads back as
    the same float), anything else as ``str``."""
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


def read_variants(out: Path, study: Study) -> tuple[VariantResult, ...]:
    """The finished variants' results (``out/variants/<id>/result.json``), in id order."""
    files = [Path(out) / "variants" / vid / "result.json" for vid, _ in study.variants]
    return tuple(VariantResult.from_json(json.loads(f.read_text())) for f in files if f.is_file())


def _columns(study: Study) -> list[str]:
    """``results.csv``'s columns: id, seed, the parameters, the figures, status, error, wall_s."""
    return ["id", "seed", *study.params, *FIGURES[study.pipeline["name"]], "status", "error",
            *TIMING_COLUMNS]


def table_text(study: Study, variants) -> str:
    """``results.csv``'s text: one row per :class:`VariantResult` of ``variants``, in the order given."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_columns(study))
    names = FIGURES[study.pipeline["name"]]
    for v in variants:
        figs = {} if v.figures is None else v.figures.to_json()
        w.writerow([v.id, v.seed, *(cell_text(v.params.get(p)) for p in study.params),
                    *(cell_text(figs.get(k)) for k in names), v.status, v.error,
                    *(cell_text(getattr(v, k)) for k in TIMING_COLUMNS)])
    return buf.getvalue()


def read_table(text: str, study: Study) -> tuple[VariantResult, ...]:
    """The variants of a ``results.csv`` text of ``study`` (``fixed``: the study's), each value of
    its field's type; :func:`table_text` of them is ``text`` again."""
    kind = FIGURE_TYPES[study.pipeline["name"]]
    types = typing.get_type_hints(kind)
    out = []
    for row in csv.DictReader(io.StringIO(text)):
        figs = None
        if row["status"] == "ok":
            figs = kind(**{k: _cell(row[k], types[k]) for k in FIGURES[study.pipeline["name"]]})
        out.append(VariantResult(id=row["id"], seed=int(row["seed"]),
                                 params={p: float(row[p]) for p in study.params}, fixed=study.fixed,
                                 pipeline=study.pipeline["name"], status=row["status"],
                                 error=row["error"], figures=figs, wall_s=float(row["wall_s"])))
    return tuple(out)


def _cell(text: str, hint):
    """A ``results.csv`` cell as its field's type (``hint``): str, int or float; "" is None but
    for a str."""
    if hint is str:
        return text
    if text == "":
        return None
    return int(text) if hint is int else float(text)


def write_table(out: Path, study: Study, variants=None) -> Path:
    """``out/results.csv`` (:func:`table_text`) of ``variants`` (default: :func:`read_variants`),
    written atomically."""
    out = Path(out)
    variants = read_variants(out, study) if variants is None else variants
    tmp = out / ".results.csv.tmp"
    tmp.write_text(table_text(study, variants))
    os.replace(tmp, out / "results.csv")
    return out / "results.csv"


def check_out(out: Path, study: Study) -> None:
    """Check the output folder before any work, writing nothing: not a file, its parent a
    writable folder; a new or empty folder, or one holding this study (a resume).

    Raises
    ------
    UserError
        Any of those is not so."""
    from identification.dataset import check_output_dir

    check_output_dir(out, force=True)  # a file, a missing or read-only parent (a resume: not empty)
    copy = out / "spec.toml"
    if copy.is_file():
        if copy.read_text() != study.text:
            raise UserError(f"{out}: holds a study with a different spec ({copy}); "
                            "use a new --out folder")
    elif out.is_dir() and any(p.name != "variants" for p in out.iterdir()):
        raise UserError(f"{out}: output folder exists, is not empty and holds no study (spec.toml)")


def _prepare_out(out: Path, study: Study) -> None:
    """The output folder (:func:`check_out`): ``spec.toml`` and ``variants/``; leftovers of a
    killed run removed."""
    check_out(out, study)
    copy = out / "spec.toml"
    (out / "variants").mkdir(parents=True, exist_ok=True)
    if not copy.is_file():
        (out / ".spec.toml.tmp").write_text(study.text)
        os.replace(out / ".spec.toml.tmp", copy)
    for d in (out / "variants").iterdir():  # leftovers of a killed run
        if d.name.startswith(".") and d.name.endswith(".tmp"):
            shutil.rmtree(d, ignore_errors=True)


def _client(workers: int | None, scheduler: str | None):
    """A Dask client: on ``scheduler``, or on a new LocalCluster (everything on 127.0.0.1, the
    dashboard on a free loopback port)."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s"), None
        except (OSError, TimeoutError) as exc:
            raise UserError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


def run_sweep(study: Study, out: str | os.PathLike, workers: int | None = None,
              scheduler: str | None = None, progress: bool | None = None) -> SweepSummary:
    """Run every unfinished variant of ``study`` into ``out``; returns a frozen
    :class:`SweepSummary` (every variant's result, what ran, what was skipped, the wall time)."""
    from distributed import as_completed
    from tqdm import tqdm

    out = Path(out)
    check_out(out, study)  # before the cluster starts; written only once it runs
    done = finished(out)
    todo = [j for j in study.jobs() if j["id"] not in done]
    t0 = time.perf_counter()
    if not todo:
        _prepare_out(out, study)
    else:
        client, cluster = _client(workers, scheduler)
        try:
            _prepare_out(out, study)
            tag = hashlib.sha256(study.text.encode()).hexdigest()[:10]
            futures = [client.submit(run_variant, j, retries=2, pure=False,
                                     key=f"omni-sweep-{tag}-{j['id']}-{uuid.uuid4().hex[:6]}")
                       for j in todo]
            bar = tqdm(total=len(study.variants), initial=len(done), unit="variant",
                       desc="sweep", disable=progress is False or (progress is None and not sys.stderr.isatty()))
            for fut in as_completed(futures):
                _write_variant(out, fut.result())
                bar.update(1)
            bar.close()
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    variants = read_variants(out, study)
    write_table(out, study, variants)
    return SweepSummary(variants, ran=len(todo), skipped=len(done), wall_s=time.perf_counter() - t0)
