"""The library database (planner.library.store, export, query): round trip, refusals, crash
recovery, query, export."""
import csv
import json
import math

import h5py
import numpy as np
import pytest
from scipy.io import loadmat

from planner import Crane
from planner.methods.ruckig import rest_to_rest
from planner.library.export import export
from planner.library.store import LibraryStore, StoreError
from planner.trajectory import evaluate


def _config(crane, frac):
    L = crane.limit_arrays()
    return L["q_min"] + np.asarray(frac) * (L["q_max"] - L["q_min"])


@pytest.fixture(scope="module")
def moves(s100f):
    """Three (id, traj, evaluation, start tip, goal tip) rest-to-rest moves."""
    out = []
    for k, (a, b) in enumerate([(0.2, 0.5), (0.4, 0.8), (0.6, 0.3)]):
        q0 = _config(s100f, [a, a, 0.5, 0.3])
        q1 = _config(s100f, [b, 0.6, 0.4, 0.5])
        res = rest_to_rest(s100f, q0, q1)
        assert res.ok, res.reason
        tr = res.trajectory
        tr.u = np.clip(tr.qd / np.abs(tr.qd).max(axis=0, initial=1e-9), -1, 1)  # some commands
        ev = evaluate(s100f, tr)
        out.append((f"move{k}-time", tr, ev, s100f.tip(q0), s100f.tip(q1)))
    return out


def _fill(path, crane, moves):
    with LibraryStore.create(path, crane.spec) as db:
        for eid, tr, ev, s, g in moves:
            db.add(eid, tr, start=s, goal=g, objective="time", method="ruckig", status="ok",
                   evaluation=ev, robustness=0.5, attrs=dict(task="t1", weights=[1, 2]))
        db.add("move3-energy", None, start=moves[0][3], goal=moves[0][4], objective="energy",
               method="nlp", status="infeasible", reason="IPOPT: infeasible problem")


def test_round_trip(tmp_path, s100f, moves):
    path = tmp_path / "lib.h5"
    _fill(path, s100f, moves)
    with LibraryStore.open(path, "r", spec=s100f.spec) as db:
        assert db.cleaned == 0
        assert db.ids() == ["move0-time", "move1-time", "move2-time", "move3-energy"]
        assert db.has("move1-time") and not db.has("nope")
        assert "s100f" in db.spec_toml and db.spec_toml == s100f.spec.text
        for eid, tr, ev, s, g in moves:
            back = db.trajectory(eid)
            for name in ("t", "q", "qd", "qdd", "u"):
                np.testing.assert_array_equal(getattr(back, name), getattr(tr, name))
            assert back.joint_names == tuple(s100f.names)
            assert (back.method, back.objective) == ("ruckig", "time")
            assert back.limits == tr.limits and back.interpolation == tr.interpolation
            assert back.meta == json.loads(json.dumps(tr.meta))
            e = db.entry(eid)
            N, n = tr.q.shape
            for name in ("x", "xd", "p_a", "p_b"):
                assert e[name].shape == (N, n)
            assert e["q_pump"].shape == e["power"].shape == (N,)
            # derived channels are evaluate()'s values at the trajectory's own sample times
            k = np.searchsorted(ev.t, tr.t)
            np.testing.assert_array_equal(e["p_a"], ev.hyd["p_a"][k])
            np.testing.assert_array_equal(e["power"], ev.hyd["power"][k])
            a = e["attrs"]
            assert a["status"] == "ok" and a["provenance"]["crane_id"] == "s100f"
            assert a["task"] == "t1" and json.loads(a["weights"]) == [1, 2]
            assert a["evaluation"]["energy_J"] == pytest.approx(ev.energy_J)
        rows = {r["id"]: r for r in db.index_rows()}
        r = rows["move1-time"]
        assert r["status"] == "ok" and r["method"] == "ruckig" and r["objective"] == "time"
        np.testing.assert_allclose(r["start"], moves[1][3])
        np.testing.assert_allclose(r["goal"], moves[1][4])
        assert r["duration_s"] == pytest.approx(moves[1][1].duration)
        assert r["energy_J"] == pytest.approx(moves[1][2].energy_J)
        assert r["robustness"] == 0.5
        f = rows["move3-energy"]
        assert f["status"] == "infeasible" and math.isnan(f["duration_s"])
        assert math.isnan(f["energy_J"])
        assert db.entry_attrs("move3-energy")["reason"] == "IPOPT: infeasible problem"
        with pytest.raises(StoreError, match="no trajectory"):
            db.trajectory("move3-energy")
        with pytest.raises(KeyError, match="nope"):
            db.trajectory("nope")
        info = db.info()
        assert info["entries"] == 4 and info["ok"] == 3
        assert info["failures"] == {"infeasible": 1}
        assert info["by_objective"] == {"time": 3, "energy": 1}
        durs = [m[1].duration for m in moves]
        assert info["duration_s"]["max"] == pytest.approx(max(durs))
        assert info["energy_J"]["total"] == pytest.approx(sum(m[2].energy_J for m in moves))
        with pytest.raises(StoreError, match="read-only"):
            db.add("x", None, start=(1, 0, 0), goal=(1, 0, 0), objective="time",
                   method="m", status="failed")


def test_duplicate_and_bad_calls_refused(tmp_path, s100f, moves):
    path = tmp_path / "lib.h5"
    eid, tr, ev, s, g = moves[0]
    with LibraryStore.create(path, s100f.spec) as db:
        db.add(eid, tr, start=s, goal=g, objective="time", method="ruckig", status="ok")
        with pytest.raises(StoreError, match="exists already"):
            db.add(eid, tr, start=s, goal=g, objective="time", method="ruckig", status="ok")
        with pytest.raises(StoreError, match="needs a trajectory"):
            db.add("b", None, start=s, goal=g, objective="time", method="m", status="ok")
        with pytest.raises(StoreError, match="entry id"):
            db.add("a/b", tr, start=s, goal=g, objective="time", method="m", status="ok")
        with pytest.raises(StoreError, match="start"):
            db.add("c", tr, start=(1, 2), goal=g, objective="time", method="m", status="ok")
        with pytest.raises(StoreError, match="evaluation"):  # move0's evaluation, move1's traj
            db.add("d", moves[1][1], start=s, goal=g, objective="time", method="m",
                   status="ok", evaluation=ev)
        assert db.ids() == [eid]
    with LibraryStore.open(path, "a") as db:
        assert db.ids() == [eid] and db.cleaned == 0  # the refused 'd' left nothing behind
        with pytest.raises(StoreError, match="exists already"):
            db.add(eid, tr, start=s, goal=g, objective="time", method="ruckig", status="ok")
    with h5py.File(path, "r") as f:
        assert f["index"].shape == (1,) and list(f["entries"]) == [eid]
    with pytest.raises(FileExistsError):
        LibraryStore.create(path, s100f.spec)


def test_foreign_files_refused(tmp_path, s100f):
    txt = tmp_path / "notes.h5"
    txt.write_text("hello, not hdf5\n")
    with pytest.raises(StoreError, match=r"notes\.h5.*not an HDF5 file"):
        LibraryStore.open(txt)
    foreign = tmp_path / "other.h5"
    with h5py.File(foreign, "w") as f:
        f.attrs["creator"] = "someone else"
        f["data"] = np.arange(3)
    with pytest.raises(StoreError, match=r"other\.h5.*without the root attribute format"):
        LibraryStore.open(foreign, "a")
    wrong = tmp_path / "wrong.h5"
    with h5py.File(wrong, "w") as f:
        f.attrs["format"] = "something-else"
    with pytest.raises(StoreError, match=r"wrong\.h5.*'something-else'"):
        LibraryStore.open(wrong)
    newer = tmp_path / "newer.h5"
    LibraryStore.create(newer, s100f.spec).close()
    with h5py.File(newer, "a") as f:
        f.attrs["format_version"] = 99
    with pytest.raises(StoreError, match=r"newer\.h5.*format_version 99 is newer"):
        LibraryStore.open(newer)
    other = tmp_path / "ok.h5"
    LibraryStore.create(other, s100f.spec).close()
    with pytest.raises(StoreError, match=r"ok\.h5.*crane 's100f', not 'umea-lab'"):
        LibraryStore.open(other, "a", spec=Crane.from_id("umea-lab").spec)
    with pytest.raises(FileNotFoundError, match="missing"):
        LibraryStore.open(tmp_path / "missing.h5")


def test_crash_leftover_cleaned_and_resumable(tmp_path, s100f, moves):
    path = tmp_path / "lib.h5"
    (e0, t0, v0, s0, g0), (e1, t1, v1, s1, g1) = moves[:2]
    with LibraryStore.create(path, s100f.spec) as db:
        db.add(e0, t0, start=s0, goal=g0, objective="time", method="ruckig", status="ok")
        # a build killed between the group and its index row:
        db._write_group(e1, t1, objective="time", method="ruckig", status="ok", reason="",
                        evaluation=v1, attrs=None)
        db._f.flush()
    with h5py.File(path, "a") as f:  # and one written by hand, half-way
        f["entries"].create_group("half")["t"] = np.arange(3.0)
    with LibraryStore.open(path, "r") as db:  # a reader neither lists nor deletes leftovers
        assert db.ids() == [e0] and not db.has(e1)
    with LibraryStore.open(path, "a", spec=s100f.spec) as db:
        assert db.cleaned == 2 and db.info()["cleaned"] == 2
        assert db.ids() == [e0] and not db.has(e1)
        db.add(e1, t1, start=s1, goal=g1, objective="time", method="ruckig", status="ok",
               evaluation=v1)
    with LibraryStore.open(path, "a") as db:
        assert db.cleaned == 0 and db.ids() == [e0, e1]
        np.testing.assert_array_equal(db.trajectory(e1).q, t1.q)
    with h5py.File(path, "r") as f:
        assert sorted(f["entries"]) == sorted([e0, e1])


def test_compressed_round_trip(tmp_path, s100f, moves):
    path = tmp_path / "lib.h5"
    eid, tr, ev, s, g = moves[0]
    with LibraryStore.create(path, s100f.spec, compress=True) as db:
        db.add(eid, tr, start=s, goal=g, objective="time", method="ruckig", status="ok",
               evaluation=ev)
    with h5py.File(path, "r") as f:
        assert f["entries"][eid]["q"].compression == "gzip"
    with LibraryStore.open(path) as db:
        np.testing.assert_array_equal(db.trajectory(eid).qdd, tr.qdd)
        k = np.searchsorted(ev.t, tr.t)
        np.testing.assert_array_equal(db.entry(eid)["p_b"], ev.hyd["p_b"][k])


def test_nearest(tmp_path, s100f, moves):
    path = tmp_path / "lib.h5"
    _fill(path, s100f, moves)
    with LibraryStore.open(path) as db:
        for eid, tr, ev, s, g in moves:
            got, d = db.nearest(s, g)
            assert got == eid and d == pytest.approx(0.0, abs=1e-9)
        # shift start by 0.3 m in z and goal by 0.4 m radially: distance 0.7 m
        eid, tr, ev, s, g = moves[2]
        got, d = db.nearest(s + [0, 0.3, 0], g + [0.4, 0, 0])
        assert got == eid and d == pytest.approx(0.7)
        # slew difference counts as arc chord in Cartesian space, not as radians
        got, d = db.nearest(s, g + [0, 0, 0.1])
        assert got == eid and d == pytest.approx(2 * g[0] * math.sin(0.05))
        # the failed entry (same tips as move0, objective energy) is never returned
        with pytest.raises(LookupError, match="no 'ok' entries with objective 'energy'"):
            db.nearest(s, g, objective="energy")
        assert db.nearest(moves[0][3], moves[0][4], objective="time")[0] == moves[0][0]


def test_export(tmp_path, s100f, moves):
    path = tmp_path / "lib.h5"
    _fill(path, s100f, moves)
    names = s100f.names
    # csv
    files = export(path, tmp_path / "csv", "csv")
    assert {p.name for p in files} == {"move0-time.csv", "move1-time.csv", "move2-time.csv",
                                       "index.csv"}
    with open(tmp_path / "csv" / "move1-time.csv") as fh:
        header = fh.readline().strip().split(",")
    assert header[:1 + 4 * len(names)] == ["t"] + [f"{p}_{j}" for p in ("q", "qd", "qdd", "u")
                                                   for j in names]
    # then the hydraulic channels the HDF5 file stores (issue 16, item 16)
    assert header[1 + 4 * len(names):] == (
        [f"{c}_{j}" for c in ("x", "xd") for j in names]
        + [f"p_{j}_{s}" for s in ("a", "b") for j in names] + ["q_pump", "power"])
    data = np.loadtxt(tmp_path / "csv" / "move1-time.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 0], moves[1][1].t, rtol=1e-9)
    with open(tmp_path / "csv" / "index.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["id"] for r in rows] == ["move0-time", "move1-time", "move2-time", "move3-energy"]
    assert rows[3]["status"] == "infeasible" and rows[3]["file"] == ""
    assert rows[3]["reason"] == "IPOPT: infeasible problem" and rows[3]["duration_s"] == ""
    assert float(rows[0]["start_r"]) == pytest.approx(moves[0][3][0])
    # mat
    (p,) = export(path, tmp_path / "mat", "mat")
    m = loadmat(p, simplify_cells=True)
    assert m["crane_id"] == "s100f"
    assert set(m["entries"]) == {"move0_time", "move1_time", "move2_time", "move3_energy"}
    e = m["entries"]["move1_time"]
    np.testing.assert_array_equal(e["q"], moves[1][1].q)
    assert e["id"] == "move1-time" and list(e["joint_names"]) == names
    assert list(m["index"]["field"]) == ["move0_time", "move1_time", "move2_time",
                                         "move3_energy"]
    assert m["index"]["start"].shape == (4, 3)
    # json
    (p,) = export(path, tmp_path / "json", "json")
    doc = json.loads(p.read_text())
    assert [r["id"] for r in doc["index"]] == ["move0-time", "move1-time", "move2-time",
                                               "move3-energy"]
    assert doc["index"][3]["duration_s"] is None
    e = {x["id"]: x for x in doc["entries"]}
    np.testing.assert_allclose(e["move2-time"]["q"], moves[2][1].q)
    assert "t" not in e["move3-energy"] and e["move3-energy"]["status"] == "infeasible"
    with pytest.raises(StoreError, match="format"):
        export(path, tmp_path / "x", "xlsx")


def test_matlab_names_and_file_stems():
    from planner.library.export import file_stem, matlab_name
    used = set()
    got = [matlab_name(x, used) for x in ("1abc", "a-b", "a_b", "x" * 80, "é")]
    assert got[0] == "e_1abc" and got[1] == "a_b" and got[2] == "a_b_2"
    assert len(got[3]) == 63 and got[4] == "e__"
    import re
    assert all(re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,62}", g) for g in got)
    used = set()
    assert [file_stem(x, used) for x in ("A", "a", "../x", "index")] == \
        ["A", "a_2", "_x", "entry_index"]


def test_nearest_agrees_with_a_brute_force_search(tmp_path, s100f, moves):
    """db.nearest (vectorised, planner.library.query) against a plain loop over index_rows
    with the Cartesian distance written out with math.cos / math.sin."""
    path = tmp_path / "lib.h5"
    _fill(path, s100f, moves)

    def xyz(p):
        return (p[0] * math.cos(p[2]), p[0] * math.sin(p[2]), p[1])

    rng = np.random.default_rng(7)
    with LibraryStore.open(path) as db:
        rows = [r for r in db.index_rows() if r["status"] == "ok"]
        for _ in range(20):
            s = rng.uniform([1, -2, -1], [7, 3, 1])
            g = rng.uniform([1, -2, -1], [7, 3, 1])
            want = min((math.dist(xyz(s), xyz(r["start"])) + math.dist(xyz(g), xyz(r["goal"])),
                        r["id"]) for r in rows)
            got, d = db.nearest(s, g)
            assert got == want[1] and d == pytest.approx(want[0], rel=1e-12)
    empty = tmp_path / "empty.h5"
    LibraryStore.create(empty, s100f.spec).close()
    with LibraryStore.open(empty) as db, pytest.raises(LookupError, match="no entries"):
        db.nearest((5, 0, 0), (3, 1, 0))


def test_join_from_a_joint_state(s100f, moves):
    """The joined move (planner.library.query.join_from) is the Ruckig join followed by the
    entry: checked against sampling the two parts on their own."""
    from planner.library.query import join_from
    entry = moves[1][1]
    q0 = _config(s100f, [0.3, 0.3, 0.3, 0.3])
    joined, join_s = join_from(s100f, q0, entry)
    ref = rest_to_rest(s100f, q0, entry.q[0]).trajectory
    assert join_s == pytest.approx(ref.duration, rel=1e-12)
    assert joined.t[-1] >= join_s + entry.duration - 1e-9
    assert joined.method == "ruckig+" + entry.method and joined.u.shape == joined.q.shape
    assert np.all(np.abs(joined.u) <= 1.0)
    np.testing.assert_allclose(joined.q[0], q0, atol=1e-12)
    np.testing.assert_allclose(joined.qd[0], 0.0, atol=1e-12)
    before = joined.t <= join_s
    np.testing.assert_allclose(joined.q[before], ref.sample(joined.t[before])[0], atol=1e-9)
    after = joined.t >= join_s
    np.testing.assert_allclose(joined.q[after], entry.sample(joined.t[after] - join_s)[0],
                               atol=1e-6)
    with pytest.raises(ValueError, match="needs 4 joint values"):
        join_from(s100f, q0[:3], entry)
