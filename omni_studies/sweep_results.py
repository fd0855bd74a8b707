"""The sweep's results as objects (:mod:`omni_studies.sweep`, the engine): each pipeline's
figures, a variant's :class:`VariantResult` (``result.json``), what a worker returns
(:class:`VariantOutput`), :func:`omni_studies.sweep.run_sweep`'s :class:`SweepSummary`, and
``results.csv``'s text written from the results and read back (:func:`table_text`,
:func:`read_table`)."""

from __future__ import annotations

import csv
import dataclasses
import io
import typing
from dataclasses import dataclass

from identification.records import Record

if typing.TYPE_CHECKING:
    from .sweep_study import Study

TIMING_COLUMNS = ("wall_s",)


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
    """What :func:`omni_studies.sweep_pipelines.run_variant` returns (from a worker): the result
    and the variant's files."""

    result: VariantResult  #: ``result.json``
    files: dict[str, str]  #: the pipeline's own files (``summary.json``, ``report.json``, ...): name -> text


@dataclass(frozen=True)
class SweepSummary:
    """What :func:`omni_studies.sweep.run_sweep` returns: every variant's result and what this
    call did."""

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


def cell_text(v) -> str:
    """A value as ``results.csv`` writes it: "" for None, a float's ``repr`` (it reads back as
    the same float), anything else as ``str``."""
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


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
