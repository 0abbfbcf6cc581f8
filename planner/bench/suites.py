"""The benchmark's task suites: a task file (planner/problems/tasks/<name>.toml, read by
:mod:`planner.tasks.suites`) plus its ``[bench]`` table, and per method its runner or why it
does not apply ("n/a"). Tip points are (r, z, slew) [m, m, rad] in the crane's frame 0.

| suite | machine | moves |
| --- | --- | --- |
| ``seed000-abc`` | cranab850 | A–B, B–C, A–C (seed 000, Tables 8.1/8.2), straight lines |
| ``seed002-hvd`` | s100f | seed 002's timed cycles h, v, d, 0.5 and 1 m/s per axis (cycles.py) |
| ``seed003-paths`` | umea-lab | seed 003's circle and parabola (α = −45°, see seed003_paths.md) |
| ``forwarder-cycle`` | s100f | a seeded sample of the shipped forwarder-cycle.toml; headboard |

The ``[bench]`` table of a task file (read here):

``description``
    the report's sentence on the suite; ``{sample}``, ``{total}`` and ``{seed}`` are replaced
    by the sample size, the number of moves in the file and the sampling seed.
``methods``
    the bench variants that run on the suite (:data:`planner.bench.methods.METHODS`); each must
    have a runner for the suite's kind (timed cycles, curved paths or point to point).
``default_reason`` and ``[bench.not_applicable]``
    why the other variants do not run ("n/a" in the report): a reason per variant name, the
    default for the rest. Registered methods outside the variants are matched by rule
    (:func:`planner.bench.runners.fit`), not listed here.
``profile_move``
    the move whose joint and stroke profiles are drawn: an id, ``"first"`` or ``"last"``.
``notes``
    sentences printed under the suite's heading.
``sample``
    true: run a seeded sample of :attr:`Settings.forwarder_moves` moves
    (``numpy.random.default_rng(Settings.seed)``) instead of all.
``path``
    ``"line"`` (default): path-following methods follow each move's own path or its straight
    line; ``"cylindrical"``: r, z and slew interpolated linearly, over the obstacles' via
    points (:meth:`planner.geometry.obstacles.Plate.vias`).
``[bench.dp]`` and ``[bench.dp_quick]`` (``--quick``)
    the DP grid: ``step`` [m] (stage spacing along the path) or ``axis_step`` [m] (stages of
    that length along the larger of |Δr|, |Δz|, seed 000's grid), ``tele_step`` [m] and
    ``window`` (telescope steps per stage).

Timed cycles keep the speeds in :attr:`Settings.cycle_speeds` (``--quick``: 1 m/s only).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from planner.bench.context import Settings
from planner.bench.methods import LAW_VARIANTS, applicability
from planner.geometry.paths import Curve, tip_to_xyz
from planner.model import Crane
from planner.model.spec import SpecError
from planner.tasks.suites import load_task_file

SUITE_NAMES = ("seed000-abc", "seed002-hvd", "seed003-paths", "forwarder-cycle")
PATHS = ("line", "cylindrical")


@dataclass
class Suite:
    """A machine, its moves, and per method a runner ``f(ctx, move) -> Outcome`` or an "n/a"
    reason (str). ``dp_kw(move)`` gives the DP grid; ``profile_move`` the move whose joint and
    stroke profiles are drawn; ``kind``: "p2p", "path" or "cycle"; ``path``: the ``[bench]
    path`` rule; ``laws``: the law variants (names without "law:") that run here."""
    name: str
    crane_id: str
    description: str
    kind: str
    moves: list
    methods: dict = field(default_factory=dict)
    dp_grid: dict = field(default_factory=dict)
    obstacles: tuple = ()
    profile_move: str = ""
    notes: list = field(default_factory=list)
    path: str = "line"
    laws: tuple = ()

    def dp_kw(self, move) -> dict:
        """The DP's grid keywords for ``move`` (``[bench.dp]``)."""
        g = dict(self.dp_grid)
        if "axis_step" in g:
            n = int(round(max(abs(move.goal[0] - move.start[0]),
                              abs(move.goal[1] - move.start[1])) / g.pop("axis_step")))
            g["stages"] = max(1, n)
        return g


def cylindrical_path(tips) -> Curve:
    """Tip path through ``tips`` (r, z, slew) interpolating r, z and slew linearly between them
    (how a slewing crane moves; the NLP's guesses and Plate.vias use the same interpolation)."""
    tips = np.asarray(tips, float)
    K = len(tips) - 1

    def p(u):
        u = np.asarray(u, float)
        k = np.clip(np.floor(u).astype(int), 0, K - 1)
        f = (u - k)[..., None]
        return tip_to_xyz(tips[k] + f * (tips[k + 1] - tips[k]))
    cv = Curve(p, 0.0, float(K))
    cv.name = "cylindrical"
    return cv


def _kind(moves, path: str) -> str:
    if any(m.cycle for m in moves):
        return "cycle"
    return "path" if path == "line" and any(m.path is not None for m in moves) else "p2p"


def _table(tf, key, expected):
    b = tf.tables["bench"]
    v = b.get(key)
    if not isinstance(v, dict) or not {"tele_step", "window"} <= set(v) or \
            len({"step", "axis_step"} & set(v)) != 1:
        raise SpecError(str(tf.path), f"bench.{key}", v, expected)
    return dict(v)


def build_suite(name: str, settings: Settings) -> Suite:
    """The bench suite of the task file ``name`` (a shipped suite or a path to a .toml with a
    ``[bench]`` table) under ``settings``."""
    tf = load_task_file(name)
    b = tf.tables.get("bench")
    f = str(tf.path)
    if not isinstance(b, dict):
        raise SpecError(f, "bench", b, "a [bench] table (see planner/bench/suites.py)")
    path = b.get("path", "line")
    if path not in PATHS:
        raise SpecError(f, "bench.path", path, f"one of {', '.join(PATHS)}")
    moves, total = list(tf.moves), len(tf.moves)
    if any(m.cycle for m in moves):
        moves = [m for m in moves if not m.cycle or m.cycle[1] in settings.cycle_speeds]
    k = len(moves)
    if b.get("sample"):
        k = min(settings.forwarder_moves, len(moves))
        pick = sorted(np.random.default_rng(settings.seed).choice(len(moves), k, replace=False))
        moves = [moves[int(i)] for i in pick]
    if path == "cylindrical":
        new = []
        for m in moves:
            a, g = np.asarray(m.start, float), np.asarray(m.goal, float)
            vias = [v for ob in tf.obstacles for v in ob.vias(a, g)]
            new.append(dataclasses.replace(m, path=cylindrical_path([a, *vias, g])))
        moves = new
    if not moves:
        raise SpecError(f, "moves", [], "at least one move for the bench's settings")
    prof = b.get("profile_move", "first")
    prof = moves[0].id if prof == "first" else moves[-1].id if prof == "last" else prof
    grid = _table(tf, "dp_quick" if settings.quick else "dp",
                  "a table with step or axis_step [m], tele_step [m], window") \
        if "dp" in b or "dp_quick" in b else {}
    suite = Suite(tf.id, tf.crane, str(b.get("description", tf.description)).format(
                      sample=k, total=total, seed=settings.seed), _kind(moves, path), moves,
                  dp_grid=grid, obstacles=tuple(tf.obstacles), profile_move=prof,
                  notes=list(b.get("notes", [])), path=path)
    listed = b.get("methods", [])
    if not isinstance(listed, list):
        raise SpecError(f, "bench.methods", listed, "a list of bench variant names")
    crane = Crane.from_id(tf.crane)
    suite.methods = applicability(suite, f, listed, dict(b.get("not_applicable", {})),
                                  str(b.get("default_reason", "not run on this suite")),
                                  tf.crane, bool(crane.spec.laws.max_lift), settings)
    suite.laws = tuple(m[4:] for m in LAW_VARIANTS if callable(suite.methods[m]))
    return suite


__all__ = ["SUITE_NAMES", "Suite", "build_suite", "cylindrical_path"]
