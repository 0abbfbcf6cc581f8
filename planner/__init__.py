"""Optimisation-centric trajectory planning for hydraulic knuckle-boom cranes.

The public API (everything else is reachable through the subpackages)::

    from planner import Crane, PlanRequest, plan, evaluate
    crane = Crane.from_id("s100f")                      # a machine of problems/cranes/
    res = plan(crane, PlanRequest((6, -1, 0), (3, 2.5, 1.5)), method="nlp")
    verdict = evaluate(crane, res.trajectory)          # the one judge of every method

Layers: :mod:`planner.model` (spec, kinematics, dynamics, hydraulics) → :mod:`planner.methods`
(laws, DP, TOPP-RA, Ruckig, NLP behind one registry) → products (:mod:`planner.library`,
:mod:`planner.simulation`, :mod:`planner.calibration`, :mod:`planner.bench`, :mod:`planner.cli`).
"""
from planner.methods import PlanRequest, PlanResult, PlanStatus, plan
from planner.model import Crane, UnreachableError
from planner.model.spec import CraneSpec, SpecError, load_spec
from planner.trajectory import Trajectory, evaluate
from planner.version import __version__

__all__ = ["Crane", "CraneSpec", "SpecError", "UnreachableError", "load_spec", "Trajectory",
           "evaluate", "plan", "PlanRequest", "PlanResult", "LibraryStore", "Discrepancy",
           "PlanStatus", "__version__"]

_LAZY = {"LibraryStore": "planner.library.store", "Discrepancy": "planner.calibration.discrepancy"}


def __getattr__(name):
    # the products with heavier imports (h5py, the calibration stack) load on first use
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'planner' has no attribute {name!r}")
