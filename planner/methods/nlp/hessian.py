"""The exact Hessian of the minimum-time move NLP's Lagrangian, with the pump rows differentiated
through their stroke Jacobians (issue 31: the NLP's own overhead against a plain Opti).

The pump row of a check point is Φ(y, w): the smooth draw (:func:`~planner.methods.nlp.limits.
pump_draw`) of the joint rates in w through the stroke Jacobians y, and at the nodes y = J(q),
J(q)ᵢ = dxᵢ/dqᵢ (the midpoints take the mean of their nodes'). Written as one expression in w,
CasADi's Hessian of λᵀΦ(J(w), w) differentiates the stroke kinematics three times inside every
pair of rows that shares a node: 85k of the 121k instructions of the whole Hessian on umea-lab
at N = 40. The chain rule splits it exactly:

    ∇²_w λᵀΦ(J(w), w) = Mᵀ ∇²_(y,w) λᵀΦ M + Σ_j (∂λᵀΦ/∂y_j) ∇²_w J_j,    M = [∂J/∂w; I],

where each J_j depends on one joint angle q (so ∂J/∂w has one entry per row, J_j′, and ∇²J_j
one, J_j″) and the first term sees y as free symbols (the draw is a short expression in them).
J, J′ and J″ of a node come from one small function with common subexpressions merged
(:func:`stroke_derivatives`). :func:`lagrangian_hessian` writes the Hessian so, the other rows
and the objective as CasADi derives them, and returns the function IPOPT calls (``hess_lag``):
the same matrix within round-off (3e-16 relative) and sparsity, 83k instructions instead of
121k on umea-lab (1.23 vs 1.73 ms per evaluation, interleaved, loaded machine). IPOPT takes the
same steps; only the evaluation is cheaper.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["lagrangian_hessian"]


def stroke_derivatives(stroke, n: int) -> ca.Function | None:
    """(J, J′, J″) of the stroke Jacobian ``stroke`` (q (n) → dx/dq (n), SX) per joint, as one
    function with common subexpressions merged (the three share the linkage's kinematics:
    479 instead of 966 instructions for J″ alone on umea-lab); None when an entry of J depends
    on another joint than its own (no diagonal structure to use)."""
    q = ca.SX.sym("q", n)
    J = stroke(q)
    r, c = ca.jacobian(J, q).sparsity().get_triplet()
    if r != c:
        return None
    d1 = [ca.jacobian(J[i], q[i]) for i in range(n)]
    d2 = [ca.jacobian(d1[i], q[i]) for i in range(n)]
    return ca.Function("stroke_derivatives", [q], [J, ca.vertcat(*d1), ca.vertcat(*d2)],
                       {"cse": True})


def _placed(values, rows, cols, shape):
    """A sparse SX matrix of ``shape`` with ``values`` (SX column) at (``rows``, ``cols``),
    the entries that are structurally zero left out."""
    order = np.lexsort((rows, cols))   # column-major, as CasADi stores nonzeros
    sp = ca.Sparsity.triplet(shape[0], shape[1], np.asarray(rows)[order].tolist(),
                             np.asarray(cols)[order].tolist())
    return ca.sparsify(ca.SX(sp, values[order.tolist()]))


def lagrangian_hessian(w, p, f, g, rows, Y, Q, stroke, rows_y) -> ca.Function | None:
    """``nlp_hess_l`` (x, p, lam_f, lam_g) → the upper triangle of ∇²_w (lam_f·f + lam_gᵀg),
    for IPOPT's ``hess_lag`` option; None when the stroke Jacobian has no per-joint structure.
    ``w``, ``p``, ``f``, ``g``: the NLP (SX); ``rows``: the indices in g of the rows given
    again as ``rows_y``, the same expressions written in the free symbols ``Y`` (n, nodes)
    where they use the stroke Jacobians ``stroke(Q[:, k])`` of the nodes' joints ``Q`` (n,
    nodes; entries of ``w``)."""
    n, nodes = Q.shape
    kin = stroke_derivatives(stroke, n)
    if kin is None:
        return None
    rows = np.asarray(rows, int)
    sigma = ca.SX.sym("lam_f")
    lam = ca.SX.sym("lam_g", g.shape[0])
    others = np.setdiff1d(np.arange(g.shape[0]), rows).tolist()
    H = ca.hessian(sigma * f + ca.dot(lam[others], g[others]), w)[0]
    # where each node joint sits in w, and J, J′, J″ there (J_j depends on that joint only)
    r, c = ca.jacobian(ca.vec(Q), w).sparsity().get_triplet()
    at = np.empty(n * nodes, int)
    at[np.asarray(r)] = c
    J, D1, D2 = (ca.vec(ca.horzcat(*parts)) for parts in
                 zip(*(kin(Q[:, k]) for k in range(nodes))))
    y, ny, nw = ca.vec(Y), n * nodes, w.shape[0]
    Ly = ca.dot(lam[rows.tolist()], rows_y)
    M = ca.vertcat(_placed(D1, np.arange(ny), at, (ny, nw)), ca.SX.eye(nw))
    H += ca.mtimes([M.T, ca.hessian(Ly, ca.vertcat(y, w))[0], M])
    H += _placed(ca.gradient(Ly, y) * D2, at, at, (nw, nw))   # Σ_j ∂λᵀΦ/∂y_j · J_j″
    H = ca.substitute(ca.triu(H), y, J)
    return ca.Function("nlp_hess_l", [w, p, sigma, lam], [H],
                       ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
