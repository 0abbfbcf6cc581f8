"""The package's shape, checked from its own source: no import cycle anywhere in the repository
(the package, its shipped data locator ``planner.problems``, tests, benchmarks, tools,
notebooks), no module over 500 lines, no private name imported across modules, the layering
model -> methods -> products (a lower layer never imports a higher one), and a distribution that
installs ``planner`` alone, its TOML data included (no top-level ``problems`` next to it).

Imports are read with ``ast`` from every module, function-local imports included, so a cycle
hidden inside a function body fails here too.
"""
import ast
import fnmatch
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "planner"
MAX_LINES = 500
SKIP = {"build", "dist", "__pycache__", "demo-output", "site-packages"}  # outputs, not source

# layer of each top-level part of the package (lower numbers never import higher ones)
LAYERS = {
    "problems": 0,  # locates the shipped TOML files; the model reads them
    "units": 0, "io": 0, "plots": 0, "version": 0,
    "model": 1,
    "geometry": 2, "trajectory": 2, "bounds": 2, "feedforward": 2, "refine": 2, "landing": 2, "tasks": 2,
    "methods": 3,
    "simulation": 4,
    "calibration": 5, "library": 5,
    "bench": 6, "animate": 6,
    "demo": 7, "cli": 8, "__main__": 9,
}


def _modules(*folders: Path) -> dict[str, Path]:
    """Dotted name (from the repository root) -> file, for every module under ``folders``."""
    out = {}
    for folder in folders:
        for p in folder.rglob("*.py"):
            parts = list(p.relative_to(ROOT).with_suffix("").parts)
            if any(x.startswith(".") or x in SKIP for x in parts):
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = p
    return out


MODULES = _modules(PKG)
REPO_MODULES = _modules(ROOT)  # every module of the repository, wherever it lives


def _type_only(tree) -> set:
    """The import nodes inside ``if TYPE_CHECKING:`` blocks: never executed (annotations
    only), so they neither cost an import nor close a cycle."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and (
                (isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING")
                or (isinstance(node.test, ast.Attribute) and node.test.attr == "TYPE_CHECKING")):
            out |= {id(n) for b in node.body for n in ast.walk(b)}
    return out


def _imports(name: str, path: Path, modules: dict[str, Path] = MODULES):
    """(imported module, imported name or None, line) for every import in the module that can
    run (function-local ones included; ``if TYPE_CHECKING:`` blocks excluded)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    skip = _type_only(tree)
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, None, node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            for a in node.names:
                sub = f"{base}.{a.name}"
                yield (sub, None, node.lineno) if sub in modules else (base, a.name, node.lineno)


def _outer_packages(module: str, target: str) -> list[str]:
    """The packages whose ``__init__`` an import of ``target`` runs from ``module``: every
    ancestor package of ``target`` that does not contain ``module`` (Python imports ``a`` and
    ``a.b`` before ``a.b.c``)."""
    parts = target.split(".")
    outer = []
    for k in range(1, len(parts)):
        anc = ".".join(parts[:k])
        if not (module == anc or module.startswith(anc + ".")):
            outer.append(anc)
    return outer


def _graph(modules: dict[str, Path] = MODULES) -> dict[str, set[str]]:
    """Module -> the modules its imports run: the imported module and the packages above it
    that the importer is not inside. A name that is not a module of ``modules`` is tried as a
    sibling of the importer (a script's folder is on ``sys.path`` when it runs)."""
    g = {m: set() for m in modules}
    for m, p in modules.items():
        folder = m.rsplit(".", 1)[0] if "." in m else ""
        for target, _, _ in _imports(m, p, modules):
            for t in (target, f"{folder}.{target}" if folder else None):
                if t in modules:
                    g[m].update(x for x in [t, *_outer_packages(m, t)]
                                if x in modules and x != m)
                    break
    return g


def _cycles(g):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in g[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle():
    # the oracle for the check below: a hand-made graph with one cycle of three and a tail
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(g) == [["a", "b", "c"]]


def test_the_graph_sees_a_hidden_cycle_and_sibling_imports(tmp_path):
    # two modules that import each other only inside function bodies, and a script that
    # imports its sibling by bare name (as the benchmarks do): all three edges must be seen
    (tmp_path / "a.py").write_text("def f():\n    from b import g\n", encoding="utf-8")
    (tmp_path / "b.py").write_text("def g():\n    import a\n", encoding="utf-8")
    mods = {"x.a": tmp_path / "a.py", "x.b": tmp_path / "b.py"}
    assert _graph(mods) == {"x.a": {"x.b"}, "x.b": {"x.a"}}
    assert _cycles(_graph(mods)) == [["x.a", "x.b"]]


def test_importing_a_submodule_runs_the_packages_above_it(tmp_path):
    # the shape the shipped-data loader once had: the data module imported ``pkg.model.spec``,
    # which runs ``pkg.model``'s __init__, which imported the data module back
    files = {"pkg/__init__.py": "", "pkg/model/__init__.py": "from pkg.data import where\n",
             "pkg/model/spec.py": "", "pkg/data.py": "def load():\n    from pkg.model.spec import x\n"}
    mods = {}
    for rel, text in files.items():
        f = tmp_path / rel
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text, encoding="utf-8")
        mods[rel.removesuffix(".py").removesuffix("/__init__").replace("/", ".")] = f
    g = _graph(mods)
    assert g["pkg.data"] == {"pkg.model", "pkg.model.spec"}
    assert g["pkg.model"] == {"pkg.data"}          # inside pkg: pkg's __init__ already runs
    assert _cycles(g) == [["pkg.data", "pkg.model"]]


def test_no_import_cycle_anywhere_in_the_repository():
    assert {"planner.problems", "tests.conftest", "benchmarks.bench_model"} <= set(REPO_MODULES)
    assert _cycles(_graph(REPO_MODULES)) == []


def test_the_data_locator_imports_nothing_of_the_package():
    # planner.problems only maps ids to files; the model reads them (no model <-> data cycle)
    mine = {t for t, _, _ in _imports("planner.problems", MODULES["planner.problems"])
            if t.split(".")[0] == "planner"}
    assert mine == set()


def test_the_distribution_ships_planner_alone_with_its_toml_data():
    """What ``pip install .`` puts into site-packages, read from pyproject.toml the way
    setuptools reads it: the packages found are planner's, and the package-data globs cover
    every shipped TOML file."""
    from setuptools import find_packages
    tool = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]
    found = find_packages(str(ROOT), **tool["setuptools"]["packages"]["find"])
    assert "planner.problems" in found
    assert {p.split(".")[0] for p in found} == {"planner"}
    data = tool["setuptools"]["package-data"]["planner.problems"]
    shipped = sorted(p.relative_to(PKG / "problems").as_posix()
                     for p in (PKG / "problems").rglob("*.toml"))
    assert len(shipped) >= 8
    assert [f for f in shipped if not any(fnmatch.fnmatch(f, g) for g in data)] == []
    assert not (ROOT / "problems").exists()


def test_no_module_over_500_lines():
    long = {m: n for m, p in MODULES.items()
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert long == {}


def test_no_private_name_imported_across_modules():
    bad = [f"{m}:{line} imports {target}.{name}" for m, p in MODULES.items()
           for target, name, line in _imports(m, p)
           if target.startswith("planner") and name and name.startswith("_")
           and not name.startswith("__") and target != m]
    assert bad == []


def _layer(module: str) -> int | None:
    parts = module.split(".")
    return LAYERS.get(parts[1]) if len(parts) > 1 else None


def test_every_part_of_the_package_has_a_layer():
    tops = {m.split(".")[1] for m in MODULES if m.count(".") >= 1}
    assert tops <= set(LAYERS), f"give these a layer in LAYERS: {sorted(tops - set(LAYERS))}"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m != "planner"))
def test_layering_model_methods_products(module):
    """A module imports only its own part or lower layers (model -> methods -> products)."""
    lo = _layer(module)
    up = sorted({t for t, _, _ in _imports(module, MODULES[module])
                 if t in MODULES and t != "planner" and t.split(".")[1] != module.split(".")[1]
                 and _layer(t) is not None and _layer(t) > lo})
    assert up == [], f"{module} (layer {lo}) imports higher layers: {up}"


def test_imports_under_type_checking_are_not_counted(tmp_path):
    # the oracle for the exclusion above: one real import, one annotation-only import
    f = tmp_path / "m.py"
    f.write_text("from typing import TYPE_CHECKING\nimport json\nif TYPE_CHECKING:\n"
                 "    from planner.model import Crane\n", encoding="utf-8")
    got = {t for t, _, _ in _imports("planner.m", f)}
    assert "json" in got and "planner.model" not in got


def test_every_crane_parameter_is_typed():
    """A ``crane`` parameter says what it takes (``Crane``; imported under TYPE_CHECKING
    where the module does not use it at run time)."""
    bare = [f"{m}:{node.lineno} {node.name}" for m, p in MODULES.items()
            for node in ast.walk(ast.parse(p.read_text(encoding="utf-8")))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            for a in node.args.posonlyargs + node.args.args + node.args.kwonlyargs
            if a.arg == "crane" and a.annotation is None]
    assert bare == []
