"""Symbolic sparse LU for the twin's Newton systems.

The BDF2 step and its adjoint solve a 5n + 1 (+ 4 with the grapple) square system whose
matrix I − c·∂f/∂x is sparse (133 of 441 entries on the s100f). ``casadi.solve`` on an SX
matrix writes a dense symbolic factorisation: 14 782 instructions for that system, a third of
the compiled step, and most of the time the C compiler spends on it. Gaussian elimination over
the structure alone, in a minimum-degree order of A + Aᵀ, writes 862 for the same system.

Like ``casadi.solve`` on SX it does not pivot. The Newton matrix is scaled first (the callers
solve in 1 rad, 1 MPa, … units) and is the identity plus c = 2h/3 times the Jacobian, whose
pivots stay near one at the twin's steps (the caller checks each step's Newton update, so a
step where this fails is seen, refined in substeps, and reported). The right-hand side's mass
matrix (:mod:`planner.model.twin.ode`) is symmetric positive definite, where elimination
without pivoting is stable.

:func:`sparse_lu` factors once; the returned function solves for any number of right-hand
sides (the step's three Newton iterations share one factorisation).
"""
from __future__ import annotations

from typing import Callable

import casadi as ca

__all__ = ["sparse_lu", "elimination_order"]


def elimination_order(sp: ca.Sparsity) -> list[int]:
    """A minimum-degree elimination order of the symmetric pattern of ``sp`` + ``sp``ᵀ
    (greedy, ties to the lower index: deterministic)."""
    n = sp.size1()
    adj = [set() for _ in range(n)]
    for i, j in zip(*sp.get_triplet()):
        if i != j:
            adj[i].add(j)
            adj[j].add(i)
    left, order = set(range(n)), []
    while left:
        k = min(left, key=lambda v: (len(adj[v] & left), v))
        nb = adj[k] & left
        for a in nb:                    # eliminating k joins its remaining neighbours
            adj[a] |= nb - {a}
        left.remove(k)
        order.append(k)
    return order


def sparse_lu(A: ca.SX) -> Callable[[ca.SX], ca.SX]:
    """``solve(b)`` = A⁻¹·b for the square SX matrix ``A`` (structural diagonal needed), by
    elimination without pivoting over A's structure (module doc)."""
    n = A.size1()
    if A.size2() != n:
        raise ValueError(f"sparse_lu: A is {n}×{A.size2()}; allowed: a square matrix")
    sp = A.sparsity()
    rows = [dict() for _ in range(n)]
    for i, j in zip(*sp.get_triplet()):
        rows[i][j] = A[i, j]
    missing = [k for k in range(n) if k not in rows[k]]
    if missing:
        raise ValueError(f"sparse_lu: A[{missing[0]}, {missing[0]}] is a structural zero; "
                         "allowed: a matrix with its whole diagonal in its structure")
    cols = [set() for _ in range(n)]
    for i in range(n):
        for j in rows[i]:
            cols[j].add(i)
    order = elimination_order(sp)
    steps = []              # (pivot row k, [(row i, multiplier)])
    done = set()
    for k in order:
        piv = rows[k][k]
        below = []
        for i in sorted(cols[k] - done - {k}):
            f = rows[i].pop(k) / piv
            below.append((i, f))
            for j, v in rows[k].items():
                if j == k or j in done:
                    continue
                rows[i][j] = rows[i][j] - f * v if j in rows[i] else -f * v
                cols[j].add(i)
        steps.append((k, below))
        done.add(k)
    upper = {k: {j: v for j, v in rows[k].items() if j != k} for k in order}

    def solve(b: ca.SX) -> ca.SX:
        if b.shape != (n, 1):
            raise ValueError(f"sparse_lu: b is {b.shape}; allowed: a column of {n}")
        y = [b[i] for i in range(n)]
        for k, below in steps:           # forward: L·y = b
            for i, f in below:
                y[i] = y[i] - f * y[k]
        x = [None] * n
        for k in reversed(order):        # backward: U·x = y
            s = y[k]
            for j, v in upper[k].items():
                s = s - v * x[j]
            x[k] = s / rows[k][k]
        return ca.vertcat(*x)

    return solve
