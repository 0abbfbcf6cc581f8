"""Optimisation-centric trajectory planning for hydraulic knuckle-boom cranes."""
from planner.model import Crane, UnreachableError
from planner.model.spec import CraneSpec, SpecError, load_spec

__version__ = "0.1.0"
__all__ = ["Crane", "CraneSpec", "SpecError", "UnreachableError", "load_spec", "__version__"]
