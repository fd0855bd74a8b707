"""The ``omni`` command line: parses arguments, calls the packages, reports user errors.

A user error (:class:`identification.errors.UserError`) is printed as one line
``error: <message>`` on stderr with exit status 2 and no traceback.
"""

from __future__ import annotations

import argparse
import sys

from identification.errors import UserError


def _int_at_least(low: int):
    """An argparse type: an integer >= ``low``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}: {text!r}")
        return value
    return parse


_nonnegative_int = _int_at_least(0)
_positive_int = _int_at_least(1)


class _Parser(argparse.ArgumentParser):
    """argparse with the contract's one-line ``error:`` message and exit status 2."""

    def error(self, message: str) -> None:  # noqa: D401
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def _version() -> str:
    """The installed distribution's version (pyproject.toml's ``version``, via its metadata)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("omni-alpha")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


def _friction_option(p: argparse.ArgumentParser, all_: bool = False, what: str = "") -> None:
    from omni_sim.model import DEFAULT_FRICTION, FRICTION_FAMILIES

    choices = FRICTION_FAMILIES + (("all",) if all_ else ())
    p.add_argument("--friction", default=None, choices=choices,
                   help=f"{what}the built-in scene of this friction family (models/omni/scene_FAMILY.xml; "
                        f"default: scene.xml = {DEFAULT_FRICTION}); not with --model"
                        + ("; 'all': every family into OUT/FAMILY/ plus OUT/comparison.json, "
                           "comparison.md and overlay figures" if all_ else ""))


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="omni",
        description="Virtual Phantom Omni (MuJoCo) and the alpha-invariant identification method.",
    )
    parser.add_argument("--version", action="version", version=f"omni {_version()}",
                        help="print the installed package's version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for add in (_add_generate, _add_identify, _add_fit_inertia, _add_validate, _add_reproduce,
                _add_discrepancy, _add_bench, _add_sweep, _add_zwidth):  # one function per command
        add(sub)
    return parser


def _add_generate(sub) -> None:
    p = sub.add_parser("generate", help="run experiments on the virtual Omni (or your own "
                                        "single-joint model) and write a dataset")
    p.add_argument("--campaign", default=None, metavar="{paper,sine,step,FILE.toml}",
                   help="paper (Table 1 sines + Table 2 squares; the file omni_sim/campaigns/paper.toml), "
                        "sine or step (its halves), or a campaign file of your own (format: "
                        "docs/usage/campaigns.md); default: paper on the Omni; a single-joint device "
                        "needs a file whose groups have no poses_deg")
    p.add_argument("--model", default=None, help="MJCF file (default: the built-in models/omni/scene.xml)")
    _friction_option(p)
    p.add_argument("--joint", default=None, metavar="NAME",
                   help="the controlled hinge of your own --model (the joint the encoder reads; "
                        "default: yaw, the Omni's); with --actuator")
    p.add_argument("--actuator", default=None, metavar="NAME",
                   help="the actuator driving --joint, whose control is the P law's command "
                        "(default: yaw_motor); with --joint")
    p.add_argument("--kp", type=float, default=None,
                   help="P gain [control units/rad] (default: the paper's 2 V/rad)")
    p.add_argument("--command-limit", type=float, default=None, metavar="U",
                   help="the P law's saturation in the actuator's control units, written to the "
                        "runs' metadata (default: the actuator's ctrlrange)")
    p.add_argument("--out", default="dataset", help="output folder (default: ./dataset)")
    p.add_argument("--seed", type=_nonnegative_int, default=0, help="seed for encoder noise (default: 0)")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")
    p.add_argument("--reference", default=None, metavar="CSV",
                   help="drive one run with a user reference (CSV with columns t, r) instead of a campaign")
    p.add_argument("--gamma1", type=float, default=None,
                   help="shoulder set point [deg] for --reference on the Omni (default 65)")
    p.add_argument("--gamma2", type=float, default=None,
                   help="elbow set point [deg] for --reference on the Omni (default 90)")
    p.add_argument("--quantize", action="store_true",
                   help="quantize the measured yaw to the encoder's 15000 counts/rev")
    p.add_argument("--noise", type=float, default=0.0, metavar="RAD",
                   help="standard deviation of white encoder noise [rad] (default 0)")
    p.add_argument("--jobs", type=_positive_int, default=None, help="threads (default: $OMNI_THREADS, else all cores)")


def _add_identify(sub) -> None:
    p = sub.add_parser("identify", help="fit the paper's models to a dataset; writes DIR/params.json")
    p.add_argument("data", help="dataset folder")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")


def _add_fit_inertia(sub) -> None:
    p = sub.add_parser("fit-inertia", help="fit the inertia model (6) to a table of linear coefficients")
    p.add_argument("table", help="CSV with columns gamma1_deg,gamma2_deg,C_linear,beta_tilde_linear")
    p.add_argument("--out", default=None, help="write the JSON result to this file")


def _add_validate(sub) -> None:
    p = sub.add_parser("validate", help="score the linear and alpha-invariant models against a dataset")
    p.add_argument("data", help="dataset folder")
    p.add_argument("--params", required=True, help="params.json written by omni identify")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")


def _add_reproduce(sub) -> None:
    p = sub.add_parser("reproduce", help="the main job: generate, identify, validate, report")
    p.add_argument("--model", default=None, help="MJCF file (default: the built-in models/omni/scene.xml)")
    _friction_option(p, all_=True)
    p.add_argument("--out", default="reproduce", help="output folder (default: ./reproduce)")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")
    p.add_argument("--jobs", type=_positive_int, default=None, help="threads (default: $OMNI_THREADS, else all cores)")


def _add_discrepancy(sub) -> None:
    p = sub.add_parser("discrepancy", help="find, name and fix the effect a model is missing")
    p.add_argument("--measured", default=None, help="measured dataset folder")
    p.add_argument("--model", default=None, help="MJCF file of the model to test")
    _friction_option(p, what="the model to test: ")
    p.add_argument("--joint", default="yaw", metavar="NAME",
                   help="the controlled hinge of the model (the joint the encoder reads; default: "
                        "yaw, the Omni's). A model without the Omni's shoulder/elbow joints needs no "
                        "pose in the runs' metadata")
    p.add_argument("--actuator", default="yaw_motor", metavar="NAME",
                   help="the actuator driving --joint, whose control is the P law's command "
                        "kp*(r - theta) clipped to the metadata's command_limit if given and to the "
                        "actuator's ctrlrange (default: yaw_motor)")
    p.add_argument("--folds", default="blocked", choices=("blocked", "runs"),
                   help="how candidates are scored held out: 'blocked' (default) fits on time blocks "
                        "of every run and predicts the others, so four runs of four different "
                        "experiments suffice; 'runs' holds out whole runs. The report gives both")
    p.add_argument("--corrections", default="auto", metavar="auto|default|none|NAME,..",
                   help="the nominal's constants refitted jointly with every candidate and reported "
                        "apart from the named effects: 'default' = armature, viscous_damping, "
                        "coulomb_friction, torque_gain, position_offset; 'auto' (default) = 'default' "
                        "with --joint/--actuator (your own device), 'none' on the virtual Omni; or a "
                        "comma-separated list of library names")
    p.add_argument("--out", default=None, help="output folder")
    p.add_argument("--demo", action="store_true", help="hide an effect in a copy of the virtual Omni and find it")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")


def _add_bench(sub) -> None:
    p = sub.add_parser("bench", help="print and write the performance figures")
    p.add_argument("--out", default=None, help="write the figures as JSON to this file")
    _friction_option(p, what="the campaign and reproduce figures on: ")
    p.add_argument("--jobs", type=_positive_int, default=None, help="threads (default: $OMNI_THREADS, else all cores)")
    p.add_argument("--only", default=None, choices=("discrepancy_servo",),
                   help="measure this one figure alone (discrepancy_servo: omni discrepancy on the "
                        "geared-servo bank case with its nominal off, 12 runs of 6 s)")
    p.add_argument("--discrepancy-campaign", action="store_true",
                   help="also time omni discrepancy on the whole paper campaign (106 runs) with the "
                        "whole effect library (takes minutes)")


def _add_sweep(sub) -> None:
    p = sub.add_parser("sweep", help="a study of many model variants on Dask (local or a cluster)")
    p.add_argument("spec", nargs="?", default=None, metavar="SPEC.toml",
                   help="study file (base model, pipeline, parameters to vary; see --example)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder: results.csv, variants/<id>/; rerun to resume")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="local worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing Dask scheduler, e.g. tcp://host:8786 (instead of a local cluster)")
    p.add_argument("--example", action="store_true", help="print a small runnable study file")
    p.add_argument("--plot", default=None, metavar="DIR",
                   help="draw each figure of DIR/results.csv against each varied parameter (PNG into DIR)")


def _add_zwidth(sub) -> None:
    p = sub.add_parser("zwidth", help="map the virtual walls (K, B) the yaw renders passively (Z-width)")
    p.add_argument("--model", default=None, metavar="PATH", help="MJCF file (default: the built-in scene)")
    _friction_option(p)
    p.add_argument("--ideal", action="store_true",
                   help="dry friction and encoder quantisation removed, viscous damping kept")
    p.add_argument("--stiffness", default=None, metavar="START:STOP:N|K1,K2,..",
                   help="wall stiffnesses [N*m/rad], sorted, duplicates dropped; 0 up to what the "
                        "drive holds at the start press (default: 20 from 0 to 3 b/T, 1.5x "
                        "Colgate's B=0 bound)")
    p.add_argument("--damping", default=None, metavar="START:STOP:N|B1,B2,..",
                   help="wall dampings [N*m*s/rad], sorted, duplicates dropped; |B| up to what "
                        "saturates the drive at the probe's speed (default: 20 from 0 to 1.25 b)")
    p.add_argument("--no-quantize", action="store_true", help="exact encoder (default: 15000 counts/rev)")
    p.add_argument("--delay", type=_nonnegative_int, default=0,
                   help="loop delay [servo periods], below the 300 periods before the energy "
                        "window (default 0)")
    p.add_argument("--substeps", type=_positive_int, default=20,
                   help="physics steps per servo period, 1 to 1000 (default 20)")
    p.add_argument("--probe-speed", type=float, default=0.02, metavar="RAD_PER_S",
                   help="speed of the Nyquist square-wave probe (default 0.02 rad/s: corners of "
                        "+-1e-5 rad, below one encoder count); speed x substeps >= 0.4, and the "
                        "slowest probe must stay inside the wall (< 1.25 rad/s)")
    p.add_argument("--jobs", type=_positive_int, default=None, help="threads (default: $OMNI_THREADS, else all cores)")
    p.add_argument("--out", required=True, metavar="DIR", help="writes DIR/zwidth.json and DIR/zwidth.png")
    p.add_argument("--force", action="store_true", help="replace a non-empty DIR")


def _dispatch(args: argparse.Namespace) -> int:
    if args.command == "generate":
        from .commands import generate
        return generate(args)
    if args.command == "identify":
        from .commands import identify
        return identify(args)
    if args.command == "fit-inertia":
        from .commands import fit_inertia
        return fit_inertia(args)
    if args.command == "validate":
        from .commands import validate
        return validate(args)
    if args.command == "reproduce":
        from .commands import reproduce
        return reproduce(args)
    if args.command == "discrepancy":
        from .commands import discrepancy
        return discrepancy(args)
    if args.command == "bench":
        from .commands import bench
        return bench(args)
    if args.command == "sweep":
        from .sweep import sweep_command
        return sweep_command(args)
    if args.command == "zwidth":
        from .zwidth import zwidth_command
        return zwidth_command(args)
    raise AssertionError(args.command)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        from omni_sim.device import default_threads
        default_threads()  # a bad OMNI_THREADS is refused before any work
        from omni_studies.accel import install
        install()  # the compiled α loop (loaded at its first use)
        code = _dispatch(args) or 0
        sys.stdout.flush()  # a closed pipe shows here, not at the interpreter's exit
        return code
    except UserError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        return 130
    except BrokenPipeError:  # the reader of stdout left (``omni ... | head``): stop quietly
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no error at exit's flush
        return 141  # 128 + SIGPIPE, as a shell reports a command killed by it


if __name__ == "__main__":
    raise SystemExit(main())
