"""The package's shape, checked from its own source: no import cycle inside planner/, no module
over 500 lines, no private name imported across modules, and the layering model -> methods ->
products (a lower layer never imports a higher one).

Imports are read with ``ast`` from every module, function-local imports included, so a cycle
hidden inside a function body fails here too.
"""
import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "planner"
MAX_LINES = 500

# layer of each top-level part of the package (lower numbers never import higher ones)
LAYERS = {
    "units": 0, "io": 0, "plots": 0, "version": 0,
    "model": 1,
    "geometry": 2, "trajectory": 2, "bounds": 2, "feedforward": 2, "tasks": 2,
    "methods": 3,
    "simulation": 4,
    "calibration": 5, "library": 5,
    "bench": 6,
    "demo": 7, "cli": 8, "__main__": 9,
}


def _modules() -> dict[str, Path]:
    out = {}
    for p in PKG.rglob("*.py"):
        parts = list(p.relative_to(PKG.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


MODULES = _modules()


def _imports(name: str, path: Path):
    """(imported module, imported name or None, line) for every import in the module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    for node in ast.walk(tree):
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
                yield (sub, None, node.lineno) if sub in MODULES else (base, a.name, node.lineno)


def _graph() -> dict[str, set[str]]:
    g = {m: set() for m in MODULES}
    for m, p in MODULES.items():
        for target, _, _ in _imports(m, p):
            if target in MODULES and target != m:
                g[m].add(target)
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


def test_no_import_cycle_inside_the_package():
    assert _cycles(_graph()) == []


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
