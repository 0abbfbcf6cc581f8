"""``library build --grapple``: sway-free entries with the swing the model predicts stored per
entry (issue 29). Oracles: the model's pendulum (Pendulum.rhs) integrated along the stored
plan by scipy's adaptive Runge-Kutta (not predict_swing's fixed-step RK4), the tip's
acceleration from the crane's kinematics, the load's distance from the plate computed from
those states by hand; the sway-blind entry of the same move for what the grapple changes."""
import argparse
import csv
import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from planner import Crane
from planner.cli import main
from planner.cli.library import build_grapple
from planner.library.store import LibraryStore
from planner.model.pendulum import Pendulum, tip_motion
from planner.problems import crane_file

PLATE = ('[obstacles.headboard]\nkind = "plate"\nx = -1.2\ny_min = -1.5\ny_max = 1.5\n'
         'z_bottom = -1.2\nz_top = 1.3\nclearance = 0.3\n')
SUITE = ('[suite]\nid = "sway-small"\ncrane = "s100f"\n'
         '[[moves]]\nid = "m0"\nstart = [6.0, 1.5, -0.25]\ngoal = [4.8, 0.2, 0.25]\n' + PLATE)


def oracle(crane, traj, pend):
    """(residual amplitude, peak offset during the move, least load distance from the
    plate) [m]: the pendulum integrated by solve_ivp along the plan's tip acceleration."""
    f = tip_motion(crane)

    def acc(t):
        q, qd, qdd, _ = traj.sample(np.atleast_1d(t))
        return np.array(f(q[0], qd[0], qdd[0])[2]).ravel()

    sol = solve_ivp(lambda t, x: pend.rhs(x, acc(t)), (traj.t[0], traj.t[-1]), np.zeros(4),
                    method="DOP853", rtol=1e-9, atol=1e-11, max_step=0.01, dense_output=True)
    t = np.linspace(traj.t[0], traj.t[-1], 2001)
    x = sol.sol(t).T
    link = pend.link(x)
    q = traj.sample(t)[0]
    tip = np.array([np.array(crane.f_fk(qi)[0]).ravel() for qi in q])
    load = tip + link
    dy = np.maximum(np.maximum(load[:, 1] - 1.5, -1.5 - load[:, 1]), 0)
    dz = np.maximum(np.maximum(load[:, 2] - 1.3, -1.2 - load[:, 2]), 0)
    plate = np.sqrt((load[:, 0] + 1.2) ** 2 + dy ** 2 + dz ** 2).min()
    return (float(pend.amplitude(x[-1])), float(np.linalg.norm(link[:, :2], axis=1).max()),
            float(plate))


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("swaylib")
    (d / "suite.toml").write_text(SUITE)
    lib = d / "lib.h5"
    argv = ["library", "build", "s100f", "--tasks", str(d / "suite.toml"), "--out", str(lib),
            "--grapple", "1.5", "--grapple-zeta", "0.05", "--no-robustness", "--intervals",
            "30"]
    assert main(argv + ["--json", str(d / "s.json")]) == 0
    return d, lib, argv


@pytest.mark.slow   # a sway-free library build (~10 s): make bench
def test_the_entry_is_sway_free_and_stores_the_swing_the_model_predicts(built):
    d, lib, _ = built
    crane = Crane.from_id("s100f")
    pend = Pendulum.of(crane, 1.5, zeta=0.05)
    with LibraryStore.open(lib, "r") as db:
        (row,) = db.index_rows()
        a = db.entry_attrs(row["id"])
        traj = db.trajectory(row["id"])
    assert row["status"] == "ok" and row["method"] == "nlp-sway"
    assert a["grapple_m"] == 1.5 and a["grapple_zeta"] == pytest.approx(0.05)
    assert a["pendulum_hz"] == pytest.approx(0.40, abs=0.005)
    residual, peak, plate = oracle(crane, traj, pend)
    assert residual <= 0.012                                   # sway-free: 10 mm asked
    assert a["swing_residual_m"] == pytest.approx(residual, abs=1e-3)
    assert a["swing_peak_m"] == pytest.approx(peak, abs=2e-3)
    assert peak > 0.1                                          # it swings during the move
    assert a["load_clearance_m"] == pytest.approx(plate, abs=2e-3)


@pytest.mark.slow   # a sway-free library build (~10 s): make bench
def test_the_sway_blind_entry_of_the_same_move_leaves_it_swinging(built, tmp_path):
    d, _, argv = built
    lib = tmp_path / "blind.h5"
    args = [argv[0], argv[1], argv[2], argv[3], argv[4], "--out", str(lib), "--grapple",
            "1.5", "--grapple-zeta", "0.05", "--method", "nlp", "--no-robustness",
            "--intervals", "30"]
    assert main(args) == 0
    crane = Crane.from_id("s100f")
    with LibraryStore.open(lib, "r") as db:
        (row,) = db.index_rows()
        a = db.entry_attrs(row["id"])
        traj = db.trajectory(row["id"])
    assert row["method"] == "nlp"
    residual = oracle(crane, traj, Pendulum.of(crane, 1.5, zeta=0.05))[0]
    assert residual > 0.1 and a["swing_residual_m"] == pytest.approx(residual, abs=1e-3)


@pytest.mark.slow   # a sway-free library build (~10 s): make bench
def test_a_rerun_resumes_and_another_link_is_refused_in_one_line(built, capsys):
    d, lib, argv = built
    capsys.readouterr()
    assert main(argv + ["--json", "-"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["planned"] == 0 and s["skipped_existing"] == 1
    for other in (["--grapple", "1.2"], ["--no-grapple"]):
        args = [a for a in argv if a not in ("--grapple", "1.5", "--grapple-zeta", "0.05")]
        assert main(args + other) == 2
        err = capsys.readouterr().err.strip()
        assert "grapple" in err and "1.5 m" in err and "\n" not in err


@pytest.mark.slow   # a sway-free library build (~10 s): make bench
def test_show_and_export_list_the_swing(built, tmp_path, capsys):
    d, lib, _ = built
    capsys.readouterr()
    assert main(["library", "show", f"{lib}#m0:time"]) == 0
    out = capsys.readouterr().out
    assert "residual swing" in out and "load clearance" in out
    assert main(["library", "export", str(lib), "--format", "csv", "--out",
                 str(tmp_path / "x")]) == 0
    rows = list(csv.DictReader((tmp_path / "x" / "index.csv").open()))
    with LibraryStore.open(lib, "r") as db:
        a = db.entry_attrs("m0:time")
    assert float(rows[0]["swing_residual_m"]) == pytest.approx(a["swing_residual_m"])
    assert float(rows[0]["load_clearance_m"]) == pytest.approx(a["load_clearance_m"])


@pytest.mark.parametrize("extra, names", [
    (["--grapple", "-1"], "--grapple"),
    (["--grapple", "0"], "--grapple"),
    (["--grapple", "1.5", "--grapple-zeta", "2"], "--grapple-zeta"),
    (["--grapple", "1.5", "--no-grapple"], "--no-grapple"),
    (["--grapple", "1.5", "--objectives", "time,energy"], "--objectives"),
])
def test_bad_grapple_input_is_one_line_exit_2(tmp_path, capsys, extra, names):
    (tmp_path / "suite.toml").write_text(SUITE)
    out = tmp_path / "lib.h5"
    assert main(["library", "build", "s100f", "--tasks", str(tmp_path / "suite.toml"),
                 "--out", str(out)] + extra) == 2
    err = capsys.readouterr().err.strip()
    assert names in err and "allowed" in err and "\n" not in err
    assert not out.exists()


def test_a_grapple_method_without_a_link_is_refused(tmp_path, capsys):
    assert main(["library", "build", "umea-lab", "--tasks", "seed003-paths", "--out",
                 str(tmp_path / "l.h5"), "--method", "zvd"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--grapple" in err and "umea-lab" in err and "\n" not in err


def test_the_spec_s_grapple_turns_it_on_by_default(tmp_path):
    spec = tmp_path / "s100f-grapple.toml"
    spec.write_text(crane_file("s100f").read_text() + "\n[dynamics.grapple]\nlink_length = "
                    "1.5\ndamping = 800.0\n")

    def args(**kw):
        base = dict(crane=str(spec), grapple=None, grapple_zeta=None, no_grapple=False,
                    method=None, objectives="time")
        return argparse.Namespace(**dict(base, **kw))
    a = args()
    assert build_grapple(a, ("time",)) is True and a.method == "nlp-sway"
    a = args(no_grapple=True)
    assert build_grapple(a, ("time",)) is None and a.method == "nlp"
    a = args(grapple=0.8, method="zvd")
    assert build_grapple(a, ("time",)) == 0.8 and a.method == "zvd"
    a = args(crane="s100f")                       # no [dynamics.grapple]: off
    assert build_grapple(a, ("time", "energy")) is None and a.method == "nlp"
