"""The optimisation twin's load-sensing ramp (planner.model.twin.ode, ``ls_ramp``).

Oracles: the machine's twin itself (the ramped one must equal it wherever the valve is open
past the ramp, and the parameter 0 must give it back), a Lipschitz bound of the ramp's own
definition, and the jump the machine's signal makes at a reversal (what the ramp removes)."""
import numpy as np
import pytest

from planner import Crane
from planner.model.twin import Twin
from planner.model.twin.params import param_index

RAMP = 1e-3


@pytest.fixture(scope="module")
def twin():
    return Twin(Crane.from_id("umea-lab"))


def _p_set(tw, spools, j=0, p_a=8e6, p_b=3e6):
    """The pump's set pressure with joint ``j``'s spool at each of ``spools`` (its chambers at
    ``p_a``, ``p_b``; every other valve closed)."""
    n = tw.crane.n
    L = tw.crane.limit_arrays()
    x = np.array(tw.rest_state(0.5 * (L["q_min"] + L["q_max"])), float)
    x[2 * n + j], x[3 * n + j] = p_a, p_b
    out = []
    for s in spools:
        x[4 * n + 1 + j] = s
        o = tw.f_outputs(x, np.zeros(n), np.zeros(n), tw.P)
        out.append(float(o[4]))
    return np.array(out)


def test_zero_ramp_is_the_machines_twin(twin):
    assert twin.with_ls_ramp(0.0) is twin
    r = twin.with_ls_ramp(RAMP)
    assert r.P[param_index(twin.crane.n, "ls_ramp")] == RAMP
    assert twin.P[param_index(twin.crane.n, "ls_ramp")] == 0.0       # the original untouched
    assert r.provenance()["fingerprint"] != twin.provenance()["fingerprint"]
    with pytest.raises(ValueError, match="ls_ramp"):
        twin.with_ls_ramp(-1.0)


def test_the_ramped_signal_is_continuous_through_a_reversal_and_the_machines_is_not(twin):
    db = float(twin.params.per["deadband"][0])
    s = np.linspace(-(db + 3 * RAMP), db + 3 * RAMP, 1201)
    hard = _p_set(twin, s)
    soft = _p_set(twin.with_ls_ramp(RAMP), s)
    margin = twin.params.scalar["ls_margin"]
    # the machine's signal jumps at the reversal: from the rod side's to the piston side's
    assert np.max(np.abs(np.diff(hard))) > 0.5 * (8e6 - 3e6)
    # the ramp's: at most (p_in + margin)·|Δo|/ramp between neighbours (|Δo| ≤ |Δs|)
    bound = (8e6 + margin) * (s[1] - s[0]) / RAMP / (1.0 - db) + 1.0
    assert np.max(np.abs(np.diff(soft))) <= bound
    # open past the ramp, both are the same signal
    past = np.abs(s) > db + 1.5 * RAMP
    assert np.allclose(soft[past], hard[past], rtol=1e-12, atol=1e-6)


def test_the_machines_switch_has_no_slope_where_a_dithered_spool_settles(twin):
    """A refined idle valve starts at an opening of OPEN_EPS and its spool settles there: the
    machine's switch must not put a slope on the pump's equation there (a ramp 1e-12 wide
    did, 1e12 per unit opening, and Newton's step blew the pump line up to 229 MPa on three
    s100f pile → deck energy entries)."""
    import casadi as ca
    from planner.model.valve_physics import OPEN_EPS
    n = twin.crane.n
    L = twin.crane.limit_arrays()
    x = np.array(twin.rest_state(0.5 * (L["q_min"] + L["q_max"])), float)
    x[2 * n], x[3 * n] = 8e6, 3e6
    X = ca.SX.sym("x", x.size)
    f = ca.Function("f", [X], [ca.jacobian(twin.f_rhs(X, np.zeros(n), np.zeros(n), twin.P)
                                           [4 * n], X)])
    db = float(twin.params.per["deadband"][0])
    for eps in (0.0, 1e-13, 5e-13, 1e-9):
        x[4 * n + 1] = db + (1.0 - db) * OPEN_EPS * (1.0 + eps) + eps  # the opening at OPEN_EPS
        slope = abs(float(f(x)[4 * n + 1]))           # ∂ṗ_s/∂spool of joint 0
        assert slope < 1e9, (eps, slope)               # Pa/s per unit spool: no 1e12 spike
