"""Fixtures of the refinement tests."""
import pytest

RATE = 50.0


@pytest.fixture(scope="module")
def umea_move():
    """(crane, trajectory, t_u, u): a umea-lab rest-to-rest move and its nominal commands."""
    from planner import Crane
    from planner.feedforward import commands, stored_commands
    from planner.methods.ruckig import rest_to_rest
    crane = Crane.from_id("umea-lab")
    L = crane.limit_arrays()
    q0, q1 = (L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (0.3, 0.7))
    tr = rest_to_rest(crane, q0, q1, scale=0.9).trajectory
    move = commands(crane, tr, RATE).attach(tr, knots=True)
    t_u, u = stored_commands(move)
    return crane, move, t_u, u

