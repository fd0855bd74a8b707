"""Maps of the missing torque (:mod:`discrepancy.torque`) for the discrepancy report:
``tau_miss`` against velocity, against the drive's torque (driving and back-driven apart),
against position and over time, the estimator's noise band shaded."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import save_png

#: Bins of the band's outline in the maps against a state (its median per bin).
BAND_BINS = 40


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _band_outline(ax, x: np.ndarray, band: np.ndarray) -> None:
    """Shade ``+-band`` about 0 against ``x``: the band's median in :data:`BAND_BINS` bins."""
    if len(x) < 2 or np.ptp(x) == 0:
        return
    edges = np.linspace(x.min(), x.max(), BAND_BINS + 1)
    idx = np.clip(np.digitize(x, edges) - 1, 0, BAND_BINS - 1)
    mids, med = [], []
    for b in range(BAND_BINS):
        m = idx == b
        if m.any():
            mids.append(0.5 * (edges[b] + edges[b + 1]))
            med.append(float(np.median(band[m])) * 1e3)
    ax.fill_between(mids, -np.array(med), med, color="0.85", lw=0, label="noise band (3 sigma)")


def _stack(results) -> dict:
    """The runs' trusted samples, concatenated (times laid end to end)."""
    cols = {k: [] for k in ("t", "q", "qd", "motor", "tau", "band", "driving")}
    offset = 0.0
    for r in results:
        k = r.trusted
        cols["t"].append(r.t[k] - r.t[0] + offset)
        offset += r.t[-1] - r.t[0] + 0.2
        for name, arr in (("q", r.q), ("qd", r.qd), ("motor", r.tau_motor), ("tau", r.tau_miss),
                          ("band", r.band), ("driving", r.driving)):
            cols[name].append(arr[k])
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items()}


def draw(results: list, path: Path, title: str = "missing torque") -> Path:
    """Write the four maps of ``results`` (a list of
    :class:`~discrepancy.torque.MissingTorque`) as one PNG at ``path``.

    Panels: ``tau_miss`` [mN*m] against velocity, against the drive's torque (driving,
    ``tau_motor qd > 0``, and back-driven in two colours), against position, and over time
    (runs end to end), each with the noise band shaded (about 0 against a state, about the
    estimate over time).  Samples within a half-window of a torque switch are left out.
    """
    plt = _plt()
    s = _stack(results)
    tau = s["tau"] * 1e3
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.4))
    ax = axes[0, 0]
    _band_outline(ax, s["qd"], s["band"])
    ax.plot(s["qd"], tau, ".", ms=2, color="C0")
    ax.set_xlabel("velocity qd [rad/s]")
    ax.set_ylabel("tau_miss [mN*m]")
    ax.legend(fontsize=7, loc="best")
    ax = axes[0, 1]
    _band_outline(ax, s["motor"], s["band"])
    drv = s["driving"]
    ax.plot(s["motor"][drv], tau[drv], ".", ms=2, color="C3", label="driving")
    ax.plot(s["motor"][~drv], tau[~drv], ".", ms=2, color="C2", label="back-driven")
    ax.set_xlabel("drive torque tau_motor [N*m]")
    ax.legend(fontsize=7, loc="best")
    ax = axes[1, 0]
    _band_outline(ax, s["q"], s["band"])
    ax.plot(s["q"], tau, ".", ms=2, color="C0")
    ax.set_xlabel("position q [rad]")
    ax.set_ylabel("tau_miss [mN*m]")
    ax = axes[1, 1]
    order = np.argsort(s["t"])
    t, lo, hi = s["t"][order], (tau - s["band"] * 1e3)[order], (tau + s["band"] * 1e3)[order]
    ax.fill_between(t, lo, hi, color="0.85", lw=0)
    ax.plot(t, tau[order], ".", ms=1.5, color="C0")
    ax.set_xlabel("time, runs end to end [s]")
    for a in axes.ravel():
        a.axhline(0.0, color="k", lw=0.6)
        a.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    path = Path(path)
    save_png(fig, path)
    return path
