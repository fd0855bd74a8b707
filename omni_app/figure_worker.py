"""The figure worker of ``omni reproduce`` (:func:`start_reproduce_worker`): what its forked
child does, stage by stage.

Import-light: the child is forked before the parent's heavy imports and loads only what
drawing needs (matplotlib, the method's modules the payloads name), not MuJoCo, scipy, numba or
the simulator.
"""

from __future__ import annotations

from pathlib import Path

from .workers import Workers


def _figure_groups():
    """The figures as drawn by the worker and its children: (p) needs only the per-pose stage
    of the identification (the worker draws it while the main process fits the global models),
    (a) and (b) the identification, (c) and (d) the validation's scores and predictions too;
    (a) is drawn by a child of the worker while the worker draws (b), (c) by a second child
    while the worker draws (d) (the main process is done by then: its core is free)."""
    from . import figures as F
    from . import identify_report as IR

    p = [lambda folder, res: IR.write_identify_figures(res["ident"], folder / "identify", ("local",))]
    a = [lambda folder, res: IR.write_identify_figures(res["ident"], folder / "identify", ("inertia",)),
         F.fig_C_beta_vs_alpha]
    b = [F.fig_alpha_vs_frequency, F.fig_nonlinear_vs_inertia, F.fig_inertia]
    c = [F.fig_inertia_truth, F.fig_bode]
    d = [F.fig_time_sine, F.fig_step]
    assert sorted(f.__name__ for f in a[1:] + b + c + d) == sorted(f.__name__ for f in F.FIGURES)
    return p, a, b, c, d


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


def _draw_split(state, payload, in_child, here) -> Workers:
    """Draw the figures ``in_child`` in a forked child and ``here`` in this worker, with the
    payload and the runs; returns the child's :class:`Workers` (to be waited for)."""
    res = {**payload, "runs": state["runs"]}
    drawer = Workers()
    drawer.start([lambda fn=fn: fn(state["folder"], res) for fn in in_child])
    for fn in here:
        fn(state["folder"], res)
    return drawer


def _worker_poses(state, payload) -> None:
    """Stage 2: the identification's per-pose stage; this worker draws group (p)."""
    group_p = _figure_groups()[0]
    for fn in group_p:
        fn(state["folder"], payload)


def _worker_identified(state, payload) -> None:
    """Stage 3: the identification; a child of this worker draws group (a) while this one
    draws group (b)."""
    _, group_a, group_b, _, _ = _figure_groups()
    state["drawer"] = _draw_split(state, payload, group_a, group_b)


def _worker_validated(state, payload) -> None:
    """Stage 4: the validation's scores and predictions; a second child draws group (c) while
    this worker draws group (d)."""
    _, _, _, group_c, group_d = _figure_groups()
    drawer = _draw_split(state, payload, group_c, group_d)
    state.pop("drawer").wait()
    drawer.wait()


def start_reproduce_worker() -> Workers:
    """Fork ``omni reproduce``'s figure worker now: it loads matplotlib, then waits for four
    payloads (:func:`omni_app.reproduce._early_writer` sends them): the output folder and the
    runs the figures show; the identification's per-pose stage (it draws its figure while the
    main process fits the global models); the identification (it draws part of the figures, a
    child of its own another part); the validation's results (it draws the rest, with a second
    child): the ``_worker_*`` stages above, sharing ``state``."""
    state: dict = {}

    def stage(fn):
        return lambda payload=None: fn(state, payload)

    workers = Workers()
    workers.start([stage(_worker_warm)],
                  then=[stage(_worker_simulated), stage(_worker_poses), stage(_worker_identified),
                        stage(_worker_validated)])
    return workers
