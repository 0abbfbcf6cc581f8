"""The benchmark's task suites: machines, moves, and which method runs on which suite.

A suite is a machine plus a list of :class:`BenchMove` and, for every method of
:data:`planner.bench.methods.METHODS`, either the runner used on it or the reason why the method
does not apply ("n/a"). Tip points are (r, z, slew) [m, m, rad] in the crane's frame 0.

| suite | machine | moves |
| --- | --- | --- |
| ``seed000-abc`` | cranab850 | A–B, B–C, A–C (seed 000, Tables 8.1/8.2), straight lines |
| ``seed002-hvd`` | s100f | seed 002's timed cycles h, v, d, 0.5 and 1 m/s per axis (cycles.py) |
| ``seed003-paths`` | umea-lab | seed 003's circle and parabola (α = −45°, see seed003_paths.md) |
| ``forwarder-cycle`` | s100f | a seeded sample of problems/tasks/forwarder-cycle.toml; headboard |
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from planner.bench import methods as bm
from planner.geometry.paths import Curve, Line, circle, parabola, tip_to_xyz

SUITE_NAMES = ("seed000-abc", "seed002-hvd", "seed003-paths", "forwarder-cycle")

SEED000_POINTS = dict(A=(1.5, 1.0, 0.0), B=(5.5, 1.0, 0.0), C=(5.5, -3.0, 0.0))
# seed 000, Table 8.1 (DP) and Table 8.2 (laws at 2.5 m/s) [s], moves A–B, B–C, A–C
SEED000_TIMES = {"dp:time": (1.15, 0.89, 1.18), "law:max_velocity": (1.6, 1.6, 2.28),
                 "law:max_lift": (1.7, 1.89, 2.81)}
# seed 002, Table 5.1 (v cycle, 1 m/s, conventional) [kJ]
SEED002_KJ = {("v", 1.0): {"law:jla": 454.0, "law:p_optimal": 351.0}}


@dataclass(frozen=True)
class BenchMove:
    """One move of a suite. ``path``: the tip path the path-following methods use (None: the
    straight line start → goal); ``cycle``: (name, per-axis speed [m/s]) of a timed seed-002
    cycle, whose clock fixes ``duration_s`` [s]; ``closed``: start = goal (no point-to-point
    lower bound)."""
    id: str
    start: tuple
    goal: tuple
    path: object = None
    cycle: tuple | None = None
    duration_s: float | None = None
    closed: bool = False

    def line_or_path(self):
        return self.path if self.path is not None else Line(self.start, self.goal)


@dataclass
class Suite:
    """A machine, its moves, and per method a runner ``f(ctx, move) -> Outcome`` or an "n/a"
    reason (str). ``dp_kw(move)`` gives the DP grid; ``profile_move`` the move whose joint and
    stroke profiles are drawn; ``kind``: "p2p", "path" or "cycle"."""
    name: str
    crane_id: str
    description: str
    kind: str
    moves: list
    methods: dict
    dp_kw: object = None
    obstacles: tuple = ()
    profile_move: str = ""
    notes: list = field(default_factory=list)


def _methods(crane_id, applicable: dict, default_reason: str) -> dict:
    """Every method of bm.METHODS: its runner if applicable, else the n/a reason."""
    from planner.model import Crane
    out = {m: applicable.get(m, default_reason) for m in bm.METHODS}
    if "law:max_lift" in applicable and not Crane.from_id(crane_id).spec.laws.max_lift:
        out["law:max_lift"] = (f"{crane_id} has no [laws] max_lift table: seed 000's "
                               "maximum-lifting-capacity circle is defined for the Cranab 850 only")
    return out


def _laws(*names):
    return {f"law:{n}": bm.law_runner(n) for n in names}


ALL_LAWS = ("least_norm", "max_velocity", "max_lift", "jla", "p_optimal")


# ------------------------------------------------------------------------------ seed 000
def seed000(settings: bm.Settings) -> Suite:
    pts = SEED000_POINTS
    moves = [BenchMove(f"{a}-{b}", pts[a], pts[b]) for a, b in ("AB", "BC", "AC")]

    def dp_kw(move):  # the seed's grid: Δ = 0.01 m along the larger axis, Δd3 = 0.01 m, q = 5
        n = int(round(max(abs(move.goal[0] - move.start[0]),
                          abs(move.goal[1] - move.start[1])) / 0.01))
        if settings.quick:
            return dict(stages=max(1, n // 2), tele_step=0.02, window=5)
        return dict(stages=n, tele_step=0.01, window=5)
    run = {**_laws(*ALL_LAWS), "ruckig": bm.ruckig, "dp:time": bm.dp_time, "topp:dp": bm.topp_dp,
           "topp:law": bm.topp_law, "nlp:time-free": bm.nlp_time_free,
           "nlp:time-free-kin": bm.nlp_time_free_kin, "nlp:time-free-acc": bm.nlp_time_free_acc,
           "nlp:time-path": bm.nlp_time_path, "nlp:energy-free": bm.nlp_energy_free,
           "nlp:kin-line": bm.nlp_kin_line}
    return Suite("seed000-abc", "cranab850",
                 "seed 000's moves A–B, B–C, A–C on the Cranab 850 (straight tip lines for the "
                 "path methods; laws at the seed's 2.5 m/s)", "p2p", moves,
                 _methods("cranab850", run, "energy methods on timed paths: seed-002 cycles only"),
                 dp_kw=dp_kw, profile_move="A-C")


# ------------------------------------------------------------------------------ seed 002
def seed002(settings: bm.Settings) -> Suite:
    from planner.tasks.cycles import CYCLES, cycle
    moves = []
    for name in CYCLES:
        for speed in settings.cycle_speeds:
            _, dur, secs = cycle(name, speed)
            moves.append(BenchMove(f"{name}@{speed:g}", tuple(secs[0].start), tuple(secs[-1].end),
                                   cycle=(name, speed), duration_s=dur))
    run = {**_laws(*ALL_LAWS), "dp:energy": bm.dp_energy_cycle,
           "dp:energy-pinned": bm.dp_energy_cycle_pinned, "topp:dp": bm.topp_dp_cycle,
           "nlp:energy-path": bm.nlp_energy_cycle}
    if settings.quick:
        run["nlp:energy-path"] = ("skipped with --quick (≈ 1 min per cycle: an energy NLP per "
                                  "section)")
    return Suite("seed002-hvd", "s100f",
                 "seed 002's timed cycles h, v, d on the s100f (conventional system), every "
                 "method on the cycle's straight sections and clock", "cycle", moves,
                 _methods("s100f", run, "timed cycle: the tip follows the cycle's sections on "
                                        "the seed's clock; minimum-time and free-path methods "
                                        "do not apply"),
                 profile_move=moves[-1].id,
                 notes=["The laws run the cycle with `follow_command` at 100 Hz from the assumed "
                        "start (planner/cycles.py START, START_TELE), as "
                        "benchmarks/seed002_table.py. Rests cost no pump energy (zero flow)."])


# ------------------------------------------------------------------------------ seed 003
def seed003(settings: bm.Settings) -> Suite:
    curves = {"circle": circle((3.0, 0.0, 2.5), 0.7, -math.pi, math.pi),
              "parabola": parabola(1.6, 3.07, 1.5, 3.0, -math.pi / 4)}
    moves = []
    for name, cv in curves.items():
        a, b = cv.tip(np.array([0.0, cv.length]))
        moves.append(BenchMove(name, tuple(a), tuple(b), path=cv,
                               closed=bool(np.allclose(a, b, atol=1e-9))))

    def dp_kw(move):  # a fine telescope grid against coarse stages (see the module doc)
        return (dict(step=0.1, tele_step=0.01, window=30) if settings.quick
                else dict(step=0.05, tele_step=0.005, window=40))
    run = {**_laws(*ALL_LAWS), "dp:time": bm.dp_time, "topp:dp": bm.topp_dp,
           "topp:law": bm.topp_law, "nlp:time-path": bm.nlp_time_path}
    meths = _methods("umea-lab", run, "path suite: the tip must stay on the circle / parabola; "
                                      "free-path and straight-line methods leave it")
    return Suite("seed003-paths", "umea-lab",
                 "seed 003's circle (θ ∈ [−π, π], closed) and parabola (α = −45° instead of the "
                 "unreachable −60°) on the umea-lab crane, tip on the path", "path", moves, meths,
                 dp_kw=dp_kw, profile_move="parabola",
                 notes=["DP grid: 0.05 m stages with a 0.005 m telescope grid and a 40-step "
                        "window; at the seed-000 grid (0.01 m / 0.01 m / 5) the telescope's "
                        "quantisation makes the DP 66 % slower on the circle (7.09 s vs 4.26 s)."])


# ------------------------------------------------------------------------------ forwarder
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


def forwarder(settings: bm.Settings) -> Suite:
    from planner.tasks.suites import load_suite
    meta, all_moves = load_suite("forwarder-cycle")
    obstacles = meta["obstacles"]
    k = min(settings.forwarder_moves, len(all_moves))
    pick = sorted(np.random.default_rng(settings.seed).choice(len(all_moves), k, replace=False))
    moves = []
    for i in pick:
        m = all_moves[int(i)]
        a, b = np.asarray(m.start, float), np.asarray(m.goal, float)
        vias = [v for ob in obstacles for v in ob.vias(a, b)]
        moves.append(BenchMove(m.id, m.start, m.goal, path=cylindrical_path([a, *vias, b])))

    def dp_kw(move):
        return (dict(step=0.05, tele_step=0.02, window=10) if settings.quick
                else dict(step=0.02, tele_step=0.01, window=10))
    run = {**_laws(*ALL_LAWS), "ruckig": bm.ruckig, "dp:time": bm.dp_time, "topp:dp": bm.topp_dp,
           "topp:law": bm.topp_law, "nlp:time-free": bm.nlp_time_free,
           "nlp:energy-free": bm.nlp_energy_free}
    meths = _methods("s100f", run, "not run on this suite")
    meths["nlp:time-path"] = ("the path (r, z, slew interpolated over the headboard) has no "
                              "symbolic face for MoveNLP's path mode")
    meths["nlp:time-free-kin"] = "seed-000 setting only (velocity limits as the laws)"
    meths["nlp:time-free-acc"] = "seed-000 comparison with topp:law only"
    meths["nlp:kin-line"] = "the straight Cartesian line passes near the slew axis: not used here"
    for m in ("dp:energy", "dp:energy-pinned", "nlp:energy-path"):
        meths[m] = "energy methods on timed paths: seed-002 cycles only"
    return Suite("forwarder-cycle", "s100f",
                 f"{k} of the {len(all_moves)} forwarder-cycle moves (seeded sample, seed "
                 f"{settings.seed}) on the s100f; the tip keeps clear of the headboard "
                 "(checked at 1 kHz for every method)", "p2p", moves, meths, dp_kw=dp_kw,
                 obstacles=tuple(obstacles), profile_move=moves[0].id,
                 notes=["Path methods (laws, DP, TOPP-RA) follow r, z and slew interpolated "
                        "linearly, over a via point above the headboard where the move meets it "
                        "(planner.geometry.obstacles.Plate.vias); free-path methods choose their own."])


BUILDERS = {"seed000-abc": seed000, "seed002-hvd": seed002, "seed003-paths": seed003,
            "forwarder-cycle": forwarder}


def build_suite(name: str, settings: bm.Settings) -> Suite:
    if name not in BUILDERS:
        raise KeyError(f"unknown suite {name!r}; known suites: {', '.join(SUITE_NAMES)}")
    return BUILDERS[name](settings)
