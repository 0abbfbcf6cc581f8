"""The benchmark's runners for seed 002's timed cycles: every section of a cycle (a straight
tip line with its own time slot, :mod:`planner.tasks.cycles`) planned in turn, the telescope
chained from one section to the next, the pieces placed on the cycle's clock.

``dp:energy`` / ``dp:energy-pinned``: the energy DP per section at the section's tip speed (the
first telescope free / pinned to the laws' start); ``topp:dp``: the free-start DP's joint path
of every section retimed by TOPP-RA to the section's time; ``nlp:energy-path``: per section the
minimum-time line NLP stretched to the section's time, then the energy NLP warm-started from
it. These runners call the methods' functions directly: a section's chained start telescope and
the cycle's shared telescope grid are settings a :class:`~planner.methods.base.PlanRequest`
does not carry.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from contextlib import contextmanager

from planner.bench.context import Outcome
from planner.geometry.paths import Line
from planner.methods.base import PlanStatus
from planner.methods.dp import dp
from planner.methods.nlp import stretch
from planner.methods.topp import retime
from planner.tasks.cycles import START_TELE, cycle, labels
from planner.trajectory import evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["dp_energy_cycle", "dp_energy_cycle_pinned", "topp_dp_cycle", "nlp_energy_cycle",
           "dp_chain"]


def _dp_tele_step(crane: Crane, path_speed, step, window):
    """Telescope grid so that ``window`` steps per stage reach the telescope's rate limit
    (≤ 0.02 m), as benchmarks/seed002_table.py."""
    vmax = float(crane.limit_arrays()["qd_max"][crane.chain.tele])
    return min(0.02, vmax * (step / path_speed) / window)


def dp_chain(ctx, move, tele_start=None):
    """Energy DP on every section of the cycle at its tip speed, the telescope chained (one
    telescope grid for the whole cycle, so consecutive sections share their junction node).
    Returns (Outcome, list of the DP PlanResults)."""
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
    return Outcome(PlanStatus.OK, pieces=pieces, notes=notes,
                   info=dict(tele_step_m=ts,
                             start_tele_m=float(results[0].path_q[0][crane.chain.tele]))), results


def dp_energy_cycle(ctx, move):
    return dp_chain(ctx, move)[0]


def dp_energy_cycle_pinned(ctx, move):
    return dp_chain(ctx, move, tele_start=START_TELE[move.cycle[0]])[0]


def topp_dp_cycle(ctx, move):
    """The free-start energy DP's joint path of every section retimed by TOPP-RA to the
    section's duration (rest to rest; velocity, acceleration, pump)."""
    out, results = dp_chain(ctx, move)
    if not out.ok:
        return Outcome(out.status, f"DP: {out.reason}")
    _, _, secs = cycle(*move.cycle)
    pieces = []
    for k, (sec, r) in enumerate(zip(secs, results)):
        t = retime(ctx.crane, r.path_q, duration=sec.t1 - sec.t0)
        if not t.ok:
            return Outcome(t.status, f"section {k + 1}: {t.reason}")
        pieces.append((sec.t0, t.trajectory))
    return Outcome(PlanStatus.OK, pieces=pieces)


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
            return Outcome(PlanStatus.INFEASIBLE, f"section {k + 1} ({lab}) needs "
                           f"{rt.duration_s:.2f} s rest to rest, the cycle gives {T:.2f} s")
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
            return Outcome(PlanStatus.ERROR, f"section {k + 1}: the telescope pin did not hold")
        pieces.append((sec.t0, best))
        winners.append(win)
        tele = float(best.q[-1, ti])
    return Outcome(PlanStatus.OK, pieces=pieces, info=dict(section_winners=winners))
