"""The size rules of every package, read from the source (ast): no module longer than
:data:`MAX_MODULE_LINES` lines, no class longer than :data:`MAX_CLASS_LINES`, no function or
method longer than :data:`MAX_FUNCTION_LINES` or taking more than :data:`MAX_REQUIRED` required
arguments (``self``/``cls`` not counted).  ``discrepancy`` keeps a stricter rule on arguments
(``tests/test_discrepancy_arguments.py``).

Numba kernels are exempt: a compiled loop takes its arrays and settings one by one, since numba
compiles plain arguments, not objects.  A kernel is found in the source: a function whose
decorator is numba's (``numba.njit``, ``@jit(...)``, ``vectorize``, ...) or one of the module's
own functions that applies numba's (e.g. ``omni_studies.alpha_kernel._jit``).  Anything else
that breaks a rule is named in :data:`EXCEPTIONS` with its reason."""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("identification", "omni_sim", "discrepancy", "omni_studies", "omni_app")
MAX_MODULE_LINES = 700
MAX_CLASS_LINES = 300
MAX_FUNCTION_LINES = 80
#: Most required arguments (positional or keyword, without a default) of a function or method.
MAX_REQUIRED = 8
#: numba's compiling decorators (called or not, as ``numba.X`` or imported by name).
NUMBA_DECORATORS = frozenset({"jit", "njit", "vectorize", "guvectorize", "cfunc", "stencil",
                              "generated_jit", "jit_module"})

#: Known exceptions, ``"module" or "module:function": reason``.
EXCEPTIONS: dict[str, str] = {
    "identification.simulate:batch_loop_numpy":
        "the numpy reference of the numba loop omni_studies.alpha_kernel.loop: it keeps the "
        "kernel's exact signature (31 arguments) so the two are called alike and compared",
}


@dataclass(frozen=True)
class Limits:
    """The largest module, class and function (lines) and the most required arguments."""
    module: int = MAX_MODULE_LINES
    cls: int = MAX_CLASS_LINES
    function: int = MAX_FUNCTION_LINES
    required: int = MAX_REQUIRED


def required_arguments(node: ast.FunctionDef | ast.AsyncFunctionDef) -> list[str]:
    """The names of a function's required arguments: positional ones without a default and
    keyword-only ones without a default, ``self`` and ``cls`` left out (``*args``/``**kwargs``
    are not required)."""
    a = node.args
    positional = a.posonlyargs + a.args
    required = positional[:len(positional) - len(a.defaults)]
    required += [arg for arg, default in zip(a.kwonlyargs, a.kw_defaults) if default is None]
    return [arg.arg for arg in required if arg.arg not in ("self", "cls")]


def _numba_names(tree: ast.Module) -> tuple[set[str], set[str]]:
    """The names under which the module reaches numba (``import numba [as nb]``) and numba's
    compiling decorators imported by name (``from numba import njit``)."""
    modules, decorators = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules |= {a.asname or a.name for a in node.names if a.name == "numba"}
        elif isinstance(node, ast.ImportFrom) and node.module == "numba":
            decorators |= {a.asname or a.name for a in node.names if a.name in NUMBA_DECORATORS}
    return modules, decorators


def _is_numba(expr: ast.expr, modules: set[str], decorators: set[str]) -> bool:
    """``expr`` names one of numba's compiling decorators: ``njit``, ``numba.njit``, or either
    called (``numba.njit(cache=True)``)."""
    if isinstance(expr, ast.Call):
        expr = expr.func
    if isinstance(expr, ast.Name):
        return expr.id in decorators
    return (isinstance(expr, ast.Attribute) and expr.attr in NUMBA_DECORATORS
            and isinstance(expr.value, ast.Name) and expr.value.id in modules)


def kernels(tree: ast.Module) -> set[ast.AST]:
    """The module's numba kernels: functions decorated by numba, or by one of the module's own
    top-level functions that calls numba's decorator (a wrapper such as ``_jit``)."""
    modules, decorators = _numba_names(tree)
    if not (modules or decorators):
        return set()
    wrappers = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)
                and any(_is_numba(sub, modules, decorators) for sub in ast.walk(node)
                        if isinstance(sub, ast.Call))}
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for dec in node.decorator_list:
                target = dec.func if isinstance(dec, ast.Call) else dec
                if _is_numba(dec, modules, decorators) or (
                        isinstance(target, ast.Name) and target.id in wrappers):
                    out.add(node)
    return out


def offenders(source: str, module: str, limits: Limits = Limits()) -> dict[str, list[str]]:
    """``{"module" or "module:name (line)": [what breaks the rules]}`` for one module's source,
    its numba kernels left out."""
    out: dict[str, list[str]] = {}
    n_lines = len(source.splitlines())
    if n_lines > limits.module:
        out[module] = [f"module of {n_lines} lines"]
    tree = ast.parse(source)
    exempt = kernels(tree)
    for node in ast.walk(tree):
        if node in exempt or not isinstance(
                node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            continue
        lines = node.end_lineno - node.lineno + 1
        found = []
        if isinstance(node, ast.ClassDef):
            if lines > limits.cls:
                found.append(f"class of {lines} lines")
        else:
            args = required_arguments(node)
            if len(args) > limits.required:
                found.append(f"{len(args)} required arguments ({', '.join(args)})")
            if lines > limits.function:
                found.append(f"function of {lines} lines")
        if found:
            out[f"{module}:{node.name} (line {node.lineno})"] = found
    return out


def module_files(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


def package_offenders(packages=PACKAGES, limits: Limits = Limits(),
                      exceptions: dict[str, str] = EXCEPTIONS) -> dict[str, list[str]]:
    """The offenders of every module of ``packages``, the named exceptions left out."""
    out = {}
    for package in packages:
        for path in module_files(package):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            out.update(offenders(path.read_text(encoding="utf-8"), module, limits))
    return {k: v for k, v in out.items() if k.split(" (line")[0] not in exceptions}


def test_the_check_finds_what_breaks_the_rules():
    args = ", ".join(f"a{i}" for i in range(MAX_REQUIRED + 1))
    src = (f"def wide({args}):\n    pass\n"
           f"def keywords(a0, *, {args[4:]}):\n    pass\n"
           f"def defaults({args}=1, *, k=2, **kw):\n    pass\n"
           f"class C:\n    def method(self, {args[4:]}):\n        pass\n"
           f"    @classmethod\n    def make(cls, {args}):\n        pass\n"
           "def long():\n" + "    x = 1\n" * MAX_FUNCTION_LINES)
    found = offenders(src, "m")
    wide = [f"{MAX_REQUIRED + 1} required arguments ({args})"]
    assert found == {"m:wide (line 1)": wide, "m:keywords (line 3)": wide,
                     "m:make (line 11)": wide,
                     "m:long (line 13)": [f"function of {MAX_FUNCTION_LINES + 1} lines"]}
    big = "class Big:\n" + "    x = 1\n" * MAX_CLASS_LINES
    assert offenders(big, "m") == {"m:Big (line 1)": [f"class of {MAX_CLASS_LINES + 1} lines"]}
    long_module = "x = 1\n" * (MAX_MODULE_LINES + 1)
    assert offenders(long_module, "m") == {"m": [f"module of {MAX_MODULE_LINES + 1} lines"]}
    assert offenders("x = 1\n" * MAX_MODULE_LINES, "m") == {}


def test_numba_kernels_are_exempt_and_nothing_else():
    body = "    x = 1\n" * MAX_FUNCTION_LINES
    args = ", ".join(f"a{i}" for i in range(MAX_REQUIRED + 1))
    kernels_src = ("import numba as nb\nfrom numba import njit as fast, vectorize\n"
                   "def _jit(fn):\n    return nb.njit(cache=True)(fn)\n"
                   f"@nb.njit\ndef k1({args}):\n{body}"
                   f"@nb.jit(nopython=True)\ndef k2({args}):\n{body}"
                   f"@fast\ndef k3({args}):\n{body}"
                   f"@vectorize(['f8(f8)'])\ndef k4({args}):\n{body}"
                   f"@_jit\ndef k5({args}):\n{body}")
    assert offenders(kernels_src, "m") == {}
    # the same functions without numba, or decorated by something else, are checked
    plain = kernels_src.replace("import numba as nb\nfrom numba import", "from other import")
    plain = plain.replace("nb.", "other.")
    assert len(offenders(plain, "m")) == 5
    other = f"import numba\nimport functools\n@functools.cache\ndef f({args}):\n    pass\n"
    assert list(offenders(other, "m")) == ["m:f (line 4)"]


def test_the_packages_keep_the_rules():
    """Every module of the five packages within the rules (numba kernels and the named
    exceptions aside)."""
    for package in PACKAGES:  # the walk reads each package (a wrong path would pass trivially)
        assert len(module_files(package)) > 5, package
    found = package_offenders()
    assert not found, "\n".join(f"{k}: {'; '.join(v)}" for k, v in found.items())


def test_the_exceptions_are_still_needed():
    """Each named exception still exists and still breaks a rule (a stale entry is removed)."""
    everything = package_offenders(exceptions={})
    named = {k.split(" (line")[0] for k in everything}
    assert set(EXCEPTIONS) <= named, set(EXCEPTIONS) - named
