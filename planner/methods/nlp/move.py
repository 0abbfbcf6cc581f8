"""MoveNLP: a point-to-point move as one CasADi NLP (IPOPT or FATROP), built once and solved
many times.

Transcription: N intervals of equal length h = T/N; every joint is a triple integrator with
piecewise-constant jerk, integrated exactly (q, q̇, q̈ at the nodes), so acceleration and jerk
limits hold everywhere by construction; velocity, position, the pump flow and (path mode) the
tip path are imposed at the nodes and the interval midpoints, the velocity with each
interval's own jerk bound and the pump as one smooth conservative inequality per check point
(minimum time: no slack variables), both in :mod:`planner.methods.nlp.limits` (the curve mode,
fragile under IPOPT, keeps the earlier uniform velocity tightening and the flow slacks); the 0.5 %
default pump margin covers the flow's nonlinearity in q between check points (IPOPT gets the
Lagrangian's Hessian through the nodes' stroke Jacobians: :mod:`planner.methods.nlp.hessian`,
the same matrix for less work). Ends: tip
positions (the redundancy is free at both ends) or joint configurations, at rest (q̇ = q̈ = 0).
The duration is a state copied per node (chained equal), so every row lies inside one interval:
the stage structure FATROP exploits (:mod:`planner.methods.nlp.stagewise`; ``solver="auto"``
uses it for minimum time without the pump, where it was measured faster, IPOPT elsewhere).

Energy (load sensing) without max/abs: flow slacks per check point and actuator split by
direction (s⁺ piston side extending, s⁻
annulus retracting, as fractions of Q_max); per node a pump-pressure variable p [MPa] ≥ standby
with p ≥ margin + p_meter-in for every function marked active at that node — the activity mask
is an NLP parameter (inactive ones relaxed by a big M, so all constraints are smooth), taken
from the warm start, then from each solution, re-solving warm until it settles (≤ 4 rounds;
functions once active stay so). Power p·Q/η, trapezoid rule. Measured: 0.9–1.4 s and ~150
IPOPT iterations per energy solve; earlier complementarity products (p − p_i)·s_i ≥ 0 took
500–950 iterations. The result is judged by :func:`~planner.trajectory.evaluate`. The variable,
constraint and parameter layout is kept by :class:`~planner.methods.nlp.transcription.Layout`.

Objectives: "time" (free T), "energy" (T ≤ T_max given), "blend" (T + λ·E). Paths: "free" or
"line" (tip on the straight line between the ends at every node). Obstacles
(:mod:`planner.geometry.obstacles`: a :class:`Wall` in the r–z plane, a :class:`Plate` such as a
forwarder's headboard) are kept clear at the check points; every free-path solution is then
verified on a 1 kHz resampling, from the plain guess and from a guess over the obstacles the move
meets, and the fastest one that clears is kept, else status "obstacle" (the over-the-wall guess
matters: a 4.56 s move at N = 60 came out as a 20.8 s detour at N = 40 from a poor guess).
Minimum time on a free path is never slower than the jerk-limited Ruckig rest-to-rest move the
guess comes from when that move is feasible (pump, obstacles): equal intervals cannot place a
long move's jerk switches exactly (measured: up to 2.5 % lost at N = 40 on slew-dominated
forwarder moves), so the exact move is returned when faster (``stats["winner"] == "ruckig"``);
when it is feasible and lasts the lower bound itself, the NLP is not solved at all
(``stats["certified"]``, :mod:`planner.methods.nlp.exact`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time as _time
from functools import partial

import casadi as ca
import numpy as np

from planner.bounds import lower_bound
from planner.geometry.paths import tip_to_xyz, xyz_to_tip
from planner.methods.base import PlanStatus
from planner.methods.nlp.activity import Activity, mask_size
from planner.methods.nlp.cache import build_or_load
from planner.methods.nlp.exact import (ExactMove, certified, certifying_bound, exact_move,
                                       exact_result)
from planner.methods.nlp.guess import Guesses, over_obstacles_guess, vias
from planner.methods.nlp.hessian import lagrangian_hessian
from planner.methods.nlp.limits import (add_relief_rows, add_velocity_limits, relief_limit,
                                        step)
from planner.methods.nlp.pump import PumpRows
from planner.methods.nlp.stagewise import SOLVERS, stagewise_solver
from planner.methods.nlp.tip import CHECKS, add_curve, add_line, add_obstacles
from planner.methods.nlp.transcription import STATUS_OK, Layout, ipopt_code, nlp_result
from planner.methods.nlp.twins import SolverTwins, warm_rounds
from planner.model.flows import actuator_table
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["MoveNLP", "IPOPT_DEFAULTS", "TIME_IPOPT"]

IPOPT_DEFAULTS = {"print_level": 0, "sb": "yes", "max_iter": 1000, "tol": 1e-7,
                  "acceptable_tol": 1e-5, "mu_strategy": "adaptive", "max_wall_time": 60.0}
#: IPOPT options added for minimum time on a free path: no residual check of the Newton step
#: (issue 31, 40 random moves per machine, the NLP always solved, interleaved: 0.92× the time
#: on umea-lab, 0.93× on s100f, 939/1315 instead of 903/1258 iterations in all, every solve
#: ok, the NLP's own durations within 1.3e-6)
TIME_IPOPT = {"fast_step_computation": "yes"}
BIG_T = 1e3  # [s] upper bound of the duration
AUTO_FATROP_ITER = 200   # FATROP's iteration limit under solver="auto" (then IPOPT)
# share of Q_max kept free at the check points (nodes, midpoints). Minimum time: 0.5 %. Least
# energy rides the pump limit for long stretches, and between the check points its draw rose
# 0.6-0.8 % above Q_max on forwarder moves (evaluate() at 1 kHz) — a solution that saves 40-55 %
# of the energy then failed the 0.1 % audit and the time-optimal move was kept: 2 %
PUMP_MARGIN = {"time": 0.005, "energy": 0.02, "blend": 0.02}
# minimum time with the pump under IPOPT: the Lagrangian's Hessian through the stroke
# Jacobians (planner.methods.nlp.hessian: the same matrix, ~30 % faster to evaluate on umea-lab)
LIFTED_HESSIAN = True


class MoveNLP:
    """One NLP structure for a crane; ``solve(start, goal, ...)`` many times.

    objective: "time" | "energy" | "blend"; path: "free" | "line" | a curve with a symbolic
    face (:func:`planner.geometry.paths.circle` / :func:`~planner.geometry.paths.parabola`);
    N intervals; ``solver``: "auto" | "ipopt" | "fatrop" (:data:`~planner.methods.nlp.stagewise.
    SOLVERS`). ``layout`` names the decision variables ("X" = [q; q̇; q̈] per node, "U" the
    jerk per interval, "T" the duration per node, energy objectives per check point the flow
    slacks "sp<k>"/"sm<k>" and the pump pressure "p<k>", curve mode "TH") and the constraint
    blocks. Its collaborators, each given what it needs: ``guesses``
    (:class:`~planner.methods.nlp.guess.Guesses`), ``activity`` (the load-sensing mask,
    :class:`~planner.methods.nlp.activity.Activity`), ``twins`` (the same formulation under
    other solver settings, :class:`~planner.methods.nlp.twins.SolverTwins`); the pump rows
    are written by :class:`~planner.methods.nlp.pump.PumpRows` while it is built.
    ``certify`` (default True): a free-path minimum-time solve returns the feasible exact
    Ruckig move without solving the NLP when that move attains the lower bound
    (:func:`~planner.methods.nlp.exact.certified`); False always solves the NLP (benchmarks
    timing the NLP itself)."""

    certify = True

    def __init__(self, crane: Crane, objective: str = "time", path: str = "free", N: int = 40,
                 pump: bool = True, reg: float = 1e-6, pump_margin: float | None = None,
                 obstacles: tuple = (), ipopt_options: dict | None = None,
                 cache: str | None = None, solver: str = "auto", relief: bool = False):
        if objective not in ("time", "energy", "blend"):
            raise ValueError(f"objective must be time, energy or blend, not {objective!r}")
        if pump_margin is None:
            pump_margin = PUMP_MARGIN[objective]
        self.curve = None
        if not isinstance(path, str):  # a Curve with a symbolic face: tip on p(θ)
            if getattr(path, "p_sym", None) is None:
                raise ValueError("a path object needs a symbolic face p_sym(θ) (see "
                                 "planner.geometry.paths.circle / parabola)")
            self.curve, path = path, "curve"
        elif path not in ("free", "line"):
            raise ValueError(f"path must be 'free', 'line' or a Curve, not {path!r}")
        self.crane, self.objective, self.path, self.N, self.pump = crane, objective, path, N, pump
        self.relief = bool(relief) and math.isfinite(relief_limit(crane.spec))
        self.obstacles = tuple(obstacles)
        self.L = crane.limit_arrays()
        self.acts = actuator_table(crane.spec)   # hydraulic constants (model.flows)
        fast = TIME_IPOPT if objective == "time" and path == "free" and not self.obstacles else {}
        ipopt = {**IPOPT_DEFAULTS, **fast, **(ipopt_options or {})}   # the caller's win
        t0 = _time.perf_counter()
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, not {solver!r}")
        # FATROP serves minimum time on a free path or the tip line ("auto": without the pump,
        # where it won; with the pump its solves had a failure tail, see SOLVERS)
        stagewise = objective == "time" and path != "curve"
        self.solver_name = ("fatrop" if stagewise and (solver == "fatrop" or (
            solver == "auto" and not pump)) else "ipopt")
        self.fallback = solver == "auto" and self.solver_name == "fatrop"
        if self.fallback:   # fail fast: its solves take ~20–40 iterations
            ipopt["max_iter"] = min(ipopt["max_iter"], AUTO_FATROP_ITER)
        self.twins = SolverTwins(
            partial(type(self), crane, objective, self.curve if self.curve is not None else path,
                    N=N, pump=pump, reg=reg, pump_margin=pump_margin, obstacles=obstacles,
                    ipopt_options=ipopt_options, cache=cache, relief=self.relief),
            objective, ipopt_options)
        formulation = dict(objective=objective, path=path, N=N, pump=pump, reg=reg,
                           pump_margin=pump_margin, obstacles=self.obstacles, ipopt=ipopt,
                           solver=self.solver_name, relief=self.relief)
        self.cache_status = build_or_load(
            self, "off" if path == "curve" else cache, formulation,
            lambda: self._build(reg, pump_margin, ipopt))
        self.built_s = _time.perf_counter() - t0
        self._last = None
        self.guesses = Guesses(crane, self.layout, self.lbw, self.ubw, N, path, self.curve)
        self.activity = Activity(crane, self.layout, self.acts)

    @property
    def build_time_s(self) -> float:
        """Seconds this NLP's build took (its own and its twins' built so far)."""
        return self.built_s + self.twins.build_time_s

    def _build(self, reg, pump_margin, ipopt):
        """Write the NLP's expressions and let CasADi derive its functions (the in-memory
        build; :mod:`planner.methods.nlp.cache` stores and reloads the result)."""
        crane, N, path, objective = self.crane, self.N, self.path, self.objective
        n, L = crane.n, self.L
        lay = self.layout = Layout()
        par = lay.parameters(start=3, goal=3, T_max=1, lam=1, payload=1,
                             activity=mask_size(n, self.acts, N))
        # ---- variables: node states, jerk per interval, duration (exact integration inside)
        jmax = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], 1e3)
        xlo = np.concatenate([L["q_min"], L["qd_min"], -L["qdd_max"]])
        xhi = np.concatenate([L["q_max"], L["qd_max"], L["qdd_max"]])
        X = lay.add_var("X", (3 * n, N + 1), np.tile(xlo[:, None], (1, N + 1)),
                        np.tile(xhi[:, None], (1, N + 1)), stage=0)
        U = lay.add_var("U", (n, N), np.tile(-jmax[:, None], (1, N)),
                        np.tile(jmax[:, None], (1, N)), stage=1)
        # the duration as one copy per node, chained equal (a state of every stage): each row
        # then involves one interval's variables only, as a stage-wise solver needs
        TT = lay.add_var("T", (1, N + 1), 1e-3, BIG_T, stage=0)
        T, hs = TT[0], [TT[k] / N for k in range(N + 1)]
        for k in range(N):
            lay.add_con("dynamics", X[:, k + 1] - ca.vertcat(*self._at(X, U, k, hs[k])), 0.0,
                        0.0, stage=(k, 0))
        for k in range(N):
            lay.add_con("duration_chain", TT[k + 1] - TT[k], 0.0, 0.0, stage=(k, 0))
        # ---- ends: the tips given, at rest
        fk = crane.f_fk
        lay.add_con("start", fk(X[:n, 0])[0] - par["start"], 0.0, 0.0, stage=(0, 1))
        lay.add_con("goal", fk(X[:n, N])[0] - par["goal"], 0.0, 0.0, stage=(N, 1))
        lay.add_con("start_at_rest", X[n:, 0], 0.0, 0.0, stage=(0, 1))
        lay.add_con("goal_at_rest", X[n:, N], 0.0, 0.0, stage=(N, 1))
        # ---- check points: nodes and interval midpoints (and each interval's end, in terms
        # of its own variables: the velocity rows stay inside one stage)
        pts = [(X[:n, k], X[n:2 * n, k], X[2 * n:, k]) for k in range(N + 1)]
        mids = [self._at(X, U, k, hs[k] / 2) for k in range(N)]
        ends = [self._at(X, U, k, hs[k]) for k in range(N)]
        if self.obstacles:
            # the joints at the interior obstacle check points as variables of their interval
            # (bounded by the position limits), tied to its motion by equality rows: the
            # second derivatives of the tip then involve those n joints, not the 4n + 1
            # variables the interpolated joints depend on (the obstacle rows were 587k of the
            # minimum-time Hessian's 688k instructions on the forwarder's headboard)
            c = len(CHECKS)
            QC = lay.add_var("QC", (c * n, N), np.tile(L["q_min"], c)[:, None] + np.zeros(N),
                             np.tile(L["q_max"], c)[:, None] + np.zeros(N), stage=1)
            for k in range(N):
                for j, f in enumerate(CHECKS):
                    lay.add_con("check_joints", QC[j * n:(j + 1) * n, k]
                                - self._at(X, U, k, f * hs[k])[0], 0.0, 0.0, stage=(k, 1))
        else:
            for k, (q, _, _) in enumerate(mids):
                lay.add_con("position", q, L["q_min"], L["q_max"], stage=(k, 1))
        # the per-interval jerk bound (exact at a cruise) stalls IPOPT where the problem is
        # already hard: the curve mode (seed 003's circle at max_iter), obstacles (forwarder
        # moves over the headboard: 300-800 iterations instead of 34-60, same durations) and
        # the tip line (seed 002's v-cycle preliminary section: max_iter, uniform 38 it.)
        add_velocity_limits(lay, L, jmax, pts, mids, ends, U, hs,
                            uniform=path != "free" or bool(self.obstacles))
        if self.obstacles:
            add_obstacles(lay, crane.f_fk, self.obstacles,
                          [(k, c) for k in range(N + 1) for c in
                           ([pts[k]] + ([(QC[j * n:(j + 1) * n, k], None, None)
                                         for j in range(len(CHECKS))] if k < N else []))])
        TH = add_curve(lay, crane.f_fk, self.curve, X, n, N) if path == "curve" else None
        if path == "line":
            add_line(lay, crane.f_fk, pts, par["start"], par["goal"])
        pump_rows = PumpRows(crane, self.acts, N, objective, path, self.pump, pump_margin,
                             stagewise=self.solver_name == "fatrop")
        lifted = {}
        energy = pump_rows.add(lay, pts, mids, hs[0], par["payload"], par["activity"], lifted)
        if self.relief:
            add_relief_rows(lay, crane, self.acts, pts, par["payload"])
        # ---- objective. ε·∫j² dt: joints that do not decide the time would otherwise be free
        # (a flat, non-unique optimum where IPOPT stalls); ε = 1e-6 moves T by ~1e-5 relative
        smooth = reg * sum(hs[k] * ca.sumsqr(U[:, k]) for k in range(N))
        if objective == "time":
            f = T + smooth
        elif objective == "energy":
            lay.add_con("duration", T - par["T_max"], -ca.inf, 0.0)
            f = energy * 1e-5 + smooth
        else:
            f = T + par["lam"] * energy + smooth
        if TH is not None:
            u0, u1 = self.curve.u_range
            lay.add_var("TH", TH, min(u0, u1), max(u0, u1))  # last block: θ per node
        wv = lay.w
        self.energy_fn = ca.Function("E", [wv, lay.P], [energy])
        self.lbw, self.ubw, self.lbg, self.ubg = lay.bounds()
        problem = {"x": wv, "p": lay.P, "f": f, "g": lay.g}
        self.solver = None
        if self.solver_name == "fatrop":
            self.solver = stagewise_solver(problem, lay, self.lbg == self.ubg, ipopt)
        if self.solver is None:
            opts = {"expand": True, "print_time": False, "ipopt": ipopt}
            hess = (lagrangian_hessian(wv, lay.P, f, lay.g, **lifted)
                    if lifted and LIFTED_HESSIAN else None)
            if hess is not None:   # the same Hessian, cheaper (nlp.hessian)
                opts["hess_lag"] = hess
            self.solver = ca.nlpsol("move", "ipopt", problem, opts)
        self.nw = lay.nw

    @property
    def _nx(self) -> int:
        """Number of node-state variables (kept for benchmarks/bench_scaling.py: the jerks
        start here; prefer ``layout.slice("U")``)."""
        return self.layout.slice("U").start

    # ------------------------------------------------------------------------ collaborators
    def guess_from(self, traj) -> np.ndarray:
        """Primal guess from any Trajectory (:meth:`Guesses.guess_from
        <planner.methods.nlp.guess.Guesses.guess_from>`)."""
        return self.guesses.guess_from(traj)

    def default_guess(self, start, goal, q_ends=(None, None)):
        """(primal guess, lower bound) of a move (:meth:`Guesses.default_guess
        <planner.methods.nlp.guess.Guesses.default_guess>`)."""
        return self.guesses.default_guess(start, goal, q_ends)

    def build_twins(self) -> float:
        """Build now the twins this NLP's solves will use (:meth:`SolverTwins.build
        <planner.methods.nlp.twins.SolverTwins.build>`). Returns seconds."""
        return self.twins.build()

    def _name(self, solver) -> str:
        """How an error names ``solver``: this NLP's own solver, or the IPOPT twin."""
        return self.solver_name.upper() if solver is self.solver else "IPOPT"

    # ------------------------------------------------------------------------ formulation
    def _at(self, X, U, k, hh):
        """(q, q̇, q̈) at time hh into interval k (exact under its constant jerk)."""
        n = self.crane.n
        return step(X[:n, k], X[n:2 * n, k], X[2 * n:, k], U[:, k], hh)

    def _prefer_exact(self, res, exact, t0):
        """Minimum time, free path: the jerk-limited rest-to-rest move ``exact`` (an
        :class:`~planner.methods.nlp.exact.ExactMove`, or None) when it is feasible and faster
        than the NLP's result ``res``. N equal intervals cannot put the jerk switches of a
        long, one-joint-dominated move where they belong (up to about one interval is lost);
        Ruckig's switch times are exact."""
        if exact is None or exact.tr is None or (res.ok and not exact.faster_than(
                res.duration_s)) or not exact.feasible():
            return res
        return exact_result(exact.tr, res, t0, _time.perf_counter())

    # ------------------------------------------------------------------------ solve
    def solve(self, start=None, goal=None, *, T_max: float | None = None, lam: float = 0.0,
              payload: float | None = None, w0=None, q_start=None, q_goal=None):
        """Solve for tips ``start``/``goal`` (r, z, slew), or joint configurations
        ``q_start``/``q_goal`` [rad, m] (free path: the end joints fixed by their bounds, the
        tips follow). ``T_max`` [s] (energy), ``lam`` [s/J] (blend), ``w0`` a primal guess
        (default: :meth:`default_guess`). Returns a :class:`~planner.methods.base.PlanResult`."""
        t0 = _time.perf_counter()
        q_ends = (q_start, q_goal)
        if q_start is not None or q_goal is not None:
            if self.path != "free" or self.obstacles:
                raise ValueError("joint ends (q_start/q_goal) need path 'free' without obstacles")
            q_ends = tuple(None if q is None else self._joint_end(q, name)
                           for q, name in ((q_start, "q_start"), (q_goal, "q_goal")))
            start = self.crane.tip(q_ends[0]) if q_ends[0] is not None else start
            goal = self.crane.tip(q_ends[1]) if q_ends[1] is not None else goal
        if self.curve is not None and start is None:  # curve mode: the curve's ends
            ends = np.asarray(self.curve.p(np.array(self.curve.u_range)))
            start, goal = xyz_to_tip(ends[0]), xyz_to_tip(ends[1])
        if start is None or goal is None:
            raise ValueError("give start and goal tips (r, z, slew)")
        if self.objective == "energy" and T_max is None:
            raise ValueError("objective 'energy' needs T_max [s]")
        if w0 is None and self.obstacles and self.path == "free":
            return self._solve_among_obstacles(start, goal, T_max, lam, payload, t0)
        try:
            guess, lb = self.default_guess(start, goal, q_ends) if w0 is None else (w0, None)
        except ValueError as e:  # unreachable end
            return nlp_result(PlanStatus.UNREACHABLE, str(e),
                              solve_time_s=_time.perf_counter() - t0)
        exact = None
        if w0 is None and self.path == "free" and self._exact_applies(T_max, lam, payload):
            # its limit check only where it decides (ExactMove): the certificate first by
            # duration, then feasibility, then the fine bound; else after the NLP
            exact = ExactMove(self, exact_move(self, start, goal, lb, q_ends))
            if self.certify and certified(exact.tr, lb) and exact.feasible() and certified(
                    exact.tr, certifying_bound(self.crane, start, goal, q_ends)):  # nothing
                return exact_result(exact.tr, None, t0, _time.perf_counter())   # is faster
        res = self._solve_from(guess, start, goal, T_max, lam, payload, t0, q_ends)
        return self._prefer_exact(res, exact, t0)

    def _joint_end(self, q, name):
        """A joint end as an array inside the position limits, else ValueError naming it."""
        q = np.asarray(q, float).ravel()
        L = self.L
        if q.shape != (self.crane.n,) or np.any(q < L["q_min"]) or np.any(q > L["q_max"]):
            raise ValueError(f"{name} = {q.tolist()}: {self.crane.n} joint values within "
                             f"[{L['q_min'].tolist()}, {L['q_max'].tolist()}] expected")
        return q

    def _solve_among_obstacles(self, start, goal, T_max, lam, payload, t0):
        """Obstacle problems are multimodal: try the plain and (when the move meets an
        obstacle) the over-the-obstacle guess; keep the fastest solution that clears every
        obstacle on a fine resampling."""
        try:
            lb = lower_bound(self.crane, start, goal)
            guesses = [self.guesses.plain_guess(start, goal, lb)]
            if vias(self.obstacles, start, goal):
                guesses.append(self.guess_from(over_obstacles_guess(self.crane, self.obstacles,
                                                                    start, goal, lb)))
        except ValueError as e:
            return nlp_result(PlanStatus.UNREACHABLE, str(e),
                              solve_time_s=_time.perf_counter() - t0)
        exact = (ExactMove(self, exact_move(self, start, goal, lb))
                 if self._exact_applies(T_max, lam, payload) else None)
        if self.certify and exact is not None and certified(exact.tr, lb) and exact.feasible():
            return exact_result(exact.tr, None, t0, _time.perf_counter())
        res = [self._solve_from(g, start, goal, T_max, lam, payload, t0) for g in guesses]
        good = [r for r in res if r.ok and self.clears(r.trajectory)]
        if good:
            best = min(good, key=lambda r: r.duration_s)
        else:
            best = next((r for r in res if not r.ok), res[0])
            if best.ok:
                best = nlp_result(PlanStatus.OBSTACLE, "no solution clears every obstacle "
                                  "between the check points: raise N or the clearance",
                                  iterations=best.iterations)
        best = self._prefer_exact(best, exact, t0)
        best.solve_time_s = _time.perf_counter() - t0
        return best

    def _exact_applies(self, T_max, lam, payload) -> bool:
        return self.objective == "time" and T_max is None and lam == 0 and payload is None

    def clears(self, traj, rate: float = 1000.0) -> bool:
        """True when the tip keeps ≥ 0.96·clearance from every wall on a fine resampling."""
        t = traj.resample(rate)
        cyl = self.crane.tip(traj.sample(t)[0])
        xyz = tip_to_xyz(cyl)
        return all(ob.distance(xyz, cyl).min() >= 0.96 * ob.clearance for ob in self.obstacles)

    def _slowed_to(self, guess, T_max):
        """The guess slowed uniformly to the duration T_max (when longer than its own)."""
        lay, n = self.layout, self.crane.n
        T0 = guess[lay.slice("T")][0]
        if T_max <= T0:
            return guess
        k = T_max / T0
        g = guess.copy()
        X = lay.unpack(g, "X")
        X[n:2 * n] /= k
        X[2 * n:] /= k ** 2
        lay.pack(g, "X", X)
        g[lay.slice("U")] /= k ** 3
        lay.pack(g, "T", T_max)
        return g

    def _solve_from(self, guess, start, goal, T_max, lam, payload, t0, q_ends=(None, None)):
        crane, lay = self.crane, self.layout
        if T_max is not None and self.objective == "energy":
            guess = self._slowed_to(guess, T_max)  # start from the guess slowed to the budget
        m = crane.spec.payload.total if payload is None else payload
        pars = dict(start=tip_to_xyz(np.asarray(start, float)),
                    goal=tip_to_xyz(np.asarray(goal, float)),
                    T_max=T_max if T_max is not None else 0.0, lam=lam, payload=m)
        # the load-sensing mask enters the energy objectives only (minimum time: zeros)
        mask = (self.activity.mask(guess) if self.objective != "time" else
                np.zeros(mask_size(crane.n, self.acts, self.N)))
        lbw, ubw = self.lbw.copy(), self.ubw.copy()
        X0 = self.layout.slice("X").start
        for k, q in zip((0, self.N), q_ends):   # joint ends: fixed by their bounds
            if q is not None:
                i = X0 + 3 * crane.n * k
                lbw[i:i + crane.n] = ubw[i:i + crane.n] = q
        iters = 0
        for _round in range(4 if self.objective != "time" else 1):
            P = lay.param_vector(**pars, activity=mask)
            # FATROP takes no fixed end joints (it counts them as end equalities): IPOPT
            fixed = self.solver_name == "fatrop" and any(q is not None for q in q_ends)
            tries = (True,) if fixed else (False, True) if self.fallback else (False,)
            # later energy rounds: warm from the last solution and multipliers, cold if that fails
            attempts = ([(self.twins.warm, dict(lam_x0=sol["lam_x"], lam_g0=sol["lam_g"]))]
                        if _round and warm_rounds() else [])   # solvers built on first use
            attempts += [(self.twins.ipopt if twin else lambda: self.solver, {})
                         for twin in tries]
            if self.objective == "time":   # a failed minimum-time solve: IPOPT probing
                attempts.append((self.twins.probing, {}))
            for k, (get_solver, warm) in enumerate(attempts):
                solver = get_solver()
                try:
                    sol = solver(x0=guess, p=P, lbx=lbw, ubx=ubw, lbg=self.lbg, ubg=self.ubg,
                                 **warm)
                except RuntimeError as e:
                    if k + 1 < len(attempts):
                        continue
                    return nlp_result(PlanStatus.ERROR, f"{self._name(solver)} failed: {e}",
                                      solve_time_s=_time.perf_counter() - t0)
                st = solver.stats()
                iters += st.get("iter_count", 0)
                ist = st.get("return_status", "")
                if ist in STATUS_OK:
                    break
            w = np.array(sol["x"]).ravel()
            if ist not in STATUS_OK or self.objective == "time":
                break
            new = np.maximum(mask, self.activity.mask(w))   # keep functions once seen active
            if np.array_equal(new, mask) or self.activity.still_optimal(sol, mask, new):
                break
            mask, guess = new, w
        if ist not in STATUS_OK:
            return nlp_result(ipopt_code(ist), ist if ist.startswith("FATROP") else
                              f"IPOPT: {ist}", iterations=iters,
                              ipopt_status=ist, solve_time_s=_time.perf_counter() - t0)
        n, N = crane.n, self.N
        X, U = lay.unpack(w, "X"), lay.unpack(w, "U")
        T = float(w[lay.slice("T")][0])
        t = np.linspace(0.0, T, N + 1)
        h = T / N
        for k in range(N):  # re-integrate exactly: node states consistent with the jerks
            X[:n, k + 1], X[n:2 * n, k + 1], X[2 * n:, k + 1] = step(
                X[:n, k], X[n:2 * n, k], X[2 * n:, k], U[:, k], h)
        traj = Trajectory(t, X[:n].T, X[n:2 * n].T, X[2 * n:].T, joint_names=tuple(crane.names),
                          method="nlp", objective=self.objective,
                          limits=("position", "velocity", "acceleration", "jerk")
                          + (("pump_flow",) if self.pump else ())
                          + (("pressure",) if self.relief else ()),
                          meta=dict(N=N, path=self.path, ipopt_status=ist))
        self._last = w
        E = float(self.energy_fn(w, P)) if self.objective != "time" else float("nan")
        return nlp_result(PlanStatus.OK, trajectory=traj, duration_s=T, energy_model_J=E,
                          iterations=iters, ipopt_status=ist,
                          solver=self._name(solver).lower(),
                          solve_time_s=_time.perf_counter() - t0)
