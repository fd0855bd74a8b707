"""The sweep's study file (:mod:`omni_studies.sweep`, the engine): the example
(:data:`EXAMPLE`), its parsing and checks (:func:`parse_study`, :func:`load_study`: a
:class:`Study`) and the variants' seeds (:func:`variant_seed`)."""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import tomllib
from pathlib import Path

from identification.errors import UserError

PIPELINES = ("reproduce", "discrepancy", "simulate")
_TOP_KEYS = ("description", "seed", "base", "pipeline", "fixed", "grid", "list", "random")
_PIPELINE_KEYS = {"reproduce": ("name", "campaign"), "simulate": ("name", "campaign"),
                  "discrepancy": ("name", "hidden", "duration_s")}

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
