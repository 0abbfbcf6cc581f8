"""ROS 2 bags: ``library export --format rosbag2`` read back by an independent reader (the
``mcap`` package and a CDR decoder written here from the ROS 2 message definitions), a round
trip entry -> bag -> ``--map`` -> measured Recording equal to entry -> CSV -> Recording, the
map's units, and the one-line refusals (no --map, no rosbags)."""
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.feedforward import commands
from planner.library.store import LibraryStore
from planner.methods.ruckig import rest_to_rest
from planner.simulation.recording import Recording
from planner.trajectory import evaluate

pytest.importorskip("rosbags", reason="the ros extra (pip install 'crane-planner[ros]')")
mcap_reader = pytest.importorskip("mcap.reader")

ROOT = Path(__file__).resolve().parents[2]
MAP = ROOT / "docs" / "examples" / "joints.toml"


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    """Two entries stored with valve commands at 50 Hz (as plan --out FILE.h5 stores them)
    and their hydraulic channels, and a failed one."""
    crane = Crane.from_id("umea-lab")
    path = tmp_path_factory.mktemp("lib") / "lib.h5"
    moves = [((3.0, 1.8, 0.0), (2.5, 3.0, -0.5)), ((2.6, 2.2, 0.2), (3.4, 2.6, -0.3))]
    with LibraryStore.create(path, crane.spec) as db:
        for i, (a, b) in enumerate(moves):
            tr = rest_to_rest(crane, crane.ik(a, 0.5), crane.ik(b, 0.5)).trajectory
            stored = commands(crane, tr, 50.0).attach(tr)
            db.add(f"move {i}", stored, start=a, goal=b, objective="time", method="ruckig",
                   status="ok", evaluation=evaluate(crane, stored))
        db.add("failed", None, start=moves[0][0], goal=moves[0][1], objective="energy",
               method="nlp", status="infeasible", reason="no")
    return crane, path


@pytest.fixture(scope="module")
def bags(lib, tmp_path_factory):
    crane, path = lib
    out = tmp_path_factory.mktemp("bags")
    assert main(["library", "export", str(path), "--format", "rosbag2", "--out", str(out)]) == 0
    return out


# ----------------------------------------------------------------------------- CDR by hand
class Cdr:
    """A little-endian CDR reader (XCDR1, as rosbag2 stores ROS 2 messages): alignment is
    counted from the end of the 4-byte encapsulation header."""

    def __init__(self, data: bytes):
        assert data[:2] == b"\x00\x01", "CDR little endian"
        self.b, self.o = data[4:], 0

    def _align(self, n):
        self.o += -self.o % n

    def _num(self, fmt, size):
        self._align(size)
        (v,) = struct.unpack_from("<" + fmt, self.b, self.o)
        self.o += size
        return v

    def u32(self):
        return self._num("I", 4)

    def i32(self):
        return self._num("i", 4)

    def string(self):
        n = self.u32()
        s = self.b[self.o:self.o + n - 1].decode()
        self.o += n
        return s

    def strings(self):
        return [self.string() for _ in range(self.u32())]

    def doubles(self):
        n = self.u32()
        if n:
            self._align(8)
        v = np.frombuffer(self.b, "<f8", n, self.o)
        self.o += 8 * n
        return v

    def header(self):
        sec, nsec = self.i32(), self.u32()
        return sec * 1_000_000_000 + nsec, self.string()

    def joint_state(self):
        stamp, frame = self.header()
        return dict(stamp=stamp, frame=frame, name=self.strings(), position=self.doubles(),
                    velocity=self.doubles(), effort=self.doubles())

    def joint_trajectory(self):
        stamp, frame = self.header()
        names = self.strings()
        points = []
        for _ in range(self.u32()):
            p = dict(positions=self.doubles(), velocities=self.doubles(),
                     accelerations=self.doubles(), effort=self.doubles())
            p["time_from_start"] = self.i32() * 1_000_000_000 + self.u32()
            points.append(p)
        return dict(stamp=stamp, joint_names=names, points=points)


def _read_mcap(path):
    """topic -> (schema name, [(log time ns, raw CDR bytes)])."""
    out = {}
    with open(path, "rb") as fh:
        for schema, channel, msg in mcap_reader.make_reader(fh).iter_messages():
            assert channel.message_encoding == "cdr"
            out.setdefault(channel.topic, (schema.name, []))[1].append((msg.log_time, msg.data))
    return out


def test_bag_read_back_by_mcap_equals_the_hdf5_entry(lib, bags):
    crane, path = lib
    index = (bags / "index.csv").read_text().splitlines()
    assert index[0].startswith("id,file,") and len(index) == 4
    assert "failed,," in index[3]                      # no trajectory: no bag
    with LibraryStore.open(path, "r") as db:
        for eid, folder in (("move 0", "move_0"), ("move 1", "move_1")):
            e = db.entry(eid)
            names = list(e["attrs"]["joint_names"])
            assert names == list(crane.names)
            files = sorted((bags / folder).glob("*.mcap"))
            assert len(files) == 1 and (bags / folder / "metadata.yaml").exists()
            topics = _read_mcap(files[0])
            assert {k: v[0] for k, v in topics.items()} == {
                "/joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
                "/joint_states": "sensor_msgs/msg/JointState",
                "/valve_commands": "sensor_msgs/msg/JointState",
                "/pressure_a": "sensor_msgs/msg/JointState",
                "/pressure_b": "sensor_msgs/msg/JointState"}
            t_ns = np.round(e["t"] * 1e9).astype(np.int64)
            # the whole move as one JointTrajectory
            (log, raw), = topics["/joint_trajectory"][1]
            jt = Cdr(raw).joint_trajectory()
            assert jt["joint_names"] == names and len(jt["points"]) == len(e["t"])
            for k, p in enumerate(jt["points"]):
                assert p["time_from_start"] == t_ns[k] - t_ns[0]
                np.testing.assert_array_equal(p["positions"], e["q"][k])
                np.testing.assert_array_equal(p["velocities"], e["qd"][k])
                np.testing.assert_array_equal(p["accelerations"], e["qdd"][k])
            # one JointState per sample, stamped (header and log time) at the sample's time
            for topic, field, want in (("/joint_states", "position", e["q"]),
                                       ("/joint_states", "velocity", e["qd"]),
                                       ("/valve_commands", "effort", e["u"]),
                                       ("/pressure_a", "effort", e["p_a"]),
                                       ("/pressure_b", "effort", e["p_b"])):
                msgs = topics[topic][1]
                states = [Cdr(raw).joint_state() for _, raw in msgs]
                assert [lt for lt, _ in msgs] == [s["stamp"] for s in states] == list(t_ns)
                assert all(s["name"] == names for s in states)
                np.testing.assert_array_equal(np.array([s[field] for s in states]), want)
            assert np.abs(e["u"]).max() > 0.05 and e["p_a"].max() > 1e6  # not all zeros


def test_round_trip_bag_through_the_map_equals_the_csv_path(lib, bags, tmp_path):
    """entry -> bag -> --map -> Recording equals entry -> measured-data CSV -> Recording: the
    same channels, the same values (the CSV's 10 significant digits)."""
    from planner.simulation.bag import read_bag_recording
    crane, path = lib
    with LibraryStore.open(path, "r") as db:
        for eid, stem in (("move 0", "move_0"), ("move 1", "move_1")):
            e = db.entry(eid)
            csv = tmp_path / f"{stem}.csv"
            Recording(e["t"], e["u"], e["q"], e["p_a"], e["p_b"]).to_csv(csv, crane)
            via_csv = Recording.from_csv(csv, crane)
            for src in (bags / stem, next((bags / stem).glob("*.mcap"))):
                via_bag = read_bag_recording(src, MAP, crane)
                assert via_bag.table(crane)[0] == via_csv.table(crane)[0]
                assert via_bag.notes == () and len(via_bag.t) == len(via_csv.t)
                for a, b in zip(via_bag.table(crane)[1].T, via_csv.table(crane)[1].T):
                    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_a_sqlite3_bag_reads_as_the_mcap_one(lib, bags, tmp_path):
    """The other rosbag2 storage: the same entry written with sqlite3 storage reads, through
    the same map, to the same recording as the MCAP bag."""
    from planner.library.rosbag import write_bag
    from planner.simulation.bag import read_bag_recording
    crane, path = lib
    with LibraryStore.open(path, "r") as db:
        e, tr = db.entry("move 0"), db.trajectory("move 0")
    bag = write_bag(tmp_path / "sq", tr, e["p_a"], e["p_b"], storage="sqlite3")
    assert list(bag.glob("*.db3")) and not list(bag.glob("*.mcap"))
    a = read_bag_recording(bag, MAP, crane).table(crane)
    b = read_bag_recording(bags / "move_0", MAP, crane).table(crane)
    assert a[0] == b[0]
    np.testing.assert_array_equal(a[1], b[1])


def test_map_units_scale_the_channels(lib, bags, tmp_path):
    """unit '%' divides the commands by 100; unit 'deg' for the angles multiplies the revolute
    positions by pi/180 and leaves the prismatic ones in m."""
    from planner.simulation.bag import read_bag_recording
    crane, _ = lib
    base = read_bag_recording(bags / "move_0", MAP, crane)
    text = MAP.read_text().replace('unit = "1"', 'unit = "%"')
    (tmp_path / "pct.toml").write_text(text)
    np.testing.assert_allclose(read_bag_recording(bags / "move_0", tmp_path / "pct.toml",
                                                  crane).u, base.u / 100)
    text = MAP.read_text().replace('unit = "rad"', 'unit = "deg"', 1)
    (tmp_path / "deg.toml").write_text(text)
    # the unit check refuses positions far outside the ranges once read as degrees? They are
    # small angles, read as degrees they stay inside: the values are scaled, nothing else
    rec = read_bag_recording(bags / "move_0", tmp_path / "deg.toml", crane)
    rev = np.array([j.revolute for j in crane.spec.joints])
    np.testing.assert_allclose(rec.q[:, rev], base.q[:, rev] * np.pi / 180)
    np.testing.assert_array_equal(rec.q[:, ~rev], base.q[:, ~rev])


@pytest.mark.parametrize("edit, needle", [
    (('unit = "1"', 'unit = "1"\nbogus = 1'), "[u] unknown key 'bogus'"),
    (('unit = "Pa"', 'unit = "atm"'), "[p_a] unit = 'atm'"),
    (('topic = "/valve_commands"', 'topic = "/valves"'), "topic /valves is not in the bag"),
    (('field = "effort"', 'field = "force"'), "no field 'force'"),
])
def test_bad_map_one_line_naming_key_and_value(lib, bags, tmp_path, capsys, edit, needle):
    crane, path = lib
    (tmp_path / "m.toml").write_text(MAP.read_text().replace(*edit, 1))
    rc = main(["discrepancy", "umea-lab", "--measured", str(bags / "move_0"), "--map",
               str(tmp_path / "m.toml")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and needle in err and len(err.splitlines()) == 1, err


def test_discrepancy_reads_the_bag_through_the_map(bags, capsys):
    # a bag without --map is refused naming --map; with it the bag is read and the diagnosis
    # runs on it (a 3.8 s move is too short for one: the reading itself succeeded)
    assert main(["discrepancy", "umea-lab", "--measured", str(bags / "move_0")]) == 2
    assert "needs --map" in capsys.readouterr().err
    assert main(["discrepancy", "umea-lab", "--measured", str(bags / "move_0"),
                 "--map", str(MAP)]) == 2
    err = capsys.readouterr().err
    assert "too short" in err and "--map" not in err


def test_without_rosbags_one_line_names_the_extra(lib, tmp_path, capsys, monkeypatch):
    crane, path = lib
    monkeypatch.setitem(sys.modules, "rosbags", None)
    assert main(["library", "export", str(path), "--format", "rosbag2", "--out",
                 str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip()
    assert "crane-planner[ros]" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "b" / "move_0").exists()


def _array_bag(path, t, q, u):
    """A bag as another logger might write it: std_msgs/Float64MultiArray on /q (joints in
    reverse order, degrees for the angles) and /u (percent), no headers: log time only."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        cq = w.add_connection("/q", "std_msgs/msg/Float64MultiArray", typestore=ts)
        cu = w.add_connection("/u", "std_msgs/msg/Float64MultiArray", typestore=ts)
        for k, tk in enumerate(t):
            ns = 1_700_000_000_000_000_000 + int(round(tk * 1e9))   # an epoch clock
            for c, row in ((cq, q[k][::-1]), (cu, 100 * u[k])):
                msg = T["std_msgs/msg/Float64MultiArray"](layout=layout,
                                                          data=np.array(row, float))
                w.write(c, ns, bytes(ts.serialize_cdr(msg, c.msgtype)))
    return path


def test_index_log_time_units_and_jitter(lib, tmp_path):
    """Headerless arrays by index, log time on an epoch clock, degrees and percent, stamps
    jittered by up to 4 % of a 50 Hz step: resampled onto the mean rate (said in the notes),
    each reading interpolated from the logged ones; rate = 25 in the map resamples to 25 Hz;
    time = 'header' on a headerless message is refused naming the topic."""
    from planner.simulation.bag import read_bag_recording
    crane, _ = lib
    rng = np.random.default_rng(3)
    n = 101
    t = np.arange(n) * 0.02 + rng.uniform(-0.0008, 0.0008, n)
    t[0], t[-1] = 0.0, 2.0
    q = np.column_stack([0.1 * np.sin(t), 0.6 + 0.1 * t, -1.2 + 0.05 * t, 0.5 + 0.1 * t])
    u = np.column_stack([np.sin(3 * t) * 0.5] * 4)
    rev = np.array([j.revolute for j in crane.spec.joints])
    logged = np.where(rev, np.degrees(q), q)
    bag = _array_bag(tmp_path / "arr", t, logged, u)
    idx = ", ".join(f"{j} = {crane.n - 1 - i}" for i, j in enumerate(crane.names))
    text = (f'time = "log"\n[q]\ntopic = "/q"\nfield = "data"\nunit = "deg"\n'
            f"index = {{{idx}}}\n[u]\ntopic = \"/u\"\nfield = \"data\"\nunit = \"%\"\n"
            f"index = {{{idx}}}\n")
    (tmp_path / "m.toml").write_text(text)
    rec = read_bag_recording(bag, tmp_path / "m.toml", crane)
    assert len(rec.notes) == 1 and "jitter" in rec.notes[0]
    np.testing.assert_allclose(rec.t, np.arange(n) * 0.02, atol=1e-9)
    for i in range(crane.n):
        np.testing.assert_allclose(rec.q[:, i], np.interp(rec.t, t, q[:, i]), atol=1e-12)
    assert rec.p_a is None
    np.testing.assert_allclose(rec.u, u, atol=1e-12)   # each command kept with its sample
    (tmp_path / "r.toml").write_text("rate = 25\n" + text)
    rec = read_bag_recording(bag, tmp_path / "r.toml", crane)
    np.testing.assert_allclose(rec.t, np.arange(51) * 0.04, atol=1e-9)
    np.testing.assert_allclose(rec.q[:, 1], np.interp(rec.t, t, q[:, 1]), atol=1e-12)
    (tmp_path / "h.toml").write_text(text.replace('time = "log"', 'time = "header"'))
    with pytest.raises(ValueError, match=r"topic /[qu] \(std_msgs/msg/Float64MultiArray\) "
                                         r"has no header"):
        read_bag_recording(bag, tmp_path / "h.toml", crane)
