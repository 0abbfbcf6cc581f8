"""planner.plots: figure formats from the suffix, no backend chosen on import, Figures returned,
and the content of the pump panel, the joint panel and the workspace region (artists, not
pixels)."""
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.path import Path as MplPath

from planner import Crane
from planner.cli import main
from planner.plots import (PUMP_FLOW_COLOUR, PUMP_POWER_COLOUR, FigureFormatError,
                           figure_format, reachable_region, trajectory_figure, workspace_extent,
                           workspace_figure)
from planner.trajectory import Trajectory, evaluate
from tests.conftest import random_configs

ROOT = Path(__file__).resolve().parents[2]


def _evaluation(crane):
    """A smooth rest-to-rest move of every joint (quintic blend over 3 s), evaluated."""
    L = crane.limit_arrays()
    q0 = L["q_min"] + 0.4 * (L["q_max"] - L["q_min"])
    q1 = L["q_min"] + 0.6 * (L["q_max"] - L["q_min"])
    T = 3.0

    def f(t):
        s = (t / T)[:, None]
        b, bd, bdd = 10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4) / T, \
            (60 * s - 180 * s**2 + 120 * s**3) / T**2
        d = q1 - q0
        return q0 + b * d, bd * d, bdd * d
    traj = Trajectory.from_function(f, T, rate=50.0, joint_names=tuple(crane.names))
    return evaluate(crane, traj, rate=200.0)


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG\r\n\x1a\n"), (".pdf", b"%PDF-"),
                                           (".PDF", b"%PDF-"), (".svg", b"<?xml")])
def test_figure_written_in_the_format_of_its_suffix(s100f, tmp_path, suffix, magic):
    p = tmp_path / f"ws{suffix}"
    fig = workspace_figure(s100f, p, n=20)
    assert isinstance(fig, Figure)
    data = p.read_bytes()
    assert data.startswith(magic)
    if suffix == ".svg":  # real vector SVG: an <svg> root with drawn paths, not an embedded PNG
        root = ET.fromstring(data)
        assert root.tag.endswith("svg")
        assert len(root.findall(".//{http://www.w3.org/2000/svg}path")) > 20
    if suffix.lower() == ".pdf":
        assert b"/Type /Page" in data and not data.startswith(b"\x89PNG")


@pytest.mark.parametrize("suffix", [".svg", ".pdf", ".png"])
def test_figure_bytes_are_deterministic(s100f, tmp_path, suffix):
    a, b = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    workspace_figure(s100f, a, n=10)
    workspace_figure(s100f, b, n=10)
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("name", ["x.jpg", "x", "x.png.txt", "x.eps"])
def test_unknown_suffix_is_refused_and_nothing_written(s100f, tmp_path, name):
    with pytest.raises(FigureFormatError, match="allowed: .png, .pdf, .svg"):
        figure_format(tmp_path / name)
    with pytest.raises(FigureFormatError):
        workspace_figure(s100f, tmp_path / name, n=5)
    assert list(tmp_path.iterdir()) == []


def test_plan_plot_unknown_suffix_is_a_one_line_usage_error(tmp_path, capsys):
    rc = main(["plan", "cranab850", "--start", "1.5,1.0,0", "--goal", "5.5,1.0,0", "--method",
               "dp", "--plot", str(tmp_path / "fig.jpeg")])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and "--plot" in err and ".jpeg" in err and ".svg" in err
    assert list(tmp_path.iterdir()) == []


def test_plan_plot_writes_a_real_pdf(tmp_path, capsys):
    p = tmp_path / "move.pdf"
    rc = main(["plan", "cranab850", "--start", "1.5,1.0,0", "--goal", "5.5,1.0,0", "--method",
               "dp", "--plot", str(p)])
    assert rc == 0
    assert p.read_bytes().startswith(b"%PDF-")


def test_problems_show_plot_svg(tmp_path, capsys):
    p = tmp_path / "ws.svg"
    assert main(["problems", "show", "umea-lab", "--plot", str(p)]) == 0
    assert ET.fromstring(p.read_bytes()).tag.endswith("svg")
    assert main(["problems", "show", "umea-lab", "--plot", str(tmp_path / "ws.gif")]) == 2
    assert "--plot" in capsys.readouterr().err


def test_import_selects_no_backend(tmp_path):
    """Importing planner.plots keeps the backend the user chose (Jupyter's inline one here),
    and a headless process can still write every format."""
    code = ("import matplotlib; import planner.plots as p; print(matplotlib.get_backend()); "
            "f = p.new_figure(); f.subplots().plot([0, 1]); p.save(f, 'x.pdf'); print('saved')")
    env = dict(os.environ, PYTHONPATH=str(ROOT),
               MPLBACKEND="module://matplotlib_inline.backend_inline")
    env.pop("DISPLAY", None)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=120, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    backend, saved = out.stdout.split()
    assert backend == "module://matplotlib_inline.backend_inline"
    assert saved == "saved"
    assert (tmp_path / "x.pdf").read_bytes().startswith(b"%PDF-")


def test_figures_are_not_registered_with_pyplot(s100f):
    import matplotlib.pyplot as plt
    before = plt.get_fignums()
    fig = workspace_figure(s100f, n=5)
    assert plt.get_fignums() == before
    assert isinstance(fig, Figure) and fig.axes


def test_pump_panel_legend_and_colours_apart_from_the_joints(s100f):
    fig = trajectory_figure(s100f, _evaluation(s100f))
    axes = fig.axes
    pump = [a for a in axes if a.get_title().startswith("pump")][0]
    labels = [t.get_text() for t in pump.get_legend().get_texts()]
    assert any("flow" in s for s in labels) and any("power" in s for s in labels)
    joint_colours = {to_rgba(f"C{i}") for i in range(s100f.n)}
    pump_lines = [ln for a in axes for ln in a.get_lines()
                  if "pump" in ln.get_label()]
    assert {ln.get_label().split(" [")[0] for ln in pump_lines} >= {"pump flow", "pump power"}
    for ln in pump_lines:
        assert to_rgba(ln.get_color()) not in joint_colours
    assert to_rgba(PUMP_FLOW_COLOUR) != to_rgba(PUMP_POWER_COLOUR)


def test_telescope_metres_on_their_own_axis(s100f):
    fig = trajectory_figure(s100f, _evaluation(s100f))
    by_label = {ln.get_label(): ln.axes for a in fig.axes for ln in a.get_lines()}
    tele, boom = "tele [m] (right)", "boom [°]"  # the joint-position panel's lines
    assert by_label[tele] is not by_label[boom]
    assert "[m]" in by_label[tele].get_ylabel() and "[°]" in by_label[boom].get_ylabel()
    # the telescope's line is in metres (its data equal the joint's positions)
    ev = _evaluation(s100f)
    i = s100f.names.index("tele")
    np.testing.assert_allclose(
        [ln for ln in by_label[tele].get_lines() if ln.get_label() == tele][0].get_ydata(),
        ev.q[:, i])
    # the legend of the joint panel names every joint once
    texts = [t.get_text() for t in by_label[boom].get_legend().get_texts()]
    assert sorted(s.split(" ")[0] for s in texts) == sorted(s100f.names)


@pytest.mark.parametrize("cid", ["s100f", "cat215b"])
def test_workspace_region_is_filled_and_contains_reachable_tips(cid):
    """Every tip of a random configuration (slew 0) lies in the filled region; points beyond
    the largest reach do not."""
    crane = Crane.from_id(cid)
    quads = reachable_region(crane, n=40)
    paths = [MplPath(q) for q in quads]
    Q = random_configs(crane, 300, seed=3)
    Q[:, crane.chain.slew] = 0.0
    tips = crane.tip(Q)[:, :2]
    inside = np.zeros(len(tips), bool)
    for p in paths:
        inside |= p.contains_points(tips, radius=1e-9)
    assert inside.mean() >= 0.99
    r_max = workspace_extent(crane)["r_max"]
    far = np.array([[r_max + 0.3, z] for z in np.linspace(-5, 5, 11)])
    assert not any(p.contains_points(far).any() for p in paths)
    fig = workspace_figure(crane, n=10)
    colls = [c for c in fig.axes[0].collections if c.get_label() == "reachable region"]
    assert len(colls) == 1 and len(colls[0].get_paths()) == len(reachable_region(crane))
    assert to_rgba(colls[0].get_facecolor()[0])[3] == 1.0  # opaque: no stripes, no seams
