"""The end stops (planner.simulation.stops): the vectorised run equals the sequential clip it
stands for, and a model whose start is fitted to a measurement reaches a stroke end the way the
plant that recorded it did (issue 26, defect 2: re-anchoring a run that was clipped from another
start invented a step at the stroke end)."""
import numpy as np
import pytest

from planner.calibration.trials import SequenceBuilder
from planner.model.effects import make
from planner.simulation.plant import respond
from planner.simulation.replay import replay, stroke_stops
from planner.simulation.stops import run_to_stops


def _sequential(x0, dx, lo, hi):
    """The oracle: clip after every step, one step at a time."""
    x = [np.clip(x0, lo, hi)]
    at = [np.zeros(len(lo), bool)]
    for d in dx:
        nxt = x[-1] + d
        c = np.clip(nxt, lo, hi)
        x.append(c)
        at.append(c != nxt)
    return np.array(x), np.array(at)


@pytest.mark.parametrize("seed", range(40))
def test_run_to_stops_is_the_sequential_clip(seed):
    rng = np.random.default_rng(seed)
    K = int(rng.integers(1, 300))
    lo, hi = np.array([0.0, -1.0, 0.2]), np.array([1.0, 0.5, 0.4])
    # held commands: runs of equal steps and rests, large enough to bounce between both ends
    dx = np.repeat(rng.normal(0.0, 0.06, (K // 5 + 1, 3)), 5, axis=0)[:K]
    dx[rng.uniform(size=K) < 0.3] = 0.0
    x0 = rng.uniform(lo - 0.1, hi + 0.1)
    run = run_to_stops(x0, dx, lo, hi)
    x, at = _sequential(x0, dx, lo, hi)
    assert np.abs(run.x - x).max() < 1e-12
    assert np.array_equal(run.at_stop, at)
    # on the stop it is exactly there (a held actuator stands exactly still)
    assert np.all((run.x == lo) | (run.x == hi) | ~at)
    # the sensitivity to the start: 1 until the first contact, 0 after (finite difference)
    h = 1e-7
    inside = np.clip(x0, lo + 2 * h, hi - 2 * h)
    d = (run_to_stops(inside + h, dx, lo, hi).x - run_to_stops(inside, dx, lo, hi).x) / h
    free = run_to_stops(inside, dx, lo, hi).free
    assert np.allclose(d[free], 1.0, atol=1e-5) and np.allclose(d[~free], 0.0, atol=1e-5)


def _to_the_end(crane, joint, end, T=12.0, seed=0):
    """Commands of a sequence that drives ``joint`` at full speed to its ``end`` (min/max)
    and then moves about inside the ranges."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + 0.2 * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - 0.2 * (L["q_max"] - L["q_min"])
    b = SequenceBuilder(crane, 0.5 * (lo + hi))
    b.hold(0.5)
    g = 0.5 * (lo + hi)
    i = crane.names.index(joint)
    g[i] = L[f"q_{end}"][i]
    b.move(g, 1.0)
    b.hold(0.5)
    while b.t_now < T:
        b.move(rng.uniform(lo, hi), 0.7)
        b.hold(0.5)
    return b.finish()


@pytest.mark.parametrize("end", ["min", "max"])
def test_a_fitted_start_reaches_the_stroke_end_as_the_plant_did(umea_lab, end):
    crane = umea_lab
    plan, ff = _to_the_end(crane, "tele", end)
    # the plant overshoots into the end (valves 10 % stronger than the commands assume)
    strong = [make("flow_gain", "tele", scale=1.1)]
    truth = respond(crane, ff.t, ff.u, plan.q[0], strong, t_end=ff.t[-1])
    assert truth.meta["clipped"].get("tele"), "the recording must be held at the stop"
    # the model starts from a guess 8 mm off and fits its start to the (noise-free) recording
    guess = plan.q[0] + np.array([0.0, 0.0, 0.0, 0.008])
    fit = respond(crane, ff.t, ff.u, guess, strong, t_end=ff.t[-1], q_fit=truth.q)
    assert np.abs(fit.q - truth.q).max() < 1e-6
    assert fit.meta["clipped"] == truth.meta["clipped"]
    # the replay and the plant take the same stops (one code path)
    sim = replay(crane, ff.t, ff.u, plan.q[0], (), t_end=ff.t[-1])
    lo, hi = stroke_stops(crane)
    x = crane.stroke(sim.q)[0]
    assert np.all((x >= lo - 1e-9) & (x <= hi + 1e-9))
    plain = respond(crane, ff.t, ff.u, plan.q[0], t_end=ff.t[-1])
    assert np.abs(plain.q - sim.q).max() < 1e-7
