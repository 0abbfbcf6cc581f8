"""Issue 32 defect 10: ``simulate --rate 1e6`` wrote a 790 MB CSV with 6.1 GB of memory; the
rate and the number of rows are capped (planner.simulation.sizes.check_rate), like the
control laws' step count."""
import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.simulation.sizes import MAX_RATE_HZ, MAX_SAMPLES, check_rate
from planner.trajectory import Trajectory


def _traj_csv(path, duration):
    c = Crane.from_id("s100f")
    t = np.linspace(0.0, duration, 200)
    L = c.limit_arrays()
    q = L["q_min"] + np.outer(0.3 + 0.1 * t / duration, L["q_max"] - L["q_min"])
    Trajectory(t=t, q=q, qd=np.gradient(q, t, axis=0), qdd=np.zeros_like(q),
               joint_names=c.names, interpolation="linear").to_csv(path)


@pytest.mark.parametrize("rate, duration, why", [
    ("1e6", 3.0, f"--rate 1e+06: allowed 1 ... {MAX_RATE_HZ:g} Hz (loggers: 20-500 Hz)"),
    ("0.5", 3.0, f"--rate 0.5: allowed 1 ... {MAX_RATE_HZ:g} Hz (loggers: 20-500 Hz)"),
    ("nan", 3.0, f"--rate nan: allowed 1 ... {MAX_RATE_HZ:g} Hz (loggers: 20-500 Hz)"),
    ("10000", 60.0, f"--rate 10000: 600001 samples over 60 s; allowed at most {MAX_SAMPLES} "
                    "(--rate <= 8333 Hz for this trajectory)"),
])
def test_simulate_rate_is_capped(tmp_path, capsys, rate, duration, why):
    _traj_csv(tmp_path / "plan.csv", duration)
    out = tmp_path / "m.csv"
    assert main(["simulate", "s100f", "--trajectory", str(tmp_path / "plan.csv"), "--rate",
                 rate, "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip() == f"crane-planner: error: {why}"
    assert not out.exists()


def test_the_cap_is_the_row_count():
    assert check_rate(50.0, 10.0) == 501
    assert check_rate(MAX_RATE_HZ, (MAX_SAMPLES - 1) / MAX_RATE_HZ) == MAX_SAMPLES
    with pytest.raises(ValueError, match="allowed at most"):
        check_rate(MAX_RATE_HZ, MAX_SAMPLES / MAX_RATE_HZ)
