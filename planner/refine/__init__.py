"""Feed-forward computed on the dynamic twin: the valve commands that make the twin follow a
planned trajectory and come to rest at its goal without ringing (issue 27).

The nominal feed-forward (:func:`planner.feedforward.commands`) inverts the quasi-static
valve model: it is exact for a machine without oil. On a real one the oil in the closed
chambers is a spring — a gravity-loaded cylinder whose holding pressure changes between start
and goal loses V·Δp/β of stroke, a motor traps its stopping pressure and rings on it at
0.7–3 Hz — so the nominal commands arrive off the goal and ring. Here the commands are
optimised on the twin (:mod:`planner.model.twin`) by single shooting:

* **Unknowns**: the valve commands on the control grid (``rate``, 50 Hz, held), over the move
  and a ``tail`` after it (the commands may go on acting while the modes settle: the move's
  end may lengthen by up to ``tail``, and by how much is reported), valves closed after that.
  Bounds |u| ≤ 1.
* **Cost**: the tip-weighted joint error ∫ w(t)·Σ_j ℓ_j²·(q_j − q_ref,j)² dt over the move, the
  tail and ``settle`` s with the valves closed (ℓ_j: the tip's lever of joint j at the reference's
  pose, m per rad | m, so the sum is close to the tip error squared; w = 1 during the move and
  ``end_weight`` after it: landing and calm count most), plus ``smooth``·Σ|u_{k+1} − u_k|²
  (no chatter at the control rate). The reference holds the goal after the plan's end, so
  any residual motion, offset or ringing is paid for.
* **Swing** (``swing_weight`` > 0, issue 29): on the twin that carries the load on its
  grapple link (:mod:`planner.model.twin.coupled`: the model's pendulum, driven by the twin's
  tip and pulling on it) the swing costs ``swing_weight``·∫ A²(t) dt after the plan's end
  (the tail and the settle window), A² the small-angle amplitude squared
  L²·(α² + β² + (α̇² + β̇²)/ω₀²) (:func:`planner.model.twin.pendulum.amplitude2`) — the swing's
  offset and rate, constant along a free swing — in the same mm²·s as the tip error: the
  refined commands end with the load at rest under the tip, not only the tip on its goal.
  The swing's states are the twin's, so the adjoint gives its gradient too.
* **Pump work** (``energy_weight`` > 0, mm²·s per kJ): the twin's hydraulic pump work
  ∫ p_s·Σ q_in dt over the record (:meth:`planner.model.twin.Twin.pump_power`: the meter-in
  flows are functions of the pressures and spools, so of states). Refined for tracking alone,
  energy entries pay for it: on Exudyn the 20 energy entries of ``refine_s100f-energy.md``
  used a median 1.06 × their nominal pump work, the drop → pick-up moves of one drop 2.4–3.4 ×
  (the twin agrees: d03-p01, 23 → 63 kJ at the shaft, the pump line at 7.0 MPa instead of
  3.4 on average — the plan's cheap lowering is not what the machine does when made to follow
  it). A weight trades that back against tracking (d03-p01 on the twin, weight 30: 45 kJ,
  ringing 2.5 → 5.2 mm, tip error during the move 17 → 24 mm; weight 300: 43 kJ, 78 mm): not
  a default.
* **Gradient**: exact, by the adjoint of the twin's compiled integrator
  (:class:`planner.model.twin.shooting.Shooting`): about six forward runs per gradient,
  whatever the number of commands.
* **Solver**: L-BFGS-B (scipy, a memory of 50 pairs) from the nominal commands, at most
  ``iterations`` iterations. With ``coarse_step`` (off by default) all but the last
  ``polish`` run on the twin at that step and the last ones on the twin at its own step from
  where the coarse ones ended (three s100f entries: 12–32 % less CPU, a higher final cost on
  two: at 4 ms the twin's Newton iteration fails more often, and the polish restarts the
  memory). Where L-BFGS-B stops early (its line search failed at a kink of the twin, or one
  step gained nothing), it is restarted from its best point with a fresh memory while the
  budget lasts (``restarts``, :mod:`planner.refine.solve`). A free command that is exactly 0
  starts at 10⁻⁶: a closed valve is a kink of the
  flow (|o|) whose adjoint slope is 0, so an idle joint's valve — one whose oil gives while
  the others move, a telescope that creeps off its stroke end — would otherwise never be used.
* **The optimisation twin** (``ls_ramp``): the machine's twin switches its load-sensing
  signal where a spool crosses ``OPEN_EPS`` or reverses, once per step, so its cost jumps on
  the finest scale and L-BFGS-B's line search stops against the jumps
  (:mod:`planner.model.twin.ode`; s100f p02-d00 ended ``ABNORMAL`` after 30 iterations on such
  an edge, the twin predicting 9.6 mm of ringing). The first stage optimises on the same twin
  with the signal ramped over openings up to ``ls_ramp`` (10⁻³ of the full opening: a crossing
  spool passes it in a few steps). Where the valves are nearly closed the two differ — a valve
  cracked below the ramp signals less than its pressure — and that is where the move comes to
  rest: on part 0 of the 400-entry s100f run the first stage left 4 energy entries 5.7–17.8 mm
  off their goal at rest (the machine's twin and Exudyn agreeing to 0.1 mm). So the calm stage
  runs on the machine's twin, and every prediction (the landing, the calm stage's trigger, the
  provenance) is the machine's twin's.
* **The calm stage** (``calm``): where the first stage leaves the twin predicting a rest
  offset or ringing above ``calm_below`` (2.5 mm, half the landing tolerance), a second
  L-BFGS-B from where it ended, on the machine's twin, with the end weighed ``calm_weight`` ×
  heavier and ``calm`` × ``iterations`` more iterations; kept when the twin predicts the move closer to
  landed (the larger of rest offset and ringing), and said so in ``predicted["calm"]``; the tip
  outside a landing tube of radius ``calm_below`` after the plan's end costs it steeply
  (``tube_weight``, :mod:`planner.refine.cost`). The
  first stage's weights trade ringing against the tip error during the move: on the s100f
  part-0 misses of ``refine_s100f-400-p0.md`` the twin (= Exudyn there, to < 1 mm) predicted
  5–26 mm of ringing at 20–100 mm of tip error during the move; from the nominal commands a
  5 × end weight alone calmed some (d00-p12 22.9 → 2.4 mm) and made others worse (d03-p09
  26 → 61 mm). Started from the first stage's result it keeps what that one found.
* **A given start** (``start``, ``library refine --start refined``): a move refined already —
  on the spec's twin, before the twin was calibrated — may start from those commands, where
  the new twin prices them below the nominal ones (``predicted["start"]``), with fewer
  iterations (40 against 150: 19 against 48 s CPU per entry, ``calibrate_loop_warm40.md``).
  A given start can lead the search into a valley the nominal commands' search avoids (a
  calibrated twin's time entry rang 9.4 mm from it, 2.0 mm from the nominal commands with
  150 iterations, 4.1 with 40); where the move is predicted above ``fallback_above``, the
  whole refinement runs again from the nominal commands with ``restart_iterations`` and the
  better is kept (``predicted["restart"]``; ``calibrate_loop_100.md``).
* **Dead bands**: the unknowns are the valve openings past each valve's dead band, not the
  commands; the commands sent are their dead-band inverse (:func:`past_deadband`), as a valve
  controller's dead-band compensation sends. In command units a valve inside its dead band is
  flat to the cost (zero slope, the dither's hair included), so an idle joint's valve was never
  used on a twin with dead bands: on the six machines of ``calibrate_loop.md`` the calibrated
  twin's own refined commands left a telescope held on its stroke end 5.9 mm crept off it
  (d01-p00, machine m2: 6.2 mm at the tip on the twin, 7.7 on Exudyn; the twin at the
  machine's true values 7.7, exactly as Exudyn). With no dead band nothing changes.
* **Valves the plan keeps closed** (``keep_closed``, off by default): a joint the plan holds
  still (its nominal commands all at most ``idle``, 0.1 % of the range: the NLP's creep is a
  few 10⁻⁶) keeps its valve closed until ``lead`` s before the tail. An open valve
  load-senses: refined freely, a telescope held on its stroke end, its valve cracked to stop
  it creeping, holds the load-sensing pump at its holding pressure through the whole move
  (s100f d03-p16:energy on the twin: pump line 10.1 MPa on average against 3.2 with the
  nominal commands; on Exudyn its pump work 3.5 × the plan's). Closed, its creep is put right
  in the tail. Measured on the twin, it is a trade, not a fix: d03-p16, pump work 1.10 × the
  nominal commands' (was 3.5 ×) but ringing 6.5 mm; d03-p01, 35 kJ against 54 (nominal 20),
  the tip error during the move 77 mm against 17.

* **Directions kept** (``keep_direction``): up to ``lead`` s before the tail, an opening keeps
  the sign of its nominal command wherever that opens past ``idle``, and a joint the plan
  moves one way only is never commanded the other way (:func:`command_bounds`). Refined
  freely, a lowered boom gets short raises to hold it on the plan, and each raise signals the
  boom's holding pressure to the load-sensing pump, which every other flow then pays (s100f
  d00-p16:energy on the twin: the pump line at 10.1 MPa on average against 3.7 with the
  nominal commands, the boom setting it half the time; with the directions kept 7.7 MPa).
  Alone it is no energy fix: on six s100f time entries whose refined commands cost Exudyn
  1.8–3.4 × their nominal pump work it cost more still on four (d03-p21 152 → 310 kJ), all
  six landing (``refine_t6-dir.md``): without a price the optimiser finds another valve to
  crack. Off by default; energy entries get it with their price (below). A joint held while
  others move may still open the other way by up to ``idle_reverse`` (0.05) in its idle rows:
  kept strictly one way, a jib held through the first 10 s of s100f d00-p00:energy drooped
  0.04 rad on its oil (compressed as the boom rose) and could not be put right before its
  own move, 208 mm off the plan on Exudyn; ten of the 50 energy entries of part 0 were
  70–218 mm off during the move that way. On 16 energy entries (those ten and the six
  below), judged on Exudyn: with 0.05, the tip error during the move median 16 mm (was
  103 mm), 15 of 16 land, 34 % less pump work than their time entries in the median and over
  the sum and none costlier; fully free (1.0), 12 mm, 15 of 16, 34 % / 31 % and one 9 %
  costlier (``refine_ir0.05.md``, ``energy_refined_pairs_ir0.05.md``, ``…ir1.0…``).
* **Energy entries** (``energy_entries`` "priced", the default; :func:`for_objective`): a
  move planned for least energy is refined with ``keep_direction`` and its pump work in the
  cost, weighed ``energy_weight`` or :data:`ENERGY_ENTRY_WEIGHT` (30 mm²·s per kJ) — its
  plan's saving is what it is for. Measured on Exudyn (the spec's parameters) on the six
  energy entries of parts 0–1 of the 400-entry s100f run whose refined commands cost at
  least as much as their time entry's: refined plain they used 0.3–42 % *more* pump work
  than the time entry (d01-p07 243 kJ against 171); with the directions kept −21…+20 %;
  priced, 0.3–44 % *less* (d01-p07 95 kJ), 5 of 6 landing as before; the weight without the
  kept directions −3…34 % less (d01-p07 114 kJ, d03-p09 3 % more) with twice the ringing
  (median 2.3 mm against 1.0) (``benchmarks/results/energy_refined_pairs_en6-*.md``).
  ``"plain"`` refines them as time moves. **The landing first** (``fallback_above``, 4 mm):
  where the kept directions and the price leave the twin predicting a rest offset or ringing
  above that, the move is refined plain as well and the commands nearer to landed kept
  (``predicted["fallback"]`` says which): on part 0 of the 400-entry run 5 of 50 priced
  entries rang 5.1–7.3 mm or rested 27 mm off on the twin as on Exudyn, three of which the
  plain refinement lands. In a library, an energy entry that then costs the twin more pump
  work than its own time entry is refined again with a heavier price
  (:mod:`planner.library.refine_pairs`). **Time entries** are priced too, lighter
  (``time_entries``: :mod:`planner.refine.bounds`).

The pump's flow limit and its starvation, the spool lag and dead band, the joint ends are in
the twin, so the refined commands respect them as the twin sees them. The result carries its
provenance: the twin's fingerprint (machine, parameters, step), the iterations, the predicted
tracking, rest offset and ringing on the twin for the nominal and the refined commands (the
twin run in full, with its convergence substeps), the lengthening and the time spent. Whether
the refined commands land on a machine is for a plant to judge (:mod:`planner.library.refine`
and ``benchmarks/bench_refine.py`` replay them on Exudyn).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time
from dataclasses import asdict, dataclass, field, replace
from enum import Enum

import numpy as np

from planner.landing import landing_measures, tip_levers
from planner.model.valves import past_deadband
from planner.refine.bounds import start_openings
from planner.refine.bounds import (ENERGY_ENTRIES, ENERGY_ENTRY_WEIGHT, TIME_ENTRIES,
                                   TIME_ENTRY_WEIGHT, closed_valves, command_bounds,
                                   for_objective)
from planner.refine.cost import CommandCost
from planner.refine.measures import horizon as _horizon, keep_better, predict as _predict
from planner.refine.measures import score as _score
from planner.refine.solve import Solved, minimize_commands
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.model.twin import Twin

#: the swing term's weight where the grapple is known (``plan --feedforward twin``): a swing
#: amplitude costs a third of a tip error of its size after the plan's end (on two s100f
#: forwarder moves: the twin's swing left 0.3 mm, its tip's rest offset 0.1 mm)
SWING_WEIGHT = 10.0

__all__ = ["RefineOptions", "RefineStatus", "Refinement", "refine_commands", "landing_measures",
           "tip_levers", "refine_cycle", "after_move", "closed_valves", "command_bounds",
           "for_objective", "ENERGY_ENTRIES", "ENERGY_ENTRY_WEIGHT", "TIME_ENTRIES",
           "TIME_ENTRY_WEIGHT",
           "SWING_WEIGHT"]


@dataclass(frozen=True)
class RefineOptions:
    """How the commands are refined (see the module doc): ``iterations`` of L-BFGS-B at most,
    the ``tail`` [s] the commands may run past the plan, ``settle`` [s] recorded with the
    valves closed after that, ``end_weight`` on the error after the plan's end, ``smooth``
    [1/(command step)²] on the command's steps, the control ``rate`` [Hz], the twin's ``step``
    [s], ``rest_window`` [s] the end of the record whose mean is the rest point,
    ``swing_weight`` on the grapple's swing after the plan's end (0: no swing term),
    ``coarse_step`` [s] the twin's step for all but the last ``polish`` iterations (0, or
    not above ``step``: every iteration on the twin at ``step``), ``periods``: ``settle`` is
    lengthened to this many periods of the slowest oil-spring mode at the goal
    (:meth:`Twin.oil_spring_frequencies <planner.model.twin.Twin.oil_spring_frequencies>`)
    and ``tail`` to a quarter of that, where they are shorter (0: never) — the cost must see
    the ringing it is to calm: cat215b's swing rings at 0.22–0.30 Hz, a 2 s settle saw half a
    period of it; the forwarders' slowest modes (0.67 Hz and up) keep 2 s and 0.5 s.
    ``restarts``: L-BFGS-B restarted where it stops early (:mod:`planner.refine.solve`);
    the calm stage's iterations, ``calm`` × ``iterations`` (0: none), with the end weighed
    ``calm_weight`` × more,
    run where the first stage leaves the twin predicting a rest offset or ringing above
    ``calm_below`` [m], the calm stage's landing tube weighed ``tube_weight`` (0: none);
    ``ls_ramp``: the optimisation twin's load-sensing ramp (an opening; 0: optimise on the
    machine's twin itself); ``idle_reverse``: with ``keep_direction``, the largest opening a
    joint the plan moves one way may get the other way in its idle rows (a held joint putting
    its droop right; 0: none; it acts only with ``keep_direction``);
    ``fallback_above`` [m]: where a refinement that keeps directions, closes valves or prices
    the pump work leaves the twin predicting a rest offset or ringing above this, the move is
    refined without them as well and the commands nearer to landed kept (0: never) (module
    doc); ``restart_iterations``: a move refined from a given start and predicted off is
    refined again from the nominal commands with these (0: never; module doc)."""
    iterations: int = 150
    tail: float = 0.5
    settle: float = 2.0
    end_weight: float = 30.0
    smooth: float = 1e-3
    rate: float = 50.0
    step: float = 2e-3
    rest_window: float = 1.0
    swing_weight: float = 0.0
    coarse_step: float = 0.0
    polish: int = 40
    energy_weight: float = 0.0
    periods: float = 1.0
    keep_closed: bool = False
    keep_direction: bool = False
    idle_reverse: float = 0.05
    fallback_above: float = 4e-3
    energy_entries: str = "priced"
    time_entries: str = "priced"
    lead: float = 0.3
    idle: float = 1e-3
    restarts: bool = True
    calm: float = 0.7
    calm_weight: float = 5.0
    calm_below: float = 2.5e-3
    ls_ramp: float = 1e-3
    restart_iterations: int = 150
    tube_weight: float = 100.0

    def __post_init__(self):
        checks = (("iterations", self.iterations, 1, 10000), ("tail", self.tail, 0.0, 10.0),
                  ("settle", self.settle, 0.2, 60.0), ("end_weight", self.end_weight, 0.0, 1e6),
                  ("smooth", self.smooth, 0.0, 1e6), ("rate", self.rate, 1.0, 1000.0),
                  ("step", self.step, 1e-4, 0.01), ("rest_window", self.rest_window, 0.05, 10.0),
                  ("swing_weight", self.swing_weight, 0.0, 1e6),
                  ("coarse_step", self.coarse_step, 0.0, 0.01),
                  ("polish", self.polish, 0, 10000),
                  ("energy_weight", self.energy_weight, 0.0, 1e6),
                  ("periods", self.periods, 0.0, 10.0), ("lead", self.lead, 0.0, 10.0),
                  ("idle", self.idle, 0.0, 0.1), ("calm", self.calm, 0.0, 10.0),
                  ("calm_weight", self.calm_weight, 1.0, 1e4),
                  ("calm_below", self.calm_below, 0.0, 1.0),
                  ("ls_ramp", self.ls_ramp, 0.0, 0.1),
                  ("idle_reverse", self.idle_reverse, 0.0, 1.0),
                  ("fallback_above", self.fallback_above, 0.0, 1.0),
                  ("restart_iterations", self.restart_iterations, 0, 10000),
                  ("tube_weight", self.tube_weight, 0.0, 1e6))
        for name, v, lo, hi in checks:
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"refine option '{name}' = {v!r}; allowed: {lo:g} .. {hi:g}")
        for name, allowed in (("energy_entries", ENERGY_ENTRIES), ("time_entries", TIME_ENTRIES)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"refine option '{name}' = {getattr(self, name)!r}; "
                                 f"allowed: {', '.join(allowed)}")
        for name in ("keep_closed", "keep_direction", "restarts"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"refine option '{name}' = {getattr(self, name)!r}; allowed: "
                                 "True, False")
        if self.rest_window > self.settle:
            raise ValueError(f"refine option 'rest_window' = {self.rest_window!r}; allowed: at "
                             f"most settle = {self.settle:g} s")


class RefineStatus(str, Enum):
    """How a refinement ended: ``improved`` (the refined commands are better on the twin),
    ``unchanged`` (no better commands found: the nominal ones are kept), ``failed`` (the twin
    could not run the move; the reason says why)."""
    IMPROVED = "improved"
    UNCHANGED = "unchanged"
    FAILED = "failed"

    def __str__(self) -> str:
        return self.value


@dataclass
class Refinement:
    """Refined commands ``u`` (M, n) held from ``t_u`` (M,) (valves closed after the last),
    with ``status``, ``reason``, the L-BFGS-B ``iterations`` and cost ``evaluations``, the
    ``predicted`` twin measures {"nominal": …, "refined": …} (:func:`landing_measures`),
    ``lengthened_s`` (how far past the plan's end a command still opens a valve), the twin's
    ``model`` provenance (:meth:`planner.model.twin.Twin.provenance`), ``options`` and
    ``wall_s``."""
    t_u: np.ndarray
    u: np.ndarray
    status: RefineStatus
    reason: str = ""
    iterations: int = 0
    evaluations: int = 0
    predicted: dict = field(default_factory=dict)
    lengthened_s: float = 0.0
    model: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)
    wall_s: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status != RefineStatus.FAILED

    def info(self) -> dict:
        """Everything but the arrays, JSON-ready (the provenance stored with the commands)."""
        return dict(status=str(self.status), reason=self.reason, iterations=self.iterations,
                    evaluations=self.evaluations, predicted=self.predicted,
                    lengthened_s=self.lengthened_s, model=self.model, options=self.options,
                    wall_s=self.wall_s)


def refine_commands(crane: Crane, traj: Trajectory, t_u, u, *, twin: Twin | None = None,
                    options: RefineOptions | None = None, pendulum=None,
                    x0=None, start=None) -> Refinement:
    """Refine the commands ``u`` (M, n), held from ``t_u`` (M,) on the control grid of
    ``traj`` (the nominal feed-forward), on ``twin`` (default: the spec's, at the options'
    step) so that the twin follows ``traj`` and comes to rest at its goal (module doc);
    with the options' ``swing_weight`` > 0 the load at rest under the tip too, the load
    hanging on the twin's grapple link (the twin's ``pendulum``; default twin: one with
    ``pendulum`` — a :class:`~planner.model.pendulum.Pendulum` or a length [m] — else the
    spec's ``[dynamics.grapple]``). ``x0``: the twin's state to start from (default its rest
    state at the plan's start: holding pressures, the unloaded chambers at tank) — in a work
    cycle, the state the previous move leaves (:func:`planner.refine.cycle.refine_cycle`).
    ``start``: (t_s, u_s), commands to start the search from instead of the nominal ones (an
    earlier refinement of the move, on the twin before calibration; :func:`start_openings`),
    taken where this twin prices them below the nominal commands (``predicted["start"]``).
    Never raises for a move the twin cannot run: the status says so."""
    opts = options or RefineOptions()
    r = _refine_landing_first(crane, traj, t_u, u, twin, opts, pendulum, x0, start)
    given = r.predicted.get("start", {}).get("commands") == "given"
    if _off(r, opts) and start is not None and \
            opts.restart_iterations > (0 if given else opts.iterations):
        # a given start may lead into a valley the nominal commands' search avoids, or (priced
        # higher) leave that search with the warm start's fewer iterations (module doc): the
        # whole refinement again from the nominal commands, the better kept
        again = replace(opts, iterations=opts.restart_iterations)
        r = keep_better(r, _refine_landing_first(crane, traj, t_u, u, twin, again, pendulum,
                                                  x0, None), "restart", "nominal", opts)
    return r


def _off(r: Refinement, opts: RefineOptions) -> bool:
    return opts.fallback_above > 0 and r.ok and \
        _score(r.predicted["refined"]) > opts.fallback_above


def _refine_landing_first(crane: Crane, traj: Trajectory, t_u, u, twin, opts: RefineOptions,
                          pendulum, x0, start) -> Refinement:
    """One refinement, and where it keeps directions, closes valves or prices the pump work
    and is predicted off, the move refined without those as well, the better kept."""
    r = _refine_once(crane, traj, t_u, u, twin, opts, pendulum, x0, start)
    constrained = opts.keep_direction or opts.keep_closed or opts.energy_weight > 0
    if not (constrained and _off(r, opts)):
        return r
    # the landing first (module doc): the move refined without the constraints and the price
    plain = replace(opts, keep_direction=False, keep_closed=False, energy_weight=0.0)
    return keep_better(r, _refine_once(crane, traj, t_u, u, twin, plain, pendulum, x0, start),
                        "fallback", "plain", opts)


def _refine_once(crane: Crane, traj: Trajectory, t_u, u, twin, opts: RefineOptions,
                 pendulum, x0, start=None) -> Refinement:
    """One refinement with ``opts`` (:func:`refine_commands` without its fallback)."""
    from planner.model.twin import Twin
    from planner.model.twin.shooting import Shooting
    wall0 = time.perf_counter()
    t_u = np.asarray(t_u, float).ravel()
    u = np.atleast_2d(np.asarray(u, float))
    n = crane.n
    if u.shape != (t_u.size, n):
        raise ValueError(f"refine: commands have shape {u.shape}; expected ({t_u.size}, {n}) "
                         "(one row per command time, one column per joint)")
    dt = 1.0 / opts.rate
    if t_u.size < 2 or abs(t_u[0] - traj.t[0]) > 1e-9 or \
            np.max(np.abs(np.diff(t_u) - dt)) > 1e-6:
        raise ValueError(f"refine: commands are not on the {opts.rate:g} Hz grid from the "
                         f"plan's start t = {traj.t[0]:g} s")
    if twin is None:
        hang = pendulum if pendulum is not None else (True if opts.swing_weight > 0 else None)
        twin = Twin(crane, step=opts.step, grapple=hang)
    if opts.swing_weight > 0 and twin.pendulum is None:
        raise ValueError(f"refine option 'swing_weight' = {opts.swing_weight!r}; allowed: 0 "
                         "with a twin that has no grapple (Twin(..., grapple=LENGTH))")
    for what, h in (("twin step", twin.step), ("refine option 'coarse_step' =", opts.coarse_step)):
        R = int(round(dt / h)) if h > 0 else 1
        if h > 0 and abs(R * h - dt) > 1e-9 * dt:
            raise ValueError(f"refine: {what} {h:g} s does not divide the control period "
                             f"{dt:g} s")
    tail, settle, f_slow = _horizon(twin, traj, opts)
    Ku = t_u.size + int(round(tail * opts.rate))
    pend = twin.pendulum if opts.swing_weight > 0 else None

    def problem(tw, end_weight=None, ramp=opts.ls_ramp, tube=(0.0, 0.0)):
        sh = Shooting(tw.with_ls_ramp(ramp))
        R = int(round(dt / tw.step))
        K = sh.steps((Ku + 1) * R + int(round(settle / tw.step)))
        return CommandCost(sh, traj, Ku, R, K, opts, crane, pend, x0, end_weight, tube), K

    cost, K = problem(twin)
    db = cost.db
    # the openings the nominal commands ask for; a closed valve is a kink of the flow (|o|):
    # its derivative there is 0 to the adjoint, so a command that starts at exactly 0 (an idle
    # joint, the tail) would never move; a hair's opening gives it a slope (the optimiser
    # crosses zero where the other side pays) — start_openings cracks it
    lo, hi = command_bounds(u, Ku, opts)
    U0 = start_openings((t_u, u), traj.t[0], Ku, db, lo, hi, opts.rate)
    box = (lo.ravel(), hi.ravel())
    t_all = traj.t[0] + dt * np.arange(Ku)
    base = dict(model=twin.provenance(), options=asdict(opts))
    horizon = dict(tail_s=tail, settle_s=settle, slowest_mode_Hz=f_slow)
    nominal = _predict(crane, twin, traj, t_all, past_deadband(U0, db), K, opts, x0)
    if nominal is None:
        return Refinement(t_u, u, RefineStatus.FAILED, "the twin diverged on the nominal commands",
                          wall_s=time.perf_counter() - wall0, **base)
    J0, _ = cost(U0.ravel())
    cost.fail = 100.0 * J0 + 1.0
    z, fine, nit, evals = U0.ravel(), int(opts.iterations), 0, 0
    began = dict(commands="nominal")
    if start is not None:       # a given start (an earlier refinement), where it prices lower
        zs = start_openings(start, traj.t[0], Ku, db, lo, hi, opts.rate).ravel()
        Js, _ = cost(zs)
        began = dict(commands="given" if Js < J0 else "nominal (the given priced higher)",
                     cost=float(Js))
        z = zs if Js < J0 else z
    if opts.coarse_step > twin.step and opts.iterations > opts.polish:
        # most iterations on the twin at the coarse step (half the work per run; its tip
        # within ~1 mm of the fine twin's on planned moves), the last ``polish`` on the twin
        # itself, from where the coarse ones ended
        coarse, _ = problem(twin.at_step(opts.coarse_step))
        Jc0, _ = coarse(z)
        coarse.fail = 100.0 * Jc0 + 1.0
        r1 = minimize_commands(coarse, z, opts.iterations - opts.polish, None,
                               opts.restarts, box)
        nit, evals, fine = int(r1.nit), coarse.evaluations, int(opts.polish)
        if r1.fun < Jc0:
            z = np.clip(r1.x, -1.0, 1.0)
    if fine > 0:
        res = minimize_commands(cost, z, fine, None, opts.restarts, box)
        res.x = np.clip(res.x, -1.0, 1.0)
    else:
        res = Solved(z, cost(z)[0], 0, "coarse iterations only")
    nit += int(res.nit)
    evals += cost.evaluations
    U = past_deadband(res.x.reshape(Ku, n), db)
    refined = _predict(crane, twin, traj, t_all, U, K, opts, x0) if res.fun < J0 else None
    pred = dict(nominal=nominal, cost_nominal=float(J0), cost_refined=float(min(res.fun, J0)),
                horizon=horizon, start=began)
    if refined is None:
        why = ("no better commands on the twin" if res.fun >= J0 else
               "the twin diverged on the optimised commands")
        return Refinement(t_u, u, RefineStatus.UNCHANGED, why, nit, evals,
                          dict(pred, refined=nominal), 0.0,
                          wall_s=time.perf_counter() - wall0, **base)
    calm, restarts = None, int(getattr(res, "restarts", 0))
    if opts.calm > 0 and opts.calm_weight > 1.0 and _score(refined) > opts.calm_below:
        # the calm stage (module doc): from where the first ended, the end weighed heavier
        cost2, _ = problem(twin, opts.end_weight * opts.calm_weight, 0.0,
                           (opts.calm_below, opts.tube_weight))
        J2, _ = cost2(res.x)
        cost2.fail = 100.0 * J2 + 1.0
        r2 = minimize_commands(cost2, res.x, max(int(round(opts.calm * opts.iterations)), 1),
                               None, opts.restarts, box)
        x2 = np.clip(r2.x, -1.0, 1.0)
        U2 = past_deadband(x2.reshape(Ku, n), db)
        p2 = _predict(crane, twin, traj, t_all, U2, K, opts, x0) if r2.fun < J2 else None
        taken = p2 is not None and _score(p2) < _score(refined)
        calm = dict(iterations=int(r2.nit), restarts=int(r2.restarts), message=r2.message,
                    taken=bool(taken), first=refined, end_weight=opts.end_weight *
                    opts.calm_weight)
        nit, evals = nit + int(r2.nit), evals + cost2.evaluations
        if taken:
            U, refined, res = U2, p2, r2
    pred.update(calm=calm, restarts=restarts)
    # drop trailing rows that open no valve (inside every dead band)
    live = np.flatnonzero(np.any(np.abs(U) > db[None, :], axis=1))
    last = max(int(live[-1]) + 1 if live.size else 0, t_u.size)
    U = U[:last]
    lengthened = max(0.0, (last - t_u.size) * dt)
    return Refinement(t_all[:last], U, RefineStatus.IMPROVED, str(res.message), nit,
                      evals, dict(pred, refined=refined), lengthened,
                      wall_s=time.perf_counter() - wall0, **base)
