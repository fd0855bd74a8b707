"""Write ``report.json``, ``report.md``, ``model.xml`` and the figures of a discrepancy run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from omni_sim import runtime
from discrepancy import effects as fx
from discrepancy.evidence import EXPLAINED_ENOUGH
from discrepancy.localise import command_note, lag_text
from discrepancy.report import CONFOUNDED_CORRELATION


def _fmt(x, digits=3) -> str:
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    if not math.isfinite(x):
        return str(x)
    return f"{x:.{digits}g}"


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else (None if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def figures(outcome, folder: Path) -> list[str]:
    """Measured vs model before vs model after, localisation maps, candidate scores (PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ev = [_figure_evidence(outcome, folder)] if getattr(outcome, "evidence", None) is not None \
        and outcome.evidence.available else []
    return ev + [_figure_runs(plt, outcome, folder), _figure_localisation(plt, outcome.report, folder),
                 _figure_candidates(plt, outcome.report, folder)]


#: The missing torque's maps (omni_app/torque_maps.py), shown in the report's first section.
EVIDENCE_FIG = "fig_missing_torque.png"


def _figure_evidence(outcome, folder: Path) -> str:
    """The missing torque's four maps under the corrected nominal (:mod:`.torque_maps`)."""
    from . import torque_maps

    torque_maps.draw(list(outcome.evidence.torques), folder / EVIDENCE_FIG,
                     title="missing torque of the corrected nominal (noise band shaded)")
    return EVIDENCE_FIG


def _figure_runs(plt, outcome, folder: Path) -> str:
    """The three worst runs before: measured, model before and after, and the residuals."""
    runs, tb, ta = outcome.runs, outcome.theta_before, outcome.theta_after
    order = np.argsort([-np.sqrt(np.mean((th - r.theta) ** 2)) for r, th in zip(runs, tb)])[:3]
    fig, axes = plt.subplots(len(order), 2, figsize=(11, 2.6 * len(order)), squeeze=False)
    for row, j in enumerate(order):
        r = runs[j]
        ax = axes[row, 0]
        ax.plot(r.t, r.r, color="0.7", lw=0.8, label="reference r")
        ax.plot(r.t, r.theta, "k", lw=1.0, label="measured")
        ax.plot(r.t, tb[j], "C3", lw=0.9, ls="--", label="model before")
        ax.plot(r.t, ta[j], "C0", lw=0.9, label="model after (held out)")
        ax.set_title(r.name, fontsize=9)
        ax.set_ylabel("theta [rad]")
        ax = axes[row, 1]
        ax.plot(r.t, tb[j] - r.theta, "C3", lw=0.8, label="before")
        ax.plot(r.t, ta[j] - r.theta, "C0", lw=0.8, label="after")
        ax.set_ylabel("model - measured [rad]")
        if row == 0:
            axes[0, 0].legend(fontsize=7, loc="upper right")
            ax.legend(fontsize=7)
    axes[-1, 0].set_xlabel("t [s]")
    axes[-1, 1].set_xlabel("t [s]")
    return _save(plt, fig, folder, "fig_runs.png")


def _figure_localisation(plt, rep: dict, folder: Path) -> str:
    """The localisation maps before and after: by regime, by time window, the sines' gain and
    phase error."""
    lb, la = rep["localisation"]["before"], rep["localisation"]["after"]
    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    keys = list(lb["regimes"]["bins"])
    y = np.arange(len(keys))
    ax = axes[0, 0]
    ax.barh(y - 0.2, [lb["regimes"]["bins"][k]["rms_rad"] for k in keys], 0.4, color="C3", label="before")
    ax.barh(y + 0.2, [la["regimes"]["bins"][k]["rms_rad"] for k in keys], 0.4, color="C0", label="after")
    ax.set_yticks(y, keys, fontsize=7)
    ax.set_xlabel("RMS gap [rad]")
    ax.set_title("by regime")
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    tw_b, tw_a = lb["time_windows"], la["time_windows"]
    ax.step([w["t_start_s"] for w in tw_b], [w["rms_rad"] for w in tw_b], "C3", where="post", label="before")
    ax.step([w["t_start_s"] for w in tw_a], [w["rms_rad"] for w in tw_a], "C0", where="post", label="after")
    ax.set_xlabel("time window start [s]")
    ax.set_ylabel("RMS gap [rad]")
    ax.set_title("by time window")
    ax.legend(fontsize=7)
    if lb["frequency_response"]:
        _plot_frequency_response(axes[1, 0], axes[1, 1], lb["frequency_response"], la["frequency_response"])
    else:
        axes[1, 0].text(0.5, 0.5, "no sine runs", ha="center")
        axes[1, 1].axis("off")
    return _save(plt, fig, folder, "fig_localisation.png")


def _plot_frequency_response(ax_gain, ax_phase, fr_b: list[dict], fr_a: list[dict]) -> None:
    """Gain (measured, model before, after) and phase error (before, after) of the sines'
    fundamental, one marker per amplitude."""
    f = np.array([d["frequency_hz"] for d in fr_b])
    amps = sorted({d["amplitude_rad"] for d in fr_b})
    ax = ax_gain
    for i, a in enumerate(amps):
        sel = [d["amplitude_rad"] == a for d in fr_b]
        mk = "os^dv"[i % 5]
        ax.plot(f[sel], [d["gain_measured"] for d, s in zip(fr_b, sel) if s], "k" + mk, ms=5,
                label=f"measured A={a:g}")
        ax.plot(f[sel], [d["gain_model"] for d, s in zip(fr_b, sel) if s], "C3" + mk, ms=4, mfc="none",
                label=f"before A={a:g}")
        ax.plot(f[sel], [d["gain_model"] for d, s in zip(fr_a, sel) if s], "C0" + mk, ms=3,
                label=f"after A={a:g}")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|theta/r| at the fundamental [-]")
    ax.set_title("frequency response (gain)")
    ax.legend(fontsize=6, ncol=2)
    ax = ax_phase
    for i, a in enumerate(amps):
        sel = [d["amplitude_rad"] == a for d in fr_b]
        mk = "os^dv"[i % 5]
        ax.plot(f[sel], [d["phase_error_deg"] for d, s in zip(fr_b, sel) if s], "C3" + mk, ms=4,
                label=f"before A={a:g}")
        ax.plot(f[sel], [d["phase_error_deg"] for d, s in zip(fr_a, sel) if s], "C0" + mk, ms=4,
                label=f"after A={a:g}")
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("phase model - measured [deg]")
    ax.set_title("phase error of the fundamental")
    ax.legend(fontsize=6)


def _figure_candidates(plt, rep: dict, folder: Path) -> str:
    """One panel per round: the held-out share of the gap each candidate removes."""
    nr = max(1, len(rep["candidates"]))
    fig, axes = plt.subplots(1, nr, figsize=(4.2 * nr, 0.28 * max(len(r) for r in rep["candidates"] or [[0]]) + 1.4),
                             squeeze=False)
    for i, rnd in enumerate(rep["candidates"]):
        ax = axes[0, i]
        nm = [c["name"] for c in rnd][::-1]
        sh = [max(c["share"], -0.5) if math.isfinite(c["share"]) else 0.0 for c in rnd][::-1]
        # not scored held out: left on the short records, or by equation error
        tags = {"prescreen": " (prescreen)", "equation-error": " (equation error)"}
        pre = [tags.get(c["method"], "") for c in rnd][::-1]
        ax.barh(np.arange(len(nm)), sh, color=["0.8" if p else "C0" for p in pre])
        ax.set_yticks(np.arange(len(nm)), [n + p for n, p in zip(nm, pre)], fontsize=7)
        ax.axvline(rep["settings"]["min_share"], color="k", ls=":", lw=0.8)
        ax.set_xlim(-0.5, 1.0)
        ax.set_xlabel("held-out share of the gap removed", fontsize=8)
        ax.set_title(f"round {i + 1}", fontsize=9)
    return _save(plt, fig, folder, "fig_candidates.png")


def _save(plt, fig, folder: Path, name: str) -> str:
    fig.tight_layout()
    fig.savefig(folder / name, dpi=110)
    plt.close(fig)
    return name


def markdown(outcome, figs: list[str], title: str = "Model discrepancy report", intro: str = "") -> str:
    """``report.md``: the named effects and the gap, where it lives, the candidates of each
    round, where the model was worst before and after, the figures, the timings."""
    rep = outcome.report
    L = [f"# {title}", ""]
    if intro:
        L += [intro, ""]
    L += (_md_evidence(rep, figs) + _md_named(rep) + _md_corrections(rep) + _md_gaps(rep) + _md_where(rep) + _md_candidates(rep)
          + _md_worst(rep) + _md_sampling(rep))
    for f in figs:
        if f != EVIDENCE_FIG:  # shown in its section
            L += [f"![{f}]({f})", ""]
    t = rep["timings"]
    per = t.get("physics_steps_per_stage", {})
    L += ["## Timings", "", f"total {t['total_s']:.1f} s; naming {t['naming_s']:.1f} s; "
          f"{t['physics_steps']:,} physics steps ({t['steps_per_s'] / 1e3:.0f} k steps/s); "
          f"{rep['mujoco_warnings']['unstable_simulations']} replays went unstable (excluded, never scored).", ""]
    if per:
        L += ["| stage | seconds | physics steps |", "|---|---|---|"]
        L += [f"| {k.replace('_', ' ')} | {t.get(k + '_s', 0.0):.1f} | {v:,} |" for k, v in per.items()]
        L.append("")
    L += [f"The patched model is `model.xml` ({patched_contents(rep)}). "
          + _md_runtime(outcome) + _md_exported(rep) + "`report.json` holds every number of this page.", ""]
    return "\n".join(L)


def _md_evidence(rep: dict, figs: list[str]) -> list[str]:
    """The first section: the torque the corrected nominal lacks (maps, noise band), the
    library's laws fitted to it by equation error, what the verdict's named law explains of
    it; one line when it could not be computed."""
    ev = rep.get("evidence")
    if ev is None:
        return []
    L = ["## Where the model lacks torque", ""]
    if not ev["available"]:
        return L + [f"Not available for this model: {ev['reason']}.", ""]
    under = "the nominal with its refitted corrections" if rep.get("corrections") else "the nominal"
    est = ev["estimator"]
    drive = ev["by_drive"]
    along = "; ".join(f"{_fmt(d['median_along_motion_mnm'], 3)} mN*m {label}"
                      for key, label in (("driving", "where the drive drives the load"),
                                         ("back_driven", "where it is back-driven or at rest"))
                      if (d := drive[key])["n"])
    L += [f"The torque the model ({under}) lacks along the runs, by inverse dynamics on the log "
          f"smoothed to {_fmt(est['bandwidth_hz'])} Hz (a Hann window of half-width "
          f"{_fmt(est['half_window_s'] * 1e3)} ms): tau_miss = qfrc_inverse - qfrc_actuator, less the "
          "model's own friction; > 0 means the robot needed more torque in +q than the model gives. "
          f"Noise band (3 sigma of the estimator's noise): median {_fmt(ev['band_median_mnm'])} mN*m. "
          f"Median along the motion (tau_miss sign(qd)): {along}.", ""]
    if EVIDENCE_FIG in figs:
        L += [f"![{EVIDENCE_FIG}]({EVIDENCE_FIG})", ""]
    alone = ev.get("corrections_alone_explained")
    if alone is not None:
        L += [f"Each law is fitted with the nominal's corrections refitted beside it; the corrections "
              f"alone explain {100 * alone:.1f} % of the missing torque, so a law's own part is what "
              "it explains above that.", ""]
    L += ["| candidate | explains (% of the missing torque) | fitted values | where it disagrees |",
          "|---|---|---|---|"]
    if alone is not None:
        L.append(f"| (the nominal's corrections alone) | {100 * alone:.1f} % | — | — |")
    for f in ev["ranking"]:
        L.append(f"| {f['name']} | {100 * f['explained']:.1f} % | {_md_values(f)} | {_md_disagrees(f)} |")
    L.append("")
    if ev["needs_replay"]:
        L += ["Not judged here (their torque depends on state the logged angle does not fix; only a "
              "replay can judge them): " + ", ".join(f["name"] for f in ev["needs_replay"]) + ".", ""]
    L += ["*This ranking is by equation error: each law fitted to the missing torque at the logged "
          "states, no replays. The closed-loop verdict below (held-out replays) is what names the "
          "effect.*", ""]
    left = [c["name"] for c in (rep["candidates"][0] if rep.get("candidates") else [])
            if c["method"] == "equation-error"]
    if left:
        L += ["Round 1 of the closed-loop search replayed the best of these laws and every law only a "
              "replay can judge; it left out, by this ranking: " + ", ".join(left) + ".", ""]
    fits = {f["name"]: f for f in ev["ranking"]}
    replay = {f["name"]: f["reason"] for f in ev["needs_replay"]}
    for entry in rep["effects"]:
        name = entry["name"]
        if name == "none":
            continue
        if name in fits:
            L += [f"The verdict names **{name}**: its law explains {100 * fits[name]['explained']:.1f} % of "
                  f"the missing torque here ({_md_values(fits[name])}); it disagrees: "
                  f"{_md_disagrees(fits[name], 3, table=False)}.", ""]
            L += _md_two_estimates(entry, fits[name])
        elif name in replay:
            L += [f"The verdict names **{name}**, which equation error cannot judge ({replay[name]}).", ""]
        else:
            L += [f"The verdict names **{name}**, which is not among the {len(fits)} best laws here "
                  "(report.json's `evidence` lists them).", ""]
        L += _md_stand_in(entry, fits, replay)
    if ev["unexplained"]:
        best = (f" (best {ev['best']}: {100 * ev['best_explained']:.1f} %)" if ev["best"] else "")
        L += [f"**Unexplained, and here is its shape:** no library law explains "
              f"{EXPLAINED_ENOUGH:.0%} of the missing torque{best}; the maps above show how large it "
              "is and where (against velocity, drive torque, position, time).", ""]
    return L


def _md_two_estimates(entry: dict, f: dict) -> list[str]:
    """A named law's two estimates side by side: equation error's (the missing torque, the
    corrected nominal held) and the closed loop's (the verdict's, fitted jointly with the
    corrections, its 95 % half-width).  Where they differ by more than that half-width the law's
    form and the data disagree somewhere (a law fitted in another form trades against the
    corrections: the geared servo's gain and load coefficients move together wherever the
    drive moves): the page says so, and which parameters, rather than pick one."""
    fit, half = entry.get("parameters", {}), entry.get("uncertainty", {})
    rows, apart = [], []
    for p, v in f["parameters"].items():
        if p not in fit:
            continue
        u = half.get(p)
        rows.append(f"{p} {_fmt(v, 4)} by equation error, {_fmt(fit[p], 4)}"
                    + (f" ± {_fmt(u, 2)}" if isinstance(u, (int, float)) else "") + " in closed loop")
        if isinstance(u, (int, float)) and abs(fit[p] - v) > u:
            apart.append(p)
    if not rows:
        return []
    verdict = (f"they differ by more than the closed loop's interval in {', '.join(apart)}: the "
               "law's form and the data disagree somewhere and its parameters trade against the "
               "corrections (above: where it disagrees); neither estimate is the truth's for certain"
               if apart else "they agree within the closed loop's interval")
    return [f"Its two estimates: {'; '.join(rows)}; {verdict}.", ""]


def _md_stand_in(entry: dict, fits: dict, replay: dict) -> list[str]:
    """A named effect's closed-loop runner-up (the effect that stands in for it best) seen on
    the same missing-torque map: the share it explains here, or why it is not judged."""
    other = entry.get("runner_up")
    if not other or "+" in other or other.startswith("("):
        return []
    head = f"Its runner-up in the closed loop, **{other}**,"
    if other in fits:
        return [f"{head} explains {100 * fits[other]['explained']:.1f} % of the missing torque here "
                f"({_md_values(fits[other])}).", ""]
    if other in replay:
        return [f"{head} cannot be judged by equation error ({replay[other]}).", ""]
    return [f"{head} is not among the {len(fits)} best laws here.", ""]


def _md_values(f: dict) -> str:
    """A candidate's fitted values with units and the model's own values; a value on its
    parameter's bound is marked (the law wanted more than its range allows)."""
    def unit(p):
        return "" if f["units"][p] in ("", "-") else " " + f["units"][p]
    return ", ".join(f"{p} = {_fmt(v, 4)}{unit(p)} (model {_fmt(f['nominal'][p], 4)}"
                     + ("; at its bound" if p in f.get("at_bound", ()) else "") + ")"
                     for p, v in f["parameters"].items())


def _md_disagrees(f: dict, most: int = 2, table: bool = True) -> str:
    """The ``most`` largest disagreements of a candidate (:func:`discrepancy.shape.disagreements`
    lines, which start with the bin's mean in mN*m), or that none exceeds the noise; ``|``
    escaped for a table cell."""
    lines = sorted(f["disagreements"], key=lambda s: -abs(float(s.split()[0])))
    if not lines:
        return "nowhere beyond the noise"
    more = len(lines) - most
    text = "; ".join(lines[:most]) + (f" (and {more} smaller)" if more > 0 else "")
    return text.replace("|", "\\|") if table else text


def patched_contents(rep: dict) -> str:
    """What ``model.xml`` holds beside the nominal, in words: the refitted constants and the
    named effects, both at their all-runs fit."""
    parts = []
    if rep.get("corrections"):
        parts.append(f"{len(rep['corrections'])} of the nominal's constants refitted")
    if rep["effects"][0]["name"] != "none":
        parts.append("the named effects added")
    if not parts:
        return "the nominal, unchanged: nothing refitted, no effect named"
    return "the nominal with " + " and ".join(parts) + ", at their all-runs fit; its header lists each value"


def _md_sampling(rep: dict) -> list[str]:
    """The measured runs as they were logged: period, jitter, longest gap, the device's loop."""
    rows = rep.get("sampling") or []
    if not rows:
        return []
    L = ["## The runs as logged", "",
         "| run | samples | period [ms] | jitter (std) [ms] | longest gap [ms] | loop period [ms] | torque off |",
         "|---|---|---|---|---|---|---|"]
    for r in rows:
        L.append(f"| {r['run']} | {r['samples']} | {r['period_s'] * 1e3:.3g} | {r['jitter_s'] * 1e3:.2g} | "
                 f"{r['max_gap_s'] * 1e3:.3g} | {r['control_period_s'] * 1e3:.3g} | {r['torque_off_share']:.0%} |")
    L += ["", "The replay runs the device's loop at the loop period, holds the reference (and "
          "the torque switch) between log samples and reads the model's angle at the logged "
          "times.", ""]
    guessed = [r["run"] for r in rows if not r.get("control_period_given", True)]
    if guessed:
        L += [f"{len(guessed)} run(s) give no `control_period_s` in their metadata ({', '.join(guessed)}): "
              "their loop period is the sample period.", ""]
    return L


#: What report.md and the command say when the model handed back predicts the held-out samples
#: worse than the user's nominal did (the corrections or the named effects do not generalise).
WORSE_THAN_NOMINAL = ("**Warning: the corrected model predicts the held-out samples worse than your "
                      "nominal did.** Its corrections and effects fit the training samples but do not "
                      "carry over: keep your nominal model, and read the missing-torque maps for what "
                      "it lacks.")


def worse_than_nominal(rep: dict) -> bool:
    """Whether the model handed back (``gap_after``) is worse held out than the nominal (``gap_before``)."""
    return rep["gap_after"] > rep["gap_before"]


def _md_named(rep: dict) -> list[str]:
    """The named effects, the gap before and after, the effects' table, ties, an unexplained gap."""
    L = []
    eff = rep["effects"]
    if eff[0]["name"] == "none":
        best = (f" (best candidate {eff[0]['best_candidate']} removes {eff[0]['best_share']:.0%} of "
                "the held-out gap)" if eff[0]["best_candidate"] is not None else "")
        L += [f"**Named effect: none.** {eff[0]['reason']}{best}.", ""]
    else:
        L += ["**Named effect(s): " + ", ".join(e["name"] for e in eff) + ".**", ""]
    L += [f"Gap (held-out RMS replay error): **{_fmt(rep['gap_before'])} rad before -> "
          f"{_fmt(rep['gap_after'])} rad after** (x{_fmt(rep['shrink_factor'], 3)}); measurement noise "
          f"floor {_fmt(rep['noise_floor_rad'])} rad; unexplained share of the excess over noise "
          f"{rep['unexplained_share']:.0%}.", ""]
    if worse_than_nominal(rep):
        L += [WORSE_THAN_NOMINAL, ""]
    if eff[0]["name"] != "none":
        L += ["| effect | parameter | nominal | fitted | ± (95 %) | runner-up | margin | confidence |",
              "|---|---|---|---|---|---|---|---|"]
        for e in eff:
            for p, v in e["parameters"].items():
                L.append(f"| {e['name']} | {p} [{e['units'][p]}] | {_fmt(e['nominal'][p], 4)} | {_fmt(v, 4)} | "
                         f"{_fmt(e['uncertainty'][p], 2)} | {e['runner_up'] or '(without it)'} | {_fmt(e['margin'], 2)} | "
                         f"{e['confidence']} |")
        L.append("")
        for e in eff:
            if "separating_experiment" in e:
                L += [f"*{e['name']} and {e['indistinguishable_from']} explain the data equally well.* "
                      f"To separate them: {e['separating_experiment']}.", ""]
    if rep["unexplained"] and eff[0]["name"] == "none":
        L += ["**The gap is unexplained**: it stands at "
              f"{rep['gap_before'] / max(rep['noise_floor_rad'], 1e-300):.0f} x the measurement noise "
              "floor, but no candidate of the library (alone or, when searched, in pairs) removes a "
              "clear share of it. `none` here does NOT mean the model is fine: the data hold an effect "
              "outside the library (or a combination it cannot fit). See where the gap sits below.", ""]
    elif rep["unexplained"]:
        L += ["**Part of the gap is not explained by the library** (the remaining error stays well "
              "above the noise floor): the named effect is the nearest candidate, not necessarily the "
              "physical cause.", ""]
    return L


def _md_corrections(rep: dict) -> list[str]:
    """The nominal's constants re-estimated (apart from the named effects)."""
    rows = rep.get("corrections") or []
    if not rows:
        return []
    L = ["## Corrections to the nominal", "",
         "Constants the nominal already had, re-estimated jointly with every candidate (not named "
         "effects: the model had them). A named effect had to beat this corrected nominal held out.", "",
         "| parameter | your value | fitted | ± (95 %) | x your value | checked |", "|---|---|---|---|---|---|"]
    for c in rows:
        ratio = "-" if c["ratio_to_nominal"] is None else f"{c['ratio_to_nominal']:.3g}"
        L.append(f"| {c['effect']}: {c['parameter']} [{c['unit']}] | {_fmt(c['nominal'], 4)} | "
                 f"{_fmt(c['fitted'], 4)} | {_fmt(c['half_width_95'], 2)} | {ratio} | "
                 f"{correction_note(c)} |")
    factor = rows[0].get("plausible_factor", 2.0)
    L += ["", f"*checked* says what was tested, and nothing more: that the fitted value lies "
          f"within a factor {factor:g} of your value and off its parameter's bounds. It does not say "
          "the fitted value is right; the ± column is the interval the data support.", ""]
    mixed = [(c, m) for c in rows for m in c.get("confounded_with", [])]
    if mixed:
        pairs = "; ".join(f"{c['effect']}: {c['parameter']} with {m['effect']}: {m['parameter']} "
                          + (f"together (multiple correlation {m['correlation']:+.2f})" if "+" in m["parameter"]
                             else f"(correlation {m['correlation']:+.2f})") for c, m in mixed)
        L += [f"**Confounded with a named law:** {pairs}. The fit trades one for the other (|correlation| "
              f"of at least {CONFOUNDED_CORRELATION:g} at the all-runs optimum), so the data do not measure "
              "these constants apart from the named effect: read the correction and the effect together, "
              "not the corrected constant as a measurement of your robot's.", ""]
    return L


def correction_note(c: dict) -> str:
    """The *checked* column of one correction: its change from the user's value, whether
    that stays within the factor checked and off the bounds, and its interval relative to the
    fitted value."""
    factor = c.get("plausible_factor", 2.0)
    hw, fitted = c["half_width_95"], c["fitted"]
    interval = (f"interval ±{100 * hw / abs(fitted):.0f} % of the fitted value"
                if fitted and math.isfinite(hw) else f"interval ±{_fmt(hw, 2)}")
    if c.get("confounded_with"):
        interval += "; confounded with " + ", ".join(m["effect"] for m in c["confounded_with"])
    if c.get("warning"):
        return f"{c['warning']}; {interval}"
    if c["ratio_to_nominal"] is None:
        return f"your value is 0 (no factor checked); off its bounds; {interval}"
    return (f"change {100 * (c['ratio_to_nominal'] - 1):+.0f} % of your value (within the factor "
            f"{factor:g} checked), off its bounds; {interval}")


def _md_gaps(rep: dict) -> list[str]:
    """The held-out gaps under both fold schemes."""
    gaps = rep.get("gaps") or {}
    if not gaps:
        return []
    verdict = rep["settings"].get("fold_scheme", "runs")
    L = ["## Held-out gaps under both fold schemes", "",
         "On the samples the fits use. *blocked*: every run cut into time blocks, each fold fitted on "
         "the other blocks of every run; *runs*: whole runs held out. The verdict used "
         f"**{verdict}** folds.", "",
         "| folds | nominal [rad] | corrected nominal [rad] | + named effects [rad] | share the effects remove |",
         "|---|---|---|---|---|"]
    for sch, g in gaps.items():
        L.append(f"| {sch} | {_fmt(g['nominal'])} | {_fmt(g['corrected'])} | {_fmt(g['after'])} | "
                 f"{g['share_removed_by_effects']:+.2f} |")
    return L + [""]


def _md_where(rep: dict) -> list[str]:
    """Where the gap lives before, in words; the nearest candidates of an unexplained gap."""
    L = []
    where = rep.get("where", [])
    if where:
        L += ["## Where the gap lives (before)", ""]
        L += [f"- {w['text']}" for w in where]
        L.append("")
    elif rep["gap_before"] > 0:
        L += ["## Where the gap lives (before)", "", "- spread evenly over the regimes mapped "
              "(speed, reversals, position, command, frequency, amplitude, time): no regime stands "
              "out.", ""]
    note = command_note(rep["localisation"]["before"]["regimes"])
    if note and rep["gap_before"] > 0:
        L += [note[0].upper() + note[1:] + ".", ""]
    near = rep.get("nearest_candidates", [])
    if near and rep["unexplained"]:
        L += ["Nearest library candidates (**low confidence**: they do not explain the gap): "
              + ", ".join(f"{c['name']} (removes {c['share']:.0%})" for c in near) + ".", ""]
    return L


def _md_candidates(rep: dict) -> list[str]:
    """Every round's candidates: held-out gap, share removed, how the folds were fitted."""
    scheme = rep["settings"].get("fold_scheme", "runs")
    L = [f"## Candidates (held-out, {scheme} folds)", ""]
    for i, rnd in enumerate(rep["candidates"]):
        L += [f"Round {i + 1} (start gap {_fmt(rep['rounds'][i]['gap_start_rad'])} rad):", "",
              "| candidate | held-out gap [rad] | share removed | folds | unstable replays | parameters |",
              "|---|---|---|---|---|---|"]
        for c in rnd:
            ps = ", ".join(f"{k}={_fmt(v, 4)}" for k, v in c["parameters"].items())
            if c["method"] == "prescreen":  # not among the best on the short records
                L.append(f"| {c['name']} | (short records {_fmt(c['prescreen_gap_rad'])}) | - | "
                         f"prescreen | {c.get('unstable_replays', 0)} | {ps} |")
                continue
            if c["method"] == "equation-error":  # not among the best by equation error: not replayed
                L.append(f"| {c['name']} | (not replayed) | - | equation error | 0 | {ps} |")
                continue
            L.append(f"| {c['name']} | {_fmt(c['heldout_gap_rad'])} | {c['share']:+.2f} | {c['method']} | "
                     f"{c.get('unstable_replays', 0)} | {ps} |")
        L.append("")
        var = rep["rounds"][i].get("variants") if i < len(rep["rounds"]) else None
        if var:
            gaps = ", ".join(f"{k} {_fmt(g['heldout_gap_rad'])} rad" for k, g in var.items() if k != "chosen")
            L += [f"The friction family's nested variants, both refitted per fold: {gaps}; kept "
                  f"**{var['chosen']}** (the simplest the held-out runs cannot tell from the best: "
                  "within one paired standard error or 10 % of it).", ""]
    return L


def _md_worst(rep: dict) -> list[str]:
    """Where the model was worst before, and the same places after; the command lag; the worst
    runs."""
    lb, la = rep["localisation"]["before"], rep["localisation"]["after"]
    L = ["## Where the model was worst, before and after", "",
         "| where | before [rad] | after [rad] |", "|---|---|---|"]
    for w in lb["worst"]:
        where = w["where"]
        after = _lookup(la, where)
        L.append(f"| {where} | {_fmt(w['rms_rad'])} | {_fmt(after)} |")
    L.append(f"| overall | {_fmt(rep['gap_before'])} | {_fmt(rep['gap_after'])} |")
    L += ["", f"Residual vs command: {lag_text(lb['command_lag'])}.", ""]
    L += ["Worst runs before: " + ", ".join(f"{d['run']} ({_fmt(d['rms_rad'])})" for d in lb["per_run"][:5]), ""]
    return L


def _lookup(loc, where: str):
    if where.startswith("regime "):
        return loc["regimes"]["bins"].get(where[7:], {}).get("rms_rad")
    if where.startswith("sine "):
        return loc["per_frequency"].get(where[5:].split()[0])
    if where.startswith("amplitude "):
        return loc["per_amplitude"].get(where[10:].split()[0])
    if where.startswith("window "):
        t0 = float(where.split()[1].split("-")[0])
        for w in loc["time_windows"]:
            if abs(w["t_start_s"] - t0) < 1e-9:
                return w["rms_rad"]
    return None


def model_xml(outcome) -> str:
    """``model.xml``: the patched model, headed by a comment that lists what was refitted and
    what was added (:func:`model_header`) and one on what it needs beyond plain MuJoCo
    (:func:`_runtime_lines`)."""
    spec = _declared_spec(outcome)
    return (model_header(outcome.report) + "<!--\n" + "\n".join(_runtime_lines(outcome, spec))
            + "\n-->\n" + spec.to_xml())


def model_header(rep: dict) -> str:
    """The comment heading ``model.xml``: each refitted constant of the nominal (your value ->
    fitted) and each named effect with its values (nominal -> fitted), all at their all-runs
    fit."""
    L = ["<!-- Patched by `omni discrepancy` (written with MjSpec.to_xml; the nominal file's comments "
         "are not kept)."]
    rows = rep.get("corrections") or []
    if rows:
        L.append("Refitted constants of the nominal (your value -> fitted, all-runs fit):")
        L += [f"  {c['effect']}: {c['parameter']} [{c['unit']}] {c['nominal']:.6g} -> {c['fitted']:.6g}"
              for c in rows]
    eff = rep["effects"]
    if eff[0]["name"] == "none":
        L.append("Effects added: none (no effect named).")
    else:
        L.append("Effects added (named; nominal -> fitted, all-runs fit):")
        L += [f"  {e['name']}: " + ", ".join(f"{k} [{e['units'][k]}] {e['nominal'][k]:.6g} -> {v:.6g}"
                                            for k, v in e["parameters"].items()) for e in eff]
    if not rows and eff[0]["name"] == "none":
        L.append("Nothing refitted and nothing added: the model is the nominal.")
    L.append("See report.json for the uncertainties. -->")
    return "\n".join(L) + "\n"


def _declared_spec(outcome):
    """The patched spec with its drive laws' control period and target declared for the
    runtime (:func:`omni_sim.runtime.declare`; unchanged when it needs none)."""
    st = outcome.report["settings"]
    return runtime.declare(outcome.spec, st["joint"], st["actuator"], outcome.runs[0].period)


def _not_carried(outcome) -> list[str]:
    """Named effects ``model.xml`` does not hold: not a library effect (every library effect
    is native MJCF or a drive law of :mod:`omni_sim.runtime`, tests/test_runtime.py)."""
    return [e["name"] for e in outcome.report["effects"] if e["name"] not in ("none", *fx.NAMES)]


def _runtime_lines(outcome, spec) -> list[str]:
    """``model.xml``'s lines on what it needs beyond plain MuJoCo
    (:func:`omni_sim.runtime.runtime_note`), and any named effect it does not carry."""
    lines = runtime.runtime_note(spec)[1]
    lost = _not_carried(outcome)
    if lost:
        lines.append(", ".join(lost) + ": not carried by model.xml (neither MJCF nor a runtime law); "
                     "report.json holds its fitted values.")
    return lines


def _md_runtime(outcome) -> str:
    """report.md's sentence on what ``model.xml`` needs beyond plain MuJoCo."""
    laws = ", ".join(runtime.needed_laws(outcome.spec))
    if laws:
        text = (f"It needs the runtime `{runtime.RUNTIME}` for {laws} (a drive law MuJoCo cannot "
                "express; its header says how to call it): stepped with `mujoco.mj_step` alone it "
                "is not the named model. ")
    else:
        text = "It runs in plain MuJoCo, no runtime. "
    lost = _not_carried(outcome)
    if lost:
        text += ", ".join(lost) + " is not carried by model.xml (report.json holds its values). "
    return text


def _md_exported(rep: dict) -> str:
    """report.md's sentence on the exported model's own gap (``report.json``'s
    ``exported_model``; nothing when the report has none)."""
    ex = rep.get("exported_model")
    if not ex:
        return ""
    how = f"plain MuJoCo with `{ex['runtime']}`" if ex["runtime"] else "plain MuJoCo"
    return (f"Replayed on every run ({how} reproduces it), `model.xml` has a gap of "
            f"{_fmt(ex['gap_rad'])} rad: in-sample, the all-runs fit on the runs it was fitted to "
            f"(the held-out {_fmt(rep['gap_after'])} rad is the verdict). ")


def write(outcome, folder: Path, title: str = "Model discrepancy report", intro: str = "") -> None:
    folder = Path(folder)
    figs = figures(outcome, folder)
    (folder / "report.json").write_text(json.dumps(_jsonable(outcome.report), indent=2) + "\n")
    (folder / "report.md").write_text(markdown(outcome, figs, title, intro))
    (folder / "model.xml").write_text(model_xml(outcome))
