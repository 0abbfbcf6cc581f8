"""Optimisation-centric trajectory planning for hydraulic knuckle-boom cranes.

The public API (everything else is reachable through the subpackages)::

    from planner import Crane, PlanRequest, UnsupportedRequest, plan, evaluate
    crane = Crane.from_id("s100f")                      # a machine of planner/problems/cranes/
    res = plan(crane, PlanRequest((6, -1, 0), (3, 2.5, 1.5)), method="nlp")
    verdict = evaluate(crane, res.trajectory)          # the one judge of every method

:func:`plan` returns a :class:`PlanResult` whose ``status`` says how planning went (``"ok"`` or
a short code with a ``reason``); it raises :class:`UnsupportedRequest` (a ``ValueError``) only
for a request the method does not plan at all: an objective or path kind it does not offer, a
field it would ignore, a value outside what is allowed.

Layers: :mod:`planner.model` (spec, kinematics, dynamics, hydraulics) → :mod:`planner.methods`
(laws, DP, TOPP-RA, Ruckig, NLP behind one registry) → products (:mod:`planner.library`,
:mod:`planner.simulation`, :mod:`planner.calibration`, :mod:`planner.bench`, :mod:`planner.cli`);
docs/design.md describes them, the models and the contracts.
"""
from planner.version import __version__

__all__ = ["Crane", "CraneSpec", "SpecError", "UnreachableError", "load_spec", "Trajectory",
           "evaluate", "plan", "PlanRequest", "PlanResult", "PlanStatus", "UnsupportedRequest",
           "LibraryStore", "Discrepancy", "__version__"]

# every public name loads its module on first use: ``import planner`` (and so every command of
# the CLI, whose modules live inside this package) costs no numpy, CasADi, scipy or h5py until a
# name that needs them is touched (tests/test_startup.py lists what must stay out)
_LAZY = {"Crane": "planner.model", "UnreachableError": "planner.model",
         "CraneSpec": "planner.model.spec", "SpecError": "planner.model.spec",
         "load_spec": "planner.model.spec",
         "Trajectory": "planner.trajectory", "evaluate": "planner.trajectory",
         "plan": "planner.methods", "PlanRequest": "planner.methods",
         "PlanResult": "planner.methods", "PlanStatus": "planner.methods",
         "UnsupportedRequest": "planner.methods",
         "LibraryStore": "planner.library.store", "Discrepancy": "planner.calibration.discrepancy"}


def __getattr__(name):
    if name in _LAZY:
        import importlib
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value   # once loaded, a plain attribute
        return value
    raise AttributeError(f"module 'planner' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
