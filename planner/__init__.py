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
from planner.methods import PlanRequest, PlanResult, PlanStatus, UnsupportedRequest, plan
from planner.model import Crane, UnreachableError
from planner.model.spec import CraneSpec, SpecError, load_spec
from planner.trajectory import Trajectory, evaluate
from planner.version import __version__

__all__ = ["Crane", "CraneSpec", "SpecError", "UnreachableError", "load_spec", "Trajectory",
           "evaluate", "plan", "PlanRequest", "PlanResult", "PlanStatus", "UnsupportedRequest",
           "LibraryStore", "Discrepancy", "__version__"]

_LAZY = {"LibraryStore": "planner.library.store", "Discrepancy": "planner.calibration.discrepancy"}


def __getattr__(name):
    # the products with heavier imports (h5py, the calibration stack) load on first use
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'planner' has no attribute {name!r}")
