"""TOPP-RA constraints of a crane's fixed joint path (toppra ``LinearConstraint`` classes, one
per idea): the pump flow as a bound on ṡ², a per-grid-point speed cap, and the joint
acceleration scaled per grid point and joint (the verification's tightening)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import toppra
import toppra.constraint as constraint
from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

from planner.model.flows import swept_volume

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["SCHEMES", "PumpFlowConstraint", "pump_flow_per_speed", "SpeedCap",
           "ScaledAcceleration"]

toppra.setup_logging("ERROR")  # failures are reported as statuses, not log lines

SCHEMES = {"interpolation": constraint.DiscretizationType.Interpolation,
           "collocation": constraint.DiscretizationType.Collocation}


class PumpFlowConstraint(constraint.LinearConstraint):
    """Σ A_dir,i |dx_i/ds| · ṡ ≤ Q_max as a bound on x = ṡ² (first order, direction-aware)."""

    def __init__(self, crane: Crane, scale: float = 1.0):
        super().__init__()
        self.crane = crane
        self.dof = crane.n
        self.scale = scale  # fraction of the pump's max flow to plan with

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        flow_per_sd = pump_flow_per_speed(self.crane, path(gridpoints), path(gridpoints, 1))
        qmax = self.scale * self.crane.spec.pump.max_flow
        with np.errstate(divide="ignore"):
            xmax = np.where(flow_per_sd > 1e-15, (qmax / flow_per_sd) ** 2, 1e12)
        xbound = np.column_stack([np.zeros_like(xmax), xmax])
        return None, None, None, None, None, None, xbound


def pump_flow_per_speed(crane: Crane, q, dq) -> np.ndarray:
    """Pump flow [m³ per unit of s] of moving along a path at ṡ = 1: Σ A_dir |dx/ds| at the
    joint positions ``q`` (..., n) with path tangents ``dq`` = dq/ds (..., n)."""
    _, dxdq = crane.stroke(q)
    return swept_volume(crane.spec, dxdq * dq).sum(-1)


class SpeedCap(constraint.LinearConstraint):
    """ṡ ≤ cap_i at every grid point as toppra's ``xbound`` (x = ṡ² ≤ cap_i²): the joint
    velocity limits and the pump limit, each already turned into a cap on ṡ per grid point
    (the caller scales them per grid point)."""

    def __init__(self, cap):
        super().__init__()
        self.cap = np.asarray(cap, float)

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        xmax = np.minimum(self.cap ** 2, 1e12)
        return None, None, None, None, None, None, np.column_stack([0 * xmax, xmax])


class ScaledAcceleration(constraint.LinearConstraint):
    """|q'(s_i) u + q''(s_i) x| ≤ f_ij · a_j per joint j and grid point i: toppra's joint
    acceleration constraint with a factor per grid point and joint (``scale`` (N+1, n)),
    written as the rows a_i / f_i, b_i / f_i against the nominal limits."""

    def __init__(self, dq, ddq, alim, scale, scheme="interpolation"):
        super().__init__()
        self.a, self.b = dq / scale, ddq / scale
        n = dq.shape[1]
        self.dof = n
        self.F = np.vstack([np.eye(n), -np.eye(n)])
        self.g = np.concatenate([alim, alim])
        self.identical = True
        self.set_discretization_type(SCHEMES[scheme])

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        c = np.zeros_like(self.a)
        if self.discretization_type == constraint.DiscretizationType.Collocation:
            return self.a, self.b, c, self.F, self.g, None, None
        return canlinear_colloc_to_interpolate(self.a, self.b, c, self.F, self.g, None, None,
                                               gridpoints, identical=True)
