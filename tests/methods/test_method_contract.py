"""The method contract, over the registry: every registered method on every shipped machine.

One ordinary move per machine (tips inside the workspace, the straight line between them too,
so line-following methods can attempt it), each method with its own objective and path kind
and, where it reads one, a tip speed. The answer must be one of:

- a valid :class:`~planner.trajectory.Trajectory`: finite, from the start tip to the goal tip
  (to 1 mm; a law tracks its line to about 0.3 mm), at rest there as far as the method's limit
  kinds reach (zero speed with acceleration limits, zero acceleration too with jerk limits),
  its duration the result's, and evaluate() — the one judge, on its 1 kHz resampling — finds
  no limit kind the method plans with exceeded by more than the method's declared
  ``tolerance``;
- a non-ok :class:`~planner.methods.PlanStatus` with a reason;
- :class:`~planner.methods.UnsupportedRequest`, only where the machine lacks what the method
  needs (listed in REFUSED), naming the machine.

A new method or machine joins this test by registering: a machine needs its move in MOVES.
"""
import math

import numpy as np
import pytest

from planner.methods import PlanRequest, PlanStatus, UnsupportedRequest, available, get, plan
from planner.trajectory import Trajectory, evaluate

# tips (r [m], z [m], slew [rad]): mid-workspace moves of about 2 m with a slew of 0.5 rad
MOVES = {
    "s100f": ((6.0, 1.5, -0.25), (4.8, 0.2, 0.25)),
    "cranab850": ((6.0, 1.5, -0.25), (4.8, 0.0, 0.25)),
    "umea-lab": ((1.8, 0.4, -0.25), (3.0, 1.3, 0.25)),
    "cat215b": ((5.2, 0.0, -0.25), (6.2, 1.0, 0.25)),
}
TIP_SPEED = 1.0        # [m/s] for the methods that read one
GRAPPLE_M = 1.5        # [m] grapple link for the methods that shape or plan its swing
# (method, machine) refused because the machine lacks what the method needs
REFUSED = {("law:max_lift", m) for m in ("s100f", "umea-lab", "cat215b")}  # no [laws] table

END_TIP_M = 1e-3       # [m] / [rad]: the trajectory's ends against the requested tips
REST = 1e-6            # joint speed and acceleration at the ends [SI]


def _request(method: str, start, goal) -> PlanRequest:
    p = get(method)
    return PlanRequest(start, goal, objective=p.objectives[0], path=p.default_path,
                       tip_speed=TIP_SPEED if p.reads("tip_speed", p.objectives[0]) else None,
                       options={"grapple": GRAPPLE_M} if getattr(p, "grapple", False) else {})


def test_every_machine_has_a_move(crane):
    assert crane.spec.id in MOVES, f"add an ordinary move for {crane.spec.id} to MOVES"


@pytest.mark.parametrize("method", available())
def test_a_method_plans_a_valid_trajectory_or_says_why(crane, method):
    cid = crane.spec.id
    start, goal = MOVES[cid]
    try:
        res = plan(crane, _request(method, start, goal), method)
    except UnsupportedRequest as e:
        assert (method, cid) in REFUSED, f"{method} refused {cid}: {e}"
        assert cid in str(e) and "\n" not in str(e)
        return
    assert (method, cid) not in REFUSED, f"{method} now plans on {cid}: update REFUSED"
    assert type(res.status) is PlanStatus and res.method == method
    if not res.ok:
        assert res.reason.strip(), f"{method} on {cid}: {res.status} without a reason"
        return
    tr = res.trajectory
    assert isinstance(tr, Trajectory) and tr.n == crane.n
    for name in ("t", "q", "qd", "qdd"):
        assert np.all(np.isfinite(getattr(tr, name))), name
    assert tr.t[0] == 0.0 and np.all(np.diff(tr.t) > 0)
    assert res.duration_s == pytest.approx(tr.duration, rel=1e-9)
    for q, tip in ((tr.q[0], start), (tr.q[-1], goal)):
        got = crane.tip(q)
        assert np.max(np.abs(np.asarray(got) - tip)) <= END_TIP_M, (method, cid, got, tip)
    # at rest as far as the method's own limit kinds reach: with acceleration limits it
    # starts and stops at zero speed, with jerk limits at zero acceleration too (a
    # velocity-only method's piecewise-linear path steps its speed, which its limits allow)
    rest = [tr.qd] * ("acceleration" in tr.limits) + [tr.qdd] * ("jerk" in tr.limits)
    for x in rest:
        assert np.max(np.abs(x[[0, -1]])) <= REST, (method, cid, "not at rest", x[[0, -1]])
    ev = evaluate(crane, tr)
    tol = get(method).tolerance
    assert ev.max_limit_violation <= tol, \
        (method, cid, ev.max_limit_violation, {k: v for k, v in ev.violations.items() if v > tol})
    assert math.isfinite(ev.energy_J) and ev.energy_J >= 0.0
