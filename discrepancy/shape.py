"""Name by shape, cheaply: fit each library effect to the missing torque by equation error.

For effect ``E`` with parameters ``x`` the nominal spec gets ``E(x)`` written in
(:func:`discrepancy.effects.compile_with`) and compiled; the missing torque of that
model along the logged states (:mod:`.torque`: the same smoothed states for every model,
computed once) is the residual::

    r_i(x) = tau_miss_i(x) / band_i,     i over the runs' trusted output times,

``band_i`` the nominal model's noise band.  The effect changes the model's own torque, so the
residual shrinks where ``x`` explains the missing torque.  ``x`` is fitted by bounded least
squares (:func:`scipy.optimize.least_squares`, finite differences: one compile and one pass of
``mj_inverse`` over the states per evaluation), started from the best point of the effect's
own starting grid (and its nominal values).  No closed loop is replayed.

The candidates are ranked by the share of the missing torque they explain::

    explained = 1 - sum_i r_i(x_hat)^2 / sum_i r_i(x_0)^2        (x_0: the nominal values)

and each says where the fitted law and the missing torque still disagree
(:func:`disagreements`: the residual binned by speed and by driving / back-driven).

An effect on the command's path only -- a loop delay, the drive's first-order lag -- is judged
through the command it makes (:attr:`~discrepancy.effects.base.Effect.command`): the model
without it is fed the logged command delayed or filtered as MuJoCo's ``delay`` or
``filterexact`` would (on the model's timestep, before the window smooths it), so its residual
is that of the model with it, up to the history before the run's start.  Other effects whose
model has state the logged angle does not fix -- LuGre bristles (activation states), a
two-mass drive (extra joints) -- cannot be judged by equation error: they are marked
``needs_replay`` with the reason, not scored.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy.optimize import least_squares

from identification.errors import UserError

from omni_sim import model as om
from .effects import LIBRARY, ModelBuilder
from .runs import ReplayRun
from .torque import Estimator, InverseModel, invert, smooth

#: Speed bins [rad/s] of :func:`disagreements` (|qd|).
SPEED_BINS = (0.0, 0.03, 0.1, 0.3, 1.0, 3.0, math.inf)
#: Least-squares evaluations at most per candidate (after its starting grid).
MAX_NFEV = 60


@dataclass(frozen=True)
class ShapeFit:
    """One candidate's equation-error fit.

    Attributes
    ----------
    name : str
        The library effect.
    x, nominal : ndarray or None
        Fitted and nominal parameter values (None: needs replay).
    explained : float or None
        Share of the missing torque explained (module docstring; None: needs replay).
    disagreements : tuple of str
        Where the fitted law and the missing torque still disagree (:func:`disagreements`).
    needs_replay : str
        Why equation error cannot judge the effect ("" if it can).
    compiles, inverse_calls : int
        The cost: models compiled and ``mj_inverse`` calls made for this candidate.
    seconds : float
        Wall time of the candidate [s].
    """

    name: str
    x: np.ndarray | None
    nominal: np.ndarray | None
    explained: float | None
    disagreements: tuple
    needs_replay: str
    compiles: int
    inverse_calls: int
    seconds: float


@dataclass
class States:
    """The smoothed runs (model-independent, cached) and the nominal model's missing torque
    and band on them: what every candidate's residual reads."""

    smoothed: list
    tau_nominal: list
    band: list
    motor: list
    keep: list
    bias: list | None = None
    bristles: dict = field(default_factory=dict)  # the LuGre torques, shared by the candidates

    @classmethod
    def of(cls, smoothed: list, torques: list, bias: list | None = None) -> "States":
        """From the smoothed runs and their missing torque (:func:`~.torque.invert`): a band
        floored at 1e-12 N*m (a weight, never a division by zero); ``bias``: the estimator's own
        error per run (on the model's own replay), taken from every candidate's missing torque."""
        return cls(smoothed, [m.tau_miss for m in torques], [np.maximum(m.band, 1e-12) for m in torques],
                   [m.tau_motor for m in torques], [m.trusted for m in torques], bias)

    def weighted(self, taus) -> np.ndarray:
        """``tau / band`` over the trusted output times of every run, concatenated."""
        return np.concatenate([t[k] / b[k] for t, b, k in zip(taus, self.band, self.keep)])


def prepare(model: mujoco.MjModel, runs: list[ReplayRun], target: om.Target | None = None,
            est: Estimator = Estimator()) -> States:
    """Smooth every run once and compute the nominal model's missing torque and noise band."""
    sm = [smooth(run, float(model.opt.timestep), est) for run in runs]
    return States.of(sm, invert(InverseModel(model, target), sm))


def needs_replay(model: mujoco.MjModel, nominal: mujoco.MjModel) -> str:
    """Why a candidate model cannot be judged by equation error ("" if it can): state the
    nominal model lacks (activation states, a delay buffer, more joints)."""
    if model.na > nominal.na:
        return "adds actuator activation states (a filter or friction bristles): hidden state"
    if model.nhistory > nominal.nhistory:
        return "adds a delay buffer: the torque depends on past commands"
    if model.nv != nominal.nv:
        return "adds joints (a two-mass drive): the rotor's state is hidden"
    return ""


class _Candidate:
    """One effect's residual ``x -> tau_miss(x) / band``, counting compiles and inverse calls;
    ``x`` holds the values of the effects ``free`` (fitted with it) first, then its own."""

    def __init__(self, builder: ModelBuilder, name: str, states: States, free=()):
        self.builder, self.states = builder, states
        self.effect = builder.effect(name) if name else None
        self.free = [builder.effect(n) for n in free]
        self.compiles = 0
        self.calls = 0

    def changes(self, x: np.ndarray) -> list:
        out, i = [], 0
        for eff in self.free + ([self.effect] if self.effect is not None else []):
            out.append((eff, np.asarray(x[i:i + eff.nparam], float)))
            i += eff.nparam
        return out

    @property
    def on_command(self) -> bool:
        """The effect acts on the command's path only (:attr:`Effect.command`): judged by
        feeding the model without it the command it makes."""
        return self.effect is not None and self.effect.command is not None

    def taus(self, x: np.ndarray) -> list[np.ndarray]:
        changes = self.changes(x)
        if self.on_command:
            changes, (eff, own) = changes[:-1], changes[-1]
        model = self.builder.compile(changes)
        self.compiles += 1
        inv = InverseModel(model, self.builder.target, self.states.bristles)
        if self.on_command:
            dt = float(model.opt.timestep)
            out = [inv.missing(s, ctrl=s.fine[0] @ eff.command(s.v_fine, dt, own))[0]
                   for s in self.states.smoothed]
        else:
            out = [inv.missing(s)[0] for s in self.states.smoothed]
        self.calls += inv.calls
        if self.states.bias is not None:
            out = [t - b for t, b in zip(out, self.states.bias)]
        return out

    def residual(self, x: np.ndarray) -> np.ndarray:
        return self.states.weighted(self.taus(x))


def fit_candidate(builder: ModelBuilder, name: str, states: States, nominal: mujoco.MjModel,
                  free: tuple = ()) -> ShapeFit:
    """Fit effect ``name`` to the missing torque by equation error (module docstring), with
    the library effects ``free`` (the nominal's corrections) refitted jointly from the values
    the builder's model holds (``x`` and ``nominal`` of the result: ``name``'s own; ``name``
    "": the ``free`` effects alone, the baseline a candidate must beat)."""
    t0 = time.perf_counter()
    cand = _Candidate(builder, name, states, free)
    effects = cand.free + ([cand.effect] if cand.effect is not None else [])
    own = cand.effect.nparam if cand.effect is not None else 0
    x0 = np.concatenate([builder.nominal_values(e) for e in effects])
    why = "" if cand.on_command else needs_replay(builder.compile(cand.changes(x0)), nominal)
    if why:
        return ShapeFit(name, None, None, None, (), why, 1, 0, time.perf_counter() - t0)
    cand.compiles = 1
    lo = np.concatenate([e.bounds()[0] for e in effects])
    hi = np.concatenate([e.bounds()[1] for e in effects])
    scales = np.concatenate([e.scales() for e in effects])
    grid = cand.effect.grid(x0[len(x0) - own:]) if cand.effect is not None else []
    starts = [x0] + [np.concatenate([x0[:len(x0) - own], cand.effect.clip(g)]) for g in grid]
    costs = [float(np.sum(cand.residual(x) ** 2)) for x in starts]
    best = starts[int(np.argmin(costs))]
    # a start on a bound (a friction level 0) can stall the trust region's first step:
    # start a tenth of the parameter's scale inside
    inset = np.minimum(0.1 * scales, 0.5 * (hi - lo))
    start = np.clip(best, lo + inset, hi - inset)
    res = least_squares(cand.residual, start, bounds=(lo, hi), x_scale=scales, max_nfev=MAX_NFEV)
    base = float(np.sum(states.weighted(states.tau_nominal) ** 2))
    final = cand.taus(res.x)
    share = 1.0 - float(np.sum(states.weighted(final) ** 2)) / base if base > 0 else 0.0
    notes = disagreements(states, final)
    return ShapeFit(name, res.x[len(x0) - own:], x0[len(x0) - own:], share, notes, "", cand.compiles,
                    cand.calls, time.perf_counter() - t0)


def disagreements(states: States, taus: list[np.ndarray], step_s: float | None = None) -> tuple:
    """Where a fitted model's missing torque ``taus`` is still beyond the noise: the residual
    along the motion, ``tau_miss sign(qd)``, averaged in bins of ``|qd|`` (:data:`SPEED_BINS`)
    and of driving (``tau_motor qd > 0``) or back-driven.  A bin disagrees when its mean
    exceeds the band's mean over ``sqrt(n_eff)``, ``n_eff`` the bin's samples times the output
    spacing over the window's width (neighbouring samples share their window).

    Returns
    -------
    tuple of str
        One line per disagreeing bin, e.g. ``"-4.2 mN*m against the motion (noise 0.9) at
        |qd| 0.03-0.1 rad/s, back-driven"``.
    """
    rows = []
    for s, tau, band, motor, keep in zip(states.smoothed, taus, states.band, states.motor, states.keep):
        share = (s.t[1] - s.t[0]) / (2 * s.half_window_s)
        rows.append((np.abs(s.qd)[keep], (tau * np.sign(s.qd))[keep], band[keep],
                     (motor * s.qd > 0)[keep], np.full(int(keep.sum()), min(1.0, share))))
    speed, along, band, driving, weight = (np.concatenate(c) for c in zip(*rows))
    out = []
    for lo, hi in zip(SPEED_BINS[:-1], SPEED_BINS[1:]):
        for drv, label in ((True, "driving"), (False, "back-driven")):
            m = (speed >= lo) & (speed < hi) & (driving == drv)
            if np.count_nonzero(m) < 5:
                continue
            mean, noise = float(np.mean(along[m])), float(np.mean(band[m]))
            n_eff = max(1.0, float(np.sum(weight[m])))
            if abs(mean) > noise / math.sqrt(n_eff):
                word = "against" if mean < 0 else "along"
                out.append(f"{mean * 1e3:+.3g} mN*m {word} the motion (noise {noise / math.sqrt(n_eff) * 1e3:.2g}) "
                           f"at |qd| {lo:g}-{hi:g} rad/s, {label}")
    return tuple(out)


def rank(spec: mujoco.MjSpec, runs: list[ReplayRun], target: om.Target = om.OMNI,
         est: Estimator = Estimator(), names: tuple | None = None) -> list[ShapeFit]:
    """Fit every applicable library effect (or ``names``) to the nominal model's missing torque
    and rank them: scored ones by explained share (highest first), then those that need a
    replay (library order).

    Raises
    ------
    UserError
        The nominal model itself cannot be inverted (:class:`~.torque.InverseModel`).
    """
    builder = ModelBuilder(spec, target)
    nominal = spec.copy().compile()
    states = prepare(nominal, runs, target, est)
    if not any(k.any() for k in states.keep):
        raise UserError("no trusted output time in any run (every window holds a torque switch)")
    return ranked(builder, states, nominal, names)


def ranked(builder: ModelBuilder, states: States, nominal: mujoco.MjModel, names: tuple | None = None,
           free: tuple = ()) -> list[ShapeFit]:
    """Every applicable library effect (or ``names``; ``free`` ones left out) fitted by
    :func:`fit_candidate`: scored ones by explained share (highest first), then those that
    need a replay (library order)."""
    spec, target = builder.spec, builder.target
    chosen = [e.name for e in LIBRARY if e.applies(spec, target)] if names is None else list(names)
    fits = [fit_candidate(builder, n, states, nominal, free) for n in chosen if n not in free]
    scored = sorted((f for f in fits if f.explained is not None), key=lambda f: -f.explained)
    return scored + [f for f in fits if f.explained is None]
