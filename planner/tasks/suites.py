"""Task suites: planner/problems/tasks/<name>.toml -> moves (and the suite's obstacles and
references).

On-disk format (TOML; lengths in m, times in s, energies in J, angles in rad or '30deg'; tip
points (r, z, slew) in the crane's frame 0, docs/design.md, "CONTRACT: tip coordinates"):

``[suite]``
    ``id``, ``crane`` (machine id), ``description``, ``source`` (provenance of the numbers).
``[pickups]`` and ``[drops]`` (optional, together)
    a grid of tip points: lists ``r`` [m] and ``slew`` [angle], one ``z`` [m]; every pick-up →
    drop move (id "pII-dJJ") and, with ``[options] both_directions`` (default true), its way
    back ("dJJ-pII").
``[points]`` (optional)
    named tip points, ``A = [r, z, slew]``, for the moves to refer to.
``[[moves]]`` (optional, after the grid's moves)
    explicit moves: ``id``; ``start`` and ``goal`` (a point name or ``[r, z, slew]``; taken from
    the path's ends when the path has its own); ``path`` (default ``"line"``: the straight tip
    line start → goal; or the name of a ``[paths.NAME]`` table, or an inline table of the same
    form); ``reference_s`` / ``reference_J`` (published durations [s] / pump energies [J] for
    the move by benchmark method name, e.g. ``{ "dp:time" = 1.15 }``; say where they come
    from in a comment).
``[paths.NAME]``
    a tip path, ``kind`` one of
    ``"line"`` (the move's start → goal), ``"waypoints"`` (``tips = [[r, z, slew], …]``,
    straight in Cartesian space between them), ``"circle"`` (``center = [x, y, z]`` [m, frame 0],
    ``radius`` [m], ``theta0`` / ``theta1`` [angle, default ∓180deg], ``plane`` "xz" or "xy";
    :func:`planner.geometry.paths.circle`), ``"parabola"`` (``x0``, ``x1``, ``z_min``,
    ``z_max`` [m], ``azimuth`` [angle]; :func:`planner.geometry.paths.parabola`) or
    ``"cycle"`` (``cycle`` "h" / "v" / "d", ``speed`` [m/s per axis]: a timed seed-002 cycle of
    :mod:`planner.tasks.cycles`, which fixes start, goal and ``duration_s``).
``[options] both_directions``
    see the grid.
``[obstacles.NAME]``
    obstacles (:func:`planner.geometry.obstacles.from_dict`).
``[bench]``
    how the benchmark uses the suite; read and documented by :mod:`planner.bench.suites`
    (kept here as a raw table, :attr:`TaskFile.tables`).

A malformed file fails with a :class:`~planner.model.spec.SpecError` naming the file, the field
and what was expected.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner.geometry.obstacles import from_dict as obstacle_from_dict
from planner.geometry.paths import Line, Waypoints, circle, parabola
from planner.model.reader import read_toml_text
from planner.model.spec import SpecError
from planner.tasks.cycles import CYCLES, cycle
from planner.units import parse_angle
from planner.problems import task_path

__all__ = ["Move", "TaskFile", "suite_path", "load_suite", "load_task_file", "PATH_KINDS"]

PATH_KINDS = ("line", "waypoints", "circle", "parabola", "cycle")


@dataclass(frozen=True)
class Move:
    """One move of a suite: ``id`` (e.g. "p00-d01"), start and goal tips (r, z, slew).
    ``path``: the tip path (a :class:`planner.geometry.paths.Path`; None: the straight line);
    ``cycle``: (name, per-axis speed [m/s]) of a timed seed-002 cycle, whose clock fixes
    ``duration_s`` [s]; ``closed``: start = goal; ``reference_s`` / ``reference_J``: published
    durations [s] / pump energies [J] by benchmark method name."""
    id: str
    start: tuple
    goal: tuple
    path: object = field(default=None, compare=False)
    cycle: tuple | None = None
    duration_s: float | None = None
    closed: bool = False
    reference_s: dict = field(default_factory=dict, compare=False, hash=False)
    reference_J: dict = field(default_factory=dict, compare=False, hash=False)

    def line_or_path(self):
        """The move's tip path: its own, or the straight line start → goal."""
        return self.path if self.path is not None else Line(self.start, self.goal)


@dataclass
class TaskFile:
    """A parsed task file: ``id``, ``crane``, ``description``, ``source`` (from ``[suite]``),
    ``moves``, ``obstacles`` and ``tables`` (the raw TOML, for readers of other tables such
    as ``[bench]``); ``path``: the file."""
    id: str
    crane: str
    description: str
    source: str
    moves: list
    obstacles: tuple
    tables: dict
    path: Path


def suite_path(name: str) -> Path:
    """The file of a shipped suite (by name) or a path to a .toml; KeyError naming the known
    suites otherwise."""
    return task_path(name)


class _Reader:
    """Field readers that raise SpecError naming the file and the field."""

    def __init__(self, path: Path):
        self.file = str(path)

    def fail(self, key, value, expected):
        raise SpecError(self.file, key, value, expected)

    def number(self, t, key, where, default=None):
        v = t.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(f"{where}.{key}", v, "a number")
        return float(v)

    def angle(self, t, key, where, default=None):
        v = t.get(key, default)
        try:
            return parse_angle(v)
        except (TypeError, ValueError):
            self.fail(f"{where}.{key}", v, "an angle: a number [rad] or a string like '30deg'")

    def tip(self, v, where, points):
        if isinstance(v, str):
            if v not in points:
                self.fail(where, v, f"a tip [r, z, slew] or a point of [points] "
                                    f"({', '.join(points) or 'none defined'})")
            return points[v]
        if not isinstance(v, list) or len(v) != 3:
            self.fail(where, v, "a tip [r, z, slew] (3 values) or a point name")
        try:
            return (float(v[0]), float(v[1]), parse_angle(v[2]))
        except (TypeError, ValueError):
            self.fail(where, v, "r and z numbers [m], slew an angle")

    def grid(self, data, key):
        t = data.get(key)
        if not isinstance(t, dict) or not {"r", "slew", "z"} <= set(t):
            self.fail(key, t, "expected a table with r (list), slew (list), z")
        try:
            rs = [float(r) for r in t["r"]]
            sl = [parse_angle(s) for s in t["slew"]]
            z = float(t["z"])
        except (TypeError, ValueError):
            self.fail(key, t, "r and slew must be lists of numbers (slew may be '30deg'), "
                              "z a number")
        return [(r, z, s) for s in sl for r in rs]

    def path(self, spec, where):
        """(Path or None, cycle or None, duration or None) of a move's path field."""
        if not isinstance(spec, dict) or spec.get("kind") not in PATH_KINDS:
            self.fail(where, spec, f"a path table with kind one of {', '.join(PATH_KINDS)}")
        kind = spec["kind"]
        if kind == "line":
            return None, None, None
        if kind == "waypoints":
            tips = spec.get("tips")
            if not isinstance(tips, list) or len(tips) < 2:
                self.fail(f"{where}.tips", tips, "a list of at least two tips [r, z, slew]")
            pts = [self.tip(x, f"{where}.tips", {}) for x in tips]
            try:
                return Waypoints(pts), None, None
            except ValueError as e:
                self.fail(f"{where}.tips", tips, str(e))
        if kind == "circle":
            c = spec.get("center")
            if not isinstance(c, list) or len(c) != 3:
                self.fail(f"{where}.center", c, "[x, y, z] in frame 0 [m]")
            plane = spec.get("plane", "xz")
            if plane not in ("xz", "xy"):
                self.fail(f"{where}.plane", plane, "'xz' or 'xy'")
            r = self.number(spec, "radius", where)
            if r <= 0:
                self.fail(f"{where}.radius", r, "a radius > 0 m")
            return circle([float(x) for x in c], r, self.angle(spec, "theta0", where, -math.pi),
                          self.angle(spec, "theta1", where, math.pi), plane=plane), None, None
        if kind == "parabola":
            return parabola(*(self.number(spec, k, where) for k in ("x0", "x1", "z_min", "z_max")),
                            self.angle(spec, "azimuth", where)), None, None
        name = spec.get("cycle")
        if name not in CYCLES:
            self.fail(f"{where}.cycle", name,
                      f"one of {', '.join(CYCLES)} (planner/tasks/cycles.py)")
        speed = self.number(spec, "speed", where)
        if speed <= 0:
            self.fail(f"{where}.speed", speed, "a per-axis tip speed > 0 m/s")
        return None, (name, speed), None


def _explicit_moves(rd: _Reader, data: dict) -> list[Move]:
    points = {}
    for k, v in (data.get("points") or {}).items():
        points[k] = rd.tip(v, f"points.{k}", {})
    paths = data.get("paths") or {}
    if not isinstance(paths, dict):
        rd.fail("paths", paths, "tables [paths.NAME]")
    moves = []
    for i, m in enumerate(data.get("moves") or []):
        where = f"moves[{i}]"
        if not isinstance(m, dict) or not isinstance(m.get("id"), str):
            rd.fail(where, m, "a table with an id (string)")
        spec = m.get("path", "line")
        if isinstance(spec, str):
            if spec == "line":
                spec = {"kind": "line"}
            elif spec in paths:
                where, spec = f"paths.{spec}", paths[spec]
            else:
                rd.fail(f"{where}.path", spec, f"'line' or a path of [paths] "
                                               f"({', '.join(paths) or 'none defined'})")
        else:
            where = f"{where}.path"
        path, cyc, duration = rd.path(spec, where)
        if cyc is not None:
            _, duration, secs = cycle(*cyc)
            start, goal = tuple(map(float, secs[0].start)), tuple(map(float, secs[-1].end))
        elif path is not None and "start" not in m:
            a, b = path.tip(np.array([0.0, path.length]))
            start, goal = tuple(map(float, a)), tuple(map(float, b))
        else:
            start = rd.tip(m.get("start"), f"moves[{i}].start", points)
            goal = rd.tip(m.get("goal"), f"moves[{i}].goal", points)
        refs = {}
        for key in ("reference_s", "reference_J"):
            t = m.get(key, {})
            if not isinstance(t, dict) or not all(isinstance(v, (int, float))
                                                  and not isinstance(v, bool) for v in t.values()):
                rd.fail(f"moves[{i}].{key}", t, "a table method name = number")
            refs[key] = {k: float(v) for k, v in t.items()}
        moves.append(Move(m["id"], start, goal, path=path, cycle=cyc, duration_s=duration,
                          closed=cyc is None and bool(np.allclose(start, goal, atol=1e-9)),
                          **refs))
    return moves


def load_task_file(name: str) -> TaskFile:
    """The parsed task file ``name`` (a shipped suite's name or a path to a .toml)."""
    path = suite_path(name)
    try:
        data = tomllib.loads(read_toml_text(path))
    except tomllib.TOMLDecodeError as e:
        raise SpecError(str(path), "<toml>", None, f"not valid TOML: {e}") from None
    rd = _Reader(path)
    moves = []
    if "pickups" in data or "drops" in data or not data.get("moves"):
        picks, drops = rd.grid(data, "pickups"), rd.grid(data, "drops")
        both = bool(data.get("options", {}).get("both_directions", True))
        for i, p in enumerate(picks):
            for j, d in enumerate(drops):
                moves.append(Move(f"p{i:02d}-d{j:02d}", p, d))
                if both:
                    moves.append(Move(f"d{j:02d}-p{i:02d}", d, p))
    moves += _explicit_moves(rd, data)
    ids = [m.id for m in moves]
    if len(set(ids)) != len(ids):
        rd.fail("moves", sorted({i for i in ids if ids.count(i) > 1}), "unique move ids")
    obstacles = []
    for name_, t in (data.get("obstacles") or {}).items():
        try:
            obstacles.append(obstacle_from_dict(t))
        except (ValueError, TypeError) as e:
            raise SpecError(str(path), f"obstacles.{name_}", t, str(e)) from None
    head = data.get("suite", {})
    return TaskFile(head.get("id", path.stem), head.get("crane", ""),
                    head.get("description", ""), head.get("source", ""), moves,
                    tuple(obstacles), data, path)


def load_suite(name: str) -> tuple[dict, list[Move]]:
    """(suite table, moves) of a task suite: the grid's moves (every pick-up × every drop, and
    back), then the explicit ``[[moves]]``. The suite table's ``obstacles`` holds the parsed
    obstacles (a tuple, possibly empty)."""
    tf = load_task_file(name)
    return dict(tf.tables.get("suite", {}), obstacles=tf.obstacles), tf.moves
