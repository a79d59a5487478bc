"""Layering of the package (read from the source with ``ast``, nothing is imported):

* no module imports a private name (leading underscore) of another module of the package;
* product code does not depend on the float64 oracle ``psbmpc_jax.reference`` (and its predictions);
* the library (everything outside ``psbmpc_jax/apps/``) does not import the applications ``psbmpc_jax.apps`` (the
  command line, the benchmark harness, the report), not even inside a function;
* no import cycle among the package's modules at module level (imports inside functions don't count);
* no import cycle through the method protocol (``psbmpc_jax.methods``) or the scenario loader
  (``psbmpc_jax.scenario``), counting imports inside functions too;
* the scenario loader imports no solver, simulator or evaluation code, not even inside a function (the methods
  build their controllers; the evaluation settings ``evaltool.params`` are the one evaltool module it reads);
* the light modules of the method protocol (base, registry, the built-in registrations, the settings modules
  that parse each method's section of a scenario file) import no solver at module level;
* ``py.typed`` ships with the package.
"""

from __future__ import annotations

import ast
import importlib.util
import pathlib
import sys
from typing import NamedTuple

import pytest

PACKAGE = "psbmpc_jax"
PACKAGE_DIR = pathlib.Path(importlib.util.find_spec(PACKAGE).submodule_search_locations[0]).resolve()
PYPROJECT = PACKAGE_DIR.parent / "pyproject.toml"

#: Modules allowed to import the reference evaluator besides reference.py itself: the benchmark harness's timing
#: (``apps/bench_timing.py``) times the reference (``impl = "reference"`` records) next to the JAX implementation,
#: by design; the smooth terms' float64 oracle (reference_smooth) builds on it.
REFERENCE_USERS = {f"{PACKAGE}.reference", f"{PACKAGE}.reference_prediction", f"{PACKAGE}.reference_smooth",
                   f"{PACKAGE}.reference_mcskf", f"{PACKAGE}.reference_informed", f"{PACKAGE}.apps.bench_timing"}
#: The sequential reference's modules (the cost evaluator and the trajectories it evaluates).
REFERENCE_MODULES = {f"{PACKAGE}.reference", f"{PACKAGE}.reference_prediction"}


def _module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE_DIR.rglob("*.py"))}


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


class Import(NamedTuple):
    module: str          # the importing module
    target: str          # the package module imported (the deepest one the statement names)
    names: tuple         # names taken from ``target`` (``from target import a, b``); () for a module import
    alias: str | None    # the local name bound to ``target`` when it is bound as a module
    lineno: int
    top_level: bool      # executed when the module is imported (not inside a function, not TYPE_CHECKING)


def _resolve_relative(module: str, level: int, name: str | None) -> str:
    base = module.split(".")
    if not _is_package(module):
        base = base[:-1]
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _walk(node, top_level: bool):
    """Yield ``(statement, top_level)`` for every import statement under ``node``."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.Import, ast.ImportFrom)):
            yield child, top_level
        elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            yield from _walk(child, False)
        elif isinstance(child, ast.If) and _is_type_checking(child.test):
            for stmt in child.body:
                yield from _walk(ast.Module(body=[stmt], type_ignores=[]), False)
            for stmt in child.orelse:
                yield from _walk(ast.Module(body=[stmt], type_ignores=[]), top_level)
        else:
            yield from _walk(child, top_level)


def _imports(module: str) -> list[Import]:
    tree = ast.parse(MODULES[module].read_text(), filename=str(MODULES[module]))
    out = []
    for stmt, top in _walk(tree, True):
        if isinstance(stmt, ast.Import):
            for a in stmt.names:
                if a.name == PACKAGE or a.name.startswith(PACKAGE + "."):
                    # ``import psbmpc_jax.x.y`` binds ``psbmpc_jax``; ``import psbmpc_jax.x.y as z`` binds z
                    out.append(Import(module, a.name, (), a.asname, stmt.lineno, top))
            continue
        if stmt.level:
            source = _resolve_relative(module, stmt.level, stmt.module)
        elif stmt.module and (stmt.module == PACKAGE or stmt.module.startswith(PACKAGE + ".")):
            source = stmt.module
        else:
            continue
        taken = []
        for a in stmt.names:
            sub = f"{source}.{a.name}"
            if sub in MODULES:  # ``from package import submodule``
                out.append(Import(module, sub, (), a.asname or a.name, stmt.lineno, top))
            else:
                taken.append(a.name)
        if taken:
            out.append(Import(module, source, tuple(taken), None, stmt.lineno, top))
    return out


IMPORTS = {m: _imports(m) for m in MODULES}


def _where(imp: Import) -> str:
    return f"{MODULES[imp.module].relative_to(PACKAGE_DIR.parent)}:{imp.lineno}"


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def test_every_import_resolves_to_a_package_module():
    """The checks below only mean something if the import parser finds the modules (a renamed module left
    behind in an import fails here, by its file and line)."""
    bad = [f"{_where(i)} imports {i.target}" for imps in IMPORTS.values() for i in imps if i.target not in MODULES]
    assert not bad, "imports of modules that do not exist:\n" + "\n".join(bad)
    assert sum(len(v) for v in IMPORTS.values()) > 50


def test_no_private_names_imported_across_modules():
    bad = []
    for module, imps in IMPORTS.items():
        for imp in imps:
            if imp.target == module:
                continue
            bad += [f"{_where(imp)}: {n} from {imp.target}" for n in imp.names if _private(n)]
            if _private(imp.target.rsplit(".", 1)[-1]):
                bad.append(f"{_where(imp)}: private module {imp.target}")
        # ``from . import metrics as m`` ... ``m._helper``: the same leak by attribute
        aliases = {i.alias: i.target for i in imps if i.alias and i.target != module}
        tree = ast.parse(MODULES[module].read_text())
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and _private(node.attr)):
                bad.append(f"{MODULES[module].relative_to(PACKAGE_DIR.parent)}:{node.lineno}: "
                           f"{node.value.id}.{node.attr} of {aliases[node.value.id]}")
    assert not bad, "private names used across modules (give them a public home):\n" + "\n".join(bad)


def test_product_code_does_not_import_the_reference():
    bad = [f"{_where(i)} imports {i.target}" for m, imps in IMPORTS.items() if m not in REFERENCE_USERS
           for i in imps if i.target in REFERENCE_MODULES]
    assert not bad, "the float64 reference is the test oracle, not a dependency:\n" + "\n".join(bad)


APPS = f"{PACKAGE}.apps"


def test_library_does_not_import_the_applications():
    """The applications (CLI, benchmark harness, report) sit on top of the library: no module outside
    ``psbmpc_jax/apps/`` imports them, at module level or inside a function."""
    bad = [f"{_where(i)} imports {i.target}" for m, imps in IMPORTS.items()
           if m != APPS and not m.startswith(APPS + ".")
           for i in imps if i.target == APPS or i.target.startswith(APPS + ".")]
    assert not bad, "the library must not depend on psbmpc_jax.apps:\n" + "\n".join(bad)
    # the check sees the applications' own imports of the library (the parser resolves the relative ``..``)
    assert any(i.target == f"{PACKAGE}.provenance" for i in IMPORTS[f"{APPS}.bench_timing"])


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (or a module importing itself) — Tarjan."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph) + 100))

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in graph[v]:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def module_graph() -> dict[str, set[str]]:
    """Module-level import edges among the package's modules."""
    return {m: {i.target for i in imps if i.top_level and i.target in MODULES} for m, imps in IMPORTS.items()}


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"a"}, "b": set()}) == [["a"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_module_level_import_cycles():
    graph = module_graph()
    lines = []
    for comp in _cycles(graph):
        edges = [f"    {_where(i)}: {i.module} -> {i.target}" for m in comp for i in IMPORTS[m]
                 if i.top_level and i.target in comp]
        lines.append(" <-> ".join(comp) + "\n" + "\n".join(edges))
    assert not lines, "import cycles at module level:\n" + "\n".join(lines)


def full_graph() -> dict[str, set[str]]:
    """Import edges among the package's modules, imports inside functions included."""
    return {m: {i.target for i in imps if i.target in MODULES} for m, imps in IMPORTS.items()}


def test_no_cycles_through_methods_or_scenario_counting_function_level_imports():
    ours = (f"{PACKAGE}.methods", f"{PACKAGE}.scenario")
    bad = [" <-> ".join(c) for c in _cycles(full_graph()) if any(m.startswith(ours) for m in c)]
    assert not bad, "import cycles (imports inside functions counted):\n" + "\n".join(bad)


#: What the scenario loader must not import (module name prefixes): the solver and its kernels, the
#: controllers, the simulator, the applications and the evaluation tool (but its settings module).
SOLVER_AND_EVALUATION = tuple(f"{PACKAGE}.{m}" for m in (
    "solve", "evaluate", "refine", "nlp", "smooth", "two_level", "costs", "packing", "ownship", "geometry",
    "sharding", "rollout_kernel", "planner", "distance_grid", "edge_blocks", "reference", "sim", "methods.grid",
    "methods.smooth", "methods.two_level", "methods.builtin", "evaltool", "bench", "cli", "report", "plots"))
SCENARIO_MAY_READ = (f"{PACKAGE}.evaltool.params",)


def _forbidden_for_scenario(target: str) -> bool:
    if target in SCENARIO_MAY_READ:
        return False
    return any(target == p or target.startswith(p + ".") or (p.endswith("reference") and target.startswith(p))
               for p in SOLVER_AND_EVALUATION)


def test_scenario_loader_imports_no_solver_or_evaluation_code():
    loaders = [m for m in MODULES if m == f"{PACKAGE}.scenario" or m.startswith(f"{PACKAGE}.scenario.")]
    assert len(loaders) >= 6
    bad = [f"{_where(i)} imports {i.target}" + ("" if i.top_level else " (inside a function)")
           for m in loaders for i in IMPORTS[m] if _forbidden_for_scenario(i.target)]
    assert not bad, "the scenario loader must not depend on solver/evaluation code:\n" + "\n".join(bad)
    assert _forbidden_for_scenario(f"{PACKAGE}.evaltool.tracks") and _forbidden_for_scenario(f"{PACKAGE}.solve")
    assert _forbidden_for_scenario(f"{PACKAGE}.reference_smooth") and not _forbidden_for_scenario(f"{PACKAGE}.params")


def test_the_light_method_modules_import_no_solver_at_module_level():
    """The scenario loader and the registry import these; the controllers import their solvers in build()."""
    light = [f"{PACKAGE}.methods", f"{PACKAGE}.methods.base", f"{PACKAGE}.methods.registry",
             f"{PACKAGE}.methods.builtin", f"{PACKAGE}.methods.sbmpc_family"]
    light += [m for m in MODULES if m.startswith(f"{PACKAGE}.methods.") and m.endswith("_settings")]
    assert len(light) >= 9
    helpers = {f"{PACKAGE}.checks", f"{PACKAGE}.config", f"{PACKAGE}.params", f"{PACKAGE}.design_ship"}
    bad = [f"{_where(i)} imports {i.target}" for m in light for i in IMPORTS[m]
           if i.top_level and i.target not in light and i.target not in helpers]
    assert not bad, "light method modules with heavy imports at module level:\n" + "\n".join(bad)
    tree = [ast.parse(MODULES[m].read_text()) for m in light]
    third = {a.name.split(".")[0] for t in tree for n in t.body if isinstance(n, ast.Import) for a in n.names}
    third |= {n.module.split(".")[0] for t in tree for n in t.body if isinstance(n, ast.ImportFrom) and n.module
              and not n.level}
    assert not third & {"jax", "jaxlib", "optax", "equinox", "shapely", "matplotlib"}, third


def test_py_typed_ships_with_the_package():
    assert (PACKAGE_DIR / "py.typed").is_file()
    if not PYPROJECT.is_file():
        pytest.skip("not a source checkout (no pyproject.toml)")
    import tomllib

    data = tomllib.loads(PYPROJECT.read_text())
    assert "py.typed" in data["tool"]["setuptools"]["package-data"][PACKAGE]
