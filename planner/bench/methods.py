"""The benchmark's method runners: one function ``f(ctx, move) -> Outcome`` per method.

A runner plans one move of a suite with one method and returns an :class:`Outcome`: status
"ok" with the trajectory pieces ``[(t0 [s], Trajectory)]`` (one piece for a move, one per
section for a timed seed-002 cycle), or a failure status with its reason. A runner may use
``evaluate()`` to choose among its own candidates (as ``energy_optimal`` does); the verdict comes
only from :mod:`planner.bench.run`, which evaluates every piece again. Each runner is
self-contained (``topp:dp`` runs its DP), so its wall time is the method's whole cost; only NLP
construction (once per crane and formulation, ``Ctx.nlp``) is excluded and reported separately.

Method names (:data:`METHODS`): ``law:NAME`` the seeds' local laws (:mod:`.methods.laws`,
:mod:`.methods.laws_energy`) along the suite's path at :attr:`Settings.law_speed`, or on a cycle's
clock (``follow_command``); ``ruckig`` jerk-limited rest-to-rest joint move; ``dp:time`` Bellman
minimum time along the path; ``dp:energy`` / ``dp:energy-pinned`` the energy DP along a cycle's
sections at the cycle's tip speed, telescope chained (first section free / pinned to the laws'
start); ``topp:dp`` TOPP-RA (velocity, acceleration, pump) on the DP's joint path;
``topp:law`` the same on every law's joint path, the fastest feasible one (the laws made
feasible under the spec's limits); ``nlp:time-free`` / ``nlp:time-path`` minimum-time MoveNLP,
free path / on the suite's line or curve; ``nlp:time-free-kin`` the same free-path NLP with the
seed-000 limit set (acceleration and jerk ×:attr:`Settings.kin_factor`, judged like the laws on
position, velocity and pump flow); ``nlp:time-free-acc`` the same without a jerk limit
(TOPP-RA's limit set, to compare with ``topp:law``); ``nlp:energy-free`` least pump energy within
:attr:`Settings.energy_budget` × the minimum time (``energy_optimal``); ``nlp:energy-path`` per
cycle section, the least pump energy on the line within the section's time, telescope chained;
``nlp:kin-line`` the velocity-only line NLP (``kinematic_line_nlp``, seed 000's model).
"""
from __future__ import annotations

import dataclasses
import time as _time
from contextlib import contextmanager
from dataclasses import dataclass, field

from planner.methods.laws import LAWS, follow, follow_command
from planner.methods.laws_energy import LAWS_ENERGY
from planner.geometry.paths import Line
from planner.trajectory import evaluate

METHODS = ("law:least_norm", "law:max_velocity", "law:max_lift", "law:jla", "law:p_optimal",
           "ruckig", "dp:time", "dp:energy", "dp:energy-pinned", "topp:dp", "topp:law",
           "nlp:time-free", "nlp:time-free-kin", "nlp:time-free-acc", "nlp:time-path",
           "nlp:energy-free", "nlp:energy-path", "nlp:kin-line")
BASE_KINDS = ("position", "velocity", "pump_flow")  # every method is judged on at least these


@dataclass(frozen=True)
class Settings:
    """Benchmark settings (SI). ``quick``: smaller grids, fewer moves, shorter IPOPT caps."""
    quick: bool = False
    law_speed: float = 2.5        # [m/s] commanded tip speed of the laws (seed 000 Table 8.2)
    law_rate: float = 100.0       # [Hz] control rate of the laws
    nlp_N: int = 40               # MoveNLP intervals (free path, line)
    curve_N: int = 60             # MoveNLP intervals on seed 003's curves (N = 40 fails there)
    nlp_wall_s: float = 60.0      # [s] IPOPT max_wall_time per solve
    energy_budget: float = 1.2    # nlp:energy-free: duration ≤ budget × minimum time
    cycle_N: int = 20             # energy NLP intervals per cycle section
    cycle_wall_s: float = 10.0    # [s] IPOPT cap per cycle section
    cycle_dp_step: float = 0.02   # [m] DP stage spacing on the cycles (seed002_table.py)
    cycle_dp_window: int = 3      # telescope grid steps per stage on the cycles
    kin_factor: float = 10.0      # nlp:time-free-kin: acceleration and jerk limits × this
    forwarder_moves: int = 8
    seed: int = 0
    cycle_speeds: tuple = (0.5, 1.0)

    @classmethod
    def make(cls, quick: bool = False) -> "Settings":
        if not quick:
            return cls()
        return cls(quick=True, nlp_N=30, nlp_wall_s=2.0, cycle_dp_step=0.04, forwarder_moves=2,
                   cycle_speeds=(1.0,))


@dataclass
class Outcome:
    status: str
    reason: str = ""
    pieces: list = field(default_factory=list)    # [(t0 [s], Trajectory)]
    notes: list = field(default_factory=list)
    info: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def _from(res, t0: float = 0.0, **info) -> Outcome:
    """Outcome of a method result with ``ok``, ``status``, ``reason``, ``trajectory``."""
    if not res.ok:
        return Outcome(res.status, res.reason or res.status)
    return Outcome("ok", pieces=[(t0, res.trajectory)], info=info)


class Ctx:
    """Per-suite context: the crane, settings, obstacles, the suite's DP grid and a cache of
    MoveNLP objects (built once; build times in ``build_s``)."""

    def __init__(self, crane, settings: Settings, suite):
        self.crane, self.settings, self.suite = crane, settings, suite
        self.obstacles = tuple(suite.obstacles)
        self.build_s: dict = {}
        self._nlp: dict = {}
        self._variants: dict = {}

    def variant(self, acc: float = 1.0, jerk: float = 1.0):
        """The crane with acceleration limits × ``acc`` and jerk limits × ``jerk`` (inf: no
        jerk limit), built once."""
        if (acc, jerk) not in self._variants:
            from planner.model import Crane
            s = self.crane.spec
            joints = tuple(dataclasses.replace(j, limits=dataclasses.replace(
                j.limits, qdd=j.limits.qdd * acc, qddd=j.limits.qddd * jerk)) for j in s.joints)
            self._variants[(acc, jerk)] = Crane(dataclasses.replace(s, joints=joints))
        return self._variants[(acc, jerk)]

    def kin_crane(self):
        """Acceleration and jerk limits × kin_factor (seed 000 gives none: its setting is
        velocity limits only)."""
        k = self.settings.kin_factor
        return self.variant(k, k)

    def nlp(self, objective, path, N, *, kin=False, acc=False, obstacles=True, wall=None,
            key=None):
        """The MoveNLP, built once: on the spec's limits, ``kin`` the seed-000 limit set
        (:meth:`kin_crane`), ``acc`` the spec's limits without jerk (TOPP-RA's limit set)."""
        from planner.methods.nlp import MoveNLP
        crane = self.kin_crane() if kin else self.variant(1.0, float("inf")) if acc else self.crane
        obs = self.obstacles if obstacles else ()
        wall = wall or self.settings.nlp_wall_s
        k = (objective, key or path, N, kin, acc, obs, wall)
        if k not in self._nlp:
            t0 = _time.perf_counter()
            self._nlp[k] = MoveNLP(crane, objective, path, N=N, obstacles=obs,
                                   ipopt_options={"max_wall_time": wall})
            label = f"{objective}/{key or path}/N={N}" + ("/kin" if kin else "/acc" if acc
                                                          else "")
            self.build_s[label] = _time.perf_counter() - t0
        return self._nlp[k]


# ------------------------------------------------------------------------------ local laws
def law_runner(name: str):
    """Runner of the law ``name``: along the move's path at law_speed, or on a cycle's clock."""
    cls = {**LAWS, **LAWS_ENERGY}[name]

    def run(ctx, move):
        s, crane = ctx.settings, ctx.crane
        if move.cycle:
            from planner.tasks.cycles import START, START_TELE, cycle
            cmd, dur, _ = cycle(*move.cycle)
            c = move.cycle[0]
            res = follow_command(crane, cls(), cmd, dur, q0=crane.ik(START[c], tele=START_TELE[c]),
                                 rate=s.law_rate)
        else:
            res = follow(crane, move.line_or_path(), cls(), s.law_speed, rate=s.law_rate)
        return _from(res, min_beta=res.min_beta, max_tracking_error_m=res.max_path_error_m)
    run.__name__ = f"law_{name}"
    return run


# ------------------------------------------------------------------------------ Ruckig, DP, TOPP
def ruckig(ctx, move):
    """Rest-to-rest joint move between the ends at the lower bound's best telescope values."""
    from planner.bounds import lower_bound
    from planner.methods.ruckig import rest_to_rest
    crane = ctx.crane
    lb = lower_bound(crane, move.start, move.goal)
    return _from(rest_to_rest(crane, crane.ik(move.start, lb.tele_start),
                              crane.ik(move.goal, lb.tele_goal)))


def _dp(ctx, move):
    from planner.methods.dp import dp
    return dp(ctx.crane, move.line_or_path(), **ctx.suite.dp_kw(move))


def dp_time(ctx, move):
    r = _dp(ctx, move)
    return _from(r, grid=r.grid)


def topp_dp(ctx, move):
    from planner.methods.topp import retime
    d = _dp(ctx, move)
    if not d.ok:
        return Outcome(d.status, f"DP: {d.reason}")
    return _from(retime(ctx.crane, d.path_q))


def topp_law(ctx, move):
    """Every local law's joint path made feasible under the spec's limits: TOPP-RA rest to rest
    (velocity, acceleration, pump) on each law's path; the fastest that evaluate() passes wins.
    ``info["per_law_s"]`` holds each law's retimed duration (or why it has none)."""
    from planner.methods.topp import retime
    names = [m[4:] for m in METHODS if m.startswith("law:") and callable(ctx.suite.methods[m])]
    best, per = None, {}
    for name in names:   # the laws this suite runs (max_lift needs the machine's table)
        r = law_runner(name)(ctx, move)
        if not r.ok:
            per[name] = f"law: {r.status}"
            continue
        t = retime(ctx.crane, r.pieces[0][1].q)
        if not t.ok:
            per[name] = f"TOPP-RA: {t.status}"
            continue
        tr = t.trajectory
        ev = evaluate(ctx.crane, tr, kinds=tuple(dict.fromkeys(tuple(tr.limits) + BASE_KINDS)))
        if ev.max_limit_violation > 1e-3:
            per[name] = f"exceeds limits by {100 * ev.max_limit_violation:.2f} %"
            continue
        per[name] = t.trajectory.duration
        if best is None or t.trajectory.duration < best[1].trajectory.duration:
            best = (name, t)
    if best is None:
        return Outcome("infeasible", "no law path could be retimed: " + "; ".join(
            f"{k}: {v}" for k, v in per.items()), info=dict(per_law_s=per))
    return _from(best[1], law=best[0], per_law_s=per)


# ------------------------------------------------------------------------------ NLPs
def _winner_note(res, out):
    if out.ok and res.stats.get("winner") == "ruckig":
        out.info["winner"] = "ruckig"
        out.notes.append("the exact jerk-limited Ruckig move: feasible and faster than the "
                         f"N-interval solution ({res.trajectory.meta.get('nlp')})")
    return out


def nlp_time_free(ctx, move):
    res = ctx.nlp("time", "free", ctx.settings.nlp_N).solve(move.start, move.goal)
    return _winner_note(res, _from(res))


def nlp_time_free_kin(ctx, move):
    res = ctx.nlp("time", "free", ctx.settings.nlp_N, kin=True).solve(move.start, move.goal)
    out = _winner_note(res, _from(res))
    if out.ok:  # judged against the real crane on the laws' limit set
        out.pieces[0][1].limits = BASE_KINDS
        out.notes.append(f"acceleration and jerk limits ×{ctx.settings.kin_factor:g} (seed 000 "
                         "is kinematic); judged on position, velocity and pump flow like the laws")
    return out


def nlp_time_free_acc(ctx, move):
    """The free-path minimum-time NLP without a jerk limit: TOPP-RA's limit set (velocity,
    acceleration, pump), to compare with ``topp:law`` on equal limits."""
    res = ctx.nlp("time", "free", ctx.settings.nlp_N, acc=True).solve(move.start, move.goal)
    out = _winner_note(res, _from(res))
    if out.ok:
        out.pieces[0][1].limits = ("position", "velocity", "acceleration", "pump_flow")
        out.notes.append("no jerk limit (TOPP-RA's limit set)")
    return out


def nlp_time_path(ctx, move):
    s = ctx.settings
    if move.path is None:
        nlp = ctx.nlp("time", "line", s.nlp_N)
        return _from(nlp.solve(move.start, move.goal))
    nlp = ctx.nlp("time", move.path, s.curve_N, key=f"curve:{move.id}")
    return _from(nlp.solve())


def nlp_energy_free(ctx, move):
    from planner.methods.nlp import energy_optimal
    s = ctx.settings
    rt = ctx.nlp("time", "free", s.nlp_N).solve(move.start, move.goal)
    if not rt.ok:
        return Outcome(rt.status, f"time-optimal NLP: {rt.reason}")
    res, info = energy_optimal(ctx.crane, move.start, move.goal, s.energy_budget * rt.duration_s,
                               time_result=rt, energy_nlp=ctx.nlp("energy", "free", s.nlp_N))
    return _from(res, winner=info.get("winner"), minimum_time_s=rt.duration_s)


def nlp_kin_line(ctx, move):
    from planner.methods.nlp import kinematic_line_nlp
    return _from(kinematic_line_nlp(ctx.crane, move.start, move.goal))


# ------------------------------------------------------------------------------ cycles
def _dp_tele_step(crane, path_speed, step, window):
    """Telescope grid so that ``window`` steps per stage reach the telescope's rate limit
    (≤ 0.02 m), as benchmarks/seed002_table.py."""
    vmax = float(crane.limit_arrays()["qd_max"][crane.chain.tele])
    return min(0.02, vmax * (step / path_speed) / window)


def _dp_chain(ctx, move, tele_start=None):
    """Energy DP on every section of the cycle at its tip speed, the telescope chained (one
    telescope grid for the whole cycle, so consecutive sections share their junction node).
    Returns (Outcome, list of the DP PlanResults)."""
    from planner.tasks.cycles import cycle, labels
    from planner.methods.dp import dp
    crane, s = ctx.crane, ctx.settings
    _, _, secs = cycle(*move.cycle)
    ts = min(_dp_tele_step(crane, x.path_speed, s.cycle_dp_step, s.cycle_dp_window)
             for x in secs)
    tele, pieces, notes, results = tele_start, [], [], []
    for k, (sec, lab) in enumerate(zip(secs, labels(move.cycle[0]))):
        kw = dict(objective="energy", tip_speed=sec.path_speed, step=s.cycle_dp_step,
                  tele_step=ts, window=s.cycle_dp_window, tele_start=tele)
        r = dp(crane, Line(sec.start, sec.end), **kw)
        if not r.ok:  # greedy chaining can dead-end on the pump limit: retry without it
            r2 = dp(crane, Line(sec.start, sec.end), pump=False, **kw)
            if r2.ok:
                notes.append(f"section {k + 1} ({lab}): pump limit dropped from the DP "
                             f"({r.reason}); judged on it all the same")
                r = r2
        if not r.ok:
            return Outcome(r.status, f"section {k + 1} ({lab}): {r.reason}"), results
        results.append(r)
        pieces.append((sec.t0, r.trajectory))
        tele = float(r.path_q[-1][crane.chain.tele])
    return Outcome("ok", pieces=pieces, notes=notes,
                   info=dict(tele_step_m=ts,
                             start_tele_m=float(results[0].path_q[0][crane.chain.tele]))), results


def dp_energy_cycle(ctx, move):
    return _dp_chain(ctx, move)[0]


def dp_energy_cycle_pinned(ctx, move):
    from planner.tasks.cycles import START_TELE
    return _dp_chain(ctx, move, tele_start=START_TELE[move.cycle[0]])[0]


def topp_dp_cycle(ctx, move):
    """The free-start energy DP's joint path of every section retimed by TOPP-RA to the
    section's duration (rest to rest; velocity, acceleration, pump)."""
    from planner.tasks.cycles import cycle
    from planner.methods.topp import retime
    out, results = _dp_chain(ctx, move)
    if not out.ok:
        return Outcome(out.status, f"DP: {out.reason}")
    _, _, secs = cycle(*move.cycle)
    pieces = []
    for k, (sec, r) in enumerate(zip(secs, results)):
        t = retime(ctx.crane, r.path_q, duration=sec.t1 - sec.t0)
        if not t.ok:
            return Outcome(t.status, f"section {k + 1}: {t.reason}")
        pieces.append((sec.t0, t.trajectory))
    return Outcome("ok", pieces=pieces)


@contextmanager
def _pinned(nlp, joint: int, value):
    """Pin ``joint`` at the first node of a MoveNLP to ``value`` through the solver's variable
    bounds while inside (None: leave it free). MoveNLP has no end-configuration argument; its
    variables start with X = [q; q̇; q̈] per node, column-major, so q_joint at node 0 is
    variable ``joint``. Callers check the pin on the result."""
    lo, hi = nlp.lbw[joint], nlp.ubw[joint]
    if value is not None:
        nlp.lbw[joint] = nlp.ubw[joint] = value
    try:
        yield
    finally:
        nlp.lbw[joint], nlp.ubw[joint] = lo, hi


def nlp_energy_cycle(ctx, move):
    """Per section, telescope chained as in dp:energy (the first section free): the
    minimum-time NLP on the line, stretched to the section's duration (a feasible incumbent),
    then the energy NLP warm-started from it; the lower judged energy within the limits is
    kept and its end telescope pins the next section's start."""
    from planner.tasks.cycles import cycle, labels
    from planner.methods.nlp import stretch
    crane, s = ctx.crane, ctx.settings
    ti = crane.chain.tele
    nt = ctx.nlp("time", "line", s.cycle_N, wall=s.cycle_wall_s)
    ne = ctx.nlp("energy", "line", s.cycle_N, wall=s.cycle_wall_s)
    _, _, secs = cycle(*move.cycle)
    pieces, winners, tele = [], [], None
    for k, (sec, lab) in enumerate(zip(secs, labels(move.cycle[0]))):
        T = sec.t1 - sec.t0
        with _pinned(nt, ti, tele):
            rt = nt.solve(sec.start, sec.end)
        if not rt.ok:
            return Outcome(rt.status, f"section {k + 1} ({lab}), time NLP: {rt.reason}")
        if rt.duration_s > T * (1 + 1e-9):
            return Outcome("infeasible", f"section {k + 1} ({lab}) needs {rt.duration_s:.2f} s "
                           f"rest to rest, the cycle gives {T:.2f} s")
        best = stretch(rt.trajectory, T)
        e_best = evaluate(crane, best).energy_J
        with _pinned(ne, ti, tele):
            re = ne.solve(sec.start, sec.end, T_max=T, w0=ne.guess_from(best))
        win = f"stretched ({re.status})"
        if re.ok:
            ev = evaluate(crane, re.trajectory)
            if ev.max_limit_violation <= 1e-3 and ev.energy_J < e_best:
                best, win = re.trajectory, "nlp"
        if tele is not None and abs(best.q[0, ti] - tele) > 1e-9:
            return Outcome("error", f"section {k + 1}: the telescope pin did not hold")
        pieces.append((sec.t0, best))
        winners.append(win)
        tele = float(best.q[-1, ti])
    return Outcome("ok", pieces=pieces, info=dict(section_winners=winners))


__all__ = ["METHODS", "BASE_KINDS", "Settings", "Outcome", "Ctx", "law_runner"]
