"""Planning methods: local laws, Bellman DP, NLP, TOPP-RA, Ruckig — one interface.

:mod:`planner.methods.base` defines the request, the result and the :class:`Planner` protocol;
:mod:`planner.methods.registry` finds a method by name (``plan(crane, request, method=...)``).
Every method returns a :class:`~planner.trajectory.Trajectory` inside its :class:`PlanResult`.
"""
from planner.methods.base import (PlanRequest, PlanResult, PlanStatus, Planner,
                                  UnsupportedRequest)
from planner.methods.registry import available, get, plan, register, unregister

__all__ = ["PlanRequest", "PlanResult", "PlanStatus", "Planner", "UnsupportedRequest",
           "available", "get", "plan", "register", "unregister"]
