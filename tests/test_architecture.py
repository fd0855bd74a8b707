"""Layering of the five packages: omni_app -> omni_studies -> discrepancy -> omni_sim ->
identification, no
import cycles, and scripts that are thin mains (no script imports another, a private name or
edits ``sys.path``); the validation bank (``bank/``, a distribution of its own) above them all,
which no module of the five imports but the one door, ``omni_studies/bank_link.py``.

The import graph is read from the source with :mod:`ast` (never by importing), including
imports inside functions, ``if TYPE_CHECKING:`` blocks and ``importlib.import_module("...")``
calls with a literal name; relative imports are resolved against the importing module.
"""

from __future__ import annotations

import ast
import functools
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("identification", "omni_sim", "discrepancy", "omni_studies", "omni_app")
#: The validation bank (bank/pyproject.toml: its own distribution, never installed with the five):
#: its modules are walked with theirs, it may import them all, and none of them imports it.
BANK = "bank"
#: Never imported by the method layer, directly or through a dependency.
METHOD_FORBIDDEN = ("matplotlib", "argparse", "mujoco", "omni_sim", "omni_app", "numba")
#: Must not appear in ``sys.modules`` after importing every identification module (numba: the
#: compiled kernels are the application's, registered with the method, never imported by it).
METHOD_FORBIDDEN_LOADED = ("mujoco", "matplotlib", "omni_sim", "omni_app", "numba")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    """Every module of the five packages and of the bank: dotted name -> source file."""
    out = {}
    for pkg in PACKAGES + (BANK,):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            # a subpackage's folder has an __init__.py (not, say, the bank's build/ of an install)
            folders = path.parent.relative_to(ROOT / pkg).parts
            if all((ROOT / pkg / Path(*folders[:i + 1]) / "__init__.py").is_file() for i in range(len(folders))):
                out[_module_name(path)] = path
    return out


MODULES = _modules()


def _resolve_relative(module: str, is_package: bool, level: int, name: str | None) -> str:
    """The absolute module named by ``from <level dots><name> import ...`` inside ``module``."""
    base = module.split(".")
    if not is_package:
        base = base[:-1]                      # a module's package
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def imports_of(module: str) -> list[tuple[str, int]]:
    """Absolute names this module imports, with line numbers, from anywhere in its source.

    ``from X import a`` yields ``X.a`` when that is one of our modules, otherwise ``X``.
    """
    return list(_imports_of(module))


@functools.cache  # each module's source parsed once for all the tests (the graph is built often)
def _imports_of(module: str) -> tuple[tuple[str, int], ...]:
    path = MODULES[module]
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = (_resolve_relative(module, is_package, node.level, node.module)
                      if node.level else node.module)
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.append((sub if sub in MODULES else target, node.lineno))
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and ((isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                   or (isinstance(node.func, ast.Name) and node.func.id in ("import_module", "__import__")))):
            found.append((node.args[0].value, node.lineno))
    return tuple(found)


def _internal_target(name: str) -> str | None:
    """The longest prefix of ``name`` that is one of our modules (None if external)."""
    parts = name.split(".")
    for n in range(len(parts), 0, -1):
        cand = ".".join(parts[:n])
        if cand in MODULES:
            return cand
    return None


def import_graph() -> dict[str, set[str]]:
    graph = {m: set() for m in MODULES}
    for m in MODULES:
        for name, _ in imports_of(m):
            t = _internal_target(name)
            if t is not None:
                graph[m].add(t)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module, or a module importing itself
    (Tarjan's algorithm, iterative)."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, it = work[-1]
            for nxt in it:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter
                    counter += 1
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        x = stack.pop()
                        on_stack.discard(x)
                        comp.append(x)
                        if x == node:
                            break
                    if len(comp) > 1 or node in graph[node]:
                        out.append(sorted(comp))
    return out


# -- the checker itself --------------------------------------------------------------------------
def test_cycle_finder_finds_a_cycle_and_a_self_import():
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}, "f": set()}
    assert sorted(cycles(g)) == [["a", "b", "c"], ["e"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_relative_imports_resolve():
    assert _resolve_relative("discrepancy.bank", False, 1, "fit") == "discrepancy.fit"
    assert _resolve_relative("bank.studies.discrepancy_bank", False, 2, "hidden") == "bank.hidden"
    assert _resolve_relative("discrepancy.effects.base", False, 2, None) == "discrepancy"
    assert _resolve_relative("discrepancy", True, 1, "bank") == "discrepancy.bank"
    assert _resolve_relative("discrepancy.effects", True, 2, "fit") == "discrepancy.fit"
    # a relative import of this repository, as the graph sees it
    assert "identification.paper" in import_graph()["identification.nonlinear"]


def test_every_package_was_walked():
    least = {"identification": 8, "omni_sim": 8, "discrepancy": 8, "omni_studies": 2, "omni_app": 8, BANK: 8}
    for pkg in PACKAGES + (BANK,):   # (omni_app has no __init__.py: a namespace package)
        assert sum(m.startswith(pkg + ".") for m in MODULES) >= least[pkg], pkg
    assert "bank.hidden" in MODULES and "bank.studies.discrepancy_bank" in MODULES and "omni_app.report" in MODULES


# -- the rules -----------------------------------------------------------------------------------
def test_no_import_cycles():
    found = cycles(import_graph())
    assert not found, "import cycles between modules: " + "; ".join(" <-> ".join(c) for c in found)


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.split(".")[0] == "identification"))
def test_method_layer_imports(module):
    bad = [f"line {line}: {name}" for name, line in imports_of(module)
           if name.split(".")[0] in METHOD_FORBIDDEN]
    assert not bad, f"{module} imports outside the method layer: {bad}"


#: What each package may import of ours (itself and the floors below).
ALLOWED = {"identification": {"identification"},
           "omni_sim": {"identification", "omni_sim"},
           "discrepancy": {"identification", "omni_sim", "discrepancy"},
           "omni_studies": {"identification", "omni_sim", "discrepancy", "omni_studies"},
           "omni_app": {"identification", "omni_sim", "discrepancy", "omni_studies", "omni_app"}}


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.split(".")[0] in ("omni_sim", "discrepancy", "omni_studies")))
def test_no_import_runs_up_a_floor(module):
    pkg = module.split(".")[0]
    bad = [f"line {line}: {name}" for name, line in imports_of(module)
           if name.split(".")[0] in PACKAGES and name.split(".")[0] not in ALLOWED[pkg]]
    assert not bad, f"{module} imports a floor above its own: {bad}"


# -- no private name crosses a package ------------------------------------------------------------
def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _dotted(node: ast.AST) -> list[str] | None:
    """``a.b.c`` as ``["a", "b", "c"]``; None if the chain does not start at a name."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return [node.id] + parts[::-1] if isinstance(node, ast.Name) else None


def private_uses(source: str, package: str) -> list[str]:
    """Uses in ``source`` (a module of ``package``) of a private name of another of our packages:
    ``from pkg.mod import _x``, an import from or of a private module (``pkg._mod``), and
    ``alias._x`` (or ``alias.sub._x``) where ``alias`` is bound to another package's module."""
    others = set(PACKAGES + (BANK,)) - {package}
    bound = {}  # local name -> the other package's dotted name it is bound to
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in others:
                    if any(_private(p) for p in a.name.split(".")):
                        out.append(f"line {node.lineno}: imports {a.name}")
                    bound[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            if node.module.split(".")[0] in others:
                if any(_private(p) for p in node.module.split(".")):
                    out.append(f"line {node.lineno}: imports from {node.module}")
                for a in node.names:
                    if _private(a.name):
                        out.append(f"line {node.lineno}: imports the private {node.module}.{a.name}")
                    bound[a.asname or a.name] = f"{node.module}.{a.name}"
    for node in ast.walk(ast.parse(source)):
        parts = _dotted(node) if isinstance(node, ast.Attribute) else None
        if parts and parts[0] in bound and _private(parts[-1]):
            out.append(f"line {node.lineno}: uses the private {'.'.join([bound[parts[0]]] + parts[1:])}")
    return out


def test_private_use_finder_finds_them():
    """The finder flags each way of reaching into another package, and nothing public or within
    the package itself."""
    bad = ("from identification.simulate import _batch\n"
           "from identification import simulate as sim, paper\n"
           "import identification.simulate\n"
           "from omni_sim._resources import models_dir\n"
           "sim._KERNEL\n"
           "paper._table\n"
           "identification.simulate._loop(1)\n")
    assert private_uses(bad, "omni_studies") == [
        "line 1: imports the private identification.simulate._batch",
        "line 4: imports from omni_sim._resources",
        "line 5: uses the private identification.simulate._KERNEL",
        "line 6: uses the private identification.paper._table",
        "line 7: uses the private identification.simulate._loop"]
    good = ("from identification import simulate as sim\nfrom omni_studies import _own\n"
            "from . import _sibling\nsim.current_kernel()\nsim.__name__\n_sibling._x\n")
    assert private_uses(good, "omni_studies") == []
    # a package's own private names are its own
    assert private_uses(bad, "identification") == ["line 4: imports from omni_sim._resources"]


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_private_name_crosses_a_package(module):
    """No module uses a private name (``_x``) of another of the five packages or of the bank:
    what one package needs of another is public there."""
    bad = private_uses(MODULES[module].read_text(), module.split(".")[0])
    assert not bad, f"{module}: {bad}"


# -- the scripts: thin mains ---------------------------------------------------------------------
SCRIPTS = sorted((ROOT / "scripts").glob("*.py"))


def script_problems(path: Path) -> list[str]:
    """What makes a script more than a thin main: an import of another script (``scripts``),
    a private name of a package (``from pkg import _x``, ``module._x``), a ``sys.path`` edit."""
    tree = ast.parse(path.read_text(), filename=str(path))
    ours = set(PACKAGES + (BANK,))
    modules = {}  # local name -> our module it is bound to
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                top = a.name.split(".")[0]
                if top == "scripts":
                    out.append(f"line {node.lineno}: imports {a.name}")
                if top in ours:
                    modules[a.asname or top] = a.name
        elif isinstance(node, ast.ImportFrom) and node.module:
            top = node.module.split(".")[0]
            if top == "scripts" or node.level:
                out.append(f"line {node.lineno}: imports from {node.module}")
            if top in ours:
                for a in node.names:
                    if a.name.startswith("_"):
                        out.append(f"line {node.lineno}: imports the private {node.module}.{a.name}")
                    modules[a.asname or a.name] = f"{node.module}.{a.name}"
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in modules and node.attr.startswith("_") and not node.attr.startswith("__")):
            out.append(f"line {node.lineno}: uses the private {modules[node.value.id]}.{node.attr}")
        if (isinstance(node, ast.Attribute) and node.attr == "path" and isinstance(node.value, ast.Name)
                and node.value.id == "sys"):
            out.append(f"line {node.lineno}: touches sys.path")
    return out


def test_script_checker_finds_what_it_forbids(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import sys\nfrom scripts import other\nfrom omni_sim.device import _numeric\n"
                   "from omni_studies import calibration as cal\nsys.path.insert(0, '.')\ncal._fmt(1)\n"
                   "from bank.writers import bank_report as rep\nrep._named({})\n")
    found = script_problems(bad)
    assert len(found) == 5, found
    good = tmp_path / "good.py"
    good.write_text("import sys\nfrom omni_studies import calibration as cal\ncal.fmt(1)\nprint(sys.argv)\n")
    assert script_problems(good) == []


#: A thin main's length: options, a study, its writer (the longest, discrepancy_bank.py, is 118
#: lines, most of it the options' help; a script past this holds a study or a writer).
SCRIPT_MAX_LINES = 150


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_scripts_are_thin_mains(path):
    found = script_problems(path)
    lines = len(path.read_text().splitlines())
    if lines > SCRIPT_MAX_LINES:
        found.append(f"{lines} lines (a thin main has at most {SCRIPT_MAX_LINES}: move the study "
                     "to omni_studies, its writing to omni_app)")
    assert not found, f"{path.name}: {found}"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.split(".")[0] == "omni_studies"
                                           or m.startswith(BANK + ".studies")))
def test_studies_draw_no_figures(module):
    """A study computes and returns; its figures are the application's (omni_app; the bank's
    studies': bank.writers)."""
    bad = [f"line {line}: {name}" for name, line in imports_of(module)
           if name.split(".")[0] == "matplotlib"]
    assert not bad, f"{module} imports matplotlib: {bad}"


def test_the_architecture_page_names_every_room():
    """docs/reference/architecture.md draws the house: every module of the five packages and of
    the bank and every script is named on it (by its file name, without .py)."""
    page = (ROOT / "docs" / "reference" / "architecture.md").read_text()
    rooms = [m.rsplit(".", 1)[-1] for m in MODULES]  # a package: its folder's name
    rooms += [p.stem for p in SCRIPTS]
    missing = sorted({r for r in rooms if not re.search(rf"\b{re.escape(r)}\b", page)})
    assert not missing, f"docs/reference/architecture.md does not name: {missing}"


def test_method_layer_loads_without_simulator_or_plotting():
    """Importing every identification module pulls in none of MuJoCo, matplotlib, omni_sim."""
    mods = sorted(m for m in MODULES if m.split(".")[0] == "identification")
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}:\n"
        "    importlib.import_module(m)\n"
        f"bad = [m for m in {METHOD_FORBIDDEN_LOADED!r} if m in sys.modules]\n"
        "sys.exit('loaded: ' + ', '.join(bad) if bad else 0)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr


# -- the discrepancy package ---------------------------------------------------------------------
DISCREPANCY = "discrepancy"
#: Its layers (module names inside the package; ``effects`` stands for the package and its modules).
DISCREPANCY_LAYERS = {
    "runs": ("runs",),  # a run prepared for replay: plain data
    "statistics": ("localise", "fit", "folds", "lockstep", "prescreen", "select", "uncertainty", "nesting", "report"),
    # MuJoCo: the replay, the effect library, the missing torque and its equation-error naming
    "simulation": ("replay", "effects", "smoothing", "bristles", "torque", "shape", "evidence"),
    "workflow": ("workflow", "search", "result"),  # joins statistics and simulation; its result
    "truth": ("experiment_set", "demo"),  # hidden effects: the demo's; the bank's cases are bank/
}
#: The layers each layer may import inside the package (the package's ``__init__`` is exempt).
DISCREPANCY_ALLOWED = {
    "runs": {"runs"},
    "statistics": {"runs", "statistics"},
    "simulation": {"runs", "simulation"},
    "workflow": {"runs", "statistics", "simulation", "workflow"},
    "truth": {"truth"},
}
#: The statistics: no MuJoCo, directly or through the modules they import.
STATISTICS = [f"{DISCREPANCY}.{m}" for m in DISCREPANCY_LAYERS["runs"] + DISCREPANCY_LAYERS["statistics"]]


def reach(module: str, graph: dict[str, set[str]]) -> dict[str, list[str]]:
    """Every module ``module`` imports, directly or through others, with the chain of imports
    that reaches it (the packages' ``__init__`` that Python runs first is not followed unless
    imported by name)."""
    seen = {module: [module]}
    todo = [module]
    while todo:
        m = todo.pop()
        for n in sorted(graph[m]):
            if n not in seen:
                seen[n] = seen[m] + [n]
                todo.append(n)
    del seen[module]
    return seen


def discrepancy_layer(module: str) -> str | None:
    """The layer of a module of the discrepancy package (None: the package's ``__init__`` or
    not a module of the package)."""
    if not module.startswith(DISCREPANCY + "."):
        return None
    name = module[len(DISCREPANCY) + 1:].split(".")[0]
    return next((layer for layer, names in DISCREPANCY_LAYERS.items() if name in names), None)


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """Imports inside the discrepancy package that go against :data:`DISCREPANCY_ALLOWED`."""
    bad = []
    for m in sorted(graph):
        layer = discrepancy_layer(m)
        if layer is None:
            continue
        for n in sorted(graph[m]):
            other = discrepancy_layer(n)
            if n.startswith(DISCREPANCY) and other not in DISCREPANCY_ALLOWED[layer]:
                bad.append(f"{m} ({layer}) imports {n} ({other})")
    return bad


def test_layer_check_finds_a_wrong_direction():
    g = {f"{DISCREPANCY}.fit": {f"{DISCREPANCY}.replay", f"{DISCREPANCY}.runs"},
         f"{DISCREPANCY}.replay": {f"{DISCREPANCY}.runs"}, f"{DISCREPANCY}.runs": set(),
         f"{DISCREPANCY}.demo": {f"{DISCREPANCY}.effects.friction"}, f"{DISCREPANCY}.effects.friction": set()}
    assert layer_violations(g) == [f"{DISCREPANCY}.demo (truth) imports {DISCREPANCY}.effects.friction (simulation)",
                                   f"{DISCREPANCY}.fit (statistics) imports {DISCREPANCY}.replay (simulation)"]
    assert reach(f"{DISCREPANCY}.fit", g) == {f"{DISCREPANCY}.replay": [f"{DISCREPANCY}.fit", f"{DISCREPANCY}.replay"],
                                              f"{DISCREPANCY}.runs": [f"{DISCREPANCY}.fit", f"{DISCREPANCY}.runs"]}


def test_discrepancy_layers():
    """Inside the discrepancy package the statistics import only each other and the runs, the
    simulation side (replay, effect library) only itself and the runs, the workflow both, and
    the truth side (the experiment set of hidden cases, the demo's truth) only itself; every
    module of the package has a layer."""
    graph = import_graph()
    unplaced = [m for m in MODULES if m.startswith(DISCREPANCY + ".") and discrepancy_layer(m) is None]
    assert not unplaced, f"modules without a layer: {unplaced}"
    bad = layer_violations(graph)
    assert not bad, bad


@pytest.mark.parametrize("module", STATISTICS)
def test_statistics_import_no_mujoco(module):
    """The statistics (fit, select, uncertainty, localise and the runs they take) import no
    MuJoCo, directly or through any module of the packages they import: models come from the
    caller's ``ModelBuilder``, simulations from its ``Replayer``."""
    chains = {module: [module], **reach(module, import_graph())}
    bad = [" -> ".join(chain) + f" (line {line}: {name})" for m, chain in chains.items()
           for name, line in imports_of(m) if name.split(".")[0] == "mujoco"]
    assert not bad, bad


def test_statistics_walk_follows_their_imports():
    """The walk of :func:`test_statistics_import_no_mujoco` sees what the statistics import
    (a walk that found nothing would pass trivially)."""
    assert {f"{DISCREPANCY}.fit", f"{DISCREPANCY}.select", f"{DISCREPANCY}.runs"} <= set(
        reach(f"{DISCREPANCY}.uncertainty", import_graph()))


# -- the validation bank: above the five packages, imported by none of them -----------------------
#: The one module of the five packages that imports the bank, inside a function only: the door
#: of the commands that run the bank's cases (omni bench's discrepancy figures, omni sweep's
#: discrepancy pipeline), which refuse in one line when the bank is not installed.
BANK_DOOR = "omni_studies.bank_link"
#: The bank's parts and what each may import of the bank and of the five packages: the truths
#: (the cases, the truth writers, the servo truth, the coverage ranges) sit on the library;
#: the studies compute on them (as omni_studies does); the writers present the studies (as
#: omni_app does); the test half was written without reading the library, and imports none of it.
BANK_PARTS = {
    "truths": ({"identification", "omni_sim", "discrepancy"}, {"truths"}),
    "studies": ({"identification", "omni_sim", "discrepancy", "omni_studies"}, {"truths", "studies"}),
    "writers": (set(PACKAGES), {"truths", "studies", "writers"}),
    "test_half": ({"identification"}, {"test_half"}),
    # the second test half reuses the first's plant, loop, campaign and scoring, nothing else
    "test_half_2": ({"identification"}, {"test_half", "test_half_2"}),
    # the third test half reuses the first's plant, campaign and scoring and the second's loop
    # and scoring, nothing else
    "test_half_3": ({"identification"}, {"test_half", "test_half_2", "test_half_3"}),
    # the fourth test half reuses the first's plant, campaign and scoring, the second's loop, make
    # and scoring and the third's voltage read-back, families and scoring, nothing else
    "test_half_4": ({"identification"}, {"test_half", "test_half_2", "test_half_3", "test_half_4"}),
}


def bank_part(module: str) -> str | None:
    """The part of the bank a module belongs to (None: not a module of the bank, or its
    ``__init__``)."""
    parts = module.split(".")
    if parts[0] != BANK or len(parts) == 1:
        return None
    return parts[1] if parts[1] in ("studies", "writers", "test_half", "test_half_2", "test_half_3",
                                           "test_half_4") else "truths"


def bank_imports(source: str) -> list[tuple[int, str, bool]]:
    """Every import of the bank in ``source``: ``(line, name, inside a function)``; ``import``,
    ``from ... import`` and ``importlib.import_module("...")`` with a literal name."""
    tree = ast.parse(source)
    in_function = {id(sub) for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                   for sub in ast.walk(node)}
    out = []
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names = [node.module]
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and ((isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                   or (isinstance(node.func, ast.Name) and node.func.id in ("import_module", "__import__")))):
            names = [node.args[0].value]
        out += [(node.lineno, n, id(node) in in_function) for n in names if n.split(".")[0] == BANK]
    return out


def test_the_bank_import_finder_finds_them():
    code = ("import bank\nfrom bank.studies import discrepancy_bank\nimport banking\n"
            "def f():\n    import bank.hidden\n    return importlib.import_module('bank.ranges')\n"
            "from . import bank\n")
    assert sorted(bank_imports(code)) == [(1, "bank", False), (2, "bank.studies", False),
                                          (5, "bank.hidden", True), (6, "bank.ranges", True)]


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.split(".")[0] in PACKAGES))
def test_no_installed_module_imports_the_bank(module):
    """No module of the five packages imports the bank (a distribution a regular install does
    not have): only :data:`BANK_DOOR` does, inside its function, where a missing bank becomes
    one line naming the fix."""
    found = bank_imports(MODULES[module].read_text())
    if module == BANK_DOOR:
        assert found and all(inside for _, _, inside in found), found
    else:
        assert not found, f"{module} imports the bank: {found} (go through {BANK_DOOR})"


def test_the_five_packages_reach_the_bank_only_through_its_door():
    """Whatever a module of the five packages reaches of the bank, directly or through others,
    passes through :data:`BANK_DOOR`, and is the bank's cases and truths: never its studies,
    writers, coverage ranges or test half."""
    graph = import_graph()
    bad = []
    for m in sorted(x for x in MODULES if x.split(".")[0] in PACKAGES):
        for t, chain in reach(m, graph).items():
            if t.split(".")[0] == BANK and (BANK_DOOR not in [m] + chain
                                            or bank_part(t) != "truths" or t == "bank.ranges"):
                bad.append(" -> ".join([m] + chain[1:]))
    assert not bad, bad
    # the walk sees the door's imports inside its function (a walk that found nothing would pass)
    for m in ("omni_studies.sweep", "omni_studies.bench"):
        assert {"bank.hidden", "bank.servo_truth"} <= set(reach(m, graph)), m


@pytest.mark.parametrize("module", sorted(m for m in MODULES if bank_part(m)))
def test_bank_parts(module):
    """Each part of the bank imports only what :data:`BANK_PARTS` allows it: of the five
    packages, and of the bank's own parts (every module of the bank has a part)."""
    packages, parts = BANK_PARTS[bank_part(module)]
    bad = []
    for name, line in imports_of(module):
        top = name.split(".")[0]
        if top in PACKAGES and top not in packages:
            bad.append(f"line {line}: {name}")
        elif top == BANK and name != BANK and bank_part(_internal_target(name) or name) not in parts:
            bad.append(f"line {line}: {name} ({bank_part(_internal_target(name) or name)})")
    assert not bad, f"{module} ({bank_part(module)}) imports: {bad}"


#: Process-global machinery the packages do without: forking a process that may
#: have threads (``os.fork``, ``get_context("fork")``), moving objects out of the collector's
#: reach (``gc.freeze``), import hooks (``sys.meta_path``).
PROCESS_GLOBAL = {("os", "fork"), ("gc", "freeze"), ("sys", "meta_path")}


def process_global_uses(source: str) -> list[str]:
    """``NAME.ATTR`` uses of :data:`PROCESS_GLOBAL` in ``source``, and the string ``"fork"``
    as a call's argument (a start method), with line numbers."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and (node.value.id, node.attr) in PROCESS_GLOBAL):
            found.append(f"line {node.lineno}: {node.value.id}.{node.attr}")
        elif isinstance(node, ast.Call) and any(isinstance(a, ast.Constant) and a.value == "fork"
                                                for a in node.args):
            found.append(f"line {node.lineno}: start method 'fork'")
    return found


def test_process_global_finder_finds_them():
    code = ("import os, gc, sys, multiprocessing as mp\nos.fork()\ngc.freeze()\n"
            "sys.meta_path.insert(0, None)\nmp.get_context('fork')\nmp.get_context('spawn')\n")
    assert sorted(process_global_uses(code)) == ["line 2: os.fork", "line 3: gc.freeze",
                                                 "line 4: sys.meta_path",
                                                 "line 5: start method 'fork'"]


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_process_global_machinery(module):
    bad = process_global_uses(MODULES[module].read_text())
    assert not bad, f"{module}: {bad}"
