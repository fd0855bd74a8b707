"""The discrepancy package's stricter rule on arguments, read from its source (ast) with the check
of ``tests/test_sizes.py``: no function or method takes more than :data:`MAX_REQUIRED` required
arguments (``self``/``cls`` not counted; a bundle that travels through many functions belongs to
an object, e.g. :class:`discrepancy.search.Search`, :class:`discrepancy.select.Scorer`); the
lines of modules, classes and functions are held to every package's limits."""

from __future__ import annotations

from test_sizes import EXCEPTIONS, Limits, module_files, offenders, package_offenders

#: Most required arguments (positional or keyword, without a default) of a function or method.
MAX_REQUIRED = 6
LIMITS = Limits(required=MAX_REQUIRED)


def test_the_check_finds_what_breaks_the_rules():
    src = ("def wide(a, b, c, d, e, f, g):\n    pass\n"
           "def keywords(a, b, c, d, *, e, f, g):\n    pass\n"
           "def defaults(a, b, c, d, e, f, g=1, *, h=2, **kw):\n    pass\n"
           "class C:\n    def method(self, a, b, c, d, e, f):\n        pass\n"
           "    @classmethod\n    def make(cls, a, b, c, d, e, f, g):\n        pass\n")
    found = offenders(src, "m", LIMITS)
    assert found == {"m:wide (line 1)": ["7 required arguments (a, b, c, d, e, f, g)"],
                     "m:keywords (line 3)": ["7 required arguments (a, b, c, d, e, f, g)"],
                     "m:make (line 11)": ["7 required arguments (a, b, c, d, e, f, g)"]}


def test_the_package_keeps_the_rules():
    """Every module of ``discrepancy`` (the effect library included) within the rules."""
    assert len(module_files("discrepancy")) > 15  # the walk reads the package
    found = package_offenders(("discrepancy",), LIMITS, EXCEPTIONS)
    assert not found, "\n".join(f"{k}: {'; '.join(v)}" for k, v in found.items())
