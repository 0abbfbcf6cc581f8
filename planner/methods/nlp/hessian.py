"""The exact Hessian of the minimum-time move NLP's Lagrangian, with the pump rows differentiated
through their stroke Jacobians (issue 31: the NLP's own overhead against a plain Opti).

The pump row of a check point is Φ(y, w): the smooth draw (:func:`~planner.methods.nlp.limits.
pump_draw`) of the joint rates in w through the stroke Jacobians y, and at the nodes y = J(q),
J(q)ᵢ = dxᵢ/dqᵢ (the midpoints take the mean of their nodes'). Written as one expression in w,
CasADi's Hessian of λᵀΦ(J(w), w) differentiates the stroke kinematics three times inside every
pair of rows that shares a node: 85k of the 121k instructions of the whole Hessian on umea-lab
at N = 40. The chain rule splits it exactly:

    ∇²_w λᵀΦ(J(w), w) = Mᵀ ∇²_(y,w) λᵀΦ M + Σ_j (∂λᵀΦ/∂y_j) ∇²_w J_j,    M = [∂J/∂w; I],

where each J_j depends on one joint angle (∇²J_j has one entry, J_j″) and the first term sees y
as free symbols (the draw is a short expression in them). :func:`lagrangian_hessian` writes the
Hessian so, the other rows and the objective as CasADi derives them, and returns the function
IPOPT calls (``hess_lag``). It is the same matrix (round-off aside), so IPOPT takes the same
steps; only the evaluation is cheaper.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["lagrangian_hessian"]


def lagrangian_hessian(w, p, f, g, rows, Y, J, rows_y) -> ca.Function:
    """``nlp_hess_l`` (x, p, lam_f, lam_g) → the upper triangle of ∇²_w (lam_f·f + lam_gᵀg),
    for IPOPT's ``hess_lag`` option. ``w``, ``p``, ``f``, ``g``: the NLP (SX); ``rows``: the
    indices in g of the rows given again as ``rows_y``, the same expressions written in the
    free symbols ``Y`` where they use ``J`` (the value of ``Y``, an expression in ``w``, each
    entry a function of one entry of ``w``)."""
    rows = np.asarray(rows, int)
    sigma = ca.SX.sym("lam_f")
    lam = ca.SX.sym("lam_g", g.shape[0])
    others = np.setdiff1d(np.arange(g.shape[0]), rows).tolist()
    H = ca.hessian(sigma * f + ca.dot(lam[others], g[others]), w)[0]
    y, j = ca.vec(Y), ca.vec(J)
    Ly = ca.dot(lam[rows.tolist()], rows_y)
    M = ca.vertcat(ca.jacobian(j, w), ca.SX.eye(w.shape[0]))
    H += ca.mtimes([M.T, ca.hessian(Ly, ca.vertcat(y, w))[0], M])
    c = ca.SX.sym("c", y.shape[0])   # ∂λᵀΦ/∂y, held fixed while J is differentiated twice
    Hj = ca.hessian(ca.dot(c, j), w)[0]
    H += ca.substitute(Hj, c, ca.gradient(Ly, y))
    H = ca.substitute(ca.triu(H), y, j)
    return ca.Function("nlp_hess_l", [w, p, sigma, lam], [H],
                       ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
