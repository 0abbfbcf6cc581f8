"""The swinging load's clearance from an obstacle at 1 kHz (planner.methods.shaping.load_path,
load_clearance, load_clearance_margin). Oracle: geometry by hand — a crane held still leaves
the load hanging straight below the tip, one link length down, so its distance from a plate
whose top edge is level with the load is the plate's horizontal distance, while the tip above
it is farther by Pythagoras."""
import math

import numpy as np
import pytest

from planner import Crane
from planner.geometry.obstacles import Plate
from planner.geometry.paths import tip_to_xyz
from planner.methods.shaping import (clearance_margin, load_clearance, load_clearance_margin,
                                     load_path)
from planner.model.pendulum import Pendulum
from planner.trajectory import Trajectory

L = 1.5      # [m] link, pivot to the load's centre of mass
GAP = 0.5    # [m] the plate's distance ahead of the tip (x)
DROP = 0.2   # [m] the plate's top edge above the hanging load


@pytest.fixture(scope="module")
def still():
    """s100f held at one configuration for 2 s, its tip, and the pendulum."""
    crane = Crane.from_id("s100f")
    q = np.array([0.0, 0.4, -0.6, 0.5])
    t = np.linspace(0.0, 2.0, 21)
    z = np.zeros((len(t), crane.n))
    traj = Trajectory(t, np.tile(q, (len(t), 1)), z, z.copy(), joint_names=tuple(crane.names))
    tip = tip_to_xyz(crane.tip(q[None])[0])
    return crane, traj, tip, Pendulum.of(crane, L, zeta=0.05)


def plate(tip, clearance):
    return Plate(x=tip[0] + GAP, y_min=tip[1] - 1.0, y_max=tip[1] + 1.0,
                 z_bottom=tip[2] - L - 2.0, z_top=tip[2] - L + DROP, clearance=clearance)


def test_the_still_load_hangs_one_link_below_the_tip_at_1khz(still):
    crane, traj, tip, pend = still
    t, xyz = load_path(crane, traj, pend)
    assert len(t) >= 2001 and np.diff(t).max() <= 1e-3 + 1e-12   # 1 kHz and the plan's own
    assert np.allclose(xyz, tip - [0.0, 0.0, L], atol=1e-9)


def test_the_load_is_closer_to_the_plate_than_the_tip_by_hand(still):
    crane, traj, tip, pend = still
    ob = plate(tip, clearance=0.3)
    assert load_clearance(crane, traj, pend, [ob]) == pytest.approx(GAP, abs=1e-9)
    tip_d = math.hypot(GAP, L - DROP)                 # the tip: over the top edge
    assert clearance_margin(crane, traj, [ob]) == pytest.approx(tip_d - 0.96 * 0.3, abs=1e-9)
    assert load_clearance_margin(crane, traj, pend, [ob]) == pytest.approx(GAP - 0.96 * 0.3,
                                                                           abs=1e-9)


def test_a_clearance_the_tip_keeps_and_the_load_breaks_is_caught(still):
    crane, traj, tip, pend = still
    ob = plate(tip, clearance=0.6)                    # 0.96 × 0.6 = 0.576 > GAP
    assert clearance_margin(crane, traj, [ob]) > 0    # the tip alone would pass
    assert load_clearance_margin(crane, traj, pend, [ob]) == pytest.approx(GAP - 0.576,
                                                                           abs=1e-9)
    assert load_clearance_margin(crane, traj, pend, []) == math.inf
