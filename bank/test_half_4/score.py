"""Score ``omni discrepancy`` reports on the fourth test half against its expectations.

Usage::

    python -m bank.test_half_4.score DATA/cases.json REPORTS --commit SHA [--out score.json]
        [--families names.json]

The third half's scoring (``bank.test_half_3.score``, itself the second's and the first's four
points: family, no spurious second effect, direction, unexplained) with two extensions, the
earlier halves' files unchanged:

* :data:`FAMILY_KEYWORDS`: keywords for the families this half adds (a position-dependent
  friction, a hysteretic stiffness, a supply sag, a goal rate limit, a torque-off coast, a
  transmission error, a sensor lag) and for the friction laws it uses, tried before the third
  half's table;
* :func:`check_signs`: the direction claims this half adds (:data:`NEW_CLAIMS`), read from the
  named effect's parameters by name keywords; a claim that cannot be read is ``None``
  (unchecked), never passed.

Every name in a report is put into a family by this half's table and handed to the third
half's ``score_case`` as its ``extra`` map, so the earlier halves' rules decide the points
(the third half's included: a case whose family is ``none`` passes its family point when every
named effect's family is accepted).
"""

from __future__ import annotations

from bank.test_half import score as base
from bank.test_half_2 import score as score2
from bank.test_half_3 import score as score3

#: This half's keywords (tried first), then the third half's table.
NEW_KEYWORDS = (
    ("maxwell", "friction: dynamic"), ("gms", "friction: dynamic"),
    ("dwell", "friction: stribeck"), ("rising_static", "friction: stribeck"),
    ("frictional_memory", "friction: stribeck"),
    ("position_dependent_friction", "friction: position-dependent"),
    ("position_friction", "friction: position-dependent"),
    ("angle_dependent_friction", "friction: position-dependent"),
    ("eccentric_friction", "friction: position-dependent"),
    ("friction_ripple", "friction: position-dependent"),
    ("bouc", "hysteretic stiffness"), ("hysteres", "hysteretic stiffness"),
    ("cable", "hysteretic stiffness"), ("harness", "hysteretic stiffness"),
    ("supply", "supply sag"), ("sag", "supply sag"), ("droop", "supply sag"),
    ("source_resist", "supply sag"), ("bus_volt", "supply sag"),
    ("profile", "goal rate limit"), ("rate_limit", "goal rate limit"),
    ("slew", "goal rate limit"), ("goal_filter", "goal rate limit"),
    ("velocity_limit", "goal rate limit"),
    ("coast", "torque-off coast"), ("open_winding", "torque-off coast"),
    ("torque_off", "torque-off coast"), ("freewheel", "torque-off coast"),
    ("transmission_error", "transmission error"), ("mesh", "transmission error"),
    ("ratio_ripple", "transmission error"), ("tooth", "transmission error"),
    ("sensor_lag", "sensor lag"), ("encoder_lag", "sensor lag"),
    ("measurement_lag", "sensor lag"), ("sensor_filter", "sensor lag"),
    ("encoder_filter", "sensor lag"), ("sensor_delay", "sensor lag"),
)
FAMILY_KEYWORDS = NEW_KEYWORDS + score3.FAMILY_KEYWORDS
#: The claims this half adds to the third half's :func:`bank.test_half_3.score.check_signs`.
NEW_CLAIMS = ("rate_limit_rad_s", "source_resistance_ohm")


def family_of(name: str, extra: dict | None = None) -> str:
    """The physics family of a library effect name by this half's :data:`FAMILY_KEYWORDS`
    (:func:`bank.test_half.score.family_of`)."""
    return base.family_of(name, extra, FAMILY_KEYWORDS)


def _new_claim(claim: str, want, params: dict) -> bool | None:
    """One of :data:`NEW_CLAIMS`: True, False or None (unreadable)."""
    p = base._param
    if claim == "rate_limit_rad_s":          # the goal's rate limit in rad/s, within 50 %
        v = p(params, "rate", "slew", "velocity", "speed")
        return None if v is None else abs(v - want) <= 0.5 * want
    if claim == "source_resistance_ohm":     # the supply's source resistance, within a factor 2
        r = p(params, "resist", "ohm", "source")
        return None if r is None else want / 2 <= r <= 2 * want
    raise KeyError(claim)


def check_signs(signs: dict, params: dict, corrections: list) -> dict:
    """Each claim: True, False or None (unreadable); the earlier halves' claims by their rules."""
    out = score3.check_signs({k: v for k, v in signs.items() if k not in NEW_CLAIMS}, params,
                             corrections)
    for claim, want in signs.items():
        if claim in NEW_CLAIMS:
            out[claim] = _new_claim(claim, want, params)
    return out


def score_case(case: dict, report: dict, extra: dict | None = None) -> dict:
    """The four points of one case (the earlier halves' rules, this half's families and
    claims)."""
    fams = {n: family_of(n, extra) for n in score2._names(report)}
    row = score3.score_case(case, report, fams)
    signs = case["expected"]["signs"]
    if any(k in NEW_CLAIMS for k in signs):
        named = [e for e in report.get("effects", []) if e.get("name") not in (None, "none")]
        params = named[0].get("parameters", {}) if named else {}
        got = check_signs(signs, params, report.get("corrections", []))
        readable = [v for v in got.values() if v is not None]
        row["signs"] = got
        row["points"]["direction"] = all(readable) if readable else None
    return row


def main(argv: list[str] | None = None) -> int:
    return base.cli(argv, score_case, "bank.test_half_4.make", __doc__.split("\n\n")[0])


if __name__ == "__main__":
    raise SystemExit(main())
