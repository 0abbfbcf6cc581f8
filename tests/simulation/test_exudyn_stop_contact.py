"""The Exudyn plant at an end stop: a stroke that reaches its stop is integrated at a quarter
step (``CONTACT_REFINE``). At the default 2 ms a umea-lab telescope driven into its stop
diverged, and a refined library move (r35) rebounded off it at 2.9 m/s with 703 bar on its rod
side and came to rest 48 mm off the goal; at 0.5 ms it rests on the stop.

Oracle: physics — a telescope pushed onto its stop by a half-open valve ends on the stop (its
stroke end, 1.55 m) with no chamber above the pump line's pressure; and the run at a finer step still (the
answer converged)."""
import numpy as np
import pytest

from planner import Crane
from planner.simulation.dynamic.circuit import CONTACT_REFINE
from planner.simulation.dynamic.exudyn_plant import ExudynPlant

pytest.importorskip("exudyn")


@pytest.fixture(scope="module")
def lab():
    return Crane.from_id("umea-lab")


def _push(crane, open_s):
    q0 = np.array([-0.2356, 0.0512, -2.3005, 1.45])
    t_u = np.arange(0.0, 1.5, 0.02)
    u = np.zeros((t_u.size, 4))
    u[:int(round(open_s / 0.02)), 3] = 0.5
    return t_u, u, q0


def test_a_telescope_driven_onto_its_stop_rests_on_it(lab):
    t_u, u, q0 = _push(lab, 0.5)
    plant = ExudynPlant(lab)
    run = plant.integrate(t_u, u, q0, t_end=1.5)
    assert run.ok, run.reason
    assert run.meta.get("stop_contact") and run.meta["step"] == plant.step / CONTACT_REFINE
    hi = lab.limit_arrays()["q_max"][3]
    assert abs(run.q[-1, 3] - hi) < 1e-3
    # no chamber pressure from a rebound (the 2 ms contact: 703 bar on r35): at its stop the
    # telescope's chambers hold at most what the pump line gave them
    assert max(run.p_a[:, 3].max(), run.p_b[:, 3].max()) <= run.p_s.max() + 1e5
    # converged: a plant whose own step is already the quarter (and so refines once more)
    fine = ExudynPlant(lab, step=plant.step / CONTACT_REFINE).integrate(t_u, u, q0, t_end=1.5)
    assert np.allclose(run.q[-1], fine.q[-1], atol=1e-4)


def test_a_run_that_stays_off_the_stops_keeps_the_default_step(lab):
    t_u, u, q0 = _push(lab, 0.1)      # 0.1 s half open: the telescope stops short
    plant = ExudynPlant(lab)
    run = plant.integrate(t_u, u, q0, t_end=1.5)
    assert run.ok and run.q[-1, 3] < lab.limit_arrays()["q_max"][3] - 0.01
    assert "stop_contact" not in run.meta and run.meta["step"] == plant.step


def test_a_telescope_resting_on_its_stop_keeps_the_default_step(lab):
    t_u = np.arange(0.0, 1.0, 0.02)
    q0 = np.array([-0.2356, 0.0512, -2.3005, 1.55])       # on the stop, valves closed
    plant = ExudynPlant(lab)
    run = plant.integrate(t_u, np.zeros((t_u.size, 4)), q0, t_end=1.0)
    assert run.ok and "stop_contact" not in run.meta and run.meta["step"] == plant.step
