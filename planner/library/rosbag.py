"""``library export --format rosbag2``: every entry of a library as a ROS 2 bag (MCAP storage)
that ``ros2 bag play``, Foxglove and PlotJuggler open (docs/rosbag.md).

One bag folder per entry with a trajectory (``<stem>/metadata.yaml`` + ``<stem>/<stem>_0.mcap``,
bag format version 8, CDR messages), ``index.csv`` and ``joints.toml`` (the map that reads
them back) beside them. Topics:

- ``/joint_trajectory`` (``trajectory_msgs/msg/JointTrajectory``): one message at the first
  sample, the whole move as a controller receives it: ``joint_names`` as in the crane spec,
  one point per sample with positions [rad | m], velocities, accelerations, empty effort and
  ``time_from_start``;
- ``/joint_states`` (``sensor_msgs/msg/JointState``): one message per sample, ``name`` the
  joints, ``position`` q, ``velocity`` qd (``effort`` empty);
- ``/valve_commands`` (``sensor_msgs/msg/JointState``): one message per sample, ``effort`` the
  valve command u in effect from that sample on (normalised −1…1), position/velocity empty;
  JointState names every joint in every message, which PlotJuggler and Foxglove plot per name;
- ``/pressure_a``, ``/pressure_b`` (``sensor_msgs/msg/JointState``): the actuator port
  pressures of the crane model at each sample in ``effort`` [Pa, absolute].

Every message's ``header.stamp`` and its log time are the sample's time t [s] (the entry's
clock, from 0: 1970-01-01 in tools that show dates). An entry stored without valve commands,
or any entry with ``rate``, is exported on the fixed control grid t0 + k/rate with the
commands of :func:`planner.feedforward.commands` (:func:`~planner.library.export.fixed_rate`;
rate 50 Hz when the entry has none and no rate is given). The bag folder is written beside
its final name and renamed into place, so a bag is there whole or not at all.
"""
from __future__ import annotations

import math
import os
import shutil
import tempfile
import tomllib
from pathlib import Path

import numpy as np

from planner.io import atomic_write_text
from planner.library.export import HYD_CSV_CHANNELS, file_stem, fixed_rate, index_csv_text
from planner.library.store import LibraryStore, StoreError
from planner.model.spec import parse_spec
from planner.simulation.bag import MapError, need_rosbags

__all__ = ["DEFAULT_RATE_HZ", "TOPICS", "write_bag", "export_rosbag2"]

DEFAULT_RATE_HZ = 50.0  # the control grid of an entry stored without valve commands
TOPICS = {"/joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
          "/joint_states": "sensor_msgs/msg/JointState",
          "/valve_commands": "sensor_msgs/msg/JointState",
          "/pressure_a": "sensor_msgs/msg/JointState",
          "/pressure_b": "sensor_msgs/msg/JointState"}


def _ns(t: float) -> int:
    return int(round(float(t) * 1e9))


def write_bag(path, traj, p_a, p_b, frame_id: str = "base_link",
              storage: str = "mcap") -> Path:
    """Write one trajectory (with commands ``traj.u``) and its port pressures p_a, p_b (N, n)
    [Pa] as a ROS 2 bag folder ``path`` (``storage`` "mcap" or "sqlite3"; the topics of the
    module docstring). It is built under a temporary name beside ``path`` and renamed over it."""
    try:
        need_rosbags()
    except MapError as e:
        raise StoreError(f"export format 'rosbag2': {str(e).split(': ', 1)[1]}") from None
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    if traj.u is None:
        raise StoreError("write_bag: the trajectory has no valve commands (u)")
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    path = Path(path)
    names = list(traj.joint_names)
    empty = np.zeros(0)

    def header(ns):
        return T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000,
                                                    nanosec=ns % 1_000_000_000),
            frame_id=frame_id)

    def state(ns, position=empty, velocity=empty, effort=empty):
        return T["sensor_msgs/msg/JointState"](header=header(ns), name=names,
                                               position=np.asarray(position, float),
                                               velocity=np.asarray(velocity, float),
                                               effort=np.asarray(effort, float))

    Duration = T["builtin_interfaces/msg/Duration"]
    t0 = float(traj.t[0])
    points = []
    for k in range(len(traj.t)):
        d = _ns(float(traj.t[k]) - t0)
        points.append(T["trajectory_msgs/msg/JointTrajectoryPoint"](
            positions=np.array(traj.q[k], float), velocities=np.array(traj.qd[k], float),
            accelerations=np.array(traj.qdd[k], float), effort=empty,
            time_from_start=Duration(sec=d // 1_000_000_000, nanosec=d % 1_000_000_000)))
    stamps = [_ns(t) for t in traj.t]
    if stamps[0] < 0:
        raise StoreError(f"write_bag: the trajectory starts at t = {traj.t[0]:g} s; ROS time "
                         "stamps cannot be negative")
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    bag = tmp / path.name
    try:
        plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
        with Writer(bag, version=8, storage_plugin=plugin) as w:
            conn = {topic: w.add_connection(topic, msgtype, typestore=ts)
                    for topic, msgtype in TOPICS.items()}

            def put(topic, ns, msg):
                w.write(conn[topic], ns,
                        bytes(ts.serialize_cdr(msg, TOPICS[topic])))
            put("/joint_trajectory", stamps[0], T["trajectory_msgs/msg/JointTrajectory"](
                header=header(stamps[0]), joint_names=names, points=points))
            for k, ns in enumerate(stamps):
                put("/joint_states", ns, state(ns, traj.q[k], traj.qd[k]))
                put("/valve_commands", ns, state(ns, effort=traj.u[k]))
                put("/pressure_a", ns, state(ns, effort=p_a[k]))
                put("/pressure_b", ns, state(ns, effort=p_b[k]))
        if path.exists():
            shutil.rmtree(path) if path.is_dir() else path.unlink()
        os.replace(bag, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path


def export_rosbag2(db_path, out_dir, rate: float | None = None) -> list[Path]:
    """Every entry of the library with a trajectory as a bag folder in ``out_dir`` (its name
    from :func:`~planner.library.export.file_stem`), and index.csv (its ``file`` column names
    the folder). Returns the paths written."""
    try:
        need_rosbags()
    except MapError as e:
        raise StoreError(f"export format 'rosbag2': {str(e).split(': ', 1)[1]}") from None
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise StoreError(f"`rate` = {rate}: must be a positive number of Hz")
    from planner.model import Crane  # the CasADi model: commands and pressures
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    with LibraryStore.open(db_path, "r") as db:
        if not db.spec_toml:
            raise StoreError(f"{db.path}: no embedded crane spec; the rosbag2 export needs "
                             "the model (valve commands, pressures)")
        crane = Crane(parse_spec(tomllib.loads(db.spec_toml), "<library spec>"))
        rows = db.index_rows()
        reasons = {r["id"]: db.entry_attrs(r["id"]).get("reason", "") for r in rows}
        used: set = set()
        files = {}
        for r in rows:
            eid = r["id"]
            if not db.has_trajectory(eid):
                files[eid] = ""
                continue
            traj = db.trajectory(eid)
            if rate is not None or traj.u is None:
                traj, hyd = fixed_rate(crane, traj, rate or DEFAULT_RATE_HZ)
            else:
                e = db.entry(eid)
                hyd = (e if all(k in e for k in HYD_CSV_CHANNELS)
                       else crane.hydraulics(traj.q, traj.qd, traj.qdd))
            n = len(traj.t)
            pa = np.asarray(hyd["p_a"], float).reshape(n, crane.n)
            pb = np.asarray(hyd["p_b"], float).reshape(n, crane.n)
            name = file_stem(eid, used)
            written.append(write_bag(out_dir / name, traj, pa, pb))
            files[eid] = name
        p = out_dir / "index.csv"
        atomic_write_text(p, index_csv_text(rows, files, reasons))
        written.append(p)
        # the map that reads these bags back (discrepancy --measured BAG --map joints.toml)
        p = out_dir / "joints.toml"
        atomic_write_text(p, READ_BACK_MAP)
        written.append(p)
    return written


#: the map (docs/rosbag.md) that reads the bags :func:`export_rosbag2` writes
READ_BACK_MAP = """\
# Map of the bags written by `crane-planner library export --format rosbag2` to the
# measured-data channels (docs/rosbag.md): `discrepancy … --measured BAG --map joints.toml`.
time = "header"

[q]
topic = "/joint_states"
field = "position"
unit = "rad"

[u]
topic = "/valve_commands"
field = "effort"
unit = "1"

[p_a]
topic = "/pressure_a"
field = "effort"
unit = "Pa"

[p_b]
topic = "/pressure_b"
field = "effort"
unit = "Pa"
"""
