"""What moves the Z-width boundary: the table of docs/studies/haptics/haptics.md's "What moves the boundary".

Each case is one passivity map of the virtual Omni's yaw (:func:`omni_studies.zwidth.passivity_map`,
the current energy test) on the same 7 x 41 grid: wall damping B from 0 to 0.012 N*m*s/rad in 7
values, wall stiffness K from 0 to 40 N*m/rad in 41 values; the device is
:func:`omni_studies.zwidth.map_device` (physics step T/20, the wall clipped at the drive's limit).
The cases: the ideal device (no dry friction, exact encoder); the lugre and coulomb families with
an exact encoder and with the encoder's quantisation, each at probe speeds 0.02 and 1 rad/s; the
ideal device with 1 and 2 servo periods of loop delay; and the coulomb
exact map at 1 rad/s with a 0.5 s run instead of 1 s.

Recorded per case: the settings, the wall time, b (the yaw's joint damping), the boundary (largest
passive K, :func:`omni_studies.zwidth.boundary`) of every damping row, K_max at B = 0 / 0.004 / 0.008,
Colgate & Schenkel's 2(b - |B|)/T, the passive cells and the energy index, and how many rows are
not monotone (a passive cell beyond a non-passive one along K: rows and cells).

:func:`run_case` (one case: its record entry), :func:`new_record` (the record around the
cases), :func:`colgate_general` (the passivity condition with loop delay).
``scripts/zwidth_study.py`` is the command; :mod:`omni_app.zwidth` formats the table entries and
writes the record (``docs/studies/haptics/study.json``).
"""

from __future__ import annotations

import math
import platform
import time

import numpy as np

from omni_studies import zwidth as zw

#: The grid of the study (the section's): B rows, K columns.
DAMPING = np.linspace(0.0, 0.012, 7)
STIFFNESS = np.linspace(0.0, 40.0, 41)
#: The damping rows the table reports.
TABLE_B = (0.0, 0.004, 0.008)

#: name -> (friction family or "ideal", quantize, probe speed [rad/s], delay [periods][, run
#: length [s], default omni_studies.zwidth.DURATION_S])
CASES = {
    "ideal": ("ideal", False, 0.02, 0),
    "lugre_exact_v002": ("lugre", False, 0.02, 0),
    "lugre_exact_v1": ("lugre", False, 1.0, 0),
    "coulomb_exact_v002": ("coulomb", False, 0.02, 0),
    "coulomb_exact_v1": ("coulomb", False, 1.0, 0),
    "lugre_quantised_v002": ("lugre", True, 0.02, 0),
    "lugre_quantised_v1": ("lugre", True, 1.0, 0),
    "coulomb_quantised_v002": ("coulomb", True, 0.02, 0),
    "coulomb_quantised_v1": ("coulomb", True, 1.0, 0),
    "ideal_delay1": ("ideal", False, 0.02, 1),
    "ideal_delay2": ("ideal", False, 0.02, 2),
    # the run length: the slow probe (16 periods) reverses only ~11 times in a 0.5 s run's window
    "coulomb_exact_v1_0p5s": ("coulomb", False, 1.0, 0, 0.5),
}


def monotonicity(passive: np.ndarray) -> tuple[int, int]:
    """(rows, cells): rows with a passive cell beyond a non-passive one along K, and how many
    such cells in all."""
    rows = cells = 0
    for row in np.asarray(passive, dtype=bool):
        bad = np.flatnonzero(~row)
        if bad.size == 0:
            continue
        beyond = int(row[bad[0]:].sum())
        cells += beyond
        rows += beyond > 0
    return rows, cells


def run_case(name: str, nthread=None) -> dict:
    family, quantize, speed, delay, *rest = CASES[name]
    duration = rest[0] if rest else zw.DURATION_S
    ideal = family == "ideal"
    dev, tlim = zw.map_device(None, None if ideal else family, ideal=ideal)
    b = zw.physical_damping(dev)
    T = dev.control_period_s
    t0 = time.perf_counter()
    res = zw.passivity_map(dev, STIFFNESS, DAMPING, torque_limit=tlim, quantize=quantize,
                           delay=delay, probe_speed=speed, duration_s=duration,
                           nthread=nthread)
    elapsed = time.perf_counter() - t0
    kb = zw.boundary(STIFFNESS, res.index)
    passive = res.passive
    # K_max as the table reports it: the interpolated boundary, and whether the row is passive
    # to the grid's end (">" 40) or not even at K = 0 ("none")
    table = {}
    for Bt in TABLE_B:
        i = int(np.argmin(np.abs(DAMPING - Bt)))
        table[f"{Bt:g}"] = {"boundary": None if not np.isfinite(kb[i]) else float(kb[i]),
                            "whole_row_passive": bool(passive[i].all()),
                            "none_passive": bool(not passive[i].any())}
    rows, cells = monotonicity(passive)
    return {
        "settings": {"friction": family, "ideal": ideal, "quantize": quantize,
                     "probe_speed": speed, "delay_periods": delay,
                     "probe_periods": list(res.probe_periods),
                     "physics_substeps": dev.substeps, "torque_limit": tlim,
                     "duration_s": duration, "settle_fraction": zw.SETTLE_FRACTION,
                     "tolerance": zw.TOL, "start_penetration_rad": zw.START_PENETRATION},
        "elapsed_s": round(elapsed, 2),
        "physical_damping": b, "sample_period_s": T,
        "boundary_stiffness": [None if not np.isfinite(x) else float(x) for x in kb],
        "colgate_stiffness": zw.colgate_limit(b, DAMPING, T).tolist(),
        "colgate_general_stiffness": colgate_general(b, DAMPING, T, delay),
        "table": table,
        "non_monotone_rows": rows, "non_monotone_cells": cells,
        "n_cells": int(passive.size),
        "diverged_cells": int(res.diverged.sum()),
        "passive": passive.astype(int).tolist(),
        "energy_index": np.round(res.index, 6).tolist(),
    }


def colgate_general(b: float, damping, T: float, delay: int, n: int = 200001) -> list:
    """Colgate & Schenkel's (1997) passivity condition for a sampled wall H(z) behind a
    zero-order hold on a mass with viscous damping b,
    ``b >= T/2 / (1 - cos wT) * Re{(1 - e^-jwT) H(e^jwT)}`` for all 0 < w <= pi/T, solved for the
    largest K per damping B, with H(z) = (K + B (1 - 1/z) / T) z^-delay (the wall of
    :func:`omni_sim.wall_env.wall_torque` with ``delay`` periods of delay).  Without delay it is
    2 (b - |B|)/T; None where no K >= 0 satisfies it."""
    th = np.linspace(np.pi / n, np.pi, n)
    z = np.exp(-1j * th)
    c = 1.0 - np.cos(th)
    g1 = 0.5 * T * np.real((1 - z) * z**delay) / c
    g2 = 0.5 * np.real((1 - z) ** 2 * z**delay) / c
    out = []
    for B in np.asarray(damping, dtype=float):
        r = b - B * g2  # need K g1 <= r at every frequency
        pos, neg = g1 > 1e-15, g1 < -1e-15
        if np.any(~pos & ~neg & (r < 0)):
            out.append(None)
            continue
        kmax = float(np.min(r[pos] / g1[pos])) if pos.any() else math.inf
        kmin = max(0.0, float(np.max(r[neg] / g1[neg]))) if neg.any() else 0.0
        out.append(kmax if kmax >= kmin else None)
    return out


def new_record(cases: dict, code_commit: str | None) -> dict:
    """The study's record around ``cases`` (name -> :func:`run_case`'s entry): the grid, the
    table's damping rows, the code commit and the machine."""
    return {"grid": {"damping": DAMPING.tolist(), "stiffness": STIFFNESS.tolist()},
            "table_damping": list(TABLE_B), "cases": cases,
            "code_commit": code_commit,
            "machine": {"python": platform.python_version(), "processor": platform.machine()}}


def in_case_order(cases: dict) -> dict:
    """``cases`` in :data:`CASES`' order."""
    return {k: cases[k] for k in CASES if k in cases}
