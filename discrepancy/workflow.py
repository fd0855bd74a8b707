"""The whole workflow: replay, localise, name (held-out scoring), fit, show the gap shrink.

:func:`run_discrepancy` loads the model once, prepares the runs and runs the stages in order
(:data:`STAGES`):

1. :func:`replay_nominal`: the nominal model's replay of every run, its gap and the noise floor;
2. a :class:`~discrepancy.search.Search` from that gap: the nominal's corrections, forward
   selection, one round per effect (every candidate screened and scored on held-out samples,
   :mod:`.select`), with the pair search of the first round and the backward step of floating
   selection; the named effects' uncertainty (:mod:`.uncertainty`) and the held-out replay of
   the patched model; the exported model's own replay, in-sample (:func:`replay_exported`);
   the held-out gaps under the other fold scheme;
3. :func:`~discrepancy.report.assemble_report`: the content of ``report.json`` (with the
   localisation of the gap before and after, :mod:`.localise`).

This module joins the MuJoCo side (the model, the effect library, the replay) to the
statistics, which get the model through an :class:`~discrepancy.effects.ModelBuilder`
and the simulations through the :class:`~discrepancy.replay.Replayer`.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from identification.dataset import Run
from identification.errors import UserError

from omni_sim import model as om
from omni_sim import runtime
from omni_sim.device import Device
from . import effects as fx
from . import select as sel
from .evidence import of_outcome as evidence_of
from .fit import gap, split_values
from .replay import Replayer, control_period_of, prepare_runs
from .report import Findings, assemble_report
from .result import DiscrepancyResult
from .runs import ReplayRun
from .search import Search
from .select import Scored

#: Samples (all runs together) above which the fits use only the start of each run: the fit and
#: the candidate scoring cost scale with it; the before/after evaluation always uses whole runs.
MAX_FIT_SAMPLES = 300_000
#: Shortest per-run record [samples] kept for fitting when runs are cut to the budget.
MIN_FIT_RUN_SAMPLES = 3000


#: The former name of :class:`~discrepancy.result.DiscrepancyResult` (kept for existing code).
Outcome = DiscrepancyResult


#: The nominal's uncertain constants refitted by default (library names): rotor inertia, viscous
#: damping, Coulomb level, torque constant and a constant drive offset (which a P loop turns into
#: a position offset) -- what a datasheet or a CAD model gets "a little wrong everywhere".
DEFAULT_CORRECTIONS = ("armature", "viscous_damping", "coulomb_friction", "torque_gain", "position_offset")


def correction_names(corrections, spec: mujoco.MjSpec, target: om.Target, own_device: bool) -> tuple[str, ...]:
    """The library effects refitted as corrections of the nominal: ``"auto"`` is
    :data:`DEFAULT_CORRECTIONS` on a user's own device (``--joint``/``--actuator``) and none on
    the virtual Omni (whose calibrated scene is the nominal the bank hides effects against);
    ``"default"`` the default set; ``"none"`` or an empty tuple none; else the names given.
    Only those that can be written into the model are kept, and of the default set only the
    constants the nominal states (a value other than zero): a zero means the nominal lacks
    that structure (no dry friction, no offset), which the library names as an effect.

    Raises
    ------
    UserError
        An unknown name."""
    if corrections in (None, "auto"):
        names = DEFAULT_CORRECTIONS if own_device else ()
    elif corrections == "default":
        names = DEFAULT_CORRECTIONS
    elif corrections == "none":
        names = ()
    else:
        names = tuple(corrections)
    unknown = [c for c in names if c not in fx.NAMES]
    if unknown:
        raise UserError(f"unknown correction(s): {', '.join(unknown)} (library: {', '.join(fx.NAMES)})")
    writable = fx.applicable(spec, target)
    names = tuple(c for c in names if c in writable)
    if corrections in (None, "auto", "default"):
        names = tuple(c for c in names if np.all(np.asarray(fx.get(c).read(spec, target), float) != 0))
    return names


#: The workflow's stages, in order (the report's ``timings`` and ``physics_steps_per_stage``).
STAGES = ("replay_nominal", "corrections", "naming", "uncertainty_and_evaluation", "other_fold_scheme")


def run_discrepancy(runs: list[Run], model_path=None, *, device: Device | None = None,
                    jobs: int | None = None, k: int = 5, max_effects: int = 3,
                    max_fit_samples: int = MAX_FIT_SAMPLES, candidates: tuple[str, ...] | None = None,
                    log=None, target: om.Target | None = None, folds: str = "blocked",
                    corrections="auto", progress=None) -> DiscrepancyResult:
    """Find, name, fit and check the effect(s) the model misses on these measured runs.

    Parameters
    ----------
    runs : list of Run
        Measured runs (the dataset contract).
    model_path : path, optional
        MJCF of the model to test (default: the built-in scene).
    device : omni_sim.Device, optional
        The model to test, already loaded (:meth:`omni_sim.Device.load`, unchanged since), in
        place of ``model_path``: its compiled model is replayed as it is (not compiled again)
        and the effects are written into its file; its target is the workflow's.
    jobs : int, optional
        Rollout threads (default: :func:`omni_sim.device.default_threads`).
    k : int
        Folds for held-out scoring.
    folds : str
        The verdict's fold scheme (:data:`discrepancy.select.FOLD_SCHEMES`): ``"blocked"``
        (time blocks within every run) or ``"runs"`` (whole runs); the report gives the other
        scheme's held-out gaps beside.
    corrections : str or tuple of str
        The nominal's constants refitted jointly with every candidate (:func:`correction_names`).
    max_effects : int
        Most effects named (rounds).
    max_fit_samples : int
        Sample budget of the fits (see :data:`MAX_FIT_SAMPLES`).
    candidates : tuple of str, optional
        Library names to consider (default: all that can be written into the model).
    target : omni_sim.model.Target, optional
        The controlled hinge and its actuator of a user's single-joint device (default None:
        the Omni's contract, ``yaw``/``yaw_motor`` with the arm).  Without the Omni's arm the
        runs need no pose metadata.
    progress : callable, optional
        ``progress(index, name, physics_steps)`` at the start of each of :data:`STAGES` and at
        the end (index ``len(STAGES)``, name ``"done"``): a front end's stage bar.

    Raises
    ------
    UserError
        Model without the contract's names, runs the model cannot replay, too little data; a
        ``device`` together with ``model_path`` or another ``target``, or compiled in memory.
    """
    t_start = time.perf_counter()
    inp = _prepare(runs, model_path, device, target, folds=folds, corrections=corrections,
                   candidates=candidates, max_fit_samples=max_fit_samples)
    log = log or (lambda s: None)
    with Replayer(jobs, inp.device.target, inp.device.control_period_s) as rep:
        clock = _Stages(rep, progress)
        with clock.stage("replay_nominal"):
            nominal = replay_nominal(inp.device.model, inp.runs, inp.fit_runs, rep)
        log(f"gap before {nominal.gap:.3e} rad, noise floor {nominal.noise:.2e} rad, {len(inp.runs)} runs, "
            f"{sum(r.n for r in inp.runs)} samples"
            + (f" (fits use the first {inp.fit_samples} of each run)" if inp.fit_samples else ""))
        search = Search(inp.builder, inp.fit_runs, rep, gap=nominal.fit_gap, noise=nominal.noise, k=k,
                        scheme=folds, log=log)
        with clock.stage("corrections"):
            start = search.refit_nominal(inp.fixed)
        with clock.stage("naming"):
            evidence = evidence_of(inp.builder, start, inp.fit_runs, inp.candidates, log, rep)
            selection = search.select(inp.candidates, max_effects, evidence)
        with clock.stage("uncertainty_and_evaluation"):
            unc, theta_after = search.estimate(inp.runs, nominal.theta)
            exported = replay_exported(patched := _patched_spec(inp.builder, selection.best), inp.runs, rep)
        with clock.stage("other_fold_scheme"):
            gaps = search.both_schemes()
        clock.done()
        warnings = {"unstable_simulations": rep.unstable_replays, "instability_warnings": rep.unstable_warnings,
                    "first": rep.first_warning}
    settings = _settings(inp, k=k, scheme=folds, max_effects=max_effects)
    report = assemble_report(inp.builder, inp.runs, Findings(nominal, selection, unc, theta_after, gaps),
                             settings, fixed=inp.fixed, actuator_limit=inp.device.voltage_limit)
    report["exported_model"], report["mujoco_warnings"] = exported, warnings
    report["timings"] = clock.timings(time.perf_counter() - t_start)
    report["timings"]["evidence"], report["evidence"] = evidence.cost, evidence.to_json()
    return DiscrepancyResult(report, patched, inp.runs, nominal.theta, theta_after, selection.rounds, evidence)


class _Stages:
    """The workflow's stages as they run: each one's wall time and physics steps (the report's
    ``timings``), and the front end's ``progress`` called at the start of each."""

    def __init__(self, rep: Replayer, progress=None):
        self.rep = rep
        self.progress = progress or (lambda index, name, steps: None)
        self.seconds, self.steps = {}, {}

    @contextmanager
    def stage(self, name: str):
        """Run one of :data:`STAGES` (a ``with`` block)."""
        self.progress(STAGES.index(name), name, self.rep.steps)
        t0, steps0 = time.perf_counter(), self.rep.steps
        yield
        self.seconds[f"{name}_s"] = time.perf_counter() - t0
        self.steps[name] = self.rep.steps - steps0

    def done(self) -> None:
        """The end of the last stage (``progress`` with ``"done"``); the physics steps taken."""
        self.progress(len(STAGES), "done", self.rep.steps)
        self.total_steps = self.rep.steps

    def timings(self, total_s: float) -> dict:
        """The report's ``timings`` (``total_s``: the whole workflow's wall time)."""
        steps = self.total_steps
        return {**self.seconds, "total_s": total_s, "physics_steps": steps,
                "physics_steps_per_stage": self.steps, "steps_per_s": steps / max(total_s, 1e-9)}


# -- inputs ------------------------------------------------------------------------------------
@dataclass
class _Prepared:
    """The workflow's inputs, checked: the model (its spec, the device replaying it, its file),
    the runs prepared for replay (whole, and as the fits use them), the corrections and the
    candidates, the effect library on the model."""

    spec: mujoco.MjSpec
    device: Device
    path: str
    effect_target: om.Target
    runs: list
    fit_runs: list
    fit_samples: int | None
    fixed: tuple
    candidates: tuple
    builder: fx.ModelBuilder


def _prepare(runs: list[Run], model_path, device: Device | None, target: om.Target | None, *,
             folds: str = "blocked", corrections="auto", candidates: tuple[str, ...] | None = None,
             max_fit_samples: int = MAX_FIT_SAMPLES) -> _Prepared:
    """Check the inputs (before any long computation) and prepare them; the checks' order is
    the refusal's (the model, the runs' periods, the fold scheme, the names, the runs' count)."""
    spec, device, path = _load(runs, model_path, device, target)
    replay_runs = prepare_runs(runs, device)
    target = device.target
    effect_target = om.OMNI if target is None else target  # where the effects are written
    if folds not in sel.FOLD_SCHEMES:
        raise UserError(f"unknown fold scheme {folds!r} (one of {', '.join(sel.FOLD_SCHEMES)})")
    fixed = correction_names(corrections, spec, effect_target, target is not None and target != om.OMNI)
    candidates = tuple(c for c in _usable_candidates(candidates, spec, effect_target, path) if c not in fixed)
    if len(replay_runs) < 2:
        raise UserError("measured data: at least 2 runs are needed (candidates are scored on runs "
                        "held out of their fit)")
    fit_runs, fit_samples = _fit_runs(replay_runs, max_fit_samples)
    return _Prepared(spec, device, path, effect_target, replay_runs, fit_runs, fit_samples, fixed, candidates,
                     fx.ModelBuilder(spec, effect_target))


def _load(runs: list[Run], model_path, device: Device | None,
          target: om.Target | None) -> tuple[mujoco.MjSpec, Device, str]:
    """The model's spec, a device replaying it at the runs' control period, and its file: from
    ``model_path`` (compiled here), or from ``device`` (its model as compiled, its spec read
    from its file)."""
    if device is None:
        spec, model, path = _load_spec(model_path, target)
    else:
        spec, model, path = _device_spec(device, model_path, target)
        target = device.target
    period = control_period_of(runs)
    try:
        device = Device(model, period, target=target) if device is None else device.at_period(period)
    except UserError as exc:
        raise UserError(f"measured data: {exc} (metadata control_period_s, default the sample "
                        "period)") from None
    return spec, device, path


def _load_spec(model_path, target: om.Target | None = None) -> tuple[mujoco.MjSpec, mujoco.MjModel, str]:
    path = Path(model_path) if model_path is not None else om.DEFAULT_SCENE
    # UserError on a missing file, bad XML or missing names (the Omni's, or the target's)
    model = om.load_model(path, target=target)
    spec = mujoco.MjSpec.from_file(str(path))
    return spec, model, str(path)


def _device_spec(device: Device, model_path,
                 target: om.Target | None) -> tuple[mujoco.MjSpec, mujoco.MjModel, str]:
    """A loaded device's spec (read from its file, not compiled), model and file."""
    if model_path is not None:
        raise UserError("give either a model file or a device, not both (the device names its file)")
    if target is not None and target != device.target:
        raise UserError(f"the device drives {device.target}, not the target {target}: load the device "
                        "with that target, or leave target out")
    if device.in_memory:
        raise UserError("the device's model was compiled in memory: the workflow writes its effects "
                        "into the model's MJCF file (load the device from a file with Device.load, "
                        "or give model_path)")
    path = Path(device.file) if device.file is not None else om.DEFAULT_SCENE
    return mujoco.MjSpec.from_file(str(path)), device.model, str(path)

def _usable_candidates(candidates: tuple[str, ...] | None, spec: mujoco.MjSpec, target: om.Target,
                       path: str) -> tuple[str, ...]:
    """The asked-for library names (default: all) that can be written into this model."""
    unknown = [c for c in (candidates or ()) if c not in fx.NAMES]
    if unknown:
        raise UserError(f"unknown candidate effect(s): {', '.join(unknown)} (library: {', '.join(fx.NAMES)})")
    writable = fx.applicable(spec, target)
    usable = tuple(c for c in (candidates or fx.NAMES) if c in writable)
    if not usable:
        raise UserError(f"{path}: none of the candidate effects can be written into this model")
    return usable


def _fit_runs(runs: list[ReplayRun], max_fit_samples: int) -> tuple[list[ReplayRun], int | None]:
    """The runs the fits use and their length per run: the whole runs, or, when all of them
    hold more than ``max_fit_samples`` samples, the start of each (at least
    :data:`MIN_FIT_RUN_SAMPLES`; None: whole runs)."""
    if sum(r.n for r in runs) <= max_fit_samples:
        return runs, None
    n = max(MIN_FIT_RUN_SAMPLES, max_fit_samples // len(runs))
    return [r.truncated(n) for r in runs], n


# -- 1. the nominal model ----------------------------------------------------------------------
@dataclass
class NominalReplay:
    """The nominal model's replay of the runs.

    Attributes
    ----------
    theta : list of ndarray [rad]
        The replayed yaw angle of each run.
    gap : float [rad]
        Its gap to the measured runs (whole runs).
    fit_gap : float [rad]
        Its gap on the samples the fits use (where the first round starts).
    noise : float [rad]
        The measurement noise floor (:func:`discrepancy.select.noise_floor`).
    """

    theta: list
    gap: float
    fit_gap: float
    noise: float


def replay_nominal(model: mujoco.MjModel, runs: list[ReplayRun], fit_runs: list[ReplayRun],
                   rep: Replayer) -> NominalReplay:
    """Replay every run on the nominal model: its gap, on whole runs and on the fits' samples,
    and the noise floor of its residuals."""
    theta = rep.simulate([model], runs)
    residuals = [th - r.theta for th, r in zip(theta, runs)]
    fit_gap = gap([res[: r.n] for res, r in zip(residuals, fit_runs)])
    return NominalReplay(theta, gap(residuals), fit_gap, sel.noise_floor(residuals))


#: The report's note on the exported model's gap (``report.json``'s ``exported_model``).
EXPORTED_NOTE = "in-sample: the all-runs fit replayed on every run; the held-out gap_after is the verdict"


def replay_exported(spec: mujoco.MjSpec, runs: list[ReplayRun], rep: Replayer) -> dict:
    """The exported model's own gap: ``spec`` (the patched model ``model.xml`` is written
    from: the accepted effects at their all-runs fit) replayed on every whole run, its gap at
    the logged times as :func:`replay_nominal`'s.  In-sample (each run is among those the
    fit saw), so usually a little below the held-out ``gap_after``; it is what a replay of
    ``model.xml`` reproduces (in plain MuJoCo with ``runtime`` when that is not None,
    :mod:`omni_sim.runtime`).

    Returns
    -------
    dict
        ``gap_rad`` [rad], ``runtime`` (``"MODULE:FUNCTION"`` or None) and ``note``: the
        report's ``exported_model``.
    """
    theta = rep.simulate([spec.copy().compile()], runs)
    needs = bool(runtime.needed_laws(spec))
    return {"gap_rad": gap([th - r.theta for th, r in zip(theta, runs)]),
            "runtime": runtime.RUNTIME if needs else None, "note": EXPORTED_NOTE}


def _settings(inp: _Prepared, *, k: int, scheme: str, max_effects: int) -> dict:
    """The report's ``settings``: what the workflow ran with."""
    return {"folds": k, "fold_scheme": scheme, "corrections": list(inp.fixed),
            "pair_search": not inp.fixed, "max_effects": max_effects, "min_share": sel.MIN_SHARE,
            "noise_factor": sel.NOISE_FACTOR, "tie_margin": sel.TIE_MARGIN,
            "fit_samples_per_run": inp.fit_samples, "model": inp.path, "joint": inp.effect_target.joint,
            "actuator": inp.effect_target.actuator, "candidates": list(inp.candidates),
            "prescreen_s": sel.PRESCREEN_S, "n_screen": sel.N_SCREEN,
            "mujoco": mujoco.__version__}


# -- the patched model ---------------------------------------------------------------------------
def _patched_spec(builder: fx.ModelBuilder, best: Scored | None) -> mujoco.MjSpec:
    """The nominal model with the accepted effects at their all-runs fit (a copy)."""
    if best is None:
        return builder.spec.copy()
    return fx.apply(builder.spec, split_values(best.effects, best.fit.x), builder.target)
