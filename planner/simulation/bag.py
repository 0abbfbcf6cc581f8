"""Measured data as robots record it: a ROS 2 bag (MCAP or sqlite3 storage) read through a
*map file* into the same :class:`~planner.simulation.recording.Recording` the measured-data CSV
gives (docs/rosbag.md), so every later step (discrepancy, calibration) is unchanged.

The map (TOML) names, for each channel of the measured-data CSV, the topic and the message
field that holds it and the unit it is recorded in::

    time = "header"            # header: each message's header.stamp; log: the bag's log time
    # rate = 50.0              # optional [Hz]: resample every channel onto this grid
    [joints]                   # optional: crane joint = name in the messages
    boom = "boom_joint"
    [q]                        # positions -> q_<joint>        (required)
    topic = "/joint_states"
    field = "position"
    unit = "rad"               # deg: revolute joints in deg (prismatic in m); mm: prismatic
                               # in mm (revolute in rad); or per joint {boom = "deg", tele = "mm"}
    [u]                        # valve commands -> u_<joint>   (optional)
    topic = "/valve_commands"
    field = "effort"
    unit = "1"                 # 1 (normalised -1...1) or "%"
    [p_a]                      # cylinder pressures -> p_<joint>_a / _b (optional, both or none)
    topic = "/pressure_a"
    field = "effort"
    unit = "Pa"                # Pa, kPa, bar, MPa, psi

A field is an array of one value per joint: the joints are found by the message's ``name`` list
(sensor_msgs/JointState), or by ``index = {boom = 0, jib = 1, …}`` in the channel's table (e.g.
std_msgs/Float64MultiArray's ``data``). The sample grid is the position topic's stamps (or the
map's ``rate``): the other channels are taken at those times — commands held (the command in
effect), readings interpolated linearly — and equal stamps give the values as logged. Time is
counted from the first position sample. The grid must be uniform within the CSV reader's
jitter (:data:`~planner.simulation.recording.JITTER`: resampled onto the mean rate, readings
interpolated and each command kept with its sample, said in ``notes``); otherwise give
``rate``.

``rosbags`` (pure Python, the ``ros`` extra) is imported only here, when a bag is read or written.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import tomllib
from pathlib import Path

import numpy as np

from planner.feedforward import commands
from planner.simulation.recording import (JITTER, P_MIN, Recording, check_units,
                                          resample_arrays)

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["ROS_EXTRA_HINT", "need_rosbags", "MapError", "read_map", "read_bag_recording",
           "is_bag", "UNITS"]

ROS_EXTRA_HINT = "pip install 'crane-planner[ros]' (the rosbags library)"

# unit -> factor to SI, per channel kind
UNITS = {
    "angle": {"rad": 1.0, "deg": math.pi / 180},
    "length": {"m": 1.0, "mm": 1e-3, "cm": 1e-2},
    "command": {"1": 1.0, "%": 1e-2},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "bar": 1e5, "MPa": 1e6, "psi": 6894.757293168},
}
CHANNELS = ("q", "u", "p_a", "p_b")
TOP_KEYS = {"time", "rate", "joints", *CHANNELS}
CHANNEL_KEYS = {"topic", "field", "unit", "index"}


class MapError(ValueError):
    """A map file or a bag that does not fit it: the message names file, key, value, allowed."""


def need_rosbags():
    """The ``rosbags`` package, or one line naming the extra that installs it."""
    try:
        import rosbags  # noqa: F401  (optional: the ``ros`` extra)
    except ImportError:
        raise MapError(f"ROS 2 bags need the rosbags library: {ROS_EXTRA_HINT}") from None
    import rosbags.highlevel
    import rosbags.rosbag2
    import rosbags.typesys
    return rosbags


def is_bag(path) -> bool:
    """Whether ``path`` names a ROS 2 bag: a .mcap / .db3 file or a folder with metadata.yaml."""
    p = Path(path)
    return p.suffix.lower() in (".mcap", ".db3") or (p.is_dir() and
                                                     (p / "metadata.yaml").exists())


# ----------------------------------------------------------------------------- the map
def read_map(path, crane: Crane) -> dict:
    """Read and check a map file against ``crane``: returns dict time, rate, names (crane
    joint -> name in the bag), and per channel present: topic, field, index (dict or None),
    factor (n,) to SI."""
    src = str(path)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except OSError as e:
        raise MapError(f"`map` = {src}: cannot read it ({e.strerror})") from None
    except tomllib.TOMLDecodeError as e:
        raise MapError(f"`map` = {src}: not valid TOML ({e})") from None

    def fail(msg):
        return MapError(f"`map` = {src}: {msg}")
    bad = sorted(set(doc) - TOP_KEYS)
    if bad:
        raise fail(f"unknown key {bad[0]!r}; allowed: {', '.join(sorted(TOP_KEYS))}")
    time = doc.get("time", "header")
    if time not in ("header", "log"):
        raise fail(f"time = {time!r}; allowed: 'header' (header.stamp) or 'log' (log time)")
    rate = doc.get("rate")
    if rate is not None and not (isinstance(rate, (int, float)) and math.isfinite(rate)
                                 and 0 < rate <= 10000):
        raise fail(f"rate = {rate!r}; allowed: a number of Hz in (0, 10000]")
    joints = doc.get("joints", {})
    if not isinstance(joints, dict):
        raise fail("[joints] must be a table: crane joint = name in the messages")
    unknown = [j for j in joints if j not in crane.names]
    if unknown:
        raise fail(f"[joints]: unknown joint {unknown[0]!r}; the crane's joints: "
                   f"{', '.join(crane.names)}")
    names = {j: str(joints.get(j, j)) for j in crane.names}
    out = dict(time=time, rate=None if rate is None else float(rate), names=names)
    if "q" not in doc:
        raise fail("no [q] table; the positions are required (topic, field, unit)")
    if ("p_a" in doc) != ("p_b" in doc):
        raise fail(f"[{'p_a' if 'p_a' in doc else 'p_b'}] without "
                   f"[{'p_b' if 'p_a' in doc else 'p_a'}]; give both pressures or none")
    for ch in CHANNELS:
        if ch in doc:
            out[ch] = _channel(doc[ch], ch, crane, fail)
    return out


def _channel(tab, ch, crane: Crane, fail) -> dict:
    if not isinstance(tab, dict):
        raise fail(f"{ch} must be a table [{ch}] with topic, field, unit")
    bad = sorted(set(tab) - CHANNEL_KEYS)
    if bad:
        raise fail(f"[{ch}] unknown key {bad[0]!r}; allowed: {', '.join(sorted(CHANNEL_KEYS))}")
    for k in ("topic", "field", "unit"):
        if k not in tab:
            raise fail(f"[{ch}] needs {k!r} (topic, field, unit)")
    if not (isinstance(tab["topic"], str) and tab["topic"].startswith("/")):
        raise fail(f"[{ch}] topic = {tab['topic']!r}; allowed: a topic name starting with '/'")
    unit = tab["unit"]
    per = unit if isinstance(unit, dict) else {j: unit for j in crane.names}
    factor = []
    for j, spec in zip(crane.names, crane.spec.joints):
        kind = ("command" if ch == "u" else "pressure" if ch.startswith("p_")
                else "angle" if spec.revolute else "length")
        if j not in per:
            raise fail(f"[{ch}] unit: no unit for joint {j!r}")
        u = per[j]
        if not isinstance(unit, dict) and ch == "q" and u not in UNITS[kind]:
            u = "rad" if kind == "angle" else "m"  # one unit names one kind; the other is SI
        if u not in UNITS[kind]:
            raise fail(f"[{ch}] unit = {u!r} for {j} ({kind}); allowed: "
                       f"{', '.join(repr(x) for x in UNITS[kind])}")
        factor.append(UNITS[kind][u])
    index = tab.get("index")
    if index is not None:
        if not isinstance(index, dict) or set(index) != set(crane.names) or not all(
                isinstance(v, int) and v >= 0 for v in index.values()):
            raise fail(f"[{ch}] index must give every joint ({', '.join(crane.names)}) a "
                       "position >= 0 in the field's array")
    return dict(topic=tab["topic"], field=str(tab["field"]), index=index,
                factor=np.array(factor))


# ----------------------------------------------------------------------------- the bag
def _bag_paths(path):
    """rosbags' AnyReader takes a bag folder; a bare .mcap / .db3 file is read through its
    folder when that folder holds the bag's metadata, else on its own (MCAP only)."""
    p = Path(path)
    if not p.exists():
        raise OSError(2, "No such file or directory", str(p))
    if p.is_file() and (p.parent / "metadata.yaml").exists():
        return p.parent
    return p


def _series(msgs, spec, names, src):
    """(stamps [ns] (M,), values (M, n)) of one channel from its decoded messages."""
    topic, field = spec["topic"], spec["field"]
    stamps, rows = [], []
    cols = None
    for ns, msg in msgs:
        try:
            arr = getattr(msg, field)
        except AttributeError:
            have = [k for k in getattr(msg, "__dataclass_fields__", {})]
            raise MapError(f"{src}: topic {topic}: the message has no field {field!r}; "
                           f"its fields: {', '.join(have)}") from None
        arr = np.asarray(arr, float).ravel()
        if spec["index"] is not None:
            idx = [spec["index"][j] for j in names]
            if max(idx) >= arr.size:
                raise MapError(f"{src}: topic {topic}, field {field}: {arr.size} value(s), the "
                               f"map's index asks for position {max(idx)}")
            rows.append(arr[idx])
        else:
            msg_names = list(getattr(msg, "name", None) or [])
            if not msg_names:
                raise MapError(f"{src}: topic {topic}: the message has no 'name' list; give "
                               "index = {joint = position, …} in the map")
            if cols is None or msg_names != cols[0]:
                missing = [b for b in names.values() if b not in msg_names]
                if missing:
                    raise MapError(f"{src}: topic {topic}: joint {missing[0]!r} not in the "
                                   f"message's names ({', '.join(msg_names)}); map crane "
                                   "joints to them in [joints]")
                cols = (msg_names, [msg_names.index(b) for b in names.values()])
            if arr.size != len(msg_names):
                raise MapError(f"{src}: topic {topic}, field {field}: {arr.size} value(s) for "
                               f"{len(msg_names)} names (an empty field is not recorded)")
            rows.append(arr[cols[1]])
        stamps.append(ns)
    if len(rows) < 2:
        raise MapError(f"{src}: topic {topic}: {len(rows)} message(s); at least 2 are needed")
    st = np.array(stamps, dtype=np.int64)
    order = np.argsort(st, kind="stable")
    return st[order], np.array(rows)[order] * spec["factor"]


def _read_topics(path, m, src) -> dict:
    """channel -> list of (stamp ns, message) for every mapped channel."""
    need_rosbags()
    from rosbags.highlevel import AnyReader
    topics = {m[ch]["topic"] for ch in CHANNELS if ch in m}
    got = {t: [] for t in topics}
    bag = _bag_paths(path)                # a missing path: OSError, as for a CSV
    try:
        reader = AnyReader([bag])
        reader.open()
    except Exception as e:  # rosbags' own errors: not a bag, unknown storage, …
        raise MapError(f"{src}: not a readable ROS 2 bag ({e})") from None
    try:
        have = {c.topic for c in reader.connections}
        for t in sorted(topics):
            if t not in have:
                raise MapError(f"{src}: topic {t} is not in the bag; its topics: "
                               f"{', '.join(sorted(have))}")
        conns = [c for c in reader.connections if c.topic in topics]
        for conn, ts, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            if m["time"] == "header":
                h = getattr(msg, "header", None)
                if h is None:
                    raise MapError(f"{src}: topic {conn.topic} ({conn.msgtype}) has no header; "
                                   "use time = 'log' in the map")
                ts = int(h.stamp.sec) * 1_000_000_000 + int(h.stamp.nanosec)
            got[conn.topic].append((int(ts), msg))
    finally:
        reader.close()
    return {ch: got[m[ch]["topic"]] for ch in CHANNELS if ch in m}


def _at(ts, t_s, Y, hold: bool):
    """Y (stamped ts, s) at the times t_s: held (last at or before; the first before it) or
    interpolated linearly (ends held); equal stamps give the logged values."""
    if hold:
        k = np.clip(np.searchsorted(ts, t_s + 1e-12, side="right") - 1, 0, len(ts) - 1)
        return Y[k]
    return np.column_stack([np.interp(t_s, ts, Y[:, c]) for c in range(Y.shape[1])])


def read_bag_recording(path, map_path, crane: Crane, plan=None) -> Recording:
    """The measured record of a ROS 2 bag through a map file (module docstring): the same
    :class:`Recording` the measured-data CSV gives, checked the same way (strictly increasing
    time, a fixed rate (jitter resampled), |u| <= 1, pressures in range, the unit check).
    Without a command topic the commands are the nominal feed-forward of ``plan`` (the
    commanded trajectory) at the recording's rate, as :meth:`Recording.from_csv` derives them."""
    src = str(path)
    m = read_map(map_path, crane)
    msgs = _read_topics(path, m, src)
    names = m["names"]
    series = {ch: _series(msgs[ch], m[ch], names, src) for ch in msgs}
    ns_q, q = series["q"]
    ns0 = int(ns_q[0])
    sec = {ch: (s - ns0).astype(float) * 1e-9 for ch, (s, _) in series.items()}
    t = sec["q"]
    dup = np.flatnonzero(np.diff(t) <= 0)
    if dup.size:
        k = int(dup[0])
        raise MapError(f"{src}: topic {m['q']['topic']}: message {k + 2} has the stamp of "
                       f"message {k + 1} ({t[k]:.9g} s); time must increase strictly")
    notes = []
    t_cmd = None   # jitter: each command stays with its sample (as the CSV reader keeps it)
    if m["rate"] is not None:
        t_new, _ = resample_arrays(t, (None,), m["rate"])
        notes.append(f"resampled onto {m['rate']:g} Hz from {len(t)} position samples "
                     "(the map's rate)")
        q = _at(t, t_new, q, hold=False)
        t = t_new
    else:
        mean = (t[-1] - t[0]) / (len(t) - 1)
        off = np.abs(t - (t[0] + np.arange(len(t)) * mean)) / mean
        if float(off.max()) > JITTER * (1 + 1e-6):
            k = int(np.argmax(off > JITTER * (1 + 1e-6)))
            raise MapError(f"{src}: topic {m['q']['topic']}: message {k + 1} at {t[k]:.9g} s "
                           f"is {100 * float(off[k]):.0f} % of the mean step ({mean:.6g} s) off "
                           f"a uniform grid; allowed: jitter within {100 * JITTER:.0f} %, or "
                           "give rate = HZ in the map to resample")
        if float(off.max()) > 1e-9:
            t_new = t[0] + np.arange(len(t)) * mean
            notes.append(f"timestamp jitter up to {100 * float(off.max()):.1f} % of the step: "
                         f"resampled onto the mean rate {1 / mean:.6g} Hz")
            q = _at(t, t_new, q, hold=False)
            t_cmd, t = t, t_new
    u = pa = pb = None
    if "u" in series:
        u = _at(sec["u"], t if t_cmd is None else t_cmd, series["u"][1], hold=True)
        bad = np.abs(u) > 1 + 1e-9
        if bad.any():
            k, c = np.argwhere(bad)[0]
            raise MapError(f"{src}: topic {m['u']['topic']}: command {u[k, c]:.6g} for "
                           f"{crane.names[c]} at {t[k]:.6g} s outside [-1, 1] after the map's "
                           "unit; valve commands are normalised to -1...1 (unit '1' or '%')")
    if "p_a" in series:
        pa = _at(sec["p_a"], t, series["p_a"][1], hold=False)
        pb = _at(sec["p_b"], t, series["p_b"][1], hold=False)
        for ch, P in (("p_a", pa), ("p_b", pb)):
            bad = (P < P_MIN) | (P > 1e9)
            if bad.any():
                k, c = np.argwhere(bad)[0]
                raise MapError(f"{src}: topic {m[ch]['topic']}: pressure {P[k, c]:.6g} Pa for "
                               f"{crane.names[c]} at {t[k]:.6g} s; allowed: -2e6 ... 1e9 Pa "
                               "(is the map's unit right?)")
    for name, Y in (("q", q), ("u", u), ("p_a", pa), ("p_b", pb)):
        if Y is not None and not np.all(np.isfinite(Y)):
            raise MapError(f"{src}: topic {m[name]['topic']}: NaN or inf values; not allowed")
    if len(t) < 2:
        raise MapError(f"{src}: fewer than 2 samples; at least 2 are needed")
    check_units(crane, dict(t=t, u=u, q=q, p_a=pa, p_b=pb, notes=notes), src)
    if u is None:
        if plan is None:
            raise MapError(f"`map` = {map_path}: no [u] table (valve commands); give the "
                           "commanded trajectory (`plan`) to derive them")
        dt = float(np.median(np.diff(t)))
        ff = commands(crane, plan, 1.0 / dt)
        k = np.clip(np.round((t - ff.t[0]) / dt).astype(int), 0, len(ff.t) - 1)
        u = ff.u[k]
    return Recording(t, u, q, pa, pb, tuple(notes))
