"""Task suites: problems/tasks/<name>.toml -> moves (and the suite's obstacles).

A suite file holds ``[pickups]`` and ``[drops]`` (tip points: lists ``r`` [m] and ``slew``
[rad, or '30deg'], one ``z`` [m]), optional ``[options] both_directions`` (default true: every
pick-up → drop move and its way back) and ``[obstacles.NAME]`` tables
(:func:`planner.geometry.obstacles.from_dict`). A malformed file fails with a
:class:`~planner.model.spec.SpecError` naming the file, the field and what was expected.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from planner.geometry.obstacles import from_dict as obstacle_from_dict
from planner.model.spec import SpecError
from planner.units import parse_angle
from problems import TASKS

__all__ = ["Move", "suite_path", "load_suite"]


@dataclass(frozen=True)
class Move:
    """One move of a suite: ``id`` (e.g. "p00-d01"), start and goal tips (r, z, slew)."""
    id: str
    start: tuple
    goal: tuple


def suite_path(name: str) -> Path:
    """The file of a shipped suite (by name) or a path to a .toml; KeyError naming the known
    suites otherwise."""
    p = Path(name)
    if p.suffix == ".toml" and p.exists():
        return p
    p = TASKS / f"{name}.toml"
    if not p.exists():
        known = ", ".join(sorted(x.stem for x in TASKS.glob("*.toml")))
        raise KeyError(f"unknown task suite '{name}'; known: {known} (or a path to a .toml)")
    return p


def load_suite(name: str) -> tuple[dict, list[Move]]:
    """(suite table, moves) of a task suite: every pick-up × every drop (and back). The suite
    table's ``obstacles`` holds the parsed obstacles (a tuple, possibly empty)."""
    path = suite_path(name)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise SpecError(str(path), "<toml>", None, f"not valid TOML: {e}") from None

    def points(key):
        t = data.get(key)
        if not isinstance(t, dict) or not {"r", "slew", "z"} <= set(t):
            raise SpecError(str(path), key, t, "expected a table with r (list), slew (list), z")
        try:
            rs = [float(r) for r in t["r"]]
            sl = [parse_angle(s) for s in t["slew"]]
            z = float(t["z"])
        except (TypeError, ValueError):
            raise SpecError(str(path), key, t, "r and slew must be lists of numbers "
                                               "(slew may be '30deg'), z a number") from None
        return [(r, z, s) for s in sl for r in rs]
    picks, drops = points("pickups"), points("drops")
    both = bool(data.get("options", {}).get("both_directions", True))
    moves = []
    for i, p in enumerate(picks):
        for j, d in enumerate(drops):
            moves.append(Move(f"p{i:02d}-d{j:02d}", p, d))
            if both:
                moves.append(Move(f"d{j:02d}-p{i:02d}", d, p))
    obstacles = []
    for name_, t in (data.get("obstacles") or {}).items():
        try:
            obstacles.append(obstacle_from_dict(t))
        except (ValueError, TypeError) as e:
            raise SpecError(str(path), f"obstacles.{name_}", t, str(e)) from None
    return dict(data.get("suite", {}), obstacles=tuple(obstacles)), moves


