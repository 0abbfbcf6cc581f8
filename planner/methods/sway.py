"""``nlp-sway``: the minimum-time move whose hanging load arrives at rest under the tip.

The move NLP of :mod:`planner.methods.nlp.move` (N equal intervals, every joint a triple
integrator with piecewise-constant jerk integrated exactly, velocity and pump rows at the
nodes and midpoints — the same rows, from the same helpers) with the grapple pendulum of
:mod:`planner.model.pendulum` added: its four states (α, β, α̇, β̇) per node, integrated over
each interval by ``substeps`` RK4 steps of the model's ``swing_rhs`` driven by the tip's
Cartesian acceleration and the last link's turning (``tip_motion``'s drive, evaluated on the
interval's exact cubic), so the swing
is a function of the joint motion the NLP chooses. Constraints beyond the sway-blind move:

- the load hangs still at the start (all four states zero);
- at the goal (tip at rest) the free swing's small-angle amplitude
  L·√(α² + β² + (α̇² + β̇²)/ω₀²) ≤ ``swing_tol`` (default 10 mm): the residual swing;
- during the move the load's horizontal offset L·√(sin²α + sin²β) ≤ ``swing_max`` [m] at the
  nodes (an operator's limit: the request's option, else the spec's
  ``[dynamics.grapple] swing_max``; default none: only |α|, |β| ≤ 1 rad, where the model
  stays valid);
- obstacles: the tip's clearance at the nodes and midpoints (as the sway-blind NLP, and checked
  afterwards on a 1 kHz resampling at 0.96 × the clearance); with ``load_clearance`` the load's
  centre of mass (tip + link) keeps the clearance at the nodes and at the RK4 steps inside each
  interval (at least two per interval: the midpoints) — at :data:`LOAD_CLEARANCE_ROWS` × the
  clearance, so that the wall's discs leave the whole clearance between them — and the
  solution is checked on the same 1 kHz resampling at 1.0 × (the whole clearance, not the
  tip's 0.96 ×) with the swing the model predicts along it
  (:func:`~planner.methods.shaping.load_clearance_margin`; stat ``load_clearance_margin_m``);
- ``swing_robust`` r > 0: the same residual bound for two more pendulums at ω₀·(1 ± r) driven
  by the same tip (zero residual over a band of frequencies, as ZVD is to ZV): robust to a
  link length or load off from what was assumed, and a little to the plant not following the
  plan exactly.

The RK4 steps are at most ω₀·h = 0.4 rad (:data:`SUBSTEP_RAD`; ``substeps`` per interval from
the sway-blind plan's duration): one step per interval of a 10.9 s forwarder move (0.68 rad)
left 16 mm of the 10 asked for on the fine integration, two steps 10.1 mm. IPOPT runs with a
limited-memory Hessian (half the build, faster solves); with ``swing_robust`` or ``swing_max``
it reached its iteration limit so, and those use the exact one.

It is warm-started from the sway-blind ``nlp`` plan of the same move (same obstacles), with the
swing the model predicts along it; when IPOPT's limited-memory run does not converge from
there, from the same plan with IPOPT's exact Hessian (measured: the short drop → pick-up
moves, 3.7 s, reach the iteration limit without it and converge with it in ~110 iterations),
then from that plan shaped by ZVD (:mod:`planner.methods.shaping`: nearly sway-free
already, half a period longer) and last from the plan slowed by 15 %. The winner is judged again by
:func:`~planner.trajectory.evaluate` (1 kHz, the limits it plans with) and its swing by
:func:`~planner.model.pendulum.predict_swing` on a 200 Hz grid (stats ``swing_residual_m``,
``swing_peak_m``): the RK4 on the NLP's intervals is a discretisation, the fine integration
the model's verdict. Options: ``grapple`` / ``grapple_zeta`` (as the shapers), ``intervals``
(N, 40), ``swing_tol`` [m], ``swing_max`` [m], ``swing_robust``, ``load_clearance`` (bool). Each NLP is built once
per (machine, N, pendulum, tolerances, obstacles) in the process (no compiled cache).
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import replace
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from planner.geometry.paths import tip_to_xyz
from planner.methods.base import (Planner, PlanRequest, PlanResult, PlanStatus,
                                  UnsupportedRequest)
from planner.methods.nlp.guess import Guesses, stretch
from planner.methods.nlp.limits import add_velocity_limits, step
from planner.methods.nlp.pump import PumpRows
from planner.methods.nlp.tip import add_obstacles
from planner.methods.nlp.transcription import STATUS_OK, Layout, ipopt_code
from planner.methods.registry import plan as plan_with, register
from planner.methods.shaping import (clearance_margin, load_clearance_margin,
                                     pendulum_of_request, shape, shaper)
from planner.model.flows import actuator_table
from planner.model.pendulum import Pendulum, predict_swing, tip_motion
from planner.trajectory import Trajectory, evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["SwayNLP", "SwayPlanner", "SWING_TOL"]

SWING_TOL = 0.01          # [m] default residual swing amplitude at the goal
ANGLE_MAX = 1.0           # [rad] |α|, |β| bound (the model's validity, not a limit)
RATE_MAX = 5.0            # [rad/s] |α̇|, |β̇| bound
PUMP_MARGIN = 0.005       # as the minimum-time move NLP
#: IPOPT's settings; bounded by iterations, not by the clock, so that a plan does not depend
#: on how busy the machine is (a 60 s wall-clock limit failed 2 of 48 forwarder moves under
#: load and not on a quiet machine)
IPOPT = {"print_level": 0, "sb": "yes", "max_iter": 600, "tol": 1e-7, "acceptable_tol": 1e-5,
         "mu_strategy": "adaptive",
         "hessian_approximation": "limited-memory"}   # exact: 2× the build, no faster
SUBSTEP_RAD = 0.4         # the largest ω₀·h of one RK4 step of the swing in the NLP
#: the load's rows keep this × each obstacle's clearance, so that the load keeps the whole
#: clearance between the rows: a wall's discs, spaced half their radius, leave 0.968 × it
#: between two of them (planner.geometry.obstacles), and the 1 kHz check is at 1.0 ×
#: (measured 2026-11-27 on 48 forwarder moves with rows at 1.0 ×: the load came 10 mm inside
#: the 0.3 m headboard clearance, exactly the discs' gap)
LOAD_CLEARANCE_ROWS = 1.04
LIMITS = ("position", "velocity", "acceleration", "jerk", "pump_flow")


class SwayNLP:
    """The minimum-time move with the grapple pendulum (module doc), built once for
    ``crane``, ``pend`` (:class:`~planner.model.pendulum.Pendulum`), ``N`` intervals,
    ``obstacles``, ``swing_tol`` / ``swing_max`` [m], ``load_clearance``, ``substeps`` RK4
    steps per interval; :meth:`solve` many times."""

    def __init__(self, crane: Crane, pend: Pendulum, N: int = 40, obstacles=(),
                 swing_tol: float = SWING_TOL, swing_max: float | None = None,
                 load_clearance: bool = False, substeps: int = 1, reg: float = 1e-6,
                 robust: float = 0.0):
        t0 = _time.perf_counter()
        self.crane, self.pend, self.N = crane, pend, N
        self.obstacles = tuple(obstacles)
        self.swing_tol, self.swing_max, self.substeps = swing_tol, swing_max, substeps
        n, L = crane.n, crane.limit_arrays()
        self.L = L
        lay = self.layout = Layout()
        par = lay.parameters(start=3, goal=3, payload=1, activity=1)
        jmax = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], 1e3)
        xlo = np.concatenate([L["q_min"], L["qd_min"], -L["qdd_max"]])
        xhi = np.concatenate([L["q_max"], L["qd_max"], L["qdd_max"]])
        X = lay.add_var("X", (3 * n, N + 1), np.tile(xlo[:, None], (1, N + 1)),
                        np.tile(xhi[:, None], (1, N + 1)))
        U = lay.add_var("U", (n, N), np.tile(-jmax[:, None], (1, N)),
                        np.tile(jmax[:, None], (1, N)))
        TT = lay.add_var("T", (1, N + 1), 1e-3, 1e3)
        slo = np.array([-ANGLE_MAX, -ANGLE_MAX, -RATE_MAX, -RATE_MAX])
        # the pendulum, then (robust > 0) the same at ω₀·(1 ± robust): gravity scaled by
        # (1 ± robust)², which scales every small-angle frequency exactly so
        self.pends = [pend] + [replace(pend, gravity=pend.gravity * (1 + s) ** 2)
                               for s in ((-robust, robust) if robust > 0 else ())]
        P = len(self.pends)
        S = lay.add_var("S", (4 * P, N + 1), np.tile(np.tile(slo, P)[:, None], (1, N + 1)),
                        np.tile(-np.tile(slo, P)[:, None], (1, N + 1)))
        T, hs = TT[0], [TT[k] / N for k in range(N + 1)]

        def at(k, tau):
            return step(X[:n, k], X[n:2 * n, k], X[2 * n:, k], U[:, k], tau)

        f_acc = tip_motion(crane)

        def acc(k, tau):
            q, qd, qdd = at(k, tau)
            return f_acc(q, qd, qdd)[3]      # the drive: the tip and the last link
        inner = []   # (interval, joints, swing angles) at the RK4 steps inside intervals
        for k in range(N):
            lay.add_con("dynamics", X[:, k + 1] - ca.vertcat(*at(k, hs[k])), 0.0, 0.0)
            lay.add_con("duration_chain", TT[k + 1] - TT[k], 0.0, 0.0)
            hh = hs[k] / substeps
            xs = [S[4 * i:4 * i + 4, k] for i in range(P)]
            for i in range(substeps):
                if i > 0:
                    inner.append((k, at(k, i * hh)[0], xs[0][:2]))
                a0, am, a1 = (acc(k, (i + f) * hh) for f in (0.0, 0.5, 1.0))
                for j, pj in enumerate(self.pends):
                    f_sw, x = pj.f_swing, xs[j]
                    k1 = f_sw(x, a0)
                    k2 = f_sw(x + hh / 2 * k1, am)
                    k3 = f_sw(x + hh / 2 * k2, am)
                    k4 = f_sw(x + hh * k3, a1)
                    xs[j] = x + hh / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            lay.add_con("swing_dynamics", S[:, k + 1] - ca.vertcat(*xs), 0.0, 0.0)
        fk = crane.f_fk
        lay.add_con("start", fk(X[:n, 0])[0] - par["start"], 0.0, 0.0)
        lay.add_con("goal", fk(X[:n, N])[0] - par["goal"], 0.0, 0.0)
        lay.add_con("start_at_rest", X[n:, 0], 0.0, 0.0)
        lay.add_con("goal_at_rest", X[n:, N], 0.0, 0.0)
        lay.add_con("swing_start", S[:, 0], 0.0, 0.0)
        for j, pj in enumerate(self.pends):
            w2, sN = pj.omega ** 2, S[4 * j:4 * j + 4, N]
            lay.add_con("swing_goal", (sN[0] ** 2 + sN[1] ** 2 + (sN[2] ** 2 + sN[3] ** 2) / w2)
                        * pend.length ** 2, -ca.inf, swing_tol ** 2)
        if swing_max is not None:
            for k in range(1, N):
                lay.add_con("swing_max", (ca.sin(S[0, k]) ** 2 + ca.sin(S[1, k]) ** 2)
                            * pend.length ** 2, -ca.inf, swing_max ** 2)
        pts = [(X[:n, k], X[n:2 * n, k], X[2 * n:, k]) for k in range(N + 1)]
        mids = [at(k, hs[k] / 2) for k in range(N)]
        ends = [at(k, hs[k]) for k in range(N)]
        for k, (q, _, _) in enumerate(mids):
            lay.add_con("position", q, L["q_min"], L["q_max"])
        add_velocity_limits(lay, L, jmax, pts, mids, ends, U, hs, uniform=bool(self.obstacles))
        if self.obstacles:
            add_obstacles(lay, fk, self.obstacles, [(k, p) for k, p in enumerate(pts + mids)])
            if load_clearance:
                qs = ca.SX.sym("qs", n + 2)
                p = fk(qs[:n])[0] + ca.vertcat(*_link(pend.length, qs[n], qs[n + 1]))
                cyl = ca.vertcat(ca.sqrt(p[0] ** 2 + p[1] ** 2), p[2], ca.atan2(p[1], p[0]))
                f_load = ca.Function("load_fk", [qs], [p, cyl])
                add_obstacles(lay, f_load, [replace(ob, clearance=LOAD_CLEARANCE_ROWS
                                                    * ob.clearance) for ob in self.obstacles],
                              [(k, (ca.vertcat(X[:n, k], S[:2, k]), None, None))
                               for k in range(N + 1)]
                              + [(k, (ca.vertcat(q, th), None, None)) for k, q, th in inner])
        PumpRows(crane, actuator_table(crane.spec), N, "time", "free", True,
                 PUMP_MARGIN).add(lay, pts, mids, hs[0], par["payload"], par["activity"])
        f = T + reg * sum(hs[k] * ca.sumsqr(U[:, k]) for k in range(N))
        self.lbw, self.ubw, self.lbg, self.ubg = lay.bounds()
        # L-BFGS: half the build and faster solves on the plain problem; the robust and the
        # swing-bounded ones reached max_iter with it (measured on s100f), so exact there
        self._problem = {"x": lay.w, "p": lay.P, "f": f, "g": lay.g}
        self._exact = None
        self.solver = self._solver(exact=robust > 0 or swing_max is not None)
        self.guesses = Guesses(crane, lay, self.lbw, self.ubw, N, "free")
        self.build_time_s = _time.perf_counter() - t0

    def _solver(self, exact: bool):
        ipopt = {k: v for k, v in IPOPT.items() if not (exact and k == "hessian_approximation")}
        # IPOPT backs off from a trial point where the swing's rows are not finite; CasADi's
        # warning for each (dozens on a cat215b move) is not for the user's terminal
        return ca.nlpsol("sway", "ipopt", self._problem,
                         {"expand": True, "print_time": False, "show_eval_warnings": False,
                          "ipopt": ipopt})

    def exact_solver(self):
        """The same NLP under IPOPT with the exact Hessian (built on first use; its seconds
        added to ``build_time_s``)."""
        if self._exact is None:
            t0 = _time.perf_counter()
            self._exact = self._solver(exact=True)
            self.build_time_s += _time.perf_counter() - t0
        return self._exact

    def guess_from(self, traj: Trajectory) -> np.ndarray:
        """Primal guess: the joints of ``traj`` on the NLP's grid and the swing the model
        predicts along it."""
        w0 = self.guesses.guess_from(traj)
        t = np.linspace(traj.t[0], traj.t[-1], self.N + 1)
        blocks = []
        for pj in self.pends:
            pred = predict_swing(self.crane, traj, pj, rate=200.0)
            Sg = np.column_stack([np.interp(t, pred.t, pred.x[:, i]) for i in range(4)])
            Sg[:, :2] = np.clip(Sg[:, :2], -ANGLE_MAX, ANGLE_MAX)
            Sg[:, 2:] = np.clip(Sg[:, 2:], -RATE_MAX, RATE_MAX)
            blocks.append(Sg.T)
        self.layout.pack(w0, "S", np.vstack(blocks))
        return w0

    def solve(self, start, goal, guess: np.ndarray, exact: bool = False) -> tuple:
        """(status code, reason, trajectory or None, IPOPT iterations) from ``guess``
        (``exact``: with the exact Hessian, :meth:`exact_solver`)."""
        solver = self.exact_solver() if exact else self.solver
        crane, lay, n, N = self.crane, self.layout, self.crane.n, self.N
        P = lay.param_vector(start=tip_to_xyz(np.asarray(start, float)),
                             goal=tip_to_xyz(np.asarray(goal, float)),
                             payload=crane.spec.payload.total, activity=0.0)
        try:
            sol = solver(x0=guess, p=P, lbx=self.lbw, ubx=self.ubw, lbg=self.lbg,
                         ubg=self.ubg)
        except RuntimeError as e:
            return PlanStatus.ERROR, f"IPOPT failed: {e}", None, 0
        st = solver.stats()
        ist, iters = st.get("return_status", ""), st.get("iter_count", 0)
        if ist not in STATUS_OK:
            return ipopt_code(ist), f"IPOPT: {ist}", None, iters
        w = np.array(sol["x"]).ravel()
        X, U = lay.unpack(w, "X"), lay.unpack(w, "U")
        T = float(w[lay.slice("T")][0])
        h = T / N
        for k in range(N):   # node states consistent with the jerks
            X[:n, k + 1], X[n:2 * n, k + 1], X[2 * n:, k + 1] = step(
                X[:n, k], X[n:2 * n, k], X[2 * n:, k], U[:, k], h)
        tr = Trajectory(np.linspace(0.0, T, N + 1), X[:n].T, X[n:2 * n].T, X[2 * n:].T,
                        joint_names=tuple(crane.names), method="nlp-sway", objective="time",
                        limits=LIMITS, meta=dict(N=N, path="free", ipopt_status=ist))
        return PlanStatus.OK, "", tr, iters


def _link(L, a, b):
    """The link vector pivot → centre of mass (as planner.model.pendulum writes it)."""
    return ca.sin(b) * L, -ca.sin(a) * ca.cos(b) * L, -ca.cos(a) * ca.cos(b) * L


class SwayPlanner(Planner):
    """``nlp-sway``: minimum time with the load at rest under the tip at the goal (module
    doc)."""
    name = "nlp-sway"
    description = ("CasADi/IPOPT minimum-time NLP with the grapple pendulum: the load at rest "
                   "under the tip at the goal, swing bounded, obstacles")
    objectives = ("time",)
    paths = ("free",)
    obstacles = True
    grapple = True        # reads the ``grapple`` option (the link length)

    def __init__(self):
        self._built: dict = {}

    def check(self, request: PlanRequest) -> None:
        super().check(request)
        for k, lo in (("grapple", 0.0), ("grapple_zeta", 0.0), ("swing_tol", 1e-4),
                      ("swing_max", 0.01), ("swing_robust", 0.0)):
            v = request.options.get(k)
            if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool)
                                      and math.isfinite(v) and v >= lo):
                raise UnsupportedRequest(f"`{k}` = {v!r}: allowed a finite number ≥ {lo:g}")

    def clear(self) -> None:
        self._built.clear()

    def library_request(self, crane: Crane, move, objective: str, *, time_result=None,
                        settings) -> PlanRequest:
        """The plain library request with the build's ``intervals``, its grapple link
        (``settings.grapple``: length or None for the spec's, pin zeta) and, with obstacles,
        the load's clearance planned (``load_clearance``)."""
        req = super().library_request(crane, move, objective, time_result=time_result,
                                      settings=settings)
        length, zeta = getattr(settings, "grapple", None) or (None, None)
        return replace(req, options=dict(req.options, intervals=settings.intervals,
                                         grapple=length, grapple_zeta=zeta,
                                         load_clearance=bool(settings.obstacles)))

    def built(self, crane: Crane, pend: Pendulum, request: PlanRequest,
              substeps: int = 1) -> SwayNLP:
        """The SwayNLP of this request's formulation, built on first use."""
        N = request.option("intervals", 40)
        tol = float(request.option("swing_tol", SWING_TOL))
        smax = request.option("swing_max")
        grapple = crane.spec.dynamics.grapple if crane.spec.dynamics is not None else None
        if smax is None and grapple is not None:
            smax = grapple.swing_max           # the operator's limit from the spec
        load = bool(request.option("load_clearance", False))
        robust = float(request.option("swing_robust", 0.0))
        key = (id(crane), pend, N, tol, smax, load, robust, request.obstacles, substeps)
        if key not in self._built:
            self._built[key] = (crane, SwayNLP(crane, pend, N, request.obstacles, tol, smax,
                                               load, substeps=substeps, robust=robust))
        return self._built[key][1]

    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        t0 = _time.perf_counter()
        pend = pendulum_of_request(crane, request, self.name)
        base = plan_with(crane, PlanRequest(
            request.start, request.goal, obstacles=request.obstacles,
            options={"intervals": request.option("intervals", 40)}), "nlp")
        if not base.ok:
            base.method, base.reason = self.name, f"the sway-blind nlp plan: {base.reason}"
            return base
        b0 = sum(x[1].build_time_s for x in self._built.values())
        # RK4 steps of at most ω₀·h = 0.4 rad: one step per interval left 16 mm where 10 were
        # asked on a 10.9 s forwarder move (ω₀·h = 0.68), two 10.1 mm (predict_swing, 200 Hz)
        N = request.option("intervals", 40)
        sub = max(1, math.ceil(pend.omega * 1.1 * base.duration_s / N / SUBSTEP_RAD))
        load = bool(request.option("load_clearance", False)) and bool(request.obstacles)
        if load:   # the load's rows at the midpoints too (a 1 kHz check follows)
            sub = max(sub, 2)
        nlp = self.built(crane, pend, request, sub)
        times, amps = shaper("zvd", pend.omega, pend.zeta)
        warm = (("sway-blind", lambda: base.trajectory, False),
                ("sway-blind, exact Hessian", lambda: base.trajectory, True),
                ("zvd", lambda: shape(base.trajectory, times, amps), False),
                ("slowed", lambda: stretch(base.trajectory, 1.15 * base.duration_s), False))
        iters, last = 0, (PlanStatus.FAILED, "no warm start converged")
        for label, make, exact in warm:
            code, reason, tr, it = nlp.solve(request.start, request.goal,
                                             nlp.guess_from(make()), exact)
            iters += it
            if code is not PlanStatus.OK:
                last = (code, reason)
                continue
            ev = evaluate(crane, tr)
            if ev.max_limit_violation > self.tolerance:
                last = (PlanStatus.LIMITS, f"a limit exceeded by "
                        f"{100 * ev.max_limit_violation:.2f} % between the check points")
                continue
            if clearance_margin(crane, tr, request.obstacles) < 0:
                last = (PlanStatus.OBSTACLE, "the tip comes closer to an obstacle than 0.96 × "
                        "its clearance between the check points")
                continue
            lmargin = (load_clearance_margin(crane, tr, pend, request.obstacles, share=1.0)
                       if load else math.inf)
            if lmargin < 0:
                last = (PlanStatus.OBSTACLE, f"the load comes {-1e3 * lmargin:.0f} mm closer "
                        "to an obstacle than its clearance between the check points")
                continue
            pred = predict_swing(crane, tr, pend)
            build = sum(x[1].build_time_s for x in self._built.values()) - b0
            return PlanResult(PlanStatus.OK, trajectory=tr, duration_s=tr.duration,
                              solve_time_s=_time.perf_counter() - t0 - build, method=self.name,
                              stats=dict(iterations=iters, warm_start=label,
                                         build_time_s=build, base_duration_s=base.duration_s,
                                         duration_ratio=tr.duration / base.duration_s,
                                         pendulum_hz=pend.omega / (2 * math.pi),
                                         swing_residual_m=pred.residual_m,
                                         swing_peak_m=pred.peak_during_m,
                                         load_clearance_margin_m=lmargin,
                                         base_swing_residual_m=predict_swing(
                                             crane, base.trajectory, pend).residual_m))
        build = sum(x[1].build_time_s for x in self._built.values()) - b0
        return PlanResult(last[0], f"{self.name}: {last[1]}", method=self.name,
                          solve_time_s=_time.perf_counter() - t0 - build, iterations=iters,
                          build_time_s=build)


register(SwayPlanner())
