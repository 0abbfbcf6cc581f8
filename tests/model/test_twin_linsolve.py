"""The twin's symbolic sparse LU (planner.model.twin.linsolve) against numpy's dense solve."""
import casadi as ca
import numpy as np
import pytest

from planner.model import Crane
from planner.model.twin import Twin
from planner.model.twin.linsolve import elimination_order, sparse_lu


def _random_pattern(rng, n, density):
    mask = rng.random((n, n)) < density
    np.fill_diagonal(mask, True)
    r, c = np.nonzero(mask)
    return ca.Sparsity.triplet(n, n, r.tolist(), c.tolist())


@pytest.mark.parametrize("seed", range(5))
def test_solves_as_numpy_on_random_sparse_systems(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 30))
    sp = _random_pattern(rng, n, 0.2)
    A = ca.SX.sym("A", sp)
    b = ca.SX.sym("b", n)
    solve = sparse_lu(A)
    f = ca.Function("f", [A, b], [solve(b), solve(2 * b)])
    dense = np.zeros((n, n))
    r, c = sp.get_triplet()
    dense[r, c] = rng.normal(size=len(r))
    dense += np.diag(2.0 + np.abs(dense).sum(axis=1))      # pivots away from zero
    rhs = rng.normal(size=n)
    x1, x2 = (np.asarray(v).ravel() for v in f(ca.DM(sp, dense[r, c]), rhs))
    want = np.linalg.solve(dense, rhs)
    np.testing.assert_allclose(x1, want, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(x2, 2 * want, rtol=1e-12, atol=1e-12)


def test_the_order_is_a_permutation_and_eliminates_a_leaf_first():
    # a star: the centre joins every leaf, so minimum degree takes leaves first
    # (ties: the lower index)
    r = [0, 0, 0, 1, 2, 3]
    c = [1, 2, 3, 0, 0, 0]
    order = elimination_order(ca.Sparsity.triplet(4, 4, r, c))
    assert sorted(order) == [0, 1, 2, 3] and order[:2] == [1, 2]


def test_the_twin_step_system_is_far_smaller_than_casadis_dense_solve():
    """The reason it exists: on the s100f step system the elimination writes under a quarter of
    the instructions ``casadi.solve`` writes, for the same answer."""
    tw = Twin(Crane.from_id("s100f"))
    st = tw.stepper
    nx, n = st.nx, st.n
    x, u, fx = ca.SX.sym("x", nx), ca.SX.sym("u", n), ca.SX.sym("f", n)
    P = ca.SX.sym("P", st._npar)
    sp = ca.jacobian(tw.f_rhs(x, u, fx, P), x).sparsity() + ca.Sparsity.diag(nx)
    A, b = ca.SX.sym("A", sp), ca.SX.sym("b", nx)
    mine = ca.Function("mine", [A, b], [sparse_lu(A)(b)], {"cse": True})
    theirs = ca.Function("theirs", [A, b], [ca.solve(A, b)], {"cse": True})
    assert mine.n_instructions() < 0.25 * theirs.n_instructions()
    rng = np.random.default_rng(0)
    Av = ca.DM(sp, 0.1 * rng.normal(size=sp.nnz())) + ca.DM.eye(nx)
    bv = rng.normal(size=nx)
    np.testing.assert_allclose(np.asarray(mine(Av, bv)), np.asarray(theirs(Av, bv)),
                               rtol=1e-10, atol=1e-12)


def test_refuses_a_structural_zero_on_the_diagonal_and_a_wrong_right_hand_side():
    sp = ca.Sparsity.triplet(2, 2, [0, 1], [1, 0])
    with pytest.raises(ValueError, match=r"A\[0, 0\] is a structural zero"):
        sparse_lu(ca.SX.sym("A", sp))
    with pytest.raises(ValueError, match="square"):
        sparse_lu(ca.SX.sym("A", 2, 3))
    solve = sparse_lu(ca.SX.sym("A", 2, 2))
    with pytest.raises(ValueError, match="a column of 2"):
        solve(ca.SX.sym("b", 3))
