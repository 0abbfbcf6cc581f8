"""Seed 002's laws as online controllers of the dynamic plant (planner/simulation/dynamic/
online.py): on a kinematic plant that moves exactly as the valve model says, the controller
reproduces the laws' own closed-loop simulation (follow_command); the Exudyn run is slow."""
import numpy as np
import pytest

from planner import Crane
from planner.methods.laws import follow_command
from planner.methods.laws_energy import JLA
from planner.model.valves import command_to_stroke_rate, valve_params
from planner.simulation.dynamic.online import OnlineLaw, make_online_law, run_online
from planner.tasks.cycles import START, START_TELE, cycle


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


def test_online_jla_on_a_kinematic_plant_reproduces_follow_command(s100f):
    cmd, _, _ = cycle("v", 1.0)
    q0 = s100f.ik(START["v"], tele=START_TELE["v"])
    ref = follow_command(s100f, JLA(), cmd, 7.0, q0=q0, rate=100.0, gain=5.0).trajectory
    ctl = OnlineLaw(s100f, make_online_law("jla"), cmd, rate=100.0, gain=5.0)
    vp = valve_params(s100f)
    q = np.array(q0, float)
    for k in range(700):                          # 5 s of rest, then 2 s of the first section
        u = ctl(k * 0.01, q, None, np.zeros(4), np.zeros(4))
        dxdq = s100f.kinematics(q)[3]
        q = q + command_to_stroke_rate(vp, u) / dxdq * 0.01
    assert np.abs(ref.q[-1] - ref.q[0]).max() > 0.05            # it did move
    assert np.abs(q - ref.q[-1]).max() < 1e-6


def test_unknown_online_law_is_refused():
    with pytest.raises(ValueError, match="allowed jla, q_optimal, p1, p1_5, p2"):
        make_online_law("max_velocity")


@pytest.mark.slow
def test_online_laws_run_on_the_exudyn_plant(s100f):
    cmd, _, _ = cycle("v", 1.0)
    q0 = s100f.ik(START["v"], tele=START_TELE["v"])
    r = {k: run_online(s100f, k, cmd, 7.0, q0, gain=1.0) for k in ("jla", "p2")}
    for v in r.values():
        assert v["status"] == "ok" and abs(v["balance_residual"]) < 0.02
        assert v["max_tip_error_m"] < 0.5
