"""Issue 16, items 5–11: bad or unbounded input is refused where it enters (PlanRequest,
Planner.check, the spec reader, the effect parser, the trajectory reader) with one line that
names the field, the value and what is allowed — exit code 2 (3 for an infeasible plan), never
a traceback, never "ok" on a wrong answer, never unbounded time or memory."""
from __future__ import annotations

import copy
import json
import math
import tomllib
import tracemalloc

import numpy as np
import pytest

from planner import Crane
from planner.bounds import lower_bound
from planner.cli import join_negative_values, main
from planner.geometry.paths import Line
from planner.library.query import far_warning, nearest_entry
from planner.methods import (PlanRequest, Planner, PlanResult, UnsupportedRequest, plan,
                             register, unregister)
from planner.methods import dp as dp_module
from planner.methods.dp import dp, grid_bytes
from planner.model.effects import effect_from_dict, parse_effect
from planner.model.spec import SpecError, parse_spec
from planner.problems import crane_path
from planner.trajectory import Trajectory
from planner.units import check_tip, parse_point

A, B = "1.5,1.0,0", "5.5,-3.0,0"          # a cranab850 move


def _cli(capsys, *argv):
    """(rc, stdout, stderr) of the CLI; argparse usage errors count as rc 2."""
    try:
        rc = main(list(argv))
    except SystemExit as e:
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


def _refused(capsys, *argv, words=()):
    rc, out, err = _cli(capsys, *argv)
    assert rc == 2, (rc, out, err)
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert "error" in last
    for w in words:
        assert w in last, last
    return last


# ------------------------------------------------------------------ 5: tip speed, limits
@pytest.mark.parametrize("v", ["nan", "inf", "0", "-1"])
def test_tip_speed_must_be_finite_and_positive(capsys, v):
    _refused(capsys, "plan", "cranab850", "--start", A, "--goal", B, "--method", "law:jla",
             "--tip-speed", v, words=(f"--tip-speed {float(v)!r} m/s", "> 0"))


def test_a_near_zero_tip_speed_is_refused_before_running():
    """1e-9 m/s would take ~5e11 control steps: refused by the law's step bound at check time
    (the bound itself: line length / speed · rate, recomputed here)."""
    req = PlanRequest((1.5, 1.0, 0.0), (5.5, -3.0, 0.0), path="line", tip_speed=1e-9)
    with pytest.raises(UnsupportedRequest, match="control steps") as e:
        plan(Crane.from_id("cranab850"), req, "law:jla")
    steps = math.hypot(4.0, 4.0) / 1e-9 * 100.0
    assert f"{steps:.3g}" in str(e.value)
    # a slow but finite speed inside the bound still plans
    from planner.methods.laws import MAX_STEPS
    ok = PlanRequest((1.5, 1.0, 0.0), (5.5, -3.0, 0.0), path="line",
                     tip_speed=1.01 * math.hypot(4.0, 4.0) * 100.0 / MAX_STEPS)
    from planner.methods import get
    get("law:jla").check(ok)


def test_tip_speed_is_not_silently_replaced_by_the_default():
    """--tip-speed 0 used to become 1 m/s; the default applies only when none is given."""
    crane = Crane.from_id("s100f")
    base = dict(start=(7.0, 0.0, 0.0), goal=(5.0, 0.0, 0.0), path="line")
    none = plan(crane, PlanRequest(**base), "law:max_velocity")
    one = plan(crane, PlanRequest(**base, tip_speed=1.0), "law:max_velocity")
    assert none.ok and none.duration_s == pytest.approx(one.duration_s, rel=1e-12)
    with pytest.raises(UnsupportedRequest, match="`tip_speed` = 0"):
        PlanRequest(**base, tip_speed=0.0)


# ------------------------------------------------------------------ 6: slew range
@pytest.mark.parametrize("text", ["5,1,170", "5,1,-3.2", "5,1,200deg"])
def test_slew_outside_pm_pi_is_refused_with_both_readings(text):
    with pytest.raises(ValueError, match=r"outside \[-pi, pi\]") as e:
        parse_point(text)
    s = float(text.split(",")[2].replace("deg", "")) * (math.pi / 180 if "deg" in text else 1)
    assert f"{math.remainder(s, 2 * math.pi):.6g}" in str(e.value)    # the wrapped value
    with pytest.raises(UnsupportedRequest, match="start: slew"):
        PlanRequest((5, 1, s), (5, 1, 0))


def test_slew_at_the_ends_of_the_range_is_accepted():
    assert parse_point("5,1,180deg")[2] == pytest.approx(math.pi)
    assert parse_point("5,1,-180deg")[2] == pytest.approx(-math.pi)
    assert check_tip((5, 1, math.pi))[2] == math.pi


def test_cli_refuses_slew_170_instead_of_echoing_it(capsys):
    last = _refused(capsys, "plan", "cranab850", "--start", "1.5,1.0,170", "--goal", B,
                    "--method", "dp", "--json", "-", words=("170", "170deg"))
    assert "argument --start" in last


# ------------------------------------------------------------------ 7: DP memory
def test_dp_grid_estimate_covers_the_measured_peak():
    """The estimate the DP checks before allocating is at least the peak numpy memory of a
    real run (tracemalloc, the independent measure), for both objectives."""
    crane = Crane.from_id("cranab850")
    path = Line((1.5, 1.0, 0.0), (5.5, -3.0, 0.0))
    for obj, kw in (("time", {}), ("energy", dict(tip_speed=0.5))):
        dp(crane, path, obj, step=0.2, tele_step=0.2, window=1, **kw)
        tracemalloc.start()
        r = dp(crane, path, obj, step=0.04, tele_step=0.02, window=3, **kw)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        g = r.grid
        assert r.ok
        assert grid_bytes(g["stages"] + 1, g["tele_nodes"], g["window"], crane.n, obj) >= peak


def test_dp_refuses_a_huge_grid_before_allocating(capsys, monkeypatch):
    crane = Crane.from_id("cranab850")
    path = Line((1.5, 1.0, 0.0), (5.5, -3.0, 0.0))
    tracemalloc.start()
    with pytest.raises(UnsupportedRequest, match="GiB; allowed up to 2.0 GiB") as e:
        dp(crane, path, step=1e-4, tele_step=1e-3)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 50 * 2 ** 20                  # nothing grid-sized was allocated
    assert "56569 stages × 1401 telescope nodes × 11 window steps" in str(e.value)
    # the limit is the one named: lowering it refuses a grid that otherwise plans
    small = dict(step=0.05, tele_step=0.05, window=2)
    assert dp(crane, path, **small).ok
    need = grid_bytes(int(np.ceil(path.length / 0.05)) + 1, 29, 2, crane.n)
    monkeypatch.setattr(dp_module, "MAX_BYTES", need * 0.99)
    with pytest.raises(UnsupportedRequest, match="allowed up to"):
        dp(crane, path, **small)
    # through the CLI: one line, exit 2
    monkeypatch.undo()
    _refused(capsys, "plan", "cranab850", "--start", A, "--goal", B, "--method", "dp",
             "--step", "1e-4", "--tele-step", "1e-3", words=("dp grid", "GiB"))


@pytest.mark.parametrize("start", ["1e4,0,0", "1e9,0,0"])
def test_dp_far_unreachable_start_answers_unreachable_quickly(capsys, start):
    rc, out, err = _cli(capsys, "plan", "cranab850", "--start", start, "--goal", "5.5,1,0",
                        "--method", "dp")
    assert rc == 3 and "unreachable" in err and "at the start" in err


# ------------------------------------------------------------------ 8: units sanity
@pytest.fixture(scope="module")
def umea() -> dict:
    return tomllib.loads(crane_path("umea-lab").read_text("utf-8"))


def test_pump_flow_in_litres_per_minute_is_refused(umea):
    d = copy.deepcopy(umea)
    d["pump"]["max_flow"] = 21.0
    with pytest.raises(SpecError, match="looks like L/min") as e:
        parse_spec(d, "x.toml")
    assert e.value.field == "pump.max_flow" and "0.00035 m³/s" in str(e.value)
    d["pump"]["max_flow"] = 0.05                # the largest plausible value still loads
    parse_spec(d, "x.toml")
    d = copy.deepcopy(umea)
    d["joint"][1]["actuator"]["flow_gain"] = 6.0
    with pytest.raises(SpecError, match="looks like L/min") as e:
        parse_spec(d, "x.toml")
    assert e.value.field.endswith("actuator.flow_gain")


@pytest.mark.parametrize("text", ["coulomb_friction:joint=boom", "time_delay",
                                  "pressure_offset:joint=boom"])
def test_effect_without_its_parameter_is_refused(text):
    with pytest.raises(ValueError, match="give") as e:
        parse_effect(text, Crane.from_id("cat215b"))
    name = text.partition(":")[0]
    assert name in str(e.value) and "neutral" in str(e.value)
    d = {"name": name, **({"joint": "boom"} if "joint" in text else {})}
    with pytest.raises(ValueError, match="give"):
        effect_from_dict(d)
    # one value given is enough (pressure_offset: the other offset stays 0)
    e = parse_effect("pressure_offset:joint=boom,offset_a=1e5")
    assert e.values == {"offset_a": 1e5, "offset_b": 0.0}


def test_spec_effect_without_its_parameter_is_refused(umea):
    d = copy.deepcopy(umea)
    d["effects"] = [{"name": "coulomb_friction", "joint": "boom"}]
    with pytest.raises(SpecError, match="force") as e:
        parse_spec(d, "x.toml")
    assert e.value.field == "effects[0]"


def test_trajectory_csv_in_degrees_is_refused_naming_the_column(tmp_path, capsys):
    crane = Crane.from_id("cat215b")
    q0, q1 = crane.ik((7.0, 0.0, 0.3)), crane.ik((6.0, 0.0, 0.8))
    t = np.linspace(0.0, 4.0, 81)
    s = 0.5 - 0.5 * np.cos(np.pi * t / 4.0)
    q = q0 + s[:, None] * (q1 - q0)
    names = tuple(crane.names)
    good = tmp_path / "rad.csv"
    Trajectory(t, q, joint_names=names, interpolation="linear").to_csv(good)
    deg = tmp_path / "deg.csv"
    Trajectory(t, np.degrees(q), joint_names=names, interpolation="linear").to_csv(deg)
    # radians (and a small overshoot of a limit) pass the reader; degrees do not
    lo, hi = crane.spec.joints[1].limits.q
    over = q.copy()
    over[:, 1] = np.clip(over[:, 1], None, hi) + 0.02
    Trajectory(t, over, joint_names=names, interpolation="linear").to_csv(tmp_path / "over.csv")
    from planner.cli.common import read_trajectory
    read_trajectory(crane, str(good))
    read_trajectory(crane, str(tmp_path / "over.csv"))
    last = _refused(capsys, "simulate", "cat215b", "--trajectory", str(deg),
                    "--out", str(tmp_path / "m.csv"), words=("looks like degrees", str(deg)))
    # the first joint whose degree values leave its range by more than the range's width
    first = next(j for j in crane.spec.joints
                 if np.any(np.abs(np.degrees(q[:, crane.names.index(j.name)])
                                  - np.mean(j.limits.q)) > 1.5 * (j.limits.q[1] - j.limits.q[0])
                           + 0.5))
    assert f"column q_{first.name} " in last
    assert not (tmp_path / "m.csv").exists()


# ------------------------------------------------------------------ 9: ignored options
@pytest.mark.parametrize("argv,words", [
    (["--method", "dp", "--duration", "0.5"], ("--duration 0.5", "dp --objective time")),
    (["--method", "dp", "--tip-speed", "0.5"], ("--tip-speed 0.5", "objective energy")),
    (["--method", "law:max_velocity", "--duration", "0.5"], ("--duration", "law:max_velocity")),
    (["--method", "ruckig", "--tip-speed", "1"], ("--tip-speed", "ruckig")),
    (["--method", "dp", "--wall", "3,2,-1"], ("obstacles",)),
])
def test_options_a_method_would_ignore_are_refused(capsys, argv, words):
    _refused(capsys, "plan", "cranab850", "--start", A, "--goal", B, *argv, words=words)


def test_one_place_refuses_for_every_caller():
    """Planner.check reads uses_duration / uses_tip_speed (True or a tuple of objectives):
    a plug-in that declares nothing gets both refused through plan()."""
    class Fixed(Planner):
        name = "test:fixed"
        objectives = ("time", "energy")
        paths = ("line",)
        uses_duration = ("energy",)

        def plan(self, crane, request):
            return PlanResult("infeasible", "never called in this test")
    register(Fixed())
    try:
        crane = Crane.from_id("cranab850")
        a, b = (1.5, 1.0, 0.0), (5.5, -3.0, 0.0)
        with pytest.raises(UnsupportedRequest, match="`duration` 2: test:fixed `objective`"):
            plan(crane, PlanRequest(a, b, path="line", duration=2.0), "test:fixed")
        with pytest.raises(UnsupportedRequest, match="`tip_speed`"):
            plan(crane, PlanRequest(a, b, path="line", tip_speed=2.0), "test:fixed")
        res = plan(crane, PlanRequest(a, b, objective="energy", path="line", duration=2.0),
                   "test:fixed")
        assert res.status == "infeasible"            # reached plan(): the duration is read
    finally:
        unregister("test:fixed")


def test_the_methods_that_read_a_duration_honour_it():
    crane = Crane.from_id("cranab850")
    a, b = (1.5, 1.0, 0.0), (5.5, -3.0, 0.0)
    fast = plan(crane, PlanRequest(a, b, path="line"), "topp")
    slow = plan(crane, PlanRequest(a, b, path="line", duration=1.5 * fast.duration_s), "topp")
    assert slow.ok and slow.trajectory.duration == pytest.approx(1.5 * fast.duration_s,
                                                                  rel=1e-3)


# ------------------------------------------------------------------ 10: no tracebacks
@pytest.mark.parametrize("argv,words", [
    (["--method", "dp", "--objective", "energy", "--duration", "0"], ("--duration 0.0 s",)),
    (["--method", "law:max_velocity", "--rate", "0"], ("--rate 0.0 (control rate",)),
    (["--method", "nlp", "--intervals", "-5"], ("--intervals -5", "integer")),
    (["--method", "nlp", "--wall", "2.2,inf,-0.5"], ("--wall", "finite", "2.2,inf,-0.5")),
    (["--method", "dp", "--objective", "energy"], ("exactly one of",)),
    (["--method", "dp", "--window", "0"], ("--window 0",)),
])
def test_bad_values_are_one_line_errors(capsys, argv, words):
    _refused(capsys, "plan", "cranab850", "--start", A, "--goal", B, *argv, words=words)


# ------------------------------------------------------------------ 11: confusing answers
def test_negative_values_need_no_equals_sign(capsys):
    assert join_negative_values(["plan", "x", "--goal", "-5,1,0", "--start", "1,-2,0",
                                 "--json", "-", "--", "--tele0", "-1"]) == \
        ["plan", "x", "--goal=-5,1,0", "--start", "1,-2,0", "--json", "-", "--",
         "--tele0", "-1"]
    assert join_negative_values(["--tele0", "-.5", "--rate", "-inf", "--json", "-"]) == \
        ["--tele0=-.5", "--rate=-inf", "--json", "-"]
    # the same request written both ways gives the same answer
    outs = []
    for goal in (["--goal", "-5.5,1.0,0"], ["--goal=-5.5,1.0,0"]):
        rc, out, err = _cli(capsys, "plan", "cranab850", "--start", "1.5,1.0,0", *goal,
                            "--method", "dp", "--json", "-")
        assert rc == 3 and "expected one argument" not in err
        outs.append(json.loads(out))
    assert outs[0]["goal"] == outs[1]["goal"] == [-5.5, 1.0, 0.0]
    assert outs[0]["reason"] == outs[1]["reason"]


def test_energy_dp_too_short_names_the_shortest_duration():
    """The "too fast" reason names the shortest duration on the grid; bracketing it (1 %
    above plans, 1 % below is infeasible) checks the number against the DP itself."""
    crane = Crane.from_id("cranab850")
    path = Line((1.5, 1.0, 0.0), (5.5, -3.0, 0.0))
    kw = dict(step=0.05, tele_step=0.05, window=2)
    r = dp(crane, path, "energy", duration=0.5, **kw)
    assert r.status == "infeasible" and "too fast" in r.reason
    t_min = float(r.reason.split("`duration` >= ")[1].split(" s")[0])
    assert dp(crane, path, "energy", duration=1.01 * t_min, **kw).ok
    assert dp(crane, path, "energy", duration=0.99 * t_min, **kw).status == "infeasible"


def test_topp_is_never_below_the_bound_it_prints(capsys):
    """cat215b: TOPP-RA does not plan with jerk limits, so its bound is the jerk-free one
    (the jerk-limited bound was above TOPP's duration: 7.233 vs 7.198 s on this move)."""
    crane = Crane.from_id("cat215b")
    s, g = (7.0, 0.0, 0.0), (7.0, 0.0, 1.0)
    jerk, free = lower_bound(crane, s, g), lower_bound(crane, s, g, jerk=False)
    assert free.combined_s < jerk.combined_s
    assert free.velocity_s == jerk.velocity_s and free.pump_s == jerk.pump_s
    rc, out, err = _cli(capsys, "plan", "cat215b", "--start", "7,0,0", "--goal", "7,0,1.0",
                        "--method", "topp", "--json", "-")
    d = json.loads(out)
    assert rc == 0 and "jerk" not in d["checked_limits"]
    # TOPP plans with acceleration and pump limits: its bound is the jerk-free ramp bound
    ramps = lower_bound(crane, s, g, jerk=False, ramps=True)
    assert d["lower_bound_s"] == pytest.approx(ramps.ramps_s, rel=1e-12)
    assert d["lower_bounds"]["ramps_s"] == d["lower_bound_s"] >= free.combined_s * (1 - 1e-3)
    assert d["duration_s"] >= d["lower_bound_s"]
    assert d["optimality_gap"] == pytest.approx(d["duration_s"] / d["lower_bound_s"] - 1)
    assert jerk.combined_s > d["duration_s"]        # the old comparison was the wrong one


def test_max_limit_violation_says_which_kinds_it_covers(capsys):
    rc, out, err = _cli(capsys, "plan", "cat215b", "--start", "7,0,0", "--goal", "7,0,1.0",
                        "--method", "dp", "--json", "-")
    d = json.loads(out)
    covered = [d["violations"][k] for k in d["checked_limits"]]
    assert d["max_limit_violation"] == pytest.approx(max(covered), abs=1e-15)
    assert d["max_violation_all_kinds"] == max(d["violations"].values())
    assert d["max_violation_all_kinds"] > 0.01 > d["max_limit_violation"]   # pressure
    rc, out, err = _cli(capsys, "plan", "cat215b", "--start", "7,0,0", "--goal", "7,0,1.0",
                        "--method", "dp")
    assert "of the limits it plans with (position, pump_flow, velocity)" in out
    assert "pressure: dp plans without a pressure limit" in out


def test_library_query_far_from_every_entry_warns():
    index = dict(id=np.array(["a", "b"]), status=np.array(["ok", "ok"]),
                 objective=np.array(["time", "time"]),
                 start=np.array([[5.0, 0.0, 0.0], [5.0, 0.0, 1.0]]),
                 goal=np.array([[3.0, 1.0, 0.5], [3.0, 1.0, 1.5]]))
    near = ((5.05, 0.0, 0.0), (3.0, 1.0, 0.5))
    eid, d = nearest_entry(index, *near)
    assert eid == "a" and far_warning(d, *near) is None
    far = ((195.0, 0.0, 0.0), (3.0, 1.0, 0.5))
    eid, d = nearest_entry(index, *far)
    assert d == pytest.approx(190.0, abs=1e-9)
    w = far_warning(d, *far)
    assert w and "190 m" in w and "does not cover" in w


def test_nlp_time_refuses_a_duration_it_would_ignore(capsys):
    rc, out, err = _cli(capsys, "plan", "s100f", "--start", "6,-1,0", "--goal", "3,2.5,1.5",
                        "--method", "nlp", "--duration", "0.5")
    assert rc == 2 and "duration" in err and "Traceback" not in err


def test_library_build_refuses_a_negative_limit_before_writing(capsys, tmp_path):
    lib = tmp_path / "lib.h5"
    rc, out, err = _cli(capsys, "library", "build", "s100f", "--tasks", "forwarder-cycle",
                        "--limit", "-2", "--out", str(lib))
    assert rc == 2 and "limit" in err and "-2" in err
    assert not lib.exists()


def test_ctrl_c_in_any_command_is_one_line_and_exit_130(capsys, monkeypatch):
    import planner.cli.problems as problems_cli

    def interrupted(args):
        raise KeyboardInterrupt
    monkeypatch.setattr(problems_cli, "cmd_bound", interrupted)
    rc, out, err = _cli(capsys, "bound", "cranab850", "--start", "1.5,1,0", "--goal", "5.5,1,0")
    assert rc == 130 and err.count("\n") == 1 and "interrupted" in err and "Traceback" not in err


def test_plan_output_paths_are_checked_before_planning(capsys, tmp_path):
    (tmp_path / "file").write_text("")
    rc, out, err = _cli(capsys, "plan", "s100f", "--start", "6,-1,0", "--goal", "3,2.5,1.5",
                        "--method", "ruckig", "--out", str(tmp_path / "file" / "x.csv"))
    assert rc == 2 and "--out" in err and "Traceback" not in err
