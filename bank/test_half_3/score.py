"""Score ``omni discrepancy`` reports on the third test half against its expectations.

Usage::

    python -m bank.test_half_3.score DATA/cases.json REPORTS --commit SHA [--out score.json]
        [--families names.json]

The second half's scoring (``bank.test_half_2.score``, itself the first half's four points:
family, no spurious second effect, direction, unexplained) with three extensions, the earlier
halves' files unchanged:

* :data:`FAMILY_KEYWORDS`: keywords for the families this half adds (a nonlinear viscous drag,
  an actuator lag, a sensor error, a joint stiffness, a payload) and for the friction laws it
  uses, tried before the second half's table;
* :func:`check_signs`: the direction claims this half adds (:data:`NEW_CLAIMS`), read from the
  named effect's parameters by name keywords, or, for ``torque_gain_vs_nominal``, from the
  report's ``corrections``; a claim that cannot be read is ``None`` (unchecked), never passed;
* a case whose family is ``none`` but which ``accept``s a law (the payload: a law of added mass
  is also right) passes its family point when every named effect's family is accepted.

Every name in a report is put into a family by this half's table and handed to the second
half's ``score_case`` as its ``extra`` map, so the earlier halves' rules decide the points.
"""

from __future__ import annotations

from bank.test_half import score as base
from bank.test_half_2 import score as score2

#: This half's keywords (tried first), then the second half's table.
NEW_KEYWORDS = (
    ("quadratic", "friction: nonlinear viscous"), ("churn", "friction: nonlinear viscous"),
    ("windage", "friction: nonlinear viscous"), ("drag", "friction: nonlinear viscous"),
    ("palmgren", "friction: nonlinear viscous"), ("power_law", "friction: nonlinear viscous"),
    ("dahl", "friction: dynamic"), ("karnopp", "friction: stribeck"),
    ("stick_slip", "friction: stribeck"), ("stiction", "friction: stribeck"),
    ("inductan", "actuator lag"), ("actuator_lag", "actuator lag"), ("current_lag", "actuator lag"),
    ("electrical", "actuator lag"),
    ("eccentric", "sensor error"), ("runout", "sensor error"), ("encoder_error", "sensor error"),
    ("sensor", "sensor error"),
    ("joint_stiffness", "joint stiffness"), ("torsion", "joint stiffness"),
    ("spring", "joint stiffness"), ("stiffness", "joint stiffness"),
    ("payload", "inertia and gravity"), ("added_mass", "inertia and gravity"),
    ("tip_mass", "inertia and gravity"),
)
FAMILY_KEYWORDS = NEW_KEYWORDS + score2.FAMILY_KEYWORDS
#: The claims this half adds to the second half's :func:`bank.test_half_2.score.check_signs`.
NEW_CLAIMS = ("coulomb_level_nm", "speed_exponent_vs_1", "load_exponent_vs_1", "time_constant_s",
              "sensor_amplitude_rad", "torque_gain_vs_nominal")


def family_of(name: str, extra: dict | None = None) -> str:
    """The physics family of a library effect name by this half's :data:`FAMILY_KEYWORDS`
    (:func:`bank.test_half.score.family_of`)."""
    return base.family_of(name, extra, FAMILY_KEYWORDS)


def _gain_ratio(corrections: list) -> float | None:
    """The torque gain's correction as a ratio to the nominal (None: not in the report)."""
    for c in corrections:
        if "gain" in str(c.get("effect", "")).lower() and c.get("ratio_to_nominal") is not None:
            return float(c["ratio_to_nominal"])
    return None


def _new_claim(claim: str, want, params: dict, corrections: list) -> bool | None:
    """One of :data:`NEW_CLAIMS`: True, False or None (unreadable)."""
    p = base._param
    if claim == "coulomb_level_nm":          # the kinetic level in N m, within 50 %
        f = p(params, "fc", "coulomb", "kinetic")
        return None if f is None else abs(f - want) <= 0.5 * want
    if claim in ("speed_exponent_vs_1", "load_exponent_vs_1"):   # the law's exponent vs linear
        e = p(params, "exponent", "power")
        return None if e is None else (e > 1) == (want == "above")
    if claim == "time_constant_s":           # in s or ms, within a factor 2
        t = p(params, "time_const", "tau", "lag", "delay", avoid=("max", "sat", "limit"))
        if t is None:
            return None
        return want / 2 <= t <= 2 * want or want * 1e3 / 2 <= t <= 2 * want * 1e3
    if claim == "sensor_amplitude_rad":      # magnitude, within 50 %
        a = p(params, "eccentric", "runout", "sensor", "error_amp")
        return None if a is None else abs(abs(a) - want) <= 0.5 * want
    if claim == "torque_gain_vs_nominal":    # read from the corrections, named effect or not
        r = _gain_ratio(corrections)
        return None if r is None else (r < 1) == (want == "lower")
    raise KeyError(claim)


def check_signs(signs: dict, params: dict, corrections: list) -> dict:
    """Each claim: True, False or None (unreadable); the earlier halves' claims by their rules."""
    out = score2.check_signs({k: v for k, v in signs.items() if k not in NEW_CLAIMS}, params,
                             corrections)
    for claim, want in signs.items():
        if claim in NEW_CLAIMS:
            out[claim] = _new_claim(claim, want, params, corrections)
    return out


def score_case(case: dict, report: dict, extra: dict | None = None) -> dict:
    """The four points of one case (the earlier halves' rules, this half's families and
    claims)."""
    fams = {n: family_of(n, extra) for n in score2._names(report)}
    row = score2.score_case(case, report, fams)
    exp = case["expected"]
    named = [e for e in report.get("effects", []) if e.get("name") not in (None, "none")]
    if exp["family"] == "none" and named:   # a law of the right family is also right
        row["points"]["family"] = all(fams[e["name"]] in exp["accept"] for e in named)
    signs = exp["signs"]
    if any(k in NEW_CLAIMS for k in signs):
        params = named[0].get("parameters", {}) if named else {}
        got = check_signs(signs, params, report.get("corrections", []))
        readable = [v for v in got.values() if v is not None]
        row["signs"] = got
        row["points"]["direction"] = all(readable) if readable else None
    return row


def main(argv: list[str] | None = None) -> int:
    return base.cli(argv, score_case, "bank.test_half_3.make", __doc__.split("\n\n")[0])


if __name__ == "__main__":
    raise SystemExit(main())
