"""``nlp-sway``: the minimum-time move with the grapple pendulum. Oracles: the model's swing
integrated finely along the returned plan (predict_swing, 200 Hz RK4, not the NLP's own
interval steps), evaluate() at 1 kHz for the limits, the sway-blind and ZVD moves of the same
request for the duration, the Exudyn plant for what arrives; and ``plan --grapple``."""
import json

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.methods import PlanRequest, plan
from planner.model.pendulum import Pendulum, predict_swing
from planner.trajectory import evaluate

MOVE = ((6.0, 1.5, -0.25), (4.8, 0.2, 0.25))
OPTS = {"grapple": 1.5, "grapple_zeta": 0.05}


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


@pytest.fixture(scope="module")
def plans(s100f):
    return {m: plan(s100f, PlanRequest(*MOVE, options={} if m == "nlp" else OPTS), m)
            for m in ("nlp", "zvd", "nlp-sway")}


def test_the_load_arrives_at_rest_within_the_tolerance(s100f, plans):
    res = plans["nlp-sway"]
    assert res.ok, res.reason
    pend = Pendulum.of(s100f, 1.5, zeta=0.05)
    fine = predict_swing(s100f, res.trajectory, pend)
    assert fine.residual_m <= 0.012            # 10 mm asked, the NLP's RK4 steps aside
    assert res.swing_residual_m == pytest.approx(fine.residual_m)
    blind = predict_swing(s100f, plans["nlp"].trajectory, pend).residual_m
    assert blind > 0.5                         # the sway-blind move leaves it swinging
    assert evaluate(s100f, res.trajectory).max_limit_violation <= 1e-3
    tips = s100f.tip(res.trajectory.q[[0, -1]])
    assert np.allclose(tips, MOVE, atol=1e-3)


def test_it_is_slower_than_the_sway_blind_move_and_faster_than_zvd(plans):
    blind, zvd, sway = (plans[m].duration_s for m in ("nlp", "zvd", "nlp-sway"))
    assert blind * (1 - 1e-6) <= sway < zvd
    assert plans["nlp-sway"].duration_ratio == pytest.approx(sway / blind)


def test_on_the_exudyn_plant_it_swings_far_less_than_the_sway_blind_move(s100f, plans):
    pytest.importorskip("exudyn")
    from planner.feedforward import with_settle
    from planner.model.effects import make
    from planner.simulation.plants import load_swing, make_plant
    pend = Pendulum.of(s100f, 1.5, zeta=0.05)
    plant = make_plant("exudyn", s100f, [make("grapple_swing", length=1.5,
                                                    damping=pend.damping)])
    after = {}
    for m in ("nlp", "nlp-sway"):
        tr = plans[m].trajectory
        run = with_settle(s100f, tr, 3.0)
        rec = plant.run(run.t, run.u, tr.q[0], t_end=float(run.t[-1]), rate=50.0)
        t, sw = load_swing(plant, rec)
        after[m] = np.linalg.norm(sw[t >= tr.duration], axis=1).max()
    assert after["nlp-sway"] < 0.4 * after["nlp"], after


def test_plan_grapple_reports_the_predicted_swing(tmp_path, capsys):
    out = tmp_path / "p.json"
    assert main(["plan", "s100f", "--start", "6,1.5,-0.25", "--goal", "4.8,0.2,0.25",
                 "--method", "zv", "--grapple", "1.5", "--grapple-zeta", "0.05",
                 "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["method"] == "zv" and d["swing"]["grapple_m"] == 1.5
    assert d["swing"]["pendulum_hz"] == pytest.approx(0.40, abs=0.005)
    assert 0 < d["swing"]["residual_swing_m"] < 0.25
    # no grapple known: no swing; the shapers refuse, naming the flag
    assert main(["plan", "umea-lab", "--start", "1.8,0.4,-0.25", "--goal", "3.0,1.3,0.25",
                 "--method", "ruckig", "--json", str(out)]) == 0
    assert "swing" not in json.loads(out.read_text())
    capsys.readouterr()
    assert main(["plan", "umea-lab", "--start", "1.8,0.4,-0.25", "--goal", "3.0,1.3,0.25",
                 "--method", "zvd"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--grapple" in err and "umea-lab" in err and "\n" not in err


@pytest.mark.slow     # one more sway-free NLP with the exact Hessian (~10 s)
def test_the_operators_swing_limit_from_the_spec_bounds_the_swing_during_the_move(s100f, plans):
    """``[dynamics.grapple] swing_max``: the plan keeps the load's horizontal offset under it
    (oracle: the fine 200 Hz integration, 3 % over the NLP's nodes allowed), where the
    unbounded sway-free plan of the same move goes past it; the goal still calm."""
    from dataclasses import replace
    from planner.model.dynamics_spec import GrappleLink
    free = plans["nlp-sway"].stats["swing_peak_m"]
    limit = round(0.7 * free, 3)
    dyn = replace(s100f.spec.dynamics, grapple=GrappleLink(1.5, swing_max=limit))
    crane = Crane(replace(s100f.spec, dynamics=dyn))
    res = plan(crane, PlanRequest(*MOVE, options=OPTS), "nlp-sway")
    assert res.ok, res.reason
    fine = predict_swing(crane, res.trajectory, Pendulum.of(crane, 1.5, zeta=0.05))
    assert fine.peak_during_m <= 1.03 * limit < free
    assert fine.residual_m <= 0.012


@pytest.mark.slow     # one sway-free NLP over the headboard (~10 s)
def test_the_load_keeps_the_whole_headboard_clearance_at_1khz(s100f):
    """``load_clearance``: a pick-up → drop move of the forwarder cycle whose load passes
    closest to the headboard (p20-d02, 1.5 m link; with the rows at 1.0 × it came 9.5 mm
    inside the 0.3 m clearance, the wall's disc gap) keeps the whole clearance on a 1 kHz
    resampling of the swing the model predicts (load_clearance, not the NLP's rows)."""
    from planner.bench.context import Settings
    from planner.bench.suites import build_suite
    from planner.methods.shaping import load_clearance
    from planner.problems import task_path
    suite = build_suite(str(task_path("forwarder-cycle")), Settings(forwarder_moves=10 ** 6))
    mv = next(m for m in suite.moves if m.id == "p20-d02")
    obstacles = tuple(suite.obstacles)
    res = plan(s100f, PlanRequest(mv.start, mv.goal, obstacles=obstacles,
                                  options=dict(OPTS, load_clearance=1.0)), "nlp-sway")
    assert res.ok, res.reason
    pend = Pendulum.of(s100f, 1.5, zeta=0.05)
    least = load_clearance(s100f, res.trajectory, pend, obstacles)
    assert min(ob.clearance for ob in obstacles) == pytest.approx(0.3)
    assert 0.3 <= least < 0.35                   # kept, and the constraint is active
    assert res.stats["load_clearance_margin_m"] == pytest.approx(least - 0.3, abs=1e-9)
