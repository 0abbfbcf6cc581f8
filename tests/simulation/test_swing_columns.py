"""``simulate --plant exudyn`` with the grapple on its link: the ``swing_x``/``swing_y`` columns
and ``residual_swing_m``. Oracle: the model's own pendulum (planner.model.pendulum, separate
code) driven by the plan's tip acceleration predicts the same swing the plant records."""
import numpy as np
import pytest

from planner import Crane
from planner.feedforward import with_settle
from planner.methods import PlanRequest, plan
from planner.model.effects import make
from planner.model.pendulum import Pendulum, predict_swing
from planner.simulation.plants import plant_to_csv
from planner.trajectory import read_csv_table

pytest.importorskip("exudyn")

MOVE = ((6.0, 1.5, -0.25), (4.8, 0.2, 0.25))
LENGTH, DAMPING = 1.5, 516.0


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


def test_the_swing_columns_follow_the_model_pendulum(s100f, tmp_path):
    tr = plan(s100f, PlanRequest(*MOVE), "nlp").trajectory
    settle = 3.0
    out = tmp_path / "m.csv"
    summ = plant_to_csv(s100f, with_settle(s100f, tr, settle), out, "exudyn",
                        effects=[make("grapple_swing", length=LENGTH, damping=DAMPING)], plan=tr)
    cols, rows, _ = read_csv_table(out)
    assert cols[-2:] == ["swing_x", "swing_y"]
    M = np.array(rows)
    t, sw = M[:, 0], M[:, -2:]
    # the model's pendulum along the plan, held still after it
    pend = Pendulum(length=LENGTH, mass=s100f.spec.payload.total, damping=DAMPING)
    pred = predict_swing(s100f, tr, pend)
    during = t <= tr.duration
    peak = np.linalg.norm(pred.offset, axis=1).max()
    assert peak > 0.2

    def off_by(lag):   # the plant follows its commands through the valves' and oil's lag
        return np.linalg.norm(sw[during] - np.column_stack(
            [np.interp(t[during] - lag, pred.t, pred.offset[:, i]) for i in (0, 1)]),
            axis=1).max()
    err = min(off_by(lag) for lag in np.arange(0.0, 0.41, 0.02))
    assert err < 0.2 * peak, (err, peak)
    assert summ["swing_peak_m"] == pytest.approx(peak, rel=0.2)
    # residual: the largest offset of the settle, near the model's free-swing amplitude
    r = np.linalg.norm(sw, axis=1)
    assert summ["residual_swing_m"] == pytest.approx(r[t >= tr.duration].max(), rel=0.05)
    assert summ["residual_swing_m"] == pytest.approx(pred.residual_m, rel=0.2)


def test_no_grapple_no_swing_columns(s100f, tmp_path):
    tr = plan(s100f, PlanRequest(*MOVE), "nlp").trajectory
    out = tmp_path / "m.csv"
    summ = plant_to_csv(s100f, tr, out, "exudyn")
    cols, _, _ = read_csv_table(out)
    assert "swing_x" not in cols and "residual_swing_m" not in summ
