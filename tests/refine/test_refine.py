"""Feed-forward computed on the dynamic twin (issue 27): the adjoint gradient, the refinement,
the library's refined commands and their replay.

Oracles: central finite differences of the twin's own cost (the adjoint's gradient), the
twin's landing with the nominal commands (what the refinement must beat, on a move where the
oil's compression leaves the nominal commands visibly off), an uninterrupted refine (what a
resumed one must reproduce exactly), and the arguments' documented ranges.
"""
import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from planner import Crane
from planner.feedforward import commands, stored_commands
from planner.library.refine import refine_library
from planner.library.refined import entry_commands, read_refined
from planner.library.store import LibraryStore
from planner.methods.ruckig import rest_to_rest
from planner.model.twin import Twin
from planner.model.twin.shooting import Shooting
from planner.refine import TIME_ENTRY_WEIGHT, RefineOptions, RefineStatus, refine_commands
from tests.conftest import check_adjoint, step_commands

MACHINE = "umea-lab"   # the lightest twin: the compiled adjoint builds quickest


def _move(crane, a, b, scale=0.8):
    L = crane.limit_arrays()
    q0, q1 = (L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (a, b))
    tr = rest_to_rest(crane, q0, q1, scale=scale).trajectory
    return commands(crane, tr, 50.0).attach(tr, knots=True)


@pytest.fixture(scope="module")
def crane():
    return Crane.from_id(MACHINE)


@pytest.fixture(scope="module")
def twin(crane):
    return Twin(crane)


@pytest.fixture(scope="module")
def move(crane):
    return _move(crane, 0.35, 0.65)


def test_the_adjoint_gradient_matches_central_differences(crane, twin, move):
    """∂J/∂u of a weighted state cost, by the adjoint, against central differences of the
    same forward runs along smooth random directions of the per-step commands."""
    sh = Shooting(twin)
    t_u, u = stored_commands(move)
    R, K, us = step_commands(sh, u, 200)
    x0 = twin.rest_state(move.q[0])
    rng = np.random.default_rng(1)
    W = np.zeros((K + 1, sh.nx))
    W[:, :crane.n] = rng.normal(size=(K + 1, crane.n))
    W[:, 2 * crane.n:3 * crane.n] = 1e-7 * rng.normal(size=(K + 1, crane.n))  # pressures
    check_adjoint(sh, x0, us, W, len(u) * R, rng)


def test_refined_commands_land_the_twin_better_than_the_nominal_ones(crane, twin, move):
    t_u, u = stored_commands(move)
    opts = RefineOptions(iterations=12, settle=1.5)
    r = refine_commands(crane, move, t_u, u, twin=twin, options=opts)
    assert r.status == RefineStatus.IMPROVED, r.reason
    nom, ref = r.predicted["nominal"], r.predicted["refined"]
    # the oil leaves the nominal commands measurably off; the refined ones do much better
    assert nom["rest_offset_m"] > 2e-3
    assert ref["rest_offset_m"] < 0.5 * nom["rest_offset_m"]
    assert ref["track_m"] < nom["track_m"]
    assert np.all(np.abs(r.u) <= 1.0)
    assert r.t_u[0] == pytest.approx(t_u[0]) and np.allclose(np.diff(r.t_u), 0.02)
    assert 0.0 <= r.lengthened_s <= opts.tail + 1e-9
    assert r.model["fingerprint"] == twin.provenance()["fingerprint"]
    # the prediction is the twin's own replay of what is returned
    tu = np.append(r.t_u, r.t_u[-1] + 0.02)
    run = twin.simulate(tu, np.vstack([r.u, np.zeros((1, crane.n))]), move.q[0],
                        t_end=move.t[-1] + opts.tail + opts.settle)
    assert run.ok
    goal = crane.fk(move.q[-1:])[0]
    rest = crane.fk(run.q[run.t >= run.t[-1] - opts.rest_window]).mean(axis=0)
    assert np.linalg.norm(rest - goal) == pytest.approx(ref["rest_offset_m"], abs=5e-4)


@pytest.mark.parametrize("kw, field", [(dict(iterations=0), "iterations"),
                                       (dict(tail=-1.0), "tail"),
                                       (dict(settle=float("nan")), "settle"),
                                       (dict(settle=0.5, rest_window=1.0), "rest_window"),
                                       (dict(coarse_step=-1e-3), "coarse_step"),
                                       (dict(polish=-1), "polish"),
                                       (dict(lead=-0.1), "lead"),
                                       (dict(keep_closed="yes"), "keep_closed"),
                                       (dict(idle=0.5), "idle"),
                                       (dict(restarts=1), "restarts"),
                                       (dict(calm=-0.5), "calm"),
                                       (dict(calm_weight=0.5), "calm_weight"),
                                       (dict(calm_below=-1e-3), "calm_below"),
                                       (dict(tube_weight=-1.0), "tube_weight"),
                                       (dict(energy_entries="cheap"), "energy_entries")])
def test_bad_options_name_the_field(kw, field):
    with pytest.raises(ValueError, match=f"'{field}'"):
        RefineOptions(**kw)


@pytest.fixture(scope="module")
def lib(tmp_path_factory, crane):
    path = tmp_path_factory.mktemp("refine") / "lib.h5"
    with LibraryStore.create(path, crane.spec) as db:
        for k, (a, b) in enumerate([(0.35, 0.6), (0.6, 0.4)]):
            tr = _move(crane, a, b)
            db.add(f"m{k}:time", tr, start=crane.tip(tr.q[0]), goal=crane.tip(tr.q[-1]),
                   objective="time", method="ruckig", status="ok")
    return path


def test_library_refine_resumes_with_identical_results(lib, tmp_path):
    """A refine stopped after the first entry and rerun gives the file an uninterrupted run
    gives; a rerun with the same twin and options skips every entry."""
    import shutil
    # the resume, not the price: time entries refined plain (one refinement each)
    opts = RefineOptions(iterations=2, settle=0.5, rest_window=0.5, time_entries="plain")
    whole, part = tmp_path / "whole.h5", tmp_path / "part.h5"
    shutil.copy(lib, whole)
    shutil.copy(lib, part)
    s = refine_library(whole, options=opts, show_progress=False)
    assert s["refined"] == 2 and s["skipped_existing"] == 0
    s1 = refine_library(part, options=opts, limit=1, show_progress=False)
    s2 = refine_library(part, options=opts, show_progress=False)
    assert (s1["refined"], s2["refined"], s2["skipped_existing"]) == (1, 1, 1)
    assert refine_library(part, options=opts, show_progress=False)["skipped_existing"] == 2
    with LibraryStore.open(whole) as a, LibraryStore.open(part) as b:
        for i in a.ids():
            ra, rb = read_refined(a, i), read_refined(b, i)
            np.testing.assert_array_equal(ra[0], rb[0])
            np.testing.assert_array_equal(ra[1], rb[1])
            assert ra[2]["model"] == rb[2]["model"]
            # which commands a replay takes: refined by default, nominal on request
            tr = a.trajectory(i)
            assert entry_commands(a, i, tr)[2] == "refined"
            t_n, u_n, which, _ = entry_commands(a, i, tr, "nominal")
            assert which == "nominal"
            np.testing.assert_array_equal(u_n, stored_commands(tr)[1])


def test_library_refine_calms_the_load_of_an_entry_planned_with_a_grapple(tmp_path, crane):
    """An entry built with a grapple link (``grapple_m``, as ``library build --grapple``
    stores it) is refined on the twin that carries the load on that link, with the swing in
    the cost: the predicted swing after the plan's end is smaller than the nominal commands';
    a plain entry beside it is refined on the plain twin."""
    path = tmp_path / "g.h5"
    with LibraryStore.create(path, crane.spec) as db:
        for k, (a, b) in enumerate([(0.35, 0.65), (0.6, 0.4)]):
            tr = _move(crane, a, b, scale=1.0)
            db.add(f"m{k}:time", tr, start=crane.tip(tr.q[0]), goal=crane.tip(tr.q[-1]),
                   objective="time", method="ruckig", status="ok",
                   attrs=dict(grapple_m=0.5) if k == 0 else {})
    opts = RefineOptions(calm=0.0, iterations=4, settle=1.0, rest_window=0.5,
                         time_entries="plain")    # the swing, not the price
    s = refine_library(path, options=opts, show_progress=False)
    assert (s["refined"], s["with_swing"]) == (2, 1)
    with LibraryStore.open(path) as db:
        info = read_refined(db, "m0:time")[2]
        plain = read_refined(db, "m1:time")[2]
    assert info["options"]["swing_weight"] == 10.0 and plain["options"]["swing_weight"] == 0.0
    assert info["model"]["grapple"]["length_m"] == 0.5 and "grapple" not in plain["model"]
    nom, ref = info["predicted"]["nominal"], info["predicted"]["refined"]
    assert ref["swing_after_m"] < 0.5 * nom["swing_after_m"], (nom, ref)
    with pytest.raises(ValueError, match="swing_weight"):
        refine_library(path, options=opts, show_progress=False, swing_weight=-1.0)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "planner", *args], capture_output=True,
                          text=True, timeout=600)


def test_simulate_takes_the_refined_commands_and_reports_the_landing(lib, tmp_path, capsys):
    import shutil

    from planner.cli import main
    path = tmp_path / "lib.h5"
    shutil.copy(lib, path)
    ref = f"{path}#m0:time"
    assert main(["simulate", MACHINE, "--trajectory", ref, "--out", str(tmp_path / "a.csv"),
                 "--plant", "twin", "--commands", "refined"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no refined commands" in err[0] and "library refine" in err[0]
    refine_library(path, options=RefineOptions(iterations=8, settle=1.0), limit=1,
                   show_progress=False)
    out = {}
    for which in ("nominal", "auto"):
        assert main(["simulate", MACHINE, "--trajectory", ref, "--out",
                     str(tmp_path / f"{which}.csv"), "--plant", "twin", "--commands", which,
                     "--settle", "1.5", "--json"]) == 0
        out[which] = json.loads(capsys.readouterr().out)
    assert out["nominal"]["commands_used"] == "nominal"
    assert out["auto"]["commands_used"] == "refined"
    for o in out.values():
        assert o["settle_s"] == 1.5 and o["rest_offset_m"] >= 0
        assert np.isfinite(o["residual_oscillation_m"])
    assert out["auto"]["rest_offset_m"] < out["nominal"]["rest_offset_m"]
    assert main(["simulate", MACHINE, "--trajectory", ref, "--out", str(tmp_path / "b.csv"),
                 "--settle", "-1"]) == 2
    assert "--settle" in capsys.readouterr().err


def test_export_carries_the_refined_commands(lib, tmp_path, crane):
    import shutil

    from planner.library.export import export
    from planner.trajectory import Trajectory
    path = tmp_path / "lib.h5"
    shutil.copy(lib, path)
    refine_library(path, options=RefineOptions(iterations=3, settle=1.0), limit=1,
                   show_progress=False)
    with LibraryStore.open(path) as db:
        t_r, u_r, _ = read_refined(db, "m0:time")
        u_nom = stored_commands(db.trajectory("m0:time"))[1]
    got = {}
    for which in ("auto", "nominal"):
        export(path, tmp_path / which, "csv", commands=which)
        got[which] = Trajectory.from_csv(next((tmp_path / which).glob("m0*.csv")),
                                         joint_names=crane.names)
    np.testing.assert_allclose(got["auto"].t, t_r, atol=1e-9)
    np.testing.assert_allclose(got["auto"].u, u_r, atol=1e-9)
    np.testing.assert_allclose(stored_commands(got["nominal"])[1], u_nom, atol=1e-9)
    export(path, tmp_path / "j", "json")
    doc = json.loads((tmp_path / "j" / "library.json").read_text())
    e = {x["id"]: x for x in doc["entries"]}
    np.testing.assert_allclose(e["m0:time"]["u_refined"], u_r, atol=1e-12)
    assert e["m0:time"]["refined"]["model"]["model"] == "twin"
    assert "u_refined" not in e["m1:time"]
    with pytest.raises(ValueError, match="no refined commands"):
        export(path, tmp_path / "r", "csv", commands="refined")


@pytest.mark.slow   # a whole-process plan and a 150-iteration refinement (~20 s quiet)
def test_plan_with_the_twin_feedforward_keeps_both_commands(tmp_path):
    """`plan --feedforward twin`: the JSON says the commands are refined and predicts a better
    landing than the nominal ones; the one-entry database keeps both, and a replay takes the
    refined ones by default."""
    out = tmp_path / "p.h5"
    r = _cli("plan", MACHINE, "--start", "1.2,0.5,0", "--goal", "1.8,0.8,20deg", "--method",
             "ruckig", "--feedforward", "twin", "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    ff = d["feedforward"]
    assert ff["commands"] == "refined" and ff["model"]["model"] == "twin"
    assert ff["predicted"]["refined"]["rest_offset_m"] < ff["predicted"]["nominal"][
        "rest_offset_m"]
    with LibraryStore.open(out) as db:
        assert read_refined(db, "plan:time") is not None
        assert stored_commands(db.trajectory("plan:time")) is not None
    r = _cli("plan", MACHINE, "--start", "1.2,0.5,0", "--goal", "1.8,0.8,20deg", "--method",
             "ruckig", "--feedforward", "twin", "--out-rate", "100", "--out",
             str(tmp_path / "p.csv"))
    assert r.returncode == 2 and "--out-rate 100" in r.stderr
    assert not (tmp_path / "p.csv").exists()


def _boom_moves_jib_still(crane):
    """(move, t_u, u): the boom raised from 35 % to 75 % of its range, every other joint held
    at 35 % — the jib's holding pressure changes, its oil gives (nominal commands 0)."""
    L = crane.limit_arrays()
    q0 = L["q_min"] + 0.35 * (L["q_max"] - L["q_min"])
    q1 = q0.copy()
    q1[1] = L["q_min"][1] + 0.75 * (L["q_max"][1] - L["q_min"][1])
    tr = rest_to_rest(crane, q0, q1, scale=0.8).trajectory
    move = commands(crane, tr, 50.0).attach(tr, knots=True)
    return (move, *stored_commands(move))


def _jib_end(crane, twin, move, opts, tt, uu):
    """|jib at the end of the cost's horizon − its goal| on ``twin`` for commands ``uu``."""
    tt = np.append(tt, tt[-1] + 0.02)
    run = twin.simulate(tt, np.vstack([uu, np.zeros((1, crane.n))]), move.q[0],
                        t_end=move.t[-1] + opts.tail + opts.settle)
    return abs(run.q[-1, 2] - move.q[-1, 2])


def test_an_idle_joint_is_refined_too(crane, twin):
    """The boom moves, the jib stays: its holding pressure changes, its oil gives, it creeps
    off (the nominal commands leave it at 0). The refinement must use the jib's valve too —
    a closed valve is a kink of the flow whose adjoint slope is 0, so commands that start at
    exactly 0 used to stay there (the s100f library's telescope on its stroke end: 5.5 mm)."""
    move, t_u, u = _boom_moves_jib_still(crane)
    assert np.all(u[:, 2] == 0.0)
    opts = RefineOptions(calm=0.0, iterations=12, settle=1.5)
    r = refine_commands(crane, move, t_u, u, twin=twin, options=opts)
    assert r.status == RefineStatus.IMPROVED, r.reason
    assert np.abs(r.u[:, 2]).max() > 1e-4            # the jib's valve is used
    nominal = _jib_end(crane, twin, move, opts, t_u, u)
    assert nominal > 5e-4                             # the oil gives: ~1.6 mrad
    assert _jib_end(crane, twin, move, opts, r.t_u, r.u) < nominal / 3
    # with keep_closed the jib's valve opens only in the tail (and the lead before it): an
    # open valve load-senses the jib's holding pressure
    kc = replace(opts, keep_closed=True)
    r = refine_commands(crane, move, t_u, u, twin=twin, options=kc)
    lead = int(round(kc.lead * kc.rate))
    assert np.all(r.u[:t_u.size - lead, 2] == 0.0)
    assert np.abs(r.u[t_u.size - lead:, 2]).max() > 1e-4
    assert _jib_end(crane, twin, move, kc, r.t_u, r.u) < nominal / 3


def test_an_idle_joint_behind_a_dead_band_is_refined_too(crane):
    """As above on a twin whose valves have a 3 % dead band (a calibrated machine's are
    0.1–0.9 %): in command units a valve inside its dead band is flat to the cost, so the
    jib's valve stayed shut and its creep stayed (a calibrated s100f telescope: 5.9 mm). The
    refinement works in openings past the dead band (past_deadband): the jib's command leaves
    its dead band and its creep is put right."""
    from planner.model.valves import opening, past_deadband, within_deadband
    db = np.full(crane.n, 0.03)
    twin = Twin(crane, deadband=db)
    assert np.allclose(twin.params.per["deadband"], 0.03)
    v = np.linspace(-1.0, 1.0, 41)[:, None] * np.ones(crane.n)
    assert np.allclose(within_deadband(past_deadband(v, db), db), v)

    class Valves:
        deadband = db
    assert np.allclose(opening(Valves, past_deadband(v, db)), v)   # the model's own opening
    move, t_u, u = _boom_moves_jib_still(crane)
    opts = RefineOptions(calm=0.0, iterations=12, settle=1.5)
    r = refine_commands(crane, move, t_u, u, twin=twin, options=opts)
    assert r.status == RefineStatus.IMPROVED, r.reason
    assert np.abs(r.u[:, 2]).max() > 0.03 + 1e-4       # past the jib's dead band
    nominal = _jib_end(crane, twin, move, opts, t_u, u)
    assert nominal > 5e-4
    assert _jib_end(crane, twin, move, opts, r.t_u, r.u) < nominal / 3


def test_closed_valves_are_the_joints_the_plan_holds_until_the_lead_before_the_tail():
    """Hand-made commands at 10 Hz, lead 0.2 s (2 rows), 12 plan rows and a 3-row tail: joint
    0 opens in rows 5-6, joint 1 creeps at 4e-6 (idle), joint 2 never opens."""
    from planner.refine import closed_valves
    u = np.zeros((12, 3))
    u[5:7, 0] = 0.3
    u[:, 1] = 4e-6
    shut = closed_valves(u, 15, RefineOptions(rate=10.0, lead=0.2))
    assert shut.shape == (15, 3)
    assert not shut[:, 0].any()
    for j in (1, 2):
        assert np.flatnonzero(shut[:, j]).tolist() == list(range(10))
    assert closed_valves(u, 15, RefineOptions(rate=10.0, lead=0.0))[:, 1].sum() == 12


def test_the_cost_weighs_each_joint_by_its_lever_along_the_path():
    """The tip's lever of the slew is the reach, the telescope's is 1 (m per m), on every pose
    along a path, not only at the goal: a slew error mid-move, stretched out, costs what its
    tip error costs (s100f: the reach goes 1.9 → 6.7 m between folded and stretched)."""
    from planner.refine import tip_levers
    c = Crane.from_id("s100f")
    L = c.limit_arrays()
    q = np.array([L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (0.2, 0.5, 0.8)])
    tip = c.fk(q)
    lev = tip_levers(c, q)
    assert lev.shape == q.shape
    assert lev[:, 0] == pytest.approx(np.hypot(tip[:, 0], tip[:, 1]), rel=1e-6)
    assert lev[:, 3] == pytest.approx(1.0, rel=1e-6)
    assert np.ptp(lev[:, 0]) > 3.0
    # one pose gives the same row as the batch
    assert tip_levers(c, q[1]) == pytest.approx(lev[1], rel=1e-12)


@pytest.mark.slow   # compiles the twin's step and adjoint at 4 ms (a minute on a fresh clone)
def test_the_coarse_phase_hands_over_to_the_twin_itself(crane, twin, move):
    """Most iterations on the twin at the coarse step, the last on the twin itself: the result
    is judged (and predicted) by the twin at its own step, and beats the nominal commands
    there."""
    t_u, u = stored_commands(move)
    opts = RefineOptions(iterations=14, polish=4, settle=1.5, coarse_step=4e-3)
    r = refine_commands(crane, move, t_u, u, twin=twin, options=opts)
    assert r.status == RefineStatus.IMPROVED, r.reason
    assert r.iterations > 4                      # the coarse iterations are counted
    assert r.model["step_s"] == twin.step        # the provenance is the fine twin's
    nom, ref = r.predicted["nominal"], r.predicted["refined"]
    assert ref["rest_offset_m"] < 0.5 * nom["rest_offset_m"]


def test_a_coarse_step_that_does_not_divide_the_control_period_is_refused(crane, twin, move):
    t_u, u = stored_commands(move)
    with pytest.raises(ValueError, match="coarse_step' = 0.003 s does not divide"):
        refine_commands(crane, move, t_u, u, twin=twin,
                        options=RefineOptions(iterations=3, polish=1, coarse_step=3e-3))


def test_the_pump_power_and_its_gradient(crane, twin, move):
    """The twin's pump power p_s·Σ q_in along a run against the valve module's flows at the
    run's own pressures and spools (the energy judge's way, planner.methods.nlp.twin_judge),
    and its state gradient against central differences."""
    from planner.model.valves import opening, valve_circuit, valve_flows
    t_u, u = stored_commands(move)
    run = twin.simulate(np.append(t_u, t_u[-1] + 0.02), np.vstack([u, np.zeros((1, crane.n))]),
                        move.q[0], t_end=move.t[-1] + 0.5)
    assert run.ok
    vc = valve_circuit(crane)
    q_in = valve_flows(vc, run.p_a, run.p_b, run.p_s, opening(vc, run.spool))["q_in"]
    f = twin.pump_power()
    X = np.column_stack([run.q, run.qd, run.p_a, run.p_b, run.p_s, run.spool])
    w, dw = f(X, np.asarray(twin.P)[None, :])
    ref = run.p_s * q_in.sum(axis=1)
    assert w[:, 0] == pytest.approx(ref, rel=1e-9, abs=1e-9 * np.abs(ref).max())
    assert ref.max() > 0
    k = int(np.argmax(ref))
    scale = np.concatenate([np.full(2 * crane.n, 1e-6), np.full(2 * crane.n + 1, 1.0),
                            np.full(crane.n, 1e-7)])
    for i in range(X.shape[1]):
        d = np.zeros_like(X[k])
        d[i] = scale[i]
        fd = (f(X[k] + d, twin.P[None, :])[0] - f(X[k] - d, twin.P[None, :])[0]) / (2 * scale[i])
        assert dw[k, i] == pytest.approx(float(fd[0, 0]), rel=1e-4, abs=1e-6 * abs(ref[k]))


@pytest.mark.slow   # two refinements (~5 s): make bench
def test_an_energy_weight_lowers_the_pump_work_on_the_twin(crane, twin, move):
    """With a weight on the pump's work the refined commands make the twin's pump work less
    than without it (the tracking alone lets the optimiser open valves that raise the
    load-sensing pressure)."""
    t_u, u = stored_commands(move)
    out = {}
    for w in (0.0, 300.0):
        opts = RefineOptions(iterations=12, settle=1.5, energy_weight=w)
        r = refine_commands(crane, move, t_u, u, twin=twin, options=opts)
        assert r.status == RefineStatus.IMPROVED, r.reason
        f = twin.pump_power()
        run = twin.simulate(np.append(r.t_u, r.t_u[-1] + 0.02),
                            np.vstack([r.u, np.zeros((1, crane.n))]), move.q[0],
                            t_end=move.t[-1] + opts.tail + opts.settle)
        X = np.column_stack([run.q, run.qd, run.p_a, run.p_b, run.p_s, run.spool])
        out[w] = float(np.sum(f(X, twin.P[None, :])[0][:, 0]) * (run.t[1] - run.t[0]))
    assert out[300.0] < out[0.0]


def test_a_cycle_refines_each_move_from_the_state_the_one_before_leaves(crane, twin, move):
    """refine_cycle on a move and its way back: the second move's start is the twin's own
    replay of the first refined move (its commands, then the valves closed until the next
    start), not the rest state; from there its refined commands land the twin better than its
    nominal ones do; and a refinement given the rest state as ``x0`` is the plain one."""
    from planner.refine.cycle import refine_cycle
    back = _move(crane, 0.65, 0.35)
    opts = RefineOptions(calm=0.0, iterations=8, settle=1.5)
    moves = [(m, *stored_commands(m)) for m in (move, back)]
    gap = 0.5
    refs, starts = refine_cycle(crane, moves, twin=twin, options=opts, gap=gap)
    assert starts[0] is None and starts[1] is not None
    r0 = refs[0]
    t_r = r0.t_u - move.t[0]
    span = round((max(move.duration, t_r[-1] + 0.02) + gap) * 50) / 50
    run = twin.simulate(np.append(t_r, t_r[-1] + 0.02), np.vstack([r0.u, np.zeros((1, crane.n))]),
                        move.q[0], t_end=span)
    n = crane.n
    np.testing.assert_allclose(starts[1][:n], run.q[-1], atol=1e-12)
    np.testing.assert_allclose(starts[1][2 * n:3 * n], run.p_a[-1], rtol=1e-12)
    rest = twin.rest_state(starts[1][:n])
    assert np.max(np.abs(starts[1][2 * n:4 * n] - rest[2 * n:4 * n])) > 1e5   # trapped ≠ rest
    r1 = refs[1]
    assert r1.status == RefineStatus.IMPROVED, r1.reason
    assert r1.predicted["refined"]["rest_offset_m"] < r1.predicted["nominal"]["rest_offset_m"]
    # its prediction starts where the first move left the twin: the nominal commands replayed
    # from that state give the same rest offset (from rest they would not)
    t_b, u_b = stored_commands(back)
    tb = np.append(t_b, t_b[-1] + 0.02)
    ub = np.vstack([u_b, np.zeros((1, n))])
    goal = crane.fk(back.q[-1:])[0]
    for x0, same in ((starts[1], True), (None, False)):
        rb = twin.simulate(tb, ub, back.q[0], t_end=back.t[-1] + opts.tail + opts.settle,
                           x0=x0)
        off = np.linalg.norm(crane.fk(rb.q[rb.t >= rb.t[-1] - opts.rest_window]).mean(axis=0)
                             - goal)
        assert (abs(off - r1.predicted["nominal"]["rest_offset_m"]) < 1e-4) == same
    plain = refine_commands(crane, move, *stored_commands(move), twin=twin,
                            options=RefineOptions(iterations=3, settle=1.5))
    given = refine_commands(crane, move, *stored_commands(move), twin=twin,
                            options=RefineOptions(iterations=3, settle=1.5),
                            x0=twin.rest_state(move.q[0]))
    np.testing.assert_array_equal(plain.u, given.u)


def test_library_refine_cycle_resumes_and_refuses_entries_that_do_not_chain(lib, tmp_path):
    """``library refine --cycle``: each entry refined from where the one before left the twin
    (its stored provenance says so); a run that lost its second entry, rerun, keeps the first
    and gives the uninterrupted file; an order that does not chain, or --gap without --cycle,
    is refused in one line naming it (exit 2)."""
    import shutil

    from planner.library.cycle import refine_cycle_library
    from planner.library.refined import GROUP
    opts = RefineOptions(calm=0.0, iterations=2, settle=0.5, rest_window=0.5,
                         time_entries="plain")    # the chaining, not the price
    whole, part = tmp_path / "whole.h5", tmp_path / "part.h5"
    shutil.copy(lib, whole)
    s = refine_cycle_library(whole, ["m0:time", "m1:time"], gap=0.5, options=opts)
    assert (s["refined"], s["kept"]) == (2, 0)
    shutil.copy(whole, part)
    with LibraryStore.open(part, "a") as db:
        del db.group("m1:time")[GROUP]
        db.commit()
    s2 = refine_cycle_library(part, ["m0:time", "m1:time"], gap=0.5, options=opts)
    assert (s2["refined"], s2["kept"]) == (1, 1)
    with LibraryStore.open(whole) as a, LibraryStore.open(part) as b:
        for k, i in enumerate(["m0:time", "m1:time"]):
            ra, rb = read_refined(a, i), read_refined(b, i)
            np.testing.assert_array_equal(ra[1], rb[1])
            assert ra[2]["cycle"] == dict(ids=["m0:time", "m1:time"], position=k, gap_s=0.5,
                                          from_rest=k == 0)
    # the second move's prediction starts from the trapped state, not from rest
    plain = tmp_path / "plain.h5"
    shutil.copy(lib, plain)
    refine_library(plain, options=opts, show_progress=False)
    with LibraryStore.open(whole) as a, LibraryStore.open(plain) as b:
        pa = read_refined(a, "m1:time")[2]["predicted"]["nominal"]["rest_offset_m"]
        pb = read_refined(b, "m1:time")[2]["predicted"]["nominal"]["rest_offset_m"]
        assert abs(pa - pb) > 1e-5
    r = _cli("library", "refine", str(whole), "--cycle", "m1:time,m0:time")
    assert r.returncode == 2
    assert "--cycle: entry 'm0:time' starts" in r.stderr and len(r.stderr.splitlines()) == 1
    r = _cli("library", "refine", str(whole), "--gap", "2")
    assert r.returncode == 2 and "--gap" in r.stderr
    r = _cli("library", "refine", str(whole), "--swing-weight", "-1")
    assert r.returncode == 2 and r.stderr.startswith("crane-planner: error: --swing-weight -1")
    assert len(r.stderr.splitlines()) == 1


def test_library_refine_prices_the_energy_entries_heavier_than_the_time_entries(crane, tmp_path):
    """An entry planned for least energy is refined with its pump work in the cost and its
    joints kept to their directions (planner.refine.for_objective); a time entry with its
    pump work priced lighter, its directions free; ``energy_entries="plain"`` and
    ``time_entries="plain"`` refine both alike. The options each used are stored."""
    path = tmp_path / "lib.h5"
    tr = _move(crane, 0.35, 0.6)
    with LibraryStore.create(path, crane.spec) as db:
        for obj in ("time", "energy"):
            db.add(f"m0:{obj}", tr, start=crane.tip(tr.q[0]), goal=crane.tip(tr.q[-1]),
                   objective=obj, method="ruckig", status="ok")
    opts = RefineOptions(iterations=2, settle=0.5, rest_window=0.5, calm=0.0)
    refine_library(path, options=opts, show_progress=False)
    with LibraryStore.open(path) as db:
        # the library's options (an energy entry refined again by the pair check keeps
        # them under "pair", planner.library.refine_pairs)
        used = {i: (read_refined(db, i)[2].get("pair") or read_refined(db, i)[2])["options"]
                for i in ("m0:time", "m0:energy")}
    assert used["m0:time"]["keep_direction"] is False
    assert used["m0:time"]["energy_weight"] == TIME_ENTRY_WEIGHT
    assert used["m0:energy"]["keep_direction"] is True
    assert used["m0:energy"]["energy_weight"] == 30.0
    # plain: the energy entry refined as the time entry is (a rerun refines it again)
    s = refine_library(path, options=replace(opts, energy_entries="plain", time_entries="plain"),
                       show_progress=False)
    assert s["refined"] == 2
    with LibraryStore.open(path) as db:
        assert read_refined(db, "m0:energy")[2]["options"]["keep_direction"] is False
        np.testing.assert_array_equal(read_refined(db, "m0:energy")[1],
                                      read_refined(db, "m0:time")[1])
