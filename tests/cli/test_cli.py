"""The ``crane-planner`` command line (planner/cli.py), run in-process through ``main``."""
from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from planner.cli import main
from planner.problems import crane_path
from planner.units import parse_point

ROOT = Path(__file__).resolve().parents[2]
IDS = ["cat215b", "cranab850", "s100f", "umea-lab"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _run(capsys, *argv):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


# ----------------------------------------------------------------------------- problems
def test_problems_list_prints_the_ids(capsys):
    rc, out, err = _run(capsys, "problems", "list")
    assert rc == 0
    lines = out.strip().splitlines()
    assert [ln.split()[0] for ln in lines] == IDS
    assert "slew, boom, jib, tele" in out
    assert "swing, boom, stick" in out      # cat215b has no telescope


def test_problems_list_json_stdout(capsys):
    rc, out, err = _run(capsys, "problems", "list", "--json", "-")
    assert rc == 0
    rows = json.loads(out)                  # only JSON on stdout, no table
    assert isinstance(rows, list)
    assert [r["id"] for r in rows] == IDS
    umea = rows[IDS.index("umea-lab")]
    assert umea["joints"] == ["slew", "boom", "jib", "tele"]
    assert umea["redundancy"] == "tele"
    assert umea["pump"] == "load_sensing"


def test_problems_list_json_without_value_means_stdout(capsys):
    rc, out, _ = _run(capsys, "problems", "list", "--json")
    assert rc == 0
    assert [r["id"] for r in json.loads(out)] == IDS


def test_problems_show_json(capsys):
    rc, out, err = _run(capsys, "problems", "show", "s100f", "--json", "-")
    assert rc == 0
    d = json.loads(out)
    toml = tomllib.loads(crane_path("s100f").read_text("utf-8"))
    assert d["id"] == "s100f"
    assert [j["name"] for j in d["joints"]] == ["slew", "boom", "jib", "tele"]
    assert d["pump"]["max_flow"] == toml["pump"]["max_flow"]
    assert d["joints"][3]["type"] == "prismatic"
    assert "raw" not in d and "text" not in d
    assert d["transformer"] is not None     # s100f has a hydraulic transformer


def test_problems_show_text(capsys):
    rc, out, err = _run(capsys, "problems", "show", "umea-lab")
    assert rc == 0
    assert "[umea-lab]" in out
    assert "umea-lab.toml" in out
    for name in ("slew", "boom", "jib", "tele"):
        assert f"  {name} " in out
    assert "21 L/min" in out                # pump max_flow 3.5e-4 m³/s


def test_problems_show_by_path(capsys):
    p = crane_path("cranab850")
    rc, out, _ = _run(capsys, "problems", "show", str(p), "--json", "-")
    assert rc == 0
    assert json.loads(out)["id"] == "cranab850"


def test_problems_show_plot_writes_png(capsys, tmp_path):
    png = tmp_path / "ws.png"
    rc, out, err = _run(capsys, "problems", "show", "umea-lab", "--plot", str(png))
    assert rc == 0
    data = png.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > 1000
    assert f"workspace figure written to {png}" in out


def test_problems_show_plot_keeps_json_stdout_clean(capsys, tmp_path):
    png = tmp_path / "ws.png"
    rc, out, err = _run(capsys, "problems", "show", "umea-lab", "--json", "-",
                        "--plot", str(png))
    assert rc == 0
    assert json.loads(out)["id"] == "umea-lab"     # the plot note went to stderr
    assert "workspace figure written" in err
    assert png.read_bytes()[:8] == PNG_SIGNATURE


def test_problems_show_unknown_crane(capsys):
    rc, out, err = _run(capsys, "problems", "show", "nope")
    assert rc == 2
    assert out == ""
    assert err.startswith("crane-planner: error: ")
    assert "unknown crane 'nope'" in err
    for cid in IDS:
        assert cid in err


def test_problems_show_invalid_toml_file(capsys, tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[crane\n", encoding="utf-8")
    rc, out, err = _run(capsys, "problems", "show", str(p))
    assert rc == 2
    assert "not valid TOML" in err
    assert str(p) in err


# ----------------------------------------------------------------------------- bound
def test_bound_json(capsys):
    rc, out, err = _run(capsys, "bound", "cranab850", "--start", "1.5,1.0,0",
                        "--goal", "5.5,1.0,0", "--json", "-")
    assert rc == 0
    d = json.loads(out)
    assert d["status"] == "ok"
    assert d["crane"] == "cranab850"
    assert d["start"] == [1.5, 1.0, 0.0] and d["goal"] == [5.5, 1.0, 0.0]
    assert 0 < d["velocity_s"] <= d["combined_s"]
    assert d["rest_to_rest_s"] <= d["combined_s"] + 1e-12
    assert d["pump_s"] <= d["combined_s"] + 1e-12


def test_bound_text(capsys):
    rc, out, err = _run(capsys, "bound", "cranab850", "--start", "1.5,1.0",
                        "--goal", "5.5,1.0")
    assert rc == 0
    assert out.startswith("lower bounds for cranab850 (1.5, 1.0, 0.0) -> (5.5, 1.0, 0.0)")
    assert "combined" in out


def test_bound_unreachable_goal(capsys):
    rc, out, err = _run(capsys, "bound", "cranab850", "--start", "1.5,1.0,0",
                        "--goal", "30,0,0", "--json", "-")
    assert rc == 2
    assert out == ""                        # no half result on stdout
    assert err.startswith("crane-planner: error: ")
    assert "unreachable" in err
    assert "r=30.000" in err


def test_bound_unknown_crane(capsys):
    rc, _, err = _run(capsys, "bound", "nope", "--start", "1.5,1.0", "--goal", "5.5,1.0")
    assert rc == 2
    assert "unknown crane 'nope'" in err


@pytest.mark.parametrize("bad", ["1,2,3,4", "a,b", "1", "1,2,xdeg", "1,nan,0", "inf,1"])
def test_bound_malformed_point_is_a_usage_error(capsys, bad):
    with pytest.raises(SystemExit) as ei:
        main(["bound", "cranab850", "--start", bad, "--goal", "5.5,1.0,0"])
    assert ei.value.code == 2
    err = capsys.readouterr().err
    assert "argument --start" in err
    assert repr(bad) in err


def test_bound_missing_goal_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as ei:
        main(["bound", "cranab850", "--start", "1.5,1.0"])
    assert ei.value.code == 2
    assert "--goal" in capsys.readouterr().err


def test_bound_json_to_file(capsys, tmp_path):
    target = tmp_path / "sub" / "out.json"
    rc, out, err = _run(capsys, "bound", "cranab850", "--start", "1.5,1.0,0",
                        "--goal", "5.5,1.0,0", "--json", str(target))
    assert rc == 0
    assert out == ""                        # --json FILE: nothing on stdout
    d = json.loads(target.read_text("utf-8"))
    assert d["status"] == "ok"
    assert d["velocity_s"] <= d["combined_s"]


def test_bound_goal_with_degrees(capsys):
    rc, out, _ = _run(capsys, "bound", "cranab850", "--start", "1.5,1.0,0",
                      "--goal", "5.5,1.0,30deg", "--json", "-")
    assert rc == 0
    d = json.loads(out)
    assert d["goal"] == pytest.approx([5.5, 1.0, 0.5235987755982988])
    rc, out, _ = _run(capsys, "bound", "cranab850", "--start", "1.5,1.0,0",
                      "--goal", "5.5,1.0,0", "--json", "-")
    d0 = json.loads(out)
    assert d["velocity_s"] > d0["velocity_s"]      # the extra 30° of slew takes time


def test_parse_point():
    assert parse_point("1.5, 1.0") == (1.5, 1.0, 0.0)
    assert parse_point("1,-2,90deg") == pytest.approx((1.0, -2.0, 1.5707963267948966))
    assert parse_point("1,2,0.5") == (1.0, 2.0, 0.5)


# ----------------------------------------------------------------------------- demo
@pytest.mark.slow  # the main job end to end (~30 s): make demo / make bench
def test_demo_writes_summary_and_figures(capsys, tmp_path):
    out_dir = tmp_path / "demo"
    rc, out, err = _run(capsys, "demo", "--out", str(out_dir), "--library-moves", "2",
                        "--workers", "1")
    assert rc == 0
    summary = (out_dir / "summary.md").read_text("utf-8")
    assert summary.startswith("# crane-planner demo")
    pngs = sorted(p.name for p in out_dir.glob("workspace_*.png"))
    assert pngs == [f"workspace_{cid}.png" for cid in IDS]
    for name in pngs:
        assert (out_dir / name).read_bytes()[:8] == PNG_SIGNATURE
        assert f"]({name})" in summary
    for move in ("A–B", "B–C", "A–C"):
        assert f"| {move} |" in summary
    for f in ("library.h5", "library_entry.png", "library_entry.gif", "bench/bench.md",
              "discrepancy/report.md",
              "discrepancy/residuals.png"):
        assert (out_dir / f).stat().st_size > 0, f
    assert "4 entries, 4 ok" in summary and "flow_gain" in summary
    assert "## Open loop on the independent plant" in summary and "| refined |" in summary
    assert "On equal limits the free-path minimum-time NLP is faster" in summary
    assert "– with the laws'" not in summary          # both margins were measured
    assert f"demo written to {out_dir}/" in out


# ----------------------------------------------------------------------------- entry points
def test_python_m_planner_problems_list():
    r = subprocess.run([sys.executable, "-m", "planner", "problems", "list"], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert [ln.split()[0] for ln in r.stdout.strip().splitlines()] == IDS


def test_python_m_planner_error_exit_status():
    r = subprocess.run([sys.executable, "-m", "planner", "problems", "show", "nope"], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "unknown crane 'nope'" in r.stderr


def test_no_command_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as ei:
        main([])
    assert ei.value.code == 2


def test_library_commands_on_a_small_database(tmp_path, capsys):
    """library info / query / export and simulate FILE.h5#ID on a database made by the store."""
    import json

    from planner import Crane
    from planner.methods.ruckig import rest_to_rest
    from planner.library.store import LibraryStore
    from planner.trajectory import evaluate
    crane = Crane.from_id("umea-lab")
    lib = tmp_path / "lib.h5"
    moves = [((3.0, 1.8, 0.0), (2.5, 3.0, -0.5)), ((2.6, 2.2, 0.2), (3.4, 2.6, -0.3))]
    with LibraryStore.create(lib, crane.spec) as db:
        for i, (a, b) in enumerate(moves):
            tr = rest_to_rest(crane, crane.ik(a, 0.5), crane.ik(b, 0.5)).trajectory
            db.add(f"m{i}", tr, start=a, goal=b, objective="time", method="ruckig",
                   status="ok", evaluation=evaluate(crane, tr))
    assert main(["library", "info", str(lib), "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["entries"] == 2
    assert main(["library", "query", str(lib), "--start", "2.65,2.2,0.2",
                 "--goal", "3.4,2.6,-0.3", "--json", "-"]) == 0
    q = json.loads(capsys.readouterr().out)
    assert q["id"] == "m1" and q["distance_m"] == pytest.approx(0.05, abs=1e-6)
    assert main(["library", "export", str(lib), "--format", "csv",
                 "--out", str(tmp_path / "x")]) == 0
    assert (tmp_path / "x" / "index.csv").exists()
    assert main(["simulate", "umea-lab", "--trajectory", f"{lib}#m0",
                 "--out", str(tmp_path / "meas.csv")]) == 0
    header = (tmp_path / "meas.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "t" and "q_boom" in header and "p_boom_a" in header
    capsys.readouterr()
    assert main(["library", "info", str(tmp_path / "missing.h5")]) == 2
    assert "no such library file" in capsys.readouterr().err


@pytest.mark.parametrize("law", ["least_norm", "max_velocity", "max_lift", "jla", "q_optimal",
                                 "p_optimal"])
def test_every_law_plans_through_the_cli(law, capsys):
    import json
    crane = "cranab850" if law == "max_lift" else "s100f"
    start, goal = ("5.5,1.0,0", "5.5,-1.0,0") if law == "max_lift" else ("7,0,0", "5,0,0")
    assert main(["plan", crane, "--start", start, "--goal", goal, "--method", f"law:{law}",
                 "--tip-speed", "0.5", "--json", "-"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == "ok" and out["method"] == f"law:{law}"
    assert out["max_limit_violation"] <= 1e-3


def test_library_query_joins_from_the_current_state(tmp_path, capsys):
    import json

    import numpy as np

    from planner import Crane
    from planner.methods.ruckig import rest_to_rest
    from planner.library.store import LibraryStore
    from planner.trajectory import Trajectory, evaluate
    crane = Crane.from_id("umea-lab")
    a, b = (3.0, 1.8, 0.0), (2.5, 3.0, -0.5)
    tr = rest_to_rest(crane, crane.ik(a, 0.5), crane.ik(b, 0.5)).trajectory
    lib = tmp_path / "lib.h5"
    with LibraryStore.create(lib, crane.spec) as db:
        db.add("m0", tr, start=a, goal=b, objective="time", method="ruckig", status="ok")
    q_now = crane.ik((2.8, 2.0, 0.2), 0.4)
    out = tmp_path / "joined.csv"
    assert main(["library", "query", str(lib), "--start", "3,1.8,0", "--goal", "2.5,3,-0.5",
                 "--from", ",".join(f"{v:.12f}" for v in q_now), "--out", str(out),
                 "--json", "-"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["join_duration_s"] > 0
    j = Trajectory.from_csv(out)
    np.testing.assert_allclose(j.q[0], q_now, atol=1e-9)           # starts where the crane is
    np.testing.assert_allclose(j.q[-1], tr.q[-1], atol=1e-9)       # ends where the entry ends
    assert abs(j.duration - (res["join_duration_s"] + tr.duration)) <= 1 / 50  # control grid
    assert j.u is not None and np.abs(j.u).max() > 0
    # a 50 Hz control-rate record: judge positions and rates (interpolating it between control
    # samples is not the plan, whose own verdict is Ruckig's)
    assert evaluate(crane, j, kinds=("position", "velocity")).ok()


def test_library_query_far_from_every_entry_warns(tmp_path, capsys):
    """Issue 16: a query far from every entry still answers with the nearest one, but warns
    (stderr and JSON ``warning``) and gives the distance; a near query has no warning."""
    import json

    from planner import Crane
    from planner.library.store import LibraryStore
    from planner.methods.ruckig import rest_to_rest
    crane = Crane.from_id("umea-lab")
    lib = tmp_path / "lib.h5"
    a, b = (3.0, 1.8, 0.0), (2.5, 3.0, -0.5)
    with LibraryStore.create(lib, crane.spec) as db:
        tr = rest_to_rest(crane, crane.ik(a, 0.5), crane.ik(b, 0.5)).trajectory
        db.add("m0", tr, start=a, goal=b, objective="time", method="ruckig", status="ok")
    assert main(["library", "query", str(lib), "--start", "3.0,1.8,0", "--goal",
                 "2.5,3.0,-0.5", "--json", "-"]) == 0
    out, err = capsys.readouterr()
    assert "warning" not in json.loads(out) and "warning" not in err
    assert main(["library", "query", str(lib), "--start", "-30,1.8,0",
                 "--goal", "2.5,3.0,-0.5", "--json", "-"]) == 0     # a negative value, no '='
    out, err = capsys.readouterr()
    q = json.loads(out)
    assert q["distance_m"] == pytest.approx(33.0, abs=1e-9)
    assert "does not cover this move" in q["warning"] and q["warning"] in err
