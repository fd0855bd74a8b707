"""The figure worker of ``omni reproduce`` (:func:`start_reproduce_worker`): what its forked
child does, stage by stage.

Import-light: the child is forked before the parent's heavy imports and loads only what
drawing needs (matplotlib, the method's modules the payloads name), not MuJoCo, scipy, numba or
the simulator.
"""

from __future__ import annotations

from pathlib import Path

from .workers import Workers


def _figure_groups() -> dict:
    """The figures drawn at each stage of ``omni reproduce``, as ``{stage: (in_child, here)}``:
    ``here`` by the worker, ``in_child`` by a child it forks.  The identification's stages come
    while the main process fits the rest (one core is free: the worker draws alone); from the
    identification on, a child draws part of the figures (the worker alone would still be
    drawing when the main process is done).  Balanced on the built-in reproduction's figure
    times (local_linear ~0.5 s of CPU, the others 0.1-0.35 s)."""
    from . import figures as F
    from . import identify_report as IR

    def identify_figure(which):
        return lambda folder, res: IR.write_identify_figures(res["ident"], folder / "identify", (which,))

    groups = {
        "poses": ((), (identify_figure("local"),)),
        "inertia": ((), (identify_figure("inertia"), F.fig_inertia)),
        "identified": ((F.fig_C_beta_vs_alpha,), (F.fig_nonlinear_vs_inertia, F.fig_alpha_vs_frequency)),
        "validated": ((F.fig_inertia_truth, F.fig_bode), (F.fig_time_sine, F.fig_step)),
    }
    named = [f.__name__ for child, here in groups.values() for f in child + here
             if f.__name__ != "<lambda>"]
    assert sorted(named) == sorted(f.__name__ for f in F.FIGURES)
    return groups


def _warm_matplotlib() -> None:
    """Import matplotlib and draw a throw-away figure (fonts, Agg, PNG writer loaded)."""
    import io

    from .figures import _plt, save_png

    plt = _plt()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1], "o-", label="x")
    ax.set(xlabel="x", title="x")
    ax.legend()
    save_png(fig, io.BytesIO())


def _worker_warm(state, _=None) -> None:
    """The figure worker's first task (before any payload): matplotlib loaded and a figure
    drawn once (fonts, Agg, PNG writer).  (The method's modules load with the payloads, without
    scipy: they import it where they fit.)"""
    _warm_matplotlib()


def _worker_simulated(state, payload) -> None:
    """Stage 1: the output folder and the runs the figures show
    (:data:`omni_app.figures.TIME_FIGURE_RUNS`).  (The dataset is written by a child of the main
    process, which has the compiled CSV writer loaded: this worker never loads numba.)"""
    state["folder"], state["runs"] = Path(payload["folder"]), payload["runs"]


def _draw(state, payload, stage) -> None:
    """Draw the figures of ``stage`` (:func:`_figure_groups`) with the payload and the runs:
    those to be drawn in a child by a forked child (waited for at the last stage), the others
    here."""
    in_child, here = _figure_groups()[stage]
    res = {**payload, "runs": state["runs"]}
    if in_child:
        drawer = Workers()
        drawer.start([lambda fn=fn: fn(state["folder"], res) for fn in in_child])
        state.setdefault("drawers", []).append(drawer)
    for fn in here:
        fn(state["folder"], res)


def _worker_poses(state, payload) -> None:
    """Stage 2: the identification's per-pose stage (the global models are being fitted)."""
    _draw(state, payload, "poses")


def _worker_inertia(state, payload) -> None:
    """Stage 3: the identification with the inertia model (the alpha model is being fitted)."""
    _draw(state, payload, "inertia")


def _worker_identified(state, payload) -> None:
    """Stage 4: the identification (the main process validates meanwhile); part in a child."""
    _draw(state, payload, "identified")


def _worker_validated(state, payload) -> None:
    """Stage 5: the validation's scores and predictions; half of the figures in a child."""
    _draw(state, payload, "validated")
    for drawer in state.pop("drawers", []):
        drawer.wait()


def start_reproduce_worker() -> Workers:
    """Fork ``omni reproduce``'s figure worker now: it loads matplotlib, then waits for five
    payloads (:func:`omni_app.reproduce._early_writer` sends them): the output folder and the
    runs the figures show; the identification's per-pose stage, then with the inertia model (it
    draws their figures while the main process fits the rest); the identification; the
    validation's results (the last figures, half of them in a child): the ``_worker_*`` stages
    above, sharing ``state``."""
    state: dict = {}

    def stage(fn):
        return lambda payload=None: fn(state, payload)

    workers = Workers()
    workers.start([stage(_worker_warm)],
                  then=[stage(fn) for fn in (_worker_simulated, _worker_poses, _worker_inertia,
                                             _worker_identified, _worker_validated)])
    return workers
