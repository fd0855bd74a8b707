"""``omni discrepancy``: the command, the demo and the benchmark."""

from __future__ import annotations

import argparse
import sys
import threading
from pathlib import Path

from identification.dataset import atomic_output_dir, check_output_dir, read_dataset, write_run
from identification.errors import UserError

from omni_sim import model as om
from omni_sim.device import Device
from discrepancy import demo as demo_truth
from discrepancy import experiment_set
from discrepancy.workflow import run_discrepancy

from . import discrepancy_report as rp
from .inputs import check_run_poses, require_run_poses

#: The effect hidden by ``--demo``: a 4 ms loop delay (USB Omnis run their loop at 700-900 Hz;
#: :mod:`discrepancy.demo`, the validation bank's case of the same name).
DEMO_CASE = demo_truth.CASE


class Progress:
    """The workflow's log: each line on ``file`` (stderr); on a terminal, below them, a bar over
    the workflow's stages (:data:`~discrepancy.workflow.STAGES`) with the current one,
    the physics steps so far, the last log line and the elapsed time, redrawn every ``tick_s``
    seconds (the search runs for minutes between two lines on long logs).  A context manager;
    call it with a line, pass :meth:`stage` as the workflow's ``progress``.
    """

    def __init__(self, enabled: bool | None = None, file=None, tick_s: float = 1.0):
        from tqdm import tqdm

        from discrepancy.workflow import STAGES

        self.file = file or sys.stderr
        if enabled is None:
            enabled = self.file.isatty()
        self.bar = tqdm(total=len(STAGES), file=self.file, disable=not enabled, leave=False,
                        bar_format="{desc} {bar:12} stage {n_fmt}/{total_fmt} [{elapsed} elapsed]{postfix}",
                        desc="discrepancy: starting")
        self.tick_s = tick_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._tick, daemon=True) if enabled else None

    def __call__(self, msg: str) -> None:
        if self.bar.disable:
            self.file.write(msg + "\n")
            return
        self.bar.write(msg, file=self.file)
        self.bar.set_postfix_str(msg.strip()[:50], refresh=True)

    def stage(self, index: int, name: str, steps: int) -> None:
        """The workflow entered stage ``index`` (``name``) after ``steps`` physics steps."""
        self.bar.n = index
        self.bar.set_description_str(f"discrepancy: {name.replace('_', ' ')} ({steps / 1e6:.1f} M steps)",
                                     refresh=False)
        self.bar.refresh()

    def _tick(self) -> None:
        while not self._stop.wait(self.tick_s):
            self.bar.refresh()

    def __enter__(self) -> "Progress":
        if self._thread is not None:
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self.bar.close()


def _target(args: argparse.Namespace) -> om.Target:
    """The controlled joint and actuator of ``--joint``/``--actuator`` (default: the Omni's)."""
    joint = getattr(args, "joint", None) or om.OMNI.joint
    actuator = getattr(args, "actuator", None) or om.OMNI.actuator
    return om.Target(joint, actuator)


def _corrections(args: argparse.Namespace):
    """``--corrections``: a keyword (auto, default, none) or a tuple of library names, checked
    before any work."""
    from discrepancy import effects as fx

    text = (getattr(args, "corrections", None) or "auto").strip()
    if text in ("auto", "default", "none"):
        return text
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in fx.NAMES]
    if unknown or not names:
        raise UserError(f"discrepancy: --corrections: unknown effect(s) {', '.join(unknown) or text!r} "
                        f"(auto, default, none, or names of the library: {', '.join(fx.NAMES)})")
    return names


def discrepancy_command(args: argparse.Namespace) -> int:
    """Entry point of ``omni discrepancy`` (see ``omni discrepancy --help``)."""
    target = _target(args)
    if target != om.OMNI:
        if args.demo:
            raise UserError("discrepancy: --demo runs on the virtual Omni; --joint/--actuator "
                            "apply to --measured runs on your own --model")
        if getattr(args, "friction", None) is not None:
            raise UserError("discrepancy: --friction picks one of the Omni's built-in scenes; it "
                            "cannot be combined with --joint/--actuator (give your model with --model)")
    if args.demo:
        if getattr(args, "friction", None) is not None:
            raise UserError("discrepancy: --demo hides its effect in the default built-in model; "
                            "--friction applies to --measured runs")
        out = Path(args.out or "discrepancy_demo")
        with Progress() as log:
            return demo(out, force=args.force, log=log)
    if not args.measured:
        raise UserError("discrepancy: --measured DATA is required (or use --demo)")
    if not args.out:
        raise UserError("discrepancy: --out DIR is required")
    friction = getattr(args, "friction", None)
    # the nominal model: --model, or the --friction family's built-in scene (both: an error)
    model = args.model if friction is None else str(om.model_path(args.model, friction))
    out = Path(args.out)
    check_output_dir(out, args.force, inputs=(args.measured, model))
    corrections = _corrections(args)
    runs = read_dataset(args.measured, require_pose=False, uniform=False)  # compared at the logged times
    device = _device(model, target)  # compiled once: the checks and the workflow share it
    if target == om.OMNI:  # the arm's actual angles too (the replay reads the set points)
        check_run_poses(runs, args.measured, device=device)
        require_run_poses(runs, args.measured)
    note = period_note(runs, args.measured)
    with Progress() as log:
        def stage(index: int, name: str, steps: int) -> None:
            if index == 0 and note:  # the inputs passed the workflow's checks
                log(note)
            log.stage(index, name, steps)

        outcome = run_discrepancy(runs, device=device, log=log, progress=stage,
                                  folds=getattr(args, "folds", "blocked"), corrections=corrections)
    with atomic_output_dir(out, force=args.force) as tmp:
        rp.write(outcome, tmp)
    _summary(outcome, out)
    return 0


def _device(model, target: om.Target) -> Device:
    """The nominal model ``model`` (``--model``, or the ``--friction`` family's built-in scene,
    as the command resolved it; None: the built-in scene.xml) as a device
    (:meth:`Device.load`), compiled once for the pose checks and the workflow.  The built-in
    Omni with ``--joint``/``--actuator`` names: one line saying to give the robot's own model."""
    try:  # the Omni's contract checked as every command checks it (target None: its names)
        return Device.load(model, target=None if target == om.OMNI else target)
    except UserError as exc:
        if model is None and target != om.OMNI:
            raise UserError(f"{exc}; --joint/--actuator name your own robot's: give its model "
                            "with --model FILE (the default is the virtual Omni's)") from None
        raise


def period_note(runs, data) -> str | None:
    """The ``note:`` line of a dataset ``data`` whose runs give no ``control_period_s`` (None if
    every run gives one): such a run's loop is replayed at its sample period, which a 200 Hz log
    of a servo that closes its loop at 1 kHz gets wrong without a word."""
    lacking = [r for r in runs if r.meta.get("control_period_s") is None]
    if not lacking:
        return None
    periods = ", ".join(sorted({f"{r.dt * 1e3:.3g}" for r in lacking}, key=float))
    return (f"note: {data}: {len(lacking)} run(s) give no control_period_s: their loop is replayed "
            f"at the sample period ({periods} ms); a servo that closes its loop faster says so in "
            'NAME.json, e.g. "control_period_s": 0.001')


def _summary(outcome, out: Path) -> None:
    rep = outcome.report
    names = ", ".join(e["name"] for e in rep["effects"])
    print(f"named: {names}; gap {rep['gap_before']:.3e} -> {rep['gap_after']:.3e} rad "
          f"(x{rep['shrink_factor']:.1f}); report in {out}/report.md")
    if rp.worse_than_nominal(rep):
        print("warning: the corrected model predicts the held-out samples worse than your nominal "
              "did: keep your nominal (report.md says more)")


def demo(out: Path, force: bool = False, log=None) -> int:
    """Hide an effect in a copy of the virtual Omni (:mod:`discrepancy.demo`), generate
    "measured" data, find it."""
    out = Path(out)
    check_output_dir(out, force)
    runs = demo_truth.generate()
    outcome = run_discrepancy(runs, None, log=log, progress=getattr(log, "stage", None))
    outcome.report["hidden"] = {"case": demo_truth.CASE, "effects": {n: list(v) for n, v in demo_truth.EFFECTS},
                                "note": demo_truth.NOTE}
    intro = (f"Demo: the virtual Omni with a hidden effect -- **{demo_truth.CASE}** "
             f"({demo_truth.NOTE}) -- generated the 'measured' runs in `measured/` (encoder quantised to "
             f"15000 counts/rev plus {experiment_set.NOISE_RAD:g} rad noise); the workflow saw only those "
             f"runs and the unmodified model.")
    with atomic_output_dir(out, force=force) as tmp:
        (tmp / "measured").mkdir()
        for r in runs:
            write_run(tmp / "measured", r)
        rp.write(outcome, tmp, title="Model discrepancy demo", intro=intro)
    _summary(outcome, out)
    return 0
