"""Score ``omni discrepancy`` reports on the second test half against its expectations.

Usage::

    python -m bank.test_half_2.score DATA/cases.json REPORTS --commit SHA [--out score.json]
        [--families names.json]

The first half's scoring (``bank.test_half.score``: the four points, family, no spurious
second effect, direction, unexplained) with two extensions, the first half's files unchanged:

* :data:`FAMILY_KEYWORDS`: keywords for the families this half adds (cogging, a gravity
  offset, a position offset, a dead zone), tried before the first half's table;
* :func:`check_signs`: the direction claims this half adds (``offset_rad``, ``delay_s``,
  ``stiffness_nm_per_rad``, ``ripple_order``), read from the named effect's parameters by
  name keywords; a claim that cannot be read is ``None`` (unchecked), never passed.

Every name in a report (its effects, ``settings.candidates`` and ``corrections``) is put into
a family by this half's table and handed to the first half's ``score_case`` as its
``extra`` map, so the first half's rules decide the points.
"""

from __future__ import annotations

from bank.test_half import score as base

#: This half's keywords (tried first), then the first half's table.
NEW_KEYWORDS = (
    ("cogging", "cogging"), ("ripple", "cogging"), ("detent", "cogging"),
    ("tilt", "gravity offset"), ("mass_offset", "gravity offset"), ("com_offset", "gravity offset"),
    ("gravity", "gravity offset"),
    ("position_offset", "position offset"), ("encoder_offset", "position offset"),
    ("zero_offset", "position offset"),
    ("dead_zone", "dead zone"), ("deadzone", "dead zone"), ("dead_band", "dead zone"),
    ("deadband", "dead zone"),
)
FAMILY_KEYWORDS = NEW_KEYWORDS + base.FAMILY_KEYWORDS
#: The claims this half adds to the first half's :func:`bank.test_half.score.check_signs`.
NEW_CLAIMS = ("offset_rad", "delay_s", "stiffness_nm_per_rad", "ripple_order")


def family_of(name: str, extra: dict | None = None) -> str:
    """The physics family of a library effect name by this half's :data:`FAMILY_KEYWORDS`
    (:func:`bank.test_half.score.family_of`)."""
    return base.family_of(name, extra, FAMILY_KEYWORDS)


def check_signs(signs: dict, params: dict, corrections: list) -> dict:
    """Each claim: True, False or None (unreadable); the first half's claims by its rules."""
    out = base.check_signs({k: v for k, v in signs.items() if k not in NEW_CLAIMS}, params, corrections)
    p = base._param
    for claim, want in signs.items():
        if claim not in NEW_CLAIMS:
            continue
        ok = None
        if claim == "offset_rad":      # the magnitude: the library's sign convention is unknown
            a = p(params, "tilt", "offset", "angle", "phi")
            if a is not None:
                ok = abs(abs(a) - want) <= 0.5 * want
        elif claim == "delay_s":       # in s or ms, within 50 %
            d = p(params, "delay", "latency", "lag", "dead_time")
            if d is not None:
                ok = abs(d - want) <= 0.5 * want or abs(d - 1e3 * want) <= 0.5 * 1e3 * want
        elif claim == "stiffness_nm_per_rad":   # within a factor 2
            k = p(params, "stiff", "spring", "k_")
            if k is not None:
                ok = want / 2 <= k <= 2 * want
        elif claim == "ripple_order":  # periods per turn, or the period in rad
            n = p(params, "order", "harmonic", "teeth", "cycles", "periods", "count")
            per = p(params, "period", "pitch", avoid=("periods",))
            if n is not None:
                ok = round(n) == want
            elif per is not None:
                ok = abs(per - 2 * 3.141592653589793 / want) <= 0.1 * 2 * 3.141592653589793 / want
        out[claim] = ok
    return out


def _names(report: dict) -> list[str]:
    return [str(e.get("name")) for e in report.get("effects", []) if e.get("name")] + \
        [str(n) for n in report.get("settings", {}).get("candidates", [])] + \
        [str(c.get("effect", "")) for c in report.get("corrections", [])]


def score_case(case: dict, report: dict, extra: dict | None = None) -> dict:
    """The four points of one case (the first half's rules, this half's families and claims)."""
    fams = {n: family_of(n, extra) for n in _names(report)}
    row = base.score_case(case, report, fams)
    signs = case["expected"]["signs"]
    if any(k in NEW_CLAIMS for k in signs):
        named = [e for e in report.get("effects", []) if e.get("name") not in (None, "none")]
        params = named[0].get("parameters", {}) if named else {}
        got = check_signs(signs, params, report.get("corrections", [])) if named else \
            {k: None for k in signs}
        readable = [v for v in got.values() if v is not None]
        row["signs"] = got
        row["points"]["direction"] = all(readable) if readable else None
    return row


def main(argv: list[str] | None = None) -> int:
    return base.cli(argv, score_case, "bank.test_half_2.make", __doc__.split("\n\n")[0])


if __name__ == "__main__":
    raise SystemExit(main())
