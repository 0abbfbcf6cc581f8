"""MoveNLP's collaborators (guesses, activity mask, solver twins, pump rows) get what they use
explicitly: no class of the NLP package reads state it was not given, and no module reads
another object's private attributes."""
import ast
import math
from pathlib import Path

import numpy as np

import planner.methods.nlp as nlp_pkg
from planner import Crane
from planner.methods.nlp import MoveNLP
from planner.trajectory import evaluate

PKG = Path(nlp_pkg.__file__).parent


def _own_names(cls: ast.ClassDef) -> set:
    """What a class defines for itself: methods, class attributes, dataclass fields and every
    ``self.x = …`` target in its own methods."""
    names = set()
    for node in cls.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.Assign):
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    for node in ast.walk(cls):
        targets = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
            targets = [node.target]
        for t in targets:
            for e in ast.walk(t):
                if (isinstance(e, ast.Attribute) and isinstance(e.value, ast.Name)
                        and e.value.id == "self"):
                    names.add(e.attr)
    return names


def test_nlp_classes_read_only_what_they_were_given_or_made():
    """A mixin reads attributes its host sets (the old MoveNLP's four did: ``self._Aa``,
    ``self.layout``, ``self._twin_args``, …); a collaborator reads only its own."""
    bad = []
    for f in sorted(PKG.glob("*.py")):
        for cls in (n for n in ast.parse(f.read_text()).body if isinstance(n, ast.ClassDef)):
            bases = [ast.unparse(b) for b in cls.bases]
            if bases and bases != ["Planner"]:
                bad.append(f"{f.name}: class {cls.name}({', '.join(bases)})")
                continue
            if bases:        # the registered planner: the base's names are its own too
                continue
            own = _own_names(cls)
            for n in ast.walk(cls):
                if (isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name)
                        and n.value.id == "self" and isinstance(n.ctx, ast.Load)
                        and n.attr not in own and not n.attr.startswith("__")):
                    bad.append(f"{f.name}:{n.lineno} {cls.name} reads self.{n.attr}")
    assert bad == []


def test_no_nlp_module_reads_another_objects_private_attributes():
    bad = []
    for f in sorted(PKG.glob("*.py")):
        for n in ast.walk(ast.parse(f.read_text())):
            if (isinstance(n, ast.Attribute) and n.attr.startswith("_")
                    and not n.attr.startswith("__")
                    and not (isinstance(n.value, ast.Name) and n.value.id in ("self", "cls"))):
                bad.append(f"{f.name}:{n.lineno} {ast.unparse(n)}")
    assert bad == []


def test_least_energy_along_a_curve_builds_its_warm_twin_on_the_curve():
    """The energy NLP's later activity rounds run on a twin of the same formulation. Along a
    curve the twin used to be built from the path name 'curve' instead of the curve itself
    (ValueError at the second round); it is the same curve now. The oracle: the tip stays
    on seed 003's circle within the limits and the time budget, and the NLP's build time
    counts the twin's."""
    from planner.geometry.paths import circle, tip_to_xyz
    crane = Crane.from_id("umea-lab")
    cv = circle((3.0, 0.0, 2.5), 0.7, -math.pi / 2, math.pi / 2)
    en = MoveNLP(crane, "energy", cv, N=12)
    r = en.solve(T_max=6.0)
    assert r.ok, r.reason
    assert en.twins.warm_nlp is not None and en.twins.warm_nlp.curve is cv
    assert en.build_time_s == en.built_s + en.twins.warm_nlp.build_time_s
    ev = evaluate(crane, r.trajectory)
    assert ev.max_limit_violation <= 1e-3 and r.duration_s <= 6.0 * (1 + 1e-6)
    for tip, tol in ((crane.tip(r.trajectory.q), 1e-6),   # the nodes, where it is imposed
                     (ev.tip, 0.02)):                      # between them, at N = 12
        X = tip_to_xyz(tip)
        assert np.abs(np.hypot(X[:, 0] - 3.0, X[:, 2] - 2.5) - 0.7).max() < tol
        assert np.abs(X[:, 1]).max() < 1e-6
