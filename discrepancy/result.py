"""What :func:`discrepancy.run_discrepancy` returns: a :class:`DiscrepancyResult`.

The result holds ``report.json``'s content (:meth:`DiscrepancyResult.to_json`, assembled by
:func:`discrepancy.report.assemble_report`) and what the writers and figures need beside it:
the patched model, the replayed runs and the replays before and after.  The verdict a program
reads first is typed: :attr:`DiscrepancyResult.named` (:class:`NamedEffect` per named effect),
:attr:`~DiscrepancyResult.corrections` (:class:`Correction` per refitted constant of the
nominal), the gaps and whether the gap is unexplained; each reads the report's own numbers, so
the JSON and the fields can never disagree.

Example::

    res = run_discrepancy(runs, "robot.xml", target=Target("pivot", "servo"))
    for e in res.named:
        print(e.name, e.parameters, e.uncertainty, e.confidence)
    print(res.gap_before, "->", res.gap_after, "rad")
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

import mujoco


def _frozen(d: dict | None) -> MappingProxyType:
    """A read-only view of ``d`` (empty for None)."""
    return MappingProxyType(dict(d or {}))


@dataclass(frozen=True)
class NamedEffect:
    """One named effect of the verdict (an entry of ``report.json``'s ``effects``).

    Attributes
    ----------
    name : str
        The library effect (``discrepancy.effects``).
    parameters : mapping of str to float
        Its fitted values on all runs, in ``units``.
    uncertainty : mapping of str to float
        Their 95 % half-widths (``report.json``'s ``uncertainty_kind`` says how).
    units : mapping of str to str
    nominal : mapping of str to float
        The values that mean "no effect" in the model.
    confidence : str
        ``"high"`` or ``"low"`` (``docs/method/discrepancy.md``).
    runner_up : str or None
        The best alternative for it; ``margin`` the share of the runner-up's held-out gap it
        removes on top.
    margin : float or None
    """

    name: str
    parameters: MappingProxyType
    uncertainty: MappingProxyType
    units: MappingProxyType
    nominal: MappingProxyType
    confidence: str | None
    runner_up: str | None
    margin: float | None

    @classmethod
    def from_json(cls, e: dict) -> "NamedEffect":
        """From an entry of ``report.json``'s ``effects``."""
        return cls(e["name"], _frozen(e.get("parameters")), _frozen(e.get("uncertainty")),
                   _frozen(e.get("units")), _frozen(e.get("nominal")), e.get("confidence"),
                   e.get("runner_up"), e.get("margin"))


@dataclass(frozen=True)
class Correction:
    """One refitted constant of the nominal (an entry of ``report.json``'s ``corrections``).

    Attributes
    ----------
    effect, parameter, unit : str
        The library effect that writes it, its parameter and unit.
    nominal, fitted : float
        The user's value and the refitted one.
    half_width_95 : float or None
        The refitted value's 95 % half-width.
    plausible : bool
        Within the plausible factor of the nominal and not on a bound.
    confounded_with : tuple of (str, str, float)
        ``(effect, parameter, correlation)`` of each named effect's parameter it cannot be
        measured apart from (correlation of magnitude 0.9 or more at the all-runs optimum).
    """

    effect: str
    parameter: str
    unit: str
    nominal: float
    fitted: float
    half_width_95: float | None
    plausible: bool
    confounded_with: tuple = ()

    @classmethod
    def from_json(cls, c: dict) -> "Correction":
        """From an entry of ``report.json``'s ``corrections``."""
        return cls(c["effect"], c["parameter"], c["unit"], c["nominal"], c["fitted"], c.get("half_width_95"),
                   bool(c.get("plausible")),
                   tuple((d["effect"], d["parameter"], d["correlation"]) for d in c.get("confounded_with") or ()))


@dataclass(frozen=True)
class DiscrepancyResult:
    """The workflow's result.

    Attributes
    ----------
    report : dict
        ``report.json``'s content (:meth:`to_json`).
    spec : MjSpec
        The patched model (nominal + accepted effects at their all-runs fit).
    runs : list of ReplayRun
    theta_before, theta_after : list of ndarray [rad]
        Replay of the nominal model; held-out replay of the patched model (each run with the
        parameters fitted without it).
    rounds : list of list of Scored
        Every round's scored candidates.
    evidence : discrepancy.evidence.Evidence or None
        The missing torque under the corrected nominal.
    """

    report: dict
    spec: mujoco.MjSpec
    runs: list
    theta_before: list
    theta_after: list
    rounds: list = field(default_factory=list)
    evidence: object = None

    def to_json(self) -> dict:
        """``report.json``'s content."""
        return self.report

    @property
    def named(self) -> tuple[NamedEffect, ...]:
        """The named effects (empty when none is named)."""
        return tuple(NamedEffect.from_json(e) for e in self.report["effects"] if e["name"] != "none")

    @property
    def corrections(self) -> tuple[Correction, ...]:
        """The nominal's refitted constants (empty without corrections)."""
        return tuple(Correction.from_json(c) for c in self.report.get("corrections", ()))

    @property
    def gap_before(self) -> float:
        """The nominal's replay gap [rad] on the whole runs."""
        return float(self.report["gap_before"])

    @property
    def gap_after(self) -> float:
        """The held-out gap [rad] of the corrected model with the named effects."""
        return float(self.report["gap_after"])

    @property
    def shrink_factor(self) -> float:
        """``gap_before / gap_after``."""
        return float(self.report["shrink_factor"])

    @property
    def noise_floor_rad(self) -> float:
        """The measurement noise floor [rad]."""
        return float(self.report["noise_floor_rad"])

    @property
    def unexplained(self) -> bool:
        """Whether a gap well above the noise is left that no library effect explains."""
        return bool(self.report["unexplained"])
