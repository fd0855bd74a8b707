"""The discrepancy package's size rules, read from its source (ast): no function or method takes
more than :data:`MAX_REQUIRED` required arguments (``self``/``cls`` not counted; a bundle that
travels through many functions belongs to an object, e.g. :class:`discrepancy.search.Search`,
:class:`discrepancy.select.Scorer`), no function is longer than :data:`MAX_FUNCTION_LINES`
lines and no class longer than :data:`MAX_CLASS_LINES`."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "discrepancy"
#: Most required arguments (positional or keyword, without a default) of a function or method.
MAX_REQUIRED = 6
MAX_FUNCTION_LINES = 80
MAX_CLASS_LINES = 300
#: Known exceptions, ``"module:function": reason`` (none today).
EXCEPTIONS: dict[str, str] = {}


def required_arguments(node: ast.FunctionDef | ast.AsyncFunctionDef) -> list[str]:
    """The names of a function's required arguments: positional ones without a default and
    keyword-only ones without a default, ``self`` and ``cls`` left out (``*args``/``**kwargs``
    are not required)."""
    a = node.args
    positional = a.posonlyargs + a.args
    required = positional[:len(positional) - len(a.defaults)]
    required += [arg for arg, default in zip(a.kwonlyargs, a.kw_defaults) if default is None]
    return [arg.arg for arg in required if arg.arg not in ("self", "cls")]


def offenders(source: str, module: str) -> dict[str, list[str]]:
    """``{"module:name (line)": [what breaks the rules]}`` for one module's source."""
    out: dict[str, list[str]] = {}
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            where = f"{module}:{node.name} (line {node.lineno})"
            lines = node.end_lineno - node.lineno + 1
            found = []
            if isinstance(node, ast.ClassDef):
                if lines > MAX_CLASS_LINES:
                    found.append(f"class of {lines} lines")
            else:
                args = required_arguments(node)
                if len(args) > MAX_REQUIRED:
                    found.append(f"{len(args)} required arguments ({', '.join(args)})")
                if lines > MAX_FUNCTION_LINES:
                    found.append(f"function of {lines} lines")
            if found:
                out[where] = found
    return out


def package_offenders() -> dict[str, list[str]]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        out.update(offenders(path.read_text(encoding="utf-8"), module))
    return {k: v for k, v in out.items() if k.split(" (line")[0] not in EXCEPTIONS}


def test_the_check_finds_what_breaks_the_rules():
    src = ("def wide(a, b, c, d, e, f, g):\n    pass\n"
           "def keywords(a, b, c, d, *, e, f, g):\n    pass\n"
           "def defaults(a, b, c, d, e, f, g=1, *, h=2, **kw):\n    pass\n"
           "class C:\n    def method(self, a, b, c, d, e, f):\n        pass\n"
           "    @classmethod\n    def make(cls, a, b, c, d, e, f, g):\n        pass\n"
           "def long():\n" + "    x = 1\n" * MAX_FUNCTION_LINES)
    found = offenders(src, "m")
    assert found == {"m:wide (line 1)": ["7 required arguments (a, b, c, d, e, f, g)"],
                     "m:keywords (line 3)": ["7 required arguments (a, b, c, d, e, f, g)"],
                     "m:make (line 11)": ["7 required arguments (a, b, c, d, e, f, g)"],
                     "m:long (line 13)": [f"function of {MAX_FUNCTION_LINES + 1} lines"]}
    big = "class Big:\n" + "    x = 1\n" * MAX_CLASS_LINES
    assert offenders(big, "m") == {"m:Big (line 1)": [f"class of {MAX_CLASS_LINES + 1} lines"]}


def test_the_package_keeps_the_rules():
    """Every module of ``discrepancy`` (the effect library included) within the rules."""
    modules = list(PACKAGE.rglob("*.py"))
    assert len(modules) > 15  # the walk reads the package (a wrong path would pass trivially)
    found = package_offenders()
    assert not found, "\n".join(f"{k}: {'; '.join(v)}" for k, v in found.items())
