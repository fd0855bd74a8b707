"""Friction-strength study: how the alpha model's advantage and the inertia bias move with the
yaw's dry friction, per friction family.

For each family (``coulomb``, ``lugre``: the built-in scenes) and each scale factor, the yaw's
dry-friction levels (``frictionloss`` and the LuGre Fc, Fs; :func:`omni_sim.model.
scale_yaw_friction`, viscous damping unchanged) are set to factor x the calibrated ones and the
whole reproduction runs in memory (:func:`omni_studies.reproduce.run_reproduce`: generate the
campaign -> identify -> validate both models -> inertia (6) against MuJoCo).  Recorded per level:
the step ratio of medians linear/alpha (whole record and first second after each edge), the
sine phase and magnitude p90 of both models, the inertia (6) max |error| and its signed worst
bias.  A level whose identification or simulation fails is recorded with the reason
(``"ok": false``), never dropped.

:func:`run_level` (one level), :func:`study` (every family x level: the record).
``scripts/friction_study.py`` is the command; :mod:`omni_app.friction_study_report` writes
``friction_study.json`` and ``friction_study.png``.
"""

from __future__ import annotations

import copy
import sys
import time

import numpy as np

from identification.errors import UserError

DEFAULT_LEVELS = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)


def _worst(values) -> float:
    return float(max(values, key=abs))


def level_figures(res) -> dict:
    """The study's figures of one in-memory reproduction (a
    :class:`omni_studies.reproduce.ReproduceResult`)."""
    s = res.summary
    win = s.step.windows
    errs = [r.rel_error for r in s.inertia.poses]
    return {
        "step_ratio_of_medians_whole_record": win.whole_record.ratio_of_medians,
        "step_ratio_of_medians_after_edges": win.after_edges.ratio_of_medians,
        "step_alpha_better_poses": s.step.alpha_better_poses,
        "step_n_poses": s.step.n_poses,
        **{f"sine_{k}": getattr(s.sine, k) for k in ("phase_p90_linear_deg", "phase_p90_alpha_deg",
                                               "magnitude_p90_linear", "magnitude_p90_alpha")},
        "inertia_max_rel_error": s.inertia.max_rel_error,
        "inertia_worst_signed_rel_error": _worst(errs),
        "alpha_breaks": [float(a) for a in res.ident.alpha_model.alpha_breaks],
        "alpha_steps_not_converged": s.alpha_simulation.steps_not_converged,
    }


def _short_reason(message: str) -> str:
    """A failed identification lists every warning; keep what failed and count the
    non-physical sine runs (the rest is in any reproduction's params.json)."""
    parts = message.split("; ")
    failed = [p for p in parts if "not fitted" in p]
    if not failed:
        return message
    n_bad = sum("non-physical local coefficients" in p for p in parts)
    return (f"{'; '.join(failed)} ({n_bad} sine run(s) with non-physical local coefficients, "
            "excluded from the alpha model)")


def run_level(base, factor: float, campaign: str, jobs: int | None) -> dict:
    """One level: the family's device ``base`` with its dry friction scaled by ``factor``."""
    from omni_sim.device import Device
    from omni_studies.reproduce import run_reproduce

    dev = Device(copy.deepcopy(base.model))
    dev.scale_friction(factor, base)
    row = {"scale": factor, "dry_friction": dev.friction()}
    t0 = time.perf_counter()
    try:
        res = run_reproduce(dev, jobs, campaign)
        row.update(ok=True, **level_figures(res))
    except (UserError, RuntimeError, ValueError, np.linalg.LinAlgError) as exc:
        row.update(ok=False, reason=_short_reason(f"{type(exc).__name__}: {exc}"))
    row["wall_s"] = time.perf_counter() - t0
    return row


def study(families, levels, campaign: str = "paper", jobs: int | None = None,
          progress: bool = True) -> dict:
    """Every family x level (see the module docstring); returns the JSON dict."""
    from tqdm import tqdm

    from omni_sim.device import Device

    bases = {fam: Device.load(friction=fam) for fam in families}
    out = {"description": __doc__.split("\n\n")[0],
           "campaign": str(campaign), "levels": list(levels),
           "scaled": "yaw dry friction: frictionloss and LuGre Fc, Fs (viscous damping unchanged)",
           "families": {}}
    with tqdm(total=len(families) * len(levels), unit="level", disable=not progress,
              file=sys.stderr) as bar:
        for fam in families:
            rows = []
            for f in levels:
                bar.set_description(f"{fam} x{f:g}")
                rows.append(run_level(bases[fam], f, campaign, jobs))
                bar.update(1)
            out["families"][fam] = {"calibrated_dry_friction": bases[fam].friction(),
                                    "levels": rows}
    return out

