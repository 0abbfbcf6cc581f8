"""The move NLP's tip constraints (:class:`~planner.methods.nlp.move.MoveNLP`): obstacles, the
straight tip line and a curve with a symbolic face. Each adds its rows to a
:class:`~planner.methods.nlp.transcription.Layout`; ``f_fk(q)`` is the crane's symbolic forward
kinematics (→ tip xyz, tip cylindrical). :mod:`planner.methods.nlp.cache` hashes this module's
source into the compiled-cache key."""
from __future__ import annotations

import casadi as ca

__all__ = ["add_obstacles", "add_curve", "add_line"]


CHECKS = (0.25, 0.5, 0.75)   # interior obstacle check points, as fractions of an interval


def add_obstacles(layout, f_fk, obstacles, checks) -> None:
    """Clearance from every obstacle at the check points ``checks``: (stage, (q, q̇, q̈)) pairs
    (the move NLP passes its nodes and, at :data:`CHECKS` of every interval, joint variables
    tied to the interval's cubic)."""
    for k, (q, _, _) in checks:
        xyz, cyl = f_fk(q)
        for ob in obstacles:
            for expr, lo in ob.constraints(xyz, cyl):
                layout.add_con("obstacle", expr, lo, ca.inf, stage=(k, 1))


def add_curve(layout, f_fk, curve, X, n: int, N: int) -> ca.SX:
    """One path parameter θ per node (returned; the caller adds it as the last variable
    block), monotone, fixed at the curve's ends; the tip on p(θ_k) at the nodes: per interval n
    jerks + 1 θ − 3 equations leave n − 2 free directions."""
    u0, u1 = curve.u_range
    TH = ca.SX.sym("TH", N + 1)
    for k in range(N + 1):
        layout.add_con("curve", f_fk(X[:n, k])[0] - curve.p_sym(TH[k]), 0.0, 0.0)
    layout.add_con("curve_ends", TH[0] - u0, 0.0, 0.0)
    layout.add_con("curve_ends", TH[N] - u1, 0.0, 0.0)
    sgn = 1.0 if u1 >= u0 else -1.0
    layout.add_con("curve_monotone", sgn * (TH[1:] - TH[:-1]), 0.0, ca.inf)
    return TH


def add_line(layout, f_fk, pts, pa, pb) -> None:
    """The tip on the straight line pa → pb at the interior nodes of ``pts`` only: per interval
    the n jerks leave n − 2 free directions (progress and redundancy); also imposing the
    midpoints would fix the motion completely."""
    d = pb - pa
    dn = d / ca.norm_2(d)
    # two unit vectors perpendicular to the line (robust for any direction)
    helper = ca.if_else(ca.fabs(dn[2]) < 0.9, ca.DM([0, 0, 1]), ca.DM([1, 0, 0]))
    e1 = ca.cross(dn, helper)
    e1 = e1 / ca.norm_2(e1)
    e2 = ca.cross(dn, e1)
    for k, (q, _, _) in enumerate(pts[1:-1], 1):
        r = f_fk(q)[0] - pa
        layout.add_con("line", ca.vertcat(ca.dot(r, e1), ca.dot(r, e2)), 0.0, 0.0,
                       stage=(k, 1))
        layout.add_con("line_progress", ca.dot(r, dn) / ca.norm_2(d), -0.02, 1.02,
                       stage=(k, 1))
