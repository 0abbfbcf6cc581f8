"""The relief pressure in the minimum-time plan (planner.methods.nlp.limits.add_relief_rows and
the ``nlp`` planner's re-solve): judged by evaluate()'s chamber pressures on a 1 kHz resampling
against the spec's relief pressure, the plain NLP's answer beside it."""
import math
from dataclasses import replace

import numpy as np
import pytest

from planner.methods.base import PlanRequest
from planner.methods.nlp import MoveNLP
from planner.methods.nlp.limits import relief_limit
from planner.methods.registry import get
from planner.trajectory import evaluate

# a 2.3 s cat215b move (stick folding 0.64 rad at 6.8 m reach with the 2.2 t load, the swing
# 0.09 rad): the plain minimum-time move asks the swing motor for ~1.2 × the 300-bar relief
CAT_START = (6.829, 0.211, -0.766)
CAT_GOAL = (5.817, -0.444, -0.673)


def test_relief_limit_is_the_relief_less_the_load_sensing_margin(cat215b, umea_lab):
    for crane in (cat215b, umea_lab):
        pu = crane.spec.pump
        assert relief_limit(crane.spec) == pytest.approx(pu.max_pressure - pu.margin)
    const = replace(cat215b.spec.pump, kind="constant_pressure", pressure=21e6)
    assert relief_limit(replace(cat215b.spec, pump=const)) == pytest.approx(21e6)
    free = replace(cat215b.spec.pump, max_pressure=math.inf)
    assert relief_limit(replace(cat215b.spec, pump=free)) == math.inf


def test_a_move_beyond_the_relief_is_planned_again_within_it(cat215b):
    """The plain NLP's move exceeds the relief (so this test can fail); the planner's answer
    keeps every chamber at or below it and every other limit, is no faster than the plain move,
    and says it was solved again."""
    pmax = cat215b.spec.pump.max_pressure
    plain = MoveNLP(cat215b, "time").solve(CAT_START, CAT_GOAL)
    assert plain.ok
    ev0 = evaluate(cat215b, plain.trajectory)
    assert np.max(np.maximum(ev0.hyd["p_a"], ev0.hyd["p_b"])) > 1.1 * pmax
    res = get("nlp").plan(cat215b, PlanRequest(start=CAT_START, goal=CAT_GOAL,
                                               objective="time"))
    assert res.ok, res.reason
    assert "pressure" in res.trajectory.limits
    ev = evaluate(cat215b, res.trajectory)
    assert np.max(np.maximum(ev.hyd["p_a"], ev.hyd["p_b"])) <= 1.01 * relief_limit(
        cat215b.spec) < pmax
    assert ev.max_limit_violation <= 1e-3
    assert res.duration_s >= plain.duration_s * (1 - 1e-6)
    assert res.stats["relief"]["excess_before"] > 0.1
    # the rows hold at the nodes; between them it may pass the limit by a hair (the LS margin,
    # 20 of 300 bar, stays between it and the relief itself)
    assert res.stats["relief"]["excess_after"] <= 0.01
    # the ends are the ones asked for
    np.testing.assert_allclose(cat215b.tip(res.trajectory.q[0]), CAT_START, atol=1e-5)
    np.testing.assert_allclose(cat215b.tip(res.trajectory.q[-1]), CAT_GOAL, atol=1e-5)


def test_a_move_within_the_relief_is_not_solved_again(umea_lab):
    """umea-lab's moves stay far below its relief: the plain answer, no relief stats."""
    q0, q1 = np.array([0.0, 0.3, -0.6, 0.1]), np.array([1.0, 0.6, -0.9, 0.3])
    L = umea_lab.limit_arrays()
    q0, q1 = np.clip(q0, L["q_min"], L["q_max"]), np.clip(q1, L["q_min"], L["q_max"])
    s, g = tuple(umea_lab.tip(q0)), tuple(umea_lab.tip(q1))
    res = get("nlp").plan(umea_lab, PlanRequest(start=s, goal=g, objective="time"))
    assert res.ok
    assert "relief" not in res.stats
    assert evaluate(umea_lab, res.trajectory).violations["pressure"] <= 0.0
