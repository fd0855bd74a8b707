"""The sweep's results as objects (:mod:`omni_studies.sweep`): a variant's result is a frozen
:class:`VariantResult` with typed figures, :func:`run_sweep` returns a frozen
:class:`SweepSummary`, and ``results.csv`` is written from the objects: the committed study's
table reads into them and writes back byte for byte."""

import dataclasses
import json
from pathlib import Path

import pytest

from omni_studies import sweep as sw
from test_sweep import GRID

DOCS = Path(__file__).resolve().parents[1] / "docs"
#: The committed study (docs/usage/sweeps.md's worked study) and its table.
STUDY = DOCS / "studies" / "sweep" / "friction_scale.toml"
TABLE = DOCS / "studies" / "sweep" / "results.csv"
#: result.json's keys, in the file's order.
RESULT_KEYS = ["id", "seed", "params", "fixed", "pipeline", "status", "error", "figures", "wall_s"]


@pytest.fixture(scope="module")
def committed():
    """The committed study and its table read into objects: ``(study, text, variants)``."""
    study = sw.load_study(STUDY)
    text = TABLE.read_text()
    return study, text, sw.read_table(text, study)


def test_the_committed_table_round_trips(committed):
    """docs/studies/sweep/results.csv read into :class:`VariantResult` objects and written
    back is the same text byte for byte, also through each variant's result.json (the path
    ``omni sweep`` takes: result.json, then the table)."""
    study, text, variants = committed
    assert sw.table_text(study, variants) == text
    via_json = [sw.VariantResult.from_json(json.loads(json.dumps(v.to_json(), indent=2))) for v in variants]
    assert sw.table_text(study, via_json) == text
    # the rows are the study's variants: ids, seeds and values from the spec, not from the table
    assert [(v.id, v.seed, v.params) for v in variants] == [
        (vid, sw.variant_seed(study.seed, vid), values) for vid, values in study.variants]
    assert all(v.fixed == {"kp": 2.0} and v.pipeline == "reproduce" for v in variants)


def test_the_committed_variants_are_typed(committed):
    """Figures are the pipeline's typed record, floats where the table has numbers; the failed
    variant has none and says why; the summary counts what the table holds."""
    study, _, variants = committed
    ok = [v for v in variants if v.status == "ok"]
    assert len(ok) == 5 and all(isinstance(v.figures, sw.ReproduceFigures) for v in ok)
    assert all(type(getattr(v.figures, k)) is float for v in ok for k in sw.FIGURES["reproduce"])
    assert ok[0].figures.inertia_max_rel_error == 0.015219869450189716
    (bad,) = [v for v in variants if v.status == "failed"]
    assert bad.figures is None and bad.error.startswith("UserError: identification failed")
    assert bad.to_json()["figures"] == {}
    summary = sw.SweepSummary(variants, ran=6, skipped=0, wall_s=1.0)
    assert (summary.n, summary.failed) == (6, 1)


def test_a_fresh_variant_has_the_documented_keys(tmp_path):
    """A variant run now (the simulate pipeline: a fraction of a second) writes result.json
    with the keys in their order, its figures' keys are results.csv's figure columns, and the
    table's columns are docs/usage/sweeps.md's: id, seed, the parameters, the figures,
    status, error, wall_s."""
    study = sw.parse_study(GRID, "s", tmp_path)
    out = sw.run_variant(study.jobs()[0])
    d = json.loads(json.dumps(out.result.to_json(), indent=2))
    assert list(d) == RESULT_KEYS and out.result.status == "ok" and out.files == {}
    assert list(d["figures"]) == list(sw.FIGURES["simulate"])
    assert d["params"] == {"joint.yaw.damping": 0.004, "noise_rad": 0.0}
    header = sw.table_text(study, [out.result]).splitlines()[0].split(",")
    assert header == ["id", "seed", *study.params, *sw.FIGURES["simulate"], "status", "error", "wall_s"]
    page = " ".join((DOCS / "usage" / "sweeps.md").read_text().split())
    assert ("one row per variant: `id`, `seed`, the parameters, the figures, `status` ok/failed, "
            "`error`, `wall_s`") in page
    text = json.dumps(out.result.to_json(), indent=2)
    assert json.dumps(sw.VariantResult.from_json(json.loads(text)).to_json(), indent=2) == text


def test_discrepancy_figures_read_back_with_their_types(tmp_path):
    """The discrepancy pipeline's text and integer figures survive the table: an empty list
    of effects stays "", the 0/1 flags stay integers."""
    study = sw.parse_study('[pipeline]\nname = "discrepancy"\n[grid]\nkp = [1.5, 2.0]\n', "d", tmp_path)
    figs = [sw.DiscrepancyFigures(effects="", passed=0, assessment="named none, expected viscous_damping",
                                  shrink_factor=1.0, gap_before_rad=0.04, gap_after_rad=0.04, unexplained=1),
            sw.DiscrepancyFigures(effects="viscous_damping+time_delay", passed=1, assessment="ok",
                                  shrink_factor=258.2, gap_before_rad=0.0415, gap_after_rad=1.6e-4,
                                  unexplained=0)]
    variants = tuple(sw.VariantResult(id=vid, seed=j["seed"], params=values, fixed={}, pipeline="discrepancy",
                                      status="ok", error="", figures=f, wall_s=93.1)
                     for (vid, values), j, f in zip(study.variants, study.jobs(), figs))
    text = sw.table_text(study, variants)
    assert sw.read_table(text, study) == variants
    seed = variants[0].seed
    assert text.splitlines()[1] == f'v0000,{seed},1.5,,0,"named none, expected viscous_damping",1.0,0.04,0.04,1,ok,,93.1'


def test_sweep_results_are_frozen(committed, tmp_path):
    """Nothing downstream can change a result: assignment raises, nested figures too."""
    _, _, variants = committed
    out = sw.run_variant(sw.parse_study(GRID, "s", tmp_path).jobs()[0])
    summary = sw.SweepSummary(variants, ran=0, skipped=6, wall_s=0.0)
    for obj, field in ((variants[0], "status"), (variants[0], "figures"),
                       (variants[0].figures, "inertia_max_rel_error"), (summary, "ran"),
                       (summary, "variants"), (out, "result"), (out.result.figures, "rms_error_rad")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, field, None)
    assert isinstance(summary.variants, tuple)
