"""Controller exports: fixed-rate CSV with valve commands (plan --out-rate, library export
--rate), the units row, the hydraulic channels of the library CSV, plan --out FILE.h5 (a
one-entry database), the ROS JointTrajectory export, and the documented JSON keys."""
import csv
import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.feedforward import commands, predict_motion
from planner.library.export import export, ros_time
from planner.library.store import LibraryStore, StoreError
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import Trajectory, evaluate

ROOT = Path(__file__).resolve().parents[2]
PLAN = ["plan", "s100f", "--start", "6,-1,0", "--goal", "4,1,0.5", "--method", "ruckig"]


def _read(path):
    with open(path) as fh:
        header = fh.readline().strip().split(",")
        second = fh.readline()
    return header, second, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


@pytest.fixture(scope="module")
def umea_lib(tmp_path_factory):
    crane = Crane.from_id("umea-lab")
    lib = tmp_path_factory.mktemp("lib") / "lib.h5"
    moves = [((3.0, 1.8, 0.0), (2.5, 3.0, -0.5)), ((2.6, 2.2, 0.2), (3.4, 2.6, -0.3))]
    with LibraryStore.create(lib, crane.spec) as db:
        for i, (a, b) in enumerate(moves):
            tr = rest_to_rest(crane, crane.ik(a, 0.5), crane.ik(b, 0.5)).trajectory
            db.add(f"m{i}", tr, start=a, goal=b, objective="time", method="ruckig",
                   status="ok", evaluation=evaluate(crane, tr), attrs=dict(solve_s=0.25))
        db.add("m2", None, start=moves[0][0], goal=moves[0][1], objective="energy",
               method="nlp", status="infeasible", reason="no")
    return crane, lib


def test_plan_fixed_rate_csv_replays_to_the_plan(tmp_path, capsys):
    """--out-rate 25: rows at t0 + k/25 with u_*, the machine's feed-forward (the oil springs
    filled); the plain feed-forward at those rows, replayed through the valve model's inverse
    (predict_motion), reproduces the planned positions at every row."""
    out = tmp_path / "m.csv"
    assert main(PLAN + ["--out", str(out), "--out-rate", "25", "--units-row", "--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    crane = Crane.from_id("s100f")
    header, units, data = _read(out)
    units = units.strip()
    assert units.startswith("# ") and len(units[2:].split(",")) == len(header)
    unit = dict(zip(header, units[2:].split(",")))
    assert unit["t"] == "s" and unit["q_boom"] == "rad" and unit["q_tele"] == "m"
    assert unit["qd_tele"] == "m/s" and unit["u_jib"] == "1" and unit["p_boom_a"] == "Pa"
    assert unit["q_pump"] == "m^3/s" and unit["power"] == "W"
    t = data[:, 0]
    np.testing.assert_allclose(np.diff(t), 1 / 25, rtol=0, atol=1e-12)
    assert t[-1] >= js["duration_s"] - 1e-9 and t[-1] < js["duration_s"] + 1 / 25
    col = {c: i for i, c in enumerate(header)}
    q = data[:, [col[f"q_{j}"] for j in crane.names]]
    u = data[:, [col[f"u_{j}"] for j in crane.names]]
    assert np.abs(u).max() <= 1.0 and np.abs(u).max() > 0.05
    # the trajectory-CSV reader takes the file, units row and all
    back = Trajectory.from_csv(out, joint_names=crane.names)
    np.testing.assert_allclose(back.q, q)
    # the same rows as the plan: the plan's positions at those times
    plain = tmp_path / "plain.csv"
    assert main(PLAN + ["--out", str(plain)]) == 0
    tr = Trajectory.from_csv(plain, joint_names=crane.names)
    np.testing.assert_allclose(tr.sample(np.minimum(t, tr.t[-1]))[0], q, atol=1e-8)
    np.testing.assert_allclose(u, commands(crane, tr, 25.0, oil=True).u, atol=1e-4)
    kin = commands(crane, tr, 25.0).u
    assert np.max(np.abs(kin - u)) > 0.01
    qr = predict_motion(crane, t, kin, q[0]).q
    assert np.max(np.abs(qr - q)) < 1e-6  # exact up to the 10-digit CSV rounding


def test_plan_plain_csv_is_unchanged(tmp_path, capsys):
    out = tmp_path / "m.csv"
    assert main(PLAN + ["--out", str(out)]) == 0
    header, second, _ = _read(out)
    assert header[0] == "t" and not second.startswith("#")
    assert "q_pump" not in header  # the method's own samples, per the contract only


@pytest.mark.parametrize("extra, word", [(["--out", "m.txt"], "--out"),
                                         (["--out", "m.csv", "--out-rate", "0"], "--out-rate"),
                                         (["--out", "m.csv", "--out-rate", "nan"], "--out-rate"),
                                         (["--out-rate", "10"], "--out"),
                                         (["--out", "m.h5", "--units-row"], "--units-row")])
def test_plan_bad_output_options_are_refused_before_planning(tmp_path, capsys, extra, word):
    args = [a if not a.startswith("m.") else str(tmp_path / a) for a in extra]
    assert main(PLAN + args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and word in err
    assert list(tmp_path.iterdir()) == []


def test_plan_out_h5_is_a_one_entry_database(tmp_path, capsys):
    out = tmp_path / "m.h5"
    assert main(PLAN + ["--out", str(out), "--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["entry"] == "plan:time"
    with h5py.File(out, "r") as f:  # the HDF5 layout, read without the package's store
        assert f.attrs["format"] == "crane-planner-library" and f.attrs["crane_id"] == "s100f"
        assert len(f["index"]) == 1
        g = f["entries"]["plan:time"]
        for name in ("t", "q", "qd", "qdd", "u", "x", "xd", "p_a", "p_b", "q_pump", "power"):
            assert name in g
        assert f["index"][0]["energy_J"] == pytest.approx(js["energy_J"], rel=1e-5)
        assert f["index"][0]["duration_s"] == pytest.approx(js["duration_s"], abs=0.02)
    # FILE.h5 and FILE.h5#ID name it wherever a trajectory is read
    for ref in (str(out), f"{out}#plan:time"):
        assert main(["simulate", "s100f", "--trajectory", ref,
                     "--out", str(tmp_path / "meas.csv")]) == 0
    # rerunning replaces the one-entry file; a bigger library is never replaced
    assert main(PLAN + ["--out", str(out)]) == 0
    capsys.readouterr()
    with LibraryStore.open(out, "a") as db:
        db.add("other", None, start=(5, 0, 0), goal=(4, 0, 0), objective="time", method="x",
               status="failed", reason="test")
    assert main(PLAN + ["--out", str(out)]) == 2
    assert "library of 2 entries" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.h5", "meas.csv"]


def test_library_csv_keeps_the_hydraulic_channels(umea_lib, tmp_path):
    crane, lib = umea_lib
    files = export(lib, tmp_path / "csv", "csv", units_row=True)
    assert {p.name for p in files} == {"m0.csv", "m1.csv", "index.csv"}
    header, units, data = _read(tmp_path / "csv" / "m1.csv")
    assert units.startswith("# ") and len(units.split(",")) == len(header)
    col = {c: i for i, c in enumerate(header)}
    with h5py.File(lib, "r") as f:
        g = f["entries"]["m1"]
        for i, j in enumerate(crane.names):
            np.testing.assert_allclose(data[:, col[f"p_{j}_a"]], g["p_a"][:, i], rtol=1e-9)
            np.testing.assert_allclose(data[:, col[f"p_{j}_b"]], g["p_b"][:, i], rtol=1e-9)
            np.testing.assert_allclose(data[:, col[f"x_{j}"]], g["x"][:, i], rtol=1e-9)
            np.testing.assert_allclose(data[:, col[f"xd_{j}"]], g["xd"][:, i], rtol=1e-9,
                                       atol=1e-12)
        np.testing.assert_allclose(data[:, col["q_pump"]], g["q_pump"][()], rtol=1e-9)
        np.testing.assert_allclose(data[:, col["power"]], g["power"][()], rtol=1e-9,
                                   atol=1e-6)


def test_library_export_at_a_fixed_rate(umea_lib, tmp_path, capsys):
    crane, lib = umea_lib
    assert main(["library", "export", str(lib), "--format", "csv", "--rate", "40",
                 "--out", str(tmp_path / "x")]) == 0
    header, _, data = _read(tmp_path / "x" / "m0.csv")
    np.testing.assert_allclose(np.diff(data[:, 0]), 1 / 40, atol=1e-12)
    assert all(f"u_{j}" in header for j in crane.names) and "q_pump" in header
    with LibraryStore.open(lib) as db:
        tr = db.trajectory("m0")
    col = {c: i for i, c in enumerate(header)}
    q = data[:, [col[f"q_{j}"] for j in crane.names]]
    np.testing.assert_allclose(tr.sample(data[:, 0])[0], q, atol=1e-8)
    # the hydraulic channels on the new rows are the model's at the entry's states there
    hyd = crane.hydraulics(*tr.sample(data[:, 0])[:3])
    np.testing.assert_allclose(data[:, col["q_pump"]], hyd["q_pump"], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(data[:, col["p_boom_a"]], hyd["p_a"][:, 1], rtol=1e-8)
    assert main(["library", "export", str(lib), "--format", "mat", "--rate", "40",
                 "--out", str(tmp_path / "y")]) == 2
    assert "--rate" in capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["ros", "ros-yaml"])
def test_ros_joint_trajectory_export(umea_lib, tmp_path, fmt):
    crane, lib = umea_lib
    files = export(lib, tmp_path, fmt)
    ext = ".json" if fmt == "ros" else ".yaml"
    assert {p.name for p in files} == {f"m0{ext}", f"m1{ext}", "index.csv"}
    text = (tmp_path / f"m1{ext}").read_text()
    if fmt == "ros":
        msg = json.loads(text)
    else:
        import yaml
        msg = yaml.safe_load(text)
    with LibraryStore.open(lib) as db:
        tr = db.trajectory("m1")
    assert msg["joint_names"] == list(crane.names)
    assert len(msg["points"]) == len(tr.t)
    for k in (0, len(tr.t) // 2, len(tr.t) - 1):
        p = msg["points"][k]
        ts = p["time_from_start"]
        assert 0 <= ts["nanosec"] < 1_000_000_000 and isinstance(ts["sec"], int)
        assert ts["sec"] + 1e-9 * ts["nanosec"] == pytest.approx(tr.t[k] - tr.t[0], abs=1e-9)
        np.testing.assert_array_equal(p["positions"], tr.q[k])
        np.testing.assert_array_equal(p["velocities"], tr.qd[k])
        np.testing.assert_array_equal(p["accelerations"], tr.qdd[k])
    with open(tmp_path / "index.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["file"] for r in rows] == [f"m0{ext}", f"m1{ext}", ""]


def test_ros_time_carries_nanoseconds():
    assert ros_time(0.0) == dict(sec=0, nanosec=0)
    assert ros_time(1.9999999999) == dict(sec=2, nanosec=0)
    assert ros_time(12.25) == dict(sec=12, nanosec=250_000_000)


def test_export_refusals(umea_lib, tmp_path):
    _, lib = umea_lib
    with pytest.raises(StoreError, match="`units_row`"):
        export(lib, tmp_path, "json", units_row=True)
    with pytest.raises(StoreError, match="positive"):
        export(lib, tmp_path, "csv", rate=-1.0)


def _documented(section):
    """The backticked key names of one command's section of docs/json-keys.md."""
    text = (ROOT / "docs" / "json-keys.md").read_text()
    m = re.search(rf"^## `{re.escape(section)}[^\n]*\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    assert m, section
    return set(re.findall(r"`([A-Za-z_][A-Za-z0-9_]*)`", m.group(1)))


def test_json_keys_are_documented_and_unified(umea_lib, tmp_path, capsys):
    """Every top-level key a command writes is in docs/json-keys.md, and the unified names
    stand beside the old ones with the same value."""
    assert main(PLAN + ["--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert set(js) <= _documented("plan CRANE")
    assert js["crane_id"] == js["crane"] == "s100f"
    for k in ("status", "method", "objective", "duration_s", "energy_J", "peak_pump_flow_m3s",
              "max_limit_violation", "lower_bound_s", "solve_time_s"):  # CONTRACT keys
        assert k in js
    assert main(["bound", "s100f", "--start", "6,-1,0", "--goal", "4,1,0", "--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert set(js) <= _documented("bound CRANE") and js["crane_id"] == js["crane"]
    assert main(["problems", "urdf", "s100f", "--out", str(tmp_path / "a.urdf"),
                 "--json", "-"]) == 0
    assert set(json.loads(capsys.readouterr().out)) <= _documented("problems urdf ID")
    _, lib = umea_lib
    assert main(["library", "info", str(lib), "--json", "-"]) == 0
    assert set(json.loads(capsys.readouterr().out)) <= _documented("library info LIB.h5")
    (p,) = export(lib, tmp_path / "j", "json")
    doc = json.loads(p.read_text())
    e = {x["id"]: x for x in doc["entries"]}
    assert e["m0"]["solve_time_s"] == e["m0"]["solve_s"] == 0.25


def test_simulate_on_exudyn_replays_the_machines_feed_forward(tmp_path, capsys):
    """``simulate --plant exudyn`` of a plan replays the machine's feed-forward (the oil
    springs filled, as the library stores it): Exudyn's pump work is evaluate()'s within 2 %
    on this move (the plain feed-forward rings the oil: the twin prices it 9.6 % over), and the
    twin's figure beside it is Exudyn's within 0.5 % (independent code)."""
    out = tmp_path / "n.h5"
    assert main(["plan", "s100f", "--start", "6,-1,0", "--goal", "4,1,0.5", "--method", "nlp",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["simulate", "s100f", "--trajectory", str(out), "--plant", "exudyn",
                 "--json", "-", "--out", str(tmp_path / "meas.csv")]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["commands"] == "feedforward@50Hz+oil"
    assert js["pump_energy_J"] == pytest.approx(js["evaluate_energy_J"], rel=0.02)
    assert js["twin_energy_J"] == pytest.approx(js["pump_energy_J"], rel=0.005)
