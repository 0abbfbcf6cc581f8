"""Issue 32, defects 5-8, 11, 13 and 15: input that used to give a silently wrong result or a
misleading message is refused (exit 2) or accepted with a note, with one line that names the
field, the value and what is allowed; Ctrl-C anywhere is exit 130 and one line."""
from __future__ import annotations

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.trajectory import Trajectory


def _cli(capsys, *argv):
    """(rc, stdout, stderr) of the CLI; argparse usage errors count as rc 2."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


def _refused(capsys, *argv, words=(), rc=2):
    code, out, err = _cli(capsys, *argv)
    assert code == rc, (code, out, err)
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def _s100f_move(tele=2.2):
    """A rest-to-rest move of the S100F with its telescope out to ``tele`` (umea-lab's
    telescope ends at 1.55 m; both machines name their joints slew, boom, jib, tele)."""
    from planner.methods.ruckig import rest_to_rest
    crane = Crane.from_id("s100f")
    q0, q1 = crane.ik((6.0, -1.0, 0.0), tele=tele), crane.ik((5.0, 0.5, 0.3), tele=tele)
    return crane, rest_to_rest(crane, q0, q1).trajectory


# ------------------------------------------------------------------ 5: another crane's move
def test_simulate_refuses_another_cranes_trajectory_csv(tmp_path, capsys):
    crane, tr = _s100f_move()
    path = tmp_path / "s100f-move.csv"
    tr.to_csv(path)
    umea = Crane.from_id("umea-lab")
    assert umea.names == crane.names
    assert tr.q[:, 3].max() > umea.spec.joints[3].limits.q[1] + 0.5
    # the oracle: the first of umea-lab's joints that the move leaves by more than 5 % of
    # its range, and the first sample where it does
    for k, j in enumerate(umea.spec.joints):
        lo, hi = j.limits.q
        out = np.flatnonzero((tr.q[:, k] < lo - 0.05 * (hi - lo))
                             | (tr.q[:, k] > hi + 0.05 * (hi - lo)))
        if out.size:
            break
    last = _refused(capsys, "simulate", "umea-lab", "--trajectory", path,
                    "--out", tmp_path / "m.csv", words=(str(path), "joint range"))
    assert f"q_{j.name} = {tr.q[out[0], k]:.6g} " in last
    assert f"[{lo:.4g}, {hi:.4g}]" in last and f"data row {out[0] + 1} " in last
    assert not (tmp_path / "m.csv").exists()
    # the same file on its own machine replays
    assert _cli(capsys, "simulate", "s100f", "--trajectory", path,
                "--out", tmp_path / "ok.csv")[0] == 0


def test_simulate_refuses_a_library_entry_of_another_crane(tmp_path, capsys):
    from planner.library.store import LibraryStore
    crane, tr = _s100f_move(tele=1.0)     # inside umea-lab's ranges? the crane id still says no
    lib = tmp_path / "s100f.h5"
    with LibraryStore.create(lib, crane.spec) as db:
        db.add("m0", tr, start=(6.0, -1.0, 0.0), goal=(5.0, 0.5, 0.3), objective="time",
               method="ruckig", status="ok")
    _refused(capsys, "simulate", "umea-lab", "--trajectory", f"{lib}#m0",
             "--out", tmp_path / "m.csv", words=("crane_id = 's100f'", "umea-lab", "#m0"))
    assert not (tmp_path / "m.csv").exists()


def test_simulate_refuses_a_trajectory_with_other_joints(tmp_path, capsys):
    _, tr = _s100f_move()
    path = tmp_path / "s100f-move.csv"
    tr.to_csv(path)
    _refused(capsys, "simulate", "cat215b", "--trajectory", path, "--out", tmp_path / "m.csv",
             words=(str(path), "slew, boom, jib, tele", "swing, boom, stick"))
