"""Joint <-> actuator maps: cylinder stroke x(q) for each actuator kind (symbolic).

x is the stroke [m] for cylinders (0 = fully retracted) and the motor angle [rad] for a rotary
drive; flow = area·ẋ and force = area·Δp in both cases, so the hydraulics need not care.
Each map depends only on its own joint, so dx/dq is a diagonal matrix.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from planner.model.spec import Actuator, Joint


def _rot2(theta, v):
    c, s = ca.cos(theta), ca.sin(theta)
    return ca.vertcat(c * v[0] - s * v[1], s * v[0] + c * v[1])


def lever_pin(act: Actuator, theta):
    """Joint point P of the two deflection levers (seed 002's outer-boom linkage).

    Lever 1 pivots on the parent at C = lever_pivot (length l1), lever 2 joins P to D on the child
    link, D = Rot(θ)·lever_link (length l2); P is the intersection of the two circles on the side
    given by lever_branch. Returns (P, h²) where h² < 0 means the linkage cannot close.
    """
    C = ca.DM(act.lever_pivot)
    D = _rot2(theta, ca.DM(act.lever_link))
    l1, l2 = act.lever_lengths
    dv = D - C
    d2 = dv[0] ** 2 + dv[1] ** 2
    d = ca.sqrt(d2)
    a = (l1 ** 2 - l2 ** 2 + d2) / (2 * d)
    h2 = l1 ** 2 - a ** 2
    h = ca.sqrt(ca.fmax(h2, 0.0))
    e = dv / d
    eperp = ca.vertcat(-e[1], e[0])
    P = C + a * e + act.lever_branch * h * eperp
    return P, h2


def pin_length(joint: Joint, q):
    """Pin-to-pin length of the cylinder [m] (triangle and lever kinds)."""
    act = joint.actuator
    theta = joint.dh.theta + q
    B = ca.DM(act.base)
    if act.kind == "triangle":
        v = B - _rot2(theta, ca.DM(act.rod))
    else:
        P, _ = lever_pin(act, theta)
        v = B - P
    return ca.sqrt(v[0] ** 2 + v[1] ** 2)


def stroke_expr(joint: Joint, q):
    """Stroke x(q) of the joint's actuator as a symbolic scalar."""
    act = joint.actuator
    if act.kind in ("triangle", "lever"):
        return pin_length(joint, q) - act.closed_length
    if act.kind == "telescope":
        return (q - act.q_ref) / act.ratio
    if act.kind == "rotary":
        return act.ratio * q
    if act.kind == "rack":
        return act.radius * q
    raise ValueError(f"unknown actuator kind {act.kind!r}")


def stroke_range(act: Actuator) -> tuple[float, float]:
    """Physical stroke range [m] of a cylinder; (-inf, inf) for rotary drives."""
    if act.kind in ("triangle", "lever", "telescope"):
        return 0.0, act.stroke
    return -np.inf, np.inf
