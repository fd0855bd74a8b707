"""The figures the documentation's pages quote in their prose, rendered from their records as
the phrases that must appear in the page named with them (:func:`claims`), and the record
passages whose every figure must be checked (:func:`unchecked_figures`).  Checked by
:func:`tools.docs_tables.check`; the module docstring there says how."""

from __future__ import annotations

import math
import re

from identification import paper

from tools.docs_sources import (PAGES, CLOSE_STEP_REL, load_sources, _s, _m, _sci, _mrad, _beta_tilde_65_90,
                                _cal_detail, _count, _norm)


# -- figures quoted in the prose and in the hand-written tables ----------------------------------
# One function per page (two for docs/method/friction-families.md): each returns the page's
# phrases, a flat list, one entry per quoted figure, read beside the page it checks.
def _values(rec: dict) -> dict:
    """A calibration record's parameter values by name."""
    return {k: p["value"] for k, p in rec["parameters"].items()}


def _lugre_values(cal: dict) -> tuple[dict, float, float]:
    """A calibration record's parameter values by name, and its LuGre Fc and Fs (N m)."""
    v = _values(cal)
    return v, v["lugre_friction"], v["lugre_friction"] * v["stribeck_ratio"]


def _resonance_by_frequency(cal: dict) -> tuple[dict, dict]:
    """The calibration's resonance detail, and frequency (Hz) -> (α, C_data, β̃_data)."""
    d = _cal_detail(cal)
    return d, dict(zip(d["frequency_hz"], zip(d["alpha"], d["C_data"], d["beta_tilde_data"])))


def _matched_figures(src: dict) -> dict:
    """The matched calibration's step figures against the real Omni's (Table 11's linear column),
    and the spread of Table 3's worst coefficient over the search's close lugre candidates."""
    from omni_studies.calibration import STEP_BAND_REL

    lug = src["comparison"]["families"]["lugre"]
    mst = src["matched_summary"]["step"]
    cm = src["cal_matched"]["achieved"]
    paper_med = lug["step_linear_vs_table11"]["paper_median_over_poses_rad"]
    close = [max(abs(r["figures"]["table3_C_worst_rel"]), abs(r["figures"]["table3_beta_tilde_worst_rel"]))
             for r in src["search"]["candidates"] if r.get("ok") and r["family"] == "lugre"
             and abs(r["figures"]["step_median_rad"] / paper_med - 1) <= CLOSE_STEP_REL]
    return {"paper_step_rad": paper_med, "step_mrad": 1e3 * cm["step_median_rad"],
            "step_p90_rad": cm["step_p90_median_rad"], "poses": cm["poses_within_40pct"],
            "C": 100 * cm["table3_C_worst_rel"], "beta": 100 * cm["table3_beta_tilde_worst_rel"],
            "angle": cm["angle_worst_deg"], "n_close": len(close), "close_lo": 100 * min(close),
            "close_hi": 100 * max(close), "n_poses": mst["n_poses"], "band": 100 * STEP_BAND_REL,
            "ratio": paper_med / lug["step_linear_vs_table11"]["median_over_poses_rad"]}


def results_claims(src: dict) -> list[str]:
    """docs/studies/reproduce/results.md's quoted figures (``omni reproduce``)."""
    s, comp = src["summary"], src["comparison"]
    st = s["step"]
    whole, after = st["windows"]["whole_record"], st["windows"]["after_edges"]
    p11 = st["paper_table11"]
    errs = [r["rel_error"] for r in s["inertia"]["poses"]]
    lug, cou = comp["families"]["lugre"], comp["families"]["coulomb"]
    _, fd = _resonance_by_frequency(src["cal"])
    bt = _beta_tilde_65_90(src["lugre_params"])
    return [
        f"the same fit is off by {_m(100 * min(errs))} to {_s(100 * max(errs))} %",
        f"(the coulomb family's worst error is {_s(100 * cou['inertia']['worst_signed_rel_error'])} %)",
        f"ratio of means {whole['ratio_of_means']:.2f} (the paper's {p11['ratio_of_means']:.2f}, its "
        f"\"{paper.PAPER_STEP_RATIO}×\"), ratio of medians {whole['ratio_of_medians']:.2f} (the "
        f"paper's {p11['ratio_of_medians']:.2f})",
        f"α's whole-record p90 error is twice the linear model's ({_mrad(whole['p90_abs_error_alpha_rad'])} "
        f"vs {_mrad(whole['p90_abs_error_linear_rad'])} mrad, median over runs; α better by the p90 at "
        f"{whole['alpha_better_poses_p90']} of {whole['n_poses']} poses), where the paper's α halved "
        f"it ({_mrad(p11['p90_abs_error_alpha_rad'])} vs {_mrad(p11['p90_abs_error_linear_rad'])} mrad)",
        f"the linear model is better ({after['ratio_of_medians']:.2f}; α better at "
        f"{after['alpha_better_poses']} of {after['n_poses']} poses)",
        f"(Fig. 10: {bt['at_0']:.0f} at α = 0, {bt['at_fitted']:.0f} at α = {bt['alpha_fitted']:.0f}, "
        f"the highest α fitted at 65/90, ~{bt['at_edge']:.0f} at the figure's edge, α = "
        f"{bt['alpha_edge']:.0f}; paper {paper.table10()['beta_tilde_0']:.0f} → "
        f"{paper.table10()['beta_tilde_1']:.0f} from α = 0 to 250)",
        f"(C_data = {fd[2.0][1]:.0f} 1/s, β̃_data = {fd[2.0][2]:.0f} at 2 Hz, 65/90)",
        f"breakpoints ({', '.join(f'{a:.3g}' for a in lug['alpha_breaks'])} V²/s²)",
        f"cycles or creeps on {100 * s['alpha_simulation']['steps_solved_by_bisection'] / s['alpha_simulation']['steps']:.1f} % of the steps",
    ]


def readme_claims(src: dict) -> list[str]:
    """README.md's quoted figures (the calibrated virtual Omni against the paper)."""
    comp = src["comparison"]
    lug, mat = comp["families"]["lugre"], comp["families"]["matched"]
    mt = _matched_figures(src)
    return [
        f"{mt['ratio']:.1f}× better than the real Omni's (Table 11's linear column: "
        f"{_mrad(lug['step_linear_vs_table11']['median_over_poses_rad'], 2)} against "
        f"{_mrad(mt['paper_step_rad'])} mrad)",
        f"calibrated {len(src['search']['candidates'])} candidate effects",
        f"linear column met ({mt['step_mrad']:.1f} mrad, {mt['poses']} of {mt['n_poses']} poses within "
        f"{mt['band']:.0f} %) with "
        f"Table 3's C_linear {abs(mt['C']):.1f} % off",
        f"(ratio of medians linear/α {mat['step']['ratio_of_medians_whole_record']:.2f}, the paper's "
        f"{comp['paper']['step']['ratio_of_medians']:.2f})",
    ]


def calibration_claims(src: dict) -> list[str]:
    """docs/studies/calibration/calibration.md's quoted figures (``scripts/calibrate.py``)."""
    comp, cal = src["comparison"], src["cal"]
    lug, mat = comp["families"]["lugre"], comp["families"]["matched"]
    mst = src["matched_summary"]["step"]
    hs, wt = src["cal_hard_stick"]["achieved"], src["cal_weighted"]["achieved"]
    v, fc, fs = _lugre_values(cal)
    d, fd = _resonance_by_frequency(cal)
    mt = _matched_figures(src)
    return [
        f"each of the {mt['n_close']} lugre-footed candidates whose step error comes within "
        f"{100 * CLOSE_STEP_REL:.0f} % of the "
        f"real Omni's misses Table 3, its worst coefficient {mt['close_lo']:.1f}–{mt['close_hi']:.1f} % off",
        f"(median {mt['step_mrad']:.1f} mrad against {_mrad(mt['paper_step_rad'])}, p90 "
        f"{_mrad(mt['step_p90_rad'])} against {_mrad(comp['paper']['step']['p90_abs_error_linear_rad'])} mrad, "
        f"{mt['poses']}/{mt['n_poses']} poses within {mt['band']:.0f} %) with Table 3's C_linear at "
        f"{_m(mt['C'])} % at its worst pose "
        f"(β̃ {_m(mt['beta'])} %, angles {mt['angle']:.2f}°)",
        f"{_mrad(mst['median_abs_error_linear_rad'], 2)} → {_mrad(mst['median_abs_error_alpha_rad'], 2)} mrad",
        f"ratio of medians {mat['step']['ratio_of_medians_whole_record']:.2f} against "
        f"{comp['paper']['step']['ratio_of_medians']:.2f}, of means {mat['step']['ratio_of_means_whole_record']:.2f} "
        f"against {comp['paper']['step']['ratio_of_means']:.2f}",
        f"p90 {_mrad(mat['step']['p90_abs_error_linear_rad'])} → {_mrad(mat['step']['p90_abs_error_alpha_rad'])} mrad",
        f"phase p90 {mat['sine']['phase_p90_linear_deg']:.1f}° → {mat['sine']['phase_p90_alpha_deg']:.1f}°",
        f"magnitude p90 {mat['sine']['magnitude_p90_linear']:.3f} → {mat['sine']['magnitude_p90_alpha']:.3f}",
        f"errs by up to {_s(100 * mat['inertia']['worst_signed_rel_error'])} % against",
        f"Calibrated values: link masses {1e3 * v['m_upper_arm']:.0f} g, {1e3 * v['m_forearm']:.0f} g, "
        f"stylus {1e3 * v['m_stylus']:.0f} g",
        f"turret {_sci(v['I_turret'])} kg m², yaw viscous damping {_sci(v['yaw_damping'])} N m s/rad, "
        f"LuGre Fc {1e3 * fc:.1f} mN m, Fs {1e3 * fs:.1f} mN m, vs {v['stribeck_speed']:.2f} rad/s, "
        f"σ0 {v['lugre_stiffness']:.2f} N m/rad, arm servo gains {v['shoulder_kp']:.2f} and "
        f"{v['elbow_kp']:.2f} N m/rad, A_r = {v['sine_amplitude_rad']:.3f} rad",
        f"(Fs/σ0 ≈ {1e3 * fs / v['lugre_stiffness']:.0f} mrad)",
        f"fall ({cal['achieved']['C_alpha_fall_65_90']:.1f}×, the calibration's identification; "
        f"{lug['C_alpha_fall']:.2f}× in the reproduction's) overshoots the paper's "
        f"{comp['paper']['C_alpha_fall']:.1f}×",
        f"coefficients at 65/90 are large ({fd[1.5][1]:.0f}–{fd[2.0][1]:.0f} 1/s)",
        f"the model's α at resonance stays at {max(d['alpha']):.0f}",
        f"meets Table 3 (C_linear within {100 * hs['max_rel_error_C_linear']:.1f} %, β̃_linear within "
        f"{100 * hs['max_rel_error_beta_tilde_linear']:.1f} %) but leaves the C(α) fall at "
        f"{hs['C_alpha_fall_65_90']:.1f}×",
        f"reaches only a fall of {wt['C_alpha_fall_65_90']:.2f}× and loses Table 3 (C_linear "
        f"{100 * wt['max_rel_error_C_linear']:.0f} %, β̃_linear {100 * wt['max_rel_error_beta_tilde_linear']:.0f} % off",
    ]


def model_claims(src: dict) -> list[str]:
    """docs/reference/model.md's quoted figures (the calibrated model's parameters)."""
    v, fc, fs = _lugre_values(src["cal"])
    return [
        f"Fc {1e3 * fc:.1f} mN m, Fs {1e3 * fs:.1f} mN m, vs {v['stribeck_speed']:.2f} rad/s, σ0 "
        f"{v['lugre_stiffness']:.2f} N m/rad",
        f"| yaw viscous damping | {_sci(v['yaw_damping'])} N m s/rad |",
        f"elastic up to Fs/σ0 ≈ {1e3 * fs / v['lugre_stiffness']:.0f} mrad",
    ]


def errata_claims(src: dict) -> list[str]:
    """docs/method/paper-errata.md's quoted figures (the paper's Table 11)."""
    p11 = src["summary"]["step"]["paper_table11"]
    return [
        f"the paper's \"{paper.PAPER_STEP_RATIO}×\" is a ratio of means ({p11['ratio_of_means']:.2f}); its "
        f"ratio of medians is {p11['ratio_of_medians']:.2f}",
    ]


def friction_calibration_claims(src: dict) -> list[str]:
    """docs/method/friction-families.md's quoted figures of the calibrated families (the first
    part of the page's phrases; :func:`friction_study_claims` the rest)."""
    comp = src["comparison"]
    lug, cou = comp["families"]["lugre"], comp["families"]["coulomb"]
    mat = comp["families"]["matched"]
    mst = src["matched_summary"]["step"]
    paper_med = lug["step_linear_vs_table11"]["paper_median_over_poses_rad"]
    v, fc, fs = _lugre_values(src["cal"])
    vc = _values(src["cal_coulomb"])
    hs = src["cal_hard_stick"]["achieved"]
    af = src["cal_coulomb_all_free"]
    afa, afv = af["achieved"], _values(af)
    beta_bar = src["cal"]["fixed"]["beta_bar_N_m_per_V"]
    kp = paper.kp()
    return [
        f"({_mrad(mat['step_linear_vs_table11']['median_over_poses_rad'], 2)} mrad against {_mrad(paper_med)})",
        f"steps linear → α {_mrad(mst['median_abs_error_linear_rad'], 2)} → "
        f"{_mrad(mst['median_abs_error_alpha_rad'], 2)} mrad by the medians (ratio "
        f"{mat['step']['ratio_of_medians_whole_record']:.2f} against the paper's "
        f"{comp['paper']['step']['ratio_of_medians']:.2f}; of means {mat['step']['ratio_of_means_whole_record']:.2f} "
        f"against {comp['paper']['step']['ratio_of_means']:.2f})",
        f"Fc {1e3 * fc:.1f} mN m, Fs {1e3 * fs:.1f} mN m, vs {v['stribeck_speed']:.2f} rad/s, σ0 "
        f"{v['lugre_stiffness']:.2f} N m/rad, σ1 0; viscous {_sci(v['yaw_damping'])} N m s/rad",
        f"joint `frictionloss` {1e3 * vc['yaw_frictionloss']:.2f} mN m; viscous "
        f"{_sci(vc['yaw_damping'], 2)} N m s/rad",
        f"drove the Coulomb level down to {1e3 * vc['yaw_frictionloss']:.2f} mN m",
        f"{af['cost_before']:.1f} → {af['cost_after']:.1f} (lugre's calibration: {src['cal']['cost_after']:.1f}), Table 3 at "
        f"{100 * afa['max_rel_error_C_linear']:.1f} %/{100 * afa['max_rel_error_beta_tilde_linear']:.1f} %, "
        f"angles {afa['max_angle_error_deg']:.2f}°, resonance {afa['resonance_65_90_hz']:.2f} Hz, frictionloss "
        f"{1e3 * afv['yaw_frictionloss']:.1f} mN m, damping {_sci(afv['yaw_damping'])} N m s/rad, A_r = "
        f"{afv['sine_amplitude_rad']:.3f} rad",
        f"a fall of C(α) of only {afa['C_alpha_fall_65_90']:.2f}×",
        f"{100 * hs['max_rel_error_C_linear']:.1f} %/{100 * hs['max_rel_error_beta_tilde_linear']:.1f} %, "
        f"fall {hs['C_alpha_fall_65_90']:.1f}×",
        f"±Fc/(kp β̄) = ±{1e3 * vc['yaw_frictionloss'] / (kp * beta_bar):.1f} mrad",
        f"the family's fall is {cou['C_alpha_fall']:.1f}×",
        f"(ratio of medians {cou['step']['ratio_of_medians_whole_record']:.2f}; p90 "
        f"{_mrad(cou['step']['p90_abs_error_alpha_rad'])} vs {_mrad(cou['step']['p90_abs_error_linear_rad'])} "
        f"mrad, α lower at {cou['step']['alpha_better_poses_p90']}/{cou['step']['n_poses']} poses)",
        ("but loses them by the p90 and in the first second after each edge, at every pose"
         if lug["step"]["alpha_better_poses_p90"] == 0 and lug["step"]["alpha_better_poses_after_edges"] == 0
         else f"α better by the p90 at {lug['step']['alpha_better_poses_p90']}/{lug['step']['n_poses']} "
              f"poses and after the edges at {lug['step']['alpha_better_poses_after_edges']}"),
        f"(ratio of means {lug['step']['ratio_of_means_whole_record']:.2f} against the paper's "
        f"{comp['paper']['step']['ratio_of_means']:.2f}, ratio of medians "
        f"{lug['step']['ratio_of_medians_whole_record']:.2f} against its "
        f"{comp['paper']['step']['ratio_of_medians']:.2f})",
    ]


def friction_study_claims(src: dict) -> list[str]:
    """docs/method/friction-families.md's quoted figures of the friction study's levels
    (``scripts/friction_study.py``)."""
    study = src["study"]["families"]
    sl = {L["scale"]: L for L in study["lugre"]["levels"]}
    sc = {L["scale"]: L for L in study["coulomb"]["levels"]}
    c_ok = [L for L in sc.values() if L["ok"]]
    l_fail = [L for L in sl.values() if not L["ok"]]
    n_nonphys = [int(re.search(r"\((\d+) sine run", L["reason"]).group(1)) for L in l_fail]
    return [
        f"tie (step ratio {sc[0.0]['step_ratio_of_medians_whole_record']:.2f} and "
        f"{sl[0.0]['step_ratio_of_medians_whole_record']:.2f}) and the inertia model is within "
        f"{math.ceil(100 * max(sc[0.0]['inertia_max_rel_error'], sl[0.0]['inertia_max_rel_error'])):.0f} % of MuJoCo",
        f"Coulomb (0 … {1e3 * sc[3.0]['dry_friction']['frictionloss']:.1f} mN m): the α model never "
        f"helps the steps by more than {max(L['step_ratio_of_medians_whole_record'] for L in c_ok):.2f}×",
        f"(magnitude p90 ratio {sc[0.0]['sine_magnitude_p90_linear'] / sc[0.0]['sine_magnitude_p90_alpha']:.1f} → "
        f"{sc[3.0]['sine_magnitude_p90_linear'] / sc[3.0]['sine_magnitude_p90_alpha']:.2f}); the inertia "
        f"bias grows linearly, {_s(100 * sc[0.0]['inertia_worst_signed_rel_error'])} % → "
        f"{_s(100 * sc[3.0]['inertia_worst_signed_rel_error'])} %",
        f"LuGre (0 … {1e3 * sl[1.0]['dry_friction']['lugre_Fc']:.1f} mN m sliding level, the calibrated one)",
        f"({sl[0.0]['step_ratio_of_medians_whole_record']:.2f} → {sl[0.5]['step_ratio_of_medians_whole_record']:.2f} → "
        f"{sl[1.0]['step_ratio_of_medians_whole_record']:.2f} at 0, 0.5, 1×)",
        f"the inertia bias goes {_m(100 * sl[0.5]['inertia_worst_signed_rel_error'])} %, "
        f"{_m(100 * sl[1.0]['inertia_worst_signed_rel_error'])} %",
        f"({min(n_nonphys)} to {max(n_nonphys)} of 81)",
    ]


def performance_claims(src: dict) -> list[str]:
    """docs/reference/performance.md's quoted figures (``omni bench``)."""
    bench = src["bench"]
    srv = bench["discrepancy_servo"]
    stages = srv["physics_steps_per_stage"]
    return [
        f"{bench['reproduce']['ratio_to_raw_rollout']:.1f} ({bench['reproduce']['wall_s']:.2f} s vs "
        f"{bench['reproduce']['raw_rollout_s']:.2f} s, the run in `docs/reference/bench.json`)",
        f"The geared servo with its nominal off: {srv['physics_steps'] / 1e6:.1f} M physics steps, "
        f"{stages['naming'] / 1e6:.1f} M of them naming",
        f"{stages['uncertainty_and_evaluation'] / 1e6:.1f} M the uncertainty, {stages['other_fold_scheme'] / 1e6:.1f} M "
        f"the other fold scheme, {stages['corrections'] / 1e6:.1f} M the corrections; {srv['unstable_replays']} "
        "replays went unstable",
        f"Its time, {srv['wall_s']:.0f} s where",
    ]


def gymnasium_claims(src: dict) -> list[str]:
    """docs/usage/gymnasium.md's quoted figures (``omni bench``'s vector environment)."""
    bench = src["bench"]
    b_vec = bench["vector_env"]
    return [
        f"{b_vec['num_envs']} Omnis at {b_vec['env_steps_per_s'] / 1e3:.0f} k steps/s against "
        f"{b_vec['rollout_ceiling_steps_per_s'] / 1e3:.0f} k steps/s of a raw `mujoco.rollout` of the "
        f"same model on {bench['cores']} threads ({b_vec['ratio_to_raw_rollout']:.2f}×; `omni bench`, "
        f"`docs/reference/bench.json`)",
    ]


#: The functions that render each page's phrases, by page (a key of :data:`PAGES`), in order.
CLAIMS = {"results": (results_claims,), "readme": (readme_claims,),
          "calibration": (calibration_claims,), "model": (model_claims,),
          "errata": (errata_claims,), "friction": (friction_calibration_claims, friction_study_claims),
          "performance": (performance_claims,), "gymnasium": (gymnasium_claims,)}


def claims(src: dict | None = None) -> dict[str, list[str]]:
    """Phrases of the pages that carry a figure from the sources, rendered from them: page
    (a key of :data:`PAGES`) -> its phrases (:data:`CLAIMS`, then :func:`record_claims`)."""
    src = src or load_sources()
    out = {page: [phrase for fn in fns for phrase in fn(src)] for page, fns in CLAIMS.items()}
    for page, found in record_claims(src).items():
        out[page] = out.get(page, []) + found
    return out


# -- the README's record passages: every figure in them checked ------------------------------------
#: The passages of a page whose every figure must be checked against a record (by a phrase of
#: :func:`claims` or by :func:`zwidth_bound`): page -> passages, each the section under a
#: heading (a key that starts with ``#``) or the paragraph that holds the key.
RECORD_PASSAGES = {"readme": ("## Haptic walls", "(examples/real_servo/README.md)")}
#: A figure: a number that is not the tail of a name (``STS3250``, ``OmniWall-v0``) or a count
#: in words.
FIGURE = re.compile(r"(?<![\w.\-−/])[\-−]?\d+(?:\.\d+)?(?:e[\-−]?\d+)?|"
                    r"\b(?:two|three|four|five|six|seven|eight|nine|ten|eleven|twelve)\b", re.I)
def zwidth_row_errors(rec: dict) -> list[float]:
    """|boundary / Colgate's bound - 1| [%] of each damping row of a ``zwidth.json`` that has a
    passive cell and a positive bound, the row B = 0 first."""
    return [100 * abs(k / c - 1) for k, c in zip(rec["boundary_stiffness"], rec["colgate_stiffness"])
            if k is not None and c > 0]


def _digits(x: float, like: str) -> str:
    """``x`` with as many decimals as the figure ``like``."""
    return f"{x:.{len(like.partition('.')[2])}f}"


def zwidth_bound(text: str, rec: dict) -> tuple[list[str], list[tuple[int, int]]]:
    """The sentence of ``text`` that compares the ideal Z-width map with Colgate & Schenkel's
    bound, checked against the map's record (``docs/studies/haptics/zwidth_ideal.json``) whatever its
    wording.  A percentage followed by "up to x b" must be the worst error of the boundary
    against the bound (:func:`zwidth_row_errors`, to the digits printed) over the rows with
    B <= x b, one followed by "at x b" that row's error.  The m others, smallest first, must be
    the worst error over all rows but the last m - 1, ..., all rows but the last, all rows: a
    bound, then its exceptions, which are the rows nearest b.  Any other "x b" must be a row's
    B/b, and a bound "near 0" the last row's, closer to 0 than to the row before's.  Returns
    the problems and the spans of the figures checked (none if no sentence names Colgate)."""
    at = text.find("Colgate")
    if at < 0:
        return [], []
    ends = [m.end() for m in re.finditer(r"[.!?]\s", text[:at])]
    start = ends[-1] if ends else 0
    stop = re.compile(r"[.!?](?:\s|$)").search(text, at)
    sentence = text[start:stop.start() if stop else len(text)]
    errs = zwidth_row_errors(rec)
    rows = [B / rec["physical_damping"] for B, k, c in zip(rec["damping"], rec["boundary_stiffness"],
                                                           rec["colgate_stiffness"]) if k is not None and c > 0]
    problems, spans, free = [], [], []
    for m in re.finditer(r"(\d+(?:\.\d+)?) ?%(?:,? (up to|at) (\d+(?:\.\d+)?) ?b\b)?", sentence):
        if m.group(2) is None:
            free.append(m)
            continue
        x = m.group(3)
        near = [float(_digits(r, x)) for r in rows]  # B/b to the digits printed
        sel = [e for e, r in zip(errs, near) if (r == float(x) if m.group(2) == "at" else r <= float(x))]
        want = _digits(max(sel), m.group(1)) if sel else f"(no row {m.group(2)} {x} b)"
        if m.group(1) != want:
            problems.append(f"Z-width sentence {sentence.strip()!r}: {m.group(1)} % {m.group(2)} {x} b should be "
                            f"{want} % (docs/studies/haptics/zwidth_ideal.json)")
        spans += [(start + m.start(1), start + m.end(1)), (start + m.start(3), start + m.end(3))]
    free.sort(key=lambda m: float(m.group(1)))
    for i, m in enumerate(free):
        n = len(errs) - (len(free) - 1 - i)
        want = _digits(max(errs[:n]), m.group(1)) if n > 0 else "(no such rows)"
        if m.group(1) != want:
            problems.append(f"Z-width sentence {sentence.strip()!r}: {m.group(1)} % should be {want} % "
                            f"(the worst of the first {n} rows of docs/studies/haptics/zwidth_ideal.json)")
        spans.append((start + m.start(1), start + m.end(1)))
    for m in re.finditer(r"(\d+(?:\.\d+)?) ?b\b", sentence):
        if any(a <= start + m.start(1) < b for a, b in spans):
            continue  # an "up to x b" or "at x b" of a percentage, checked above
        if m.group(1) not in {_digits(x, m.group(1)) for x in rows}:
            problems.append(f"Z-width sentence {sentence.strip()!r}: {m.group(1)} b is no row of the map "
                            f"(B/b = {', '.join(f'{x:.2f}' for x in rows)})")
        spans.append((start + m.start(1), start + m.end(1)))
    near = re.search(r"near (0|zero)\b", sentence)
    if near:
        c = [c for k, c in zip(rec["boundary_stiffness"], rec["colgate_stiffness"]) if k is not None and c > 0]
        if not (len(c) > 1 and c[-1] < c[-2] - c[-1]):
            problems.append(f"Z-width sentence {sentence.strip()!r}: the last row's bound is not near 0 "
                            f"(rows' bounds {', '.join(f'{x:.3g}' for x in c[-2:])} N·m/rad)")
        spans.append((start + near.start(1), start + near.end(1)))
    return problems, spans


#: The passages of :data:`RECORD_PASSAGES` that a rule checks besides the phrases:
#: key -> rule(passage text, sources) -> (problems, spans of the figures checked).
PASSAGE_RULES = {"## Haptic walls": lambda text, src: zwidth_bound(text, src["zwidth_ideal"])}


def passage_span(text: str, key: str) -> tuple[int, int] | None:
    """Where in ``text`` the passage that ``key`` names (:data:`RECORD_PASSAGES`) is; None if
    the page has none."""
    if key.startswith("#"):
        i = text.find("\n" + key)
        j = text.find("\n" + key.split()[0] + " ", i + 1)
        return None if i < 0 else (i, j if j >= 0 else len(text))
    starts = [0] + [m.end() for m in re.finditer(r"\n\s*\n", text)]
    ends = [m.start() for m in re.finditer(r"\n\s*\n", text)] + [len(text)]
    return next(((i, j) for i, j in zip(starts, ends) if key in text[i:j]), None)


def _passage(text: str, key: str) -> str | None:
    """The passage of ``text`` that ``key`` names, white space collapsed; None if none."""
    span = passage_span(text, key)
    return None if span is None else _norm(text[span[0]:span[1]])


def mask(text: str) -> str:
    """``text`` with code spans, link targets and comments blanked (the same length)."""
    return re.sub(r"`[^`]*`|\]\([^)]*\)|<!--.*?-->", lambda m: " " * len(m.group()), text)


def unchecked_figures(pages: dict[str, str], src: dict, phrases: dict[str, list[str]]) -> list[str]:
    """Every figure of the :data:`RECORD_PASSAGES` that no phrase of its page and no rule
    checks against a record: one problem per figure (and per passage not found)."""
    problems = []
    for page, keys in RECORD_PASSAGES.items():
        for key in keys:
            text = _passage(pages[page], key)
            if text is None:
                problems.append(f"{PAGES[page]}: no passage {key!r} (scripts/docs_tables.py RECORD_PASSAGES)")
                continue
            bad, spans = PASSAGE_RULES[key](text, src) if key in PASSAGE_RULES else ([], [])
            problems += bad
            for c in map(_norm, phrases.get(page, [])):
                spans += [(m.start(), m.end()) for m in re.finditer(re.escape(c), text)]
            for m in FIGURE.finditer(mask(text)):
                if not any(a <= m.start() and m.end() <= b for a, b in spans):
                    where = text[max(0, m.start() - 40):m.end() + 20]
                    problems.append(f"{PAGES[page]}: figure {m.group()!r} in {where!r} is checked against "
                                    "no record (scripts/docs_tables.py claims)")
    return problems


def record_claims(src: dict) -> dict[str, list[str]]:
    """The phrases of the README's haptics and real-servo passages and of the real-servo
    example's page, rendered from their records (``docs/studies/haptics/zwidth_ideal.json``,
    ``examples/real_servo/report/report.json``, the example's ``model.xml``)."""
    zw, rs = src["zwidth_ideal"], src["real_servo"]
    gap, noise = rs["gap_after"], rs["noise_floor_rad"]
    runs = [r["run"] for r in rs["sampling"]]
    named = [e["name"] for e in rs["effects"] if e["name"] != "none"]
    verdict = (f"names {', '.join(f'`{n}`' for n in named)}" if named else "names nothing") + (
        " and flags the gap unexplained" if rs["unexplained"] else "")
    cands = {c["name"]: c for c in rs["candidates"][0]}
    corr = {c["parameter"]: c for c in rs["corrections"]}
    blocked = rs["gaps"]["blocked"]
    where = {w["where"]: w["ratio"] for w in rs["where"]}
    joint, act = src["real_servo_model"]["joint"], src["real_servo_model"]["actuator"]
    bias = [float(x) for x in act["biasprm"].split()]
    removed = 100 * (1 - blocked["corrected"] / blocked["nominal"])
    best = min((c for n, c in cands.items() if n != "(no new effect)" and c["method"] == "refit"),
               key=lambda c: c["heldout_gap_rad"])
    lf = cands["load_friction"]

    def row(param: str, label: str, digits: int) -> str:
        c = corr[param]
        flag = " (flagged: more than 2x)" if c.get("warning") else ""
        return (f"| {label} | {c['nominal']:.{digits}g} | {c['fitted']:.2g} ± {c['half_width_95']:.2g} | "
                f"{c['ratio_to_nominal']:.2g}{flag} |")

    return {"readme": [
        f"at the {1e-3 / zw['sample_period_s']:g} kHz servo rate",
        f"the nominal's corrections remove {removed:.0f} % of the held-out gap ({_sci(blocked['nominal'], 2)} to "
        f"{_sci(blocked['corrected'], 2)} rad, blocked folds)",
        f"the workflow {verdict} ({gap / noise:.1f} x the noise floor)",
    ], "real_servo": [
        f"| torque per volt (the actuator's gain, `gainprm`) | {float(act['gainprm']):.4f} N·m/V = kt/R |",
        f"| back-EMF (the actuator's velocity bias, `biasprm`) | {-bias[2]:.4f} N·m·s/rad = kt²/R |",
        f"| reflected rotor inertia (`armature`) | {float(joint['armature']):.4f} kg·m² |",
        f"| gearbox viscous friction (in `damping`) | {float(joint['damping']):.4f} N·m·s/rad |",
        f"| dry friction (`frictionloss`) | {float(joint['frictionloss']):.3f} N·m |",
        f"(`gainprm=\"{act['gainprm']}\"`) and its affine velocity bias is the back-EMF "
        f"(`biasprm=\"{act['biasprm']}\"`)",
        f"the joint keeps only the gearbox's {float(joint['damping']):.4f} N·m·s/rad",
        f"on the {_count(len(runs))} converted runs ({sum(r['samples'] for r in rs['sampling'])} logged samples)",
        f"took {rs['timings']['total_s']:.0f} s (`timings.total_s` of `report.json`), "
        f"{rs['timings']['physics_steps'] / 1e6:.1f} M physics steps",
        f"falls from {_sci(blocked['nominal'], 2)} to {_sci(blocked['corrected'], 2)} rad ({removed:.0f} %) under "
        f"blocked folds",
        f"{gap / noise:.1f} x the noise floor ({_sci(noise, 2)} rad) is left",
        row("armature_kgm2", "armature [kg·m²]", 3), row("damping_nms_per_rad", "damping [N·m·s/rad]", 3),
        row("frictionloss_nm", "frictionloss [N·m]", 3), row("gear_nm_per_v", "torque per volt (gear) [-]", 3),
        f"the best, `{best['name']}`, leaves {_sci(best['heldout_gap_rad'], 2)} rad "
        f"({abs(100 * best['share']):.0f} % {'better' if best['share'] > 0 else 'worse'} than the corrected "
        f"nominal's {_sci(blocked['corrected'], 2)})",
        f"ends at `mu_drive` {lf['parameters']['mu_drive']:.2f} and `mu_back` {lf['parameters']['mu_back']:.2f} "
        f"and replays the held-out blocks far worse ({_sci(lf['heldout_gap_rad'], 2)} rad)",
        f"make the held-out gap {rs['gaps']['runs']['corrected'] / blocked['nominal']:.1f}x worse "
        f"({_sci(rs['gaps']['runs']['corrected'], 2)} rad)",
        f"{where['small amplitudes']:.1f} x larger at the smallest amplitude, {where['high speed']:.1f} x at "
        f"high speed and {where['command near its limit']:.1f} x where the command is near its limit",
        f"The gap left is {gap / noise:.1f}x the noise floor",
    ]}
