"""``plan --animate`` / ``library show --animate``: the frame count as documented, the first and
last frames' tip at the move's start and goal (read from the artists), a self-contained HTML
page, the bad suffix / fps refused with exit 2 before any work, and matplotlib left unimported
by ``import planner`` and ``import planner.animate``."""
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from planner import Crane
from planner.animate import MAX_FRAMES, build_animation, frame_count
from planner.cli import main
from planner.geometry.obstacles import Plate
from planner.library.store import LibraryStore
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import Trajectory

ROOT = Path(__file__).resolve().parents[2]
START, GOAL = (6.0, -1.0, 0.0), (4.0, 1.0, 0.5)


@pytest.fixture(scope="module")
def entry(tmp_path_factory):
    """A one-entry s100f library built 'from' the forwarder cycle (its headboard plate)."""
    crane = Crane.from_id("s100f")
    lib = tmp_path_factory.mktemp("anim") / "lib.h5"
    tr = rest_to_rest(crane, crane.ik(START, 0.5), crane.ik(GOAL, 0.5)).trajectory
    with LibraryStore.create(lib, crane.spec) as db:
        db.add("fwd:0", tr, start=START, goal=GOAL, objective="time", method="ruckig",
               status="ok", attrs=dict(suite="forwarder-cycle"))
    return crane, lib, tr


def _tip_of(a, k):
    a.draw(k)
    (r,), (z,) = a.artists["side_tip"].get_data()
    (x,), (y,) = a.artists["top_tip"].get_data()
    return r, z, x, y


def test_first_and_last_frames_show_the_tip_at_start_and_goal(entry):
    crane, _, tr = entry
    a = build_animation(crane, tr, obstacles=(Plate(-1.2, -1.5, 1.5, -1.2, 1.3),), fps=5)
    for k, (r0, z0, slew) in ((0, START), (len(a.times) - 1, GOAL)):
        r, z, x, y = _tip_of(a, k)
        assert (r, z) == pytest.approx((r0, z0), abs=1e-6)
        assert (x, y) == pytest.approx((r0 * math.cos(slew), r0 * math.sin(slew)), abs=1e-6)
        # the drawn crane ends at the tip, in both views; without a grapple the load is there
        sx, sz = a.artists["side_crane"].get_data()
        tx, ty = a.artists["top_crane"].get_data()
        assert (sx[-1], sz[-1], tx[-1], ty[-1]) == pytest.approx((r, z, x, y), abs=1e-9)
        assert a.artists["top_load"].get_data()[0][-1] == pytest.approx(x)
        assert sx[0] == pytest.approx(0.0, abs=1e-9)    # the slew base on the axis
    assert a.times[0] == tr.t[0] and a.times[-1] == tr.t[-1]


def test_frame_count_is_bounded_as_documented(entry):
    crane, _, tr = entry
    assert frame_count(2.0, 20) == 41 and frame_count(0.01, 20) == 2
    assert frame_count(100.0, 30) == MAX_FRAMES
    # a 40 s move at 30 fps: 600 frames, played 2x faster than real time
    slow = Trajectory(t=tr.t * 40 / tr.t[-1], q=tr.q, qd=tr.qd * tr.t[-1] / 40,
                      qdd=tr.qdd * (tr.t[-1] / 40) ** 2, joint_names=tr.joint_names)
    a = build_animation(crane, slow, fps=30)
    assert len(a.times) == MAX_FRAMES
    assert a.speedup == pytest.approx(40 * 30 / (MAX_FRAMES - 1))


def test_the_hanging_load_follows_the_grapple_angles(entry):
    crane, _, tr = entry
    n = len(tr.t)
    swing = np.column_stack([np.zeros(n), np.full(n, 0.3)])      # 0.3 rad about y
    g = Trajectory(t=tr.t, q=tr.q, qd=tr.qd, qdd=tr.qdd, joint_names=tr.joint_names,
                   meta=dict(grapple=dict(angles=swing, length=1.5)))
    a = build_animation(crane, g, fps=5)
    a.draw(0)
    (tx, lx), (ty, ly) = a.artists["top_load"].get_data()
    assert (lx - tx, ly - ty) == pytest.approx((1.5 * math.sin(0.3), 0.0), abs=1e-9)
    (_, _), (tz, lz) = a.artists["side_load"].get_data()
    assert tz - lz == pytest.approx(1.5 * math.cos(0.3), abs=1e-9)


def test_library_show_animate_gif_and_html(entry, tmp_path, capsys):
    crane, lib, tr = entry
    want = frame_count(float(tr.t[-1] - tr.t[0]), 5)
    want_html = frame_count(float(tr.t[-1] - tr.t[0]), 3)
    assert want == math.ceil(5 * (tr.t[-1] - tr.t[0])) + 1
    gif = tmp_path / "move.gif"
    assert main(["library", "show", f"{lib}#fwd:0", "--animate", str(gif), "--fps", "5",
                 "--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["id"] == "fwd:0" and js["status"] == "ok" and js["samples"] == len(tr.t)
    assert js["animation"]["frames"] == want and js["animation"]["format"] == "gif"
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames == want
        assert im.info.get("duration") == pytest.approx(200, abs=10)   # 5 fps
    html = tmp_path / "move.html"
    assert main(["library", "show", str(lib), "--animate", str(html), "--fps", "3"]) == 0
    out = capsys.readouterr().out
    assert f"{want_html} frames" in out
    text = html.read_text()
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    assert not re.search(r"https?://|src=[\"']//|href=[\"']//", text)  # nothing external
    assert text.count("data:image/png;base64,") == want_html


def test_plan_animate_writes_the_planned_move(tmp_path, capsys):
    gif = tmp_path / "plan.gif"
    assert main(["plan", "s100f", "--start", "6,-1,0", "--goal", "4,1,0.5", "--method",
                 "ruckig", "--animate", str(gif), "--fps", "2", "--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["animation"]["frames"] == frame_count(js["duration_s"], 2)
    with Image.open(gif) as im:
        assert im.n_frames == js["animation"]["frames"]


@pytest.mark.parametrize("args, needle", [
    (["--animate", "{d}/move.avi"], "unknown format '.avi'"),
    (["--animate", "{d}/move"], "unknown format '(no suffix)'"),
    (["--animate", "{d}/move.gif", "--fps", "60"], "--fps 60"),
])
def test_bad_animation_refused_before_any_work(entry, tmp_path, capsys, args, needle):
    _, lib, _ = entry
    args = [a.format(d=tmp_path) for a in args]
    assert main(["library", "show", f"{lib}#fwd:0"] + args) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1
    assert main(["plan", "s100f", "--start", "6,-1,0", "--goal", "4,1,0.5", "--method",
                 "ruckig"] + args) == 2
    assert needle in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_mp4_needs_ffmpeg(entry, tmp_path, capsys):
    from matplotlib import animation
    _, lib, _ = entry
    rc = main(["library", "show", f"{lib}#fwd:0", "--animate", str(tmp_path / "m.mp4"),
               "--fps", "2"])
    if animation.writers.is_available("ffmpeg"):
        assert rc == 0 and (tmp_path / "m.mp4").stat().st_size > 0
    else:
        assert rc == 2 and "needs ffmpeg" in capsys.readouterr().err
        assert list(tmp_path.iterdir()) == []


def test_import_planner_and_animate_leave_matplotlib_alone():
    code = ("import sys, planner, planner.animate, planner.library.rosbag, "
            "planner.simulation.bag; print(sorted(m for m in sys.modules "
            "if m.split('.')[0] in ('matplotlib', 'rosbags')))")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
