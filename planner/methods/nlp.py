"""Point-to-point moves as CasADi NLPs (IPOPT), built once and solved many times.

Transcription: N intervals of equal length h = T/N; every joint is a triple integrator with
piecewise-constant jerk, integrated exactly (q, q̇, q̈ at the nodes), so acceleration and jerk
limits hold everywhere by construction; velocity, position, the pump flow and (path mode) the
tip path are imposed at the nodes and the interval midpoints. Velocity is quadratic on an
interval, so its extremum lies at most h/4 from a check point and exceeds it by at most
j_max·h²/32: the checked velocity is tightened by exactly that, and the limit holds everywhere.
Ends: tip positions (the redundancy is free at both ends) at rest (q̇ = q̈ = 0).

Pump flow without abs/max (anchors.md): per check point and actuator a slack s ≥ A_a·ẋ,
s ≥ −A_b·ẋ (single-acting: s ≥ A_a·ẋ), s ≥ 0, and Σ s ≤ (1 − pump_margin)·Q_max; the flow is
nonlinear in q between check points, the 0.5 % default margin covers that (measured overshoot
≤ 0.15 % at N = 30).

Energy (load sensing) without max/abs: flows split by direction (s⁺ piston side extending, s⁻
annulus retracting, as fractions of Q_max); per node a pump-pressure variable p [MPa] ≥ standby
with p ≥ margin + p_meter-in for every function marked active at that node — the activity mask
is an NLP parameter (inactive ones relaxed by a big M, so all constraints are smooth), taken
from the warm start, then from each solution, re-solving warm until it settles (≤ 4 rounds;
functions once active stay so). Power p·Q/η, trapezoid rule. Measured: 0.9–1.4 s and ~150
IPOPT iterations per energy solve; earlier complementarity products (p − p_i)·s_i ≥ 0 took
500–950 iterations. The result is judged by :func:`~planner.trajectory.evaluate`.

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
forwarder moves), so the exact move is returned when faster (``stats["winner"] == "ruckig"``).
"""
from __future__ import annotations

import time as _time

import casadi as ca
import numpy as np

from planner.bounds import lower_bound
from planner.geometry.obstacles import Plate, Wall
from planner.geometry.paths import tip_to_xyz
from planner.methods.base import Planner, PlanRequest, PlanResult, UnsupportedRequest
from planner.methods.registry import register
from planner.trajectory import Trajectory
from planner.methods.ruckig import rest_to_rest

STATUS_OK = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


OBSTACLE_TYPES = (Wall, Plate)   # the obstacles MoveNLP accepts (re-exported here)


def _result(status: str, reason: str = "", **kw) -> PlanResult:
    """The NLP's result: status "ok" or a short code ("infeasible", "max_iter", "error",
    "unreachable", "obstacle", …); stats ``energy_model_J`` (the NLP's own conservative energy
    estimate), ``iterations``, ``ipopt_status`` and the solver details."""
    kw.setdefault("energy_model_J", float("nan"))
    kw.setdefault("iterations", 0)
    kw.setdefault("ipopt_status", "")
    return PlanResult(status, reason, **kw)


class MoveNLP:
    """One NLP structure for a crane; ``solve(start, goal, ...)`` many times.

    objective: "time" | "energy" | "blend"; path: "free" | "line"; N intervals."""

    def __init__(self, crane, objective: str = "time", path: str = "free", N: int = 40,
                 pump: bool = True, reg: float = 1e-6, pump_margin: float = 0.005,
                 obstacles: tuple = (), ipopt_options: dict | None = None):
        if objective not in ("time", "energy", "blend"):
            raise ValueError(f"objective must be time, energy or blend, not {objective!r}")
        self.curve = None
        if not isinstance(path, str):  # a Curve with a symbolic face: tip on p(θ)
            if getattr(path, "p_sym", None) is None:
                raise ValueError("a path object needs a symbolic face p_sym(θ) (see "
                                 "planner.geometry.paths.circle / parabola)")
            self.curve, path = path, "curve"
        elif path not in ("free", "line"):
            raise ValueError(f"path must be 'free', 'line' or a Curve, not {path!r}")
        self.crane, self.objective, self.path, self.N, self.pump = crane, objective, path, N, pump
        spec = crane.spec
        n = crane.n
        L = crane.limit_arrays()
        self.L = L
        jmax = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], 1e3)
        # ---------------------------------------------------------------- variables
        X = ca.SX.sym("X", 3 * n, N + 1)  # [q; qd; qdd] per node
        U = ca.SX.sym("U", n, N)          # jerk per interval
        T = ca.SX.sym("T")
        n_dbl = sum(j.actuator.acting == "double" for j in spec.joints)
        self._n_act = (N + 1) * (n + n_dbl)  # activity mask: one per node, actuator, direction
        # start xyz, goal xyz, T_max, lambda, payload, activity mask
        P = ca.SX.sym("P", 9 + self._n_act)
        pa, pb, Tmax, lam, payload = P[0:3], P[3:6], P[6], P[7], P[8]
        act_mask = P[9:]
        h = T / N
        w, lbw, ubw = [], [], []
        g, lbg, ubg = [], [], []

        def add_w(v, lo, hi):
            w.append(ca.vec(v))
            lbw.extend(np.broadcast_to(lo, v.shape).ravel(order="F").tolist())
            ubw.extend(np.broadcast_to(hi, v.shape).ravel(order="F").tolist())

        def add_g(e, lo, hi):
            e = ca.vec(e)
            g.append(e)
            lbg.extend(np.broadcast_to(lo, (e.shape[0],)).tolist())
            ubg.extend(np.broadcast_to(hi, (e.shape[0],)).tolist())

        big = 1e3
        xlo = np.concatenate([L["q_min"], L["qd_min"], -L["qdd_max"]])
        xhi = np.concatenate([L["q_max"], L["qd_max"], L["qdd_max"]])
        add_w(X, np.tile(xlo[:, None], (1, N + 1)), np.tile(xhi[:, None], (1, N + 1)))
        add_w(U, np.tile(-jmax[:, None], (1, N)), np.tile(jmax[:, None], (1, N)))
        add_w(T, 1e-3, big)
        self._nx = 3 * n * (N + 1)
        self._nu = n * N
        # ---------------------------------------------------------------- dynamics (exact)
        for k in range(N):
            q, v, a = X[:n, k], X[n:2 * n, k], X[2 * n:, k]
            j = U[:, k]
            nxt = ca.vertcat(q + h * v + h ** 2 / 2 * a + h ** 3 / 6 * j,
                             v + h * a + h ** 2 / 2 * j, a + h * j)
            add_g(X[:, k + 1] - nxt, 0.0, 0.0)
        # ---------------------------------------------------------------- ends at rest
        fk = crane.f_fk
        add_g(fk(X[:n, 0])[0] - pa, 0.0, 0.0)
        add_g(fk(X[:n, N])[0] - pb, 0.0, 0.0)
        add_g(X[n:, 0], 0.0, 0.0)
        add_g(X[n:, N], 0.0, 0.0)
        # ---------------------------------------------------------------- check points
        pts = [(X[:n, k], X[n:2 * n, k], X[2 * n:, k]) for k in range(N + 1)]
        mids = []
        for k in range(N):
            q, v, a, j = X[:n, k], X[n:2 * n, k], X[2 * n:, k], U[:, k]
            hh = h / 2
            mids.append((q + hh * v + hh ** 2 / 2 * a + hh ** 3 / 6 * j,
                         v + hh * a + hh ** 2 / 2 * j, a + hh * j))
        gap = jmax * h ** 2 / 32  # largest velocity overshoot between check points
        for q, v, a in mids:
            add_g(q, L["q_min"], L["q_max"])
        for q, v, a in pts + mids:
            add_g(v + gap, -ca.inf, L["qd_max"])
            add_g(v - gap, L["qd_min"], ca.inf)
        self.obstacles = tuple(obstacles)
        if self.obstacles:
            # obstacles at the nodes, midpoints and quarter points (q is a cubic per interval):
            # the tip moves a quarter interval between checks, less room to slip through
            quarters = []
            for k in range(N):
                q, v, a, j = X[:n, k], X[n:2 * n, k], X[2 * n:, k], U[:, k]
                for hh in (h / 4, 3 * h / 4):
                    quarters.append((q + hh * v + hh ** 2 / 2 * a + hh ** 3 / 6 * j, None, None))
            for q, _, _ in pts + mids + quarters:
                xyz, cyl = crane.f_fk(q)
                for ob in self.obstacles:
                    for expr, lo in ob.constraints(xyz, cyl):
                        add_g(expr, lo, ca.inf)
        if path == "curve":
            # one path parameter per node, monotone, fixed at the ends; the tip on p(θ_k) at the
            # nodes: per interval n jerks + 1 θ − 3 equations leave n − 2 free directions
            u0, u1 = self.curve.u_range
            TH = ca.SX.sym("TH", N + 1)
            lo_u, hi_u = min(u0, u1), max(u0, u1)
            th_vars = TH
            for k in range(N + 1):
                q = X[:n, k]
                add_g(fk(q)[0] - self.curve.p_sym(TH[k]), 0.0, 0.0)
            add_g(TH[0] - u0, 0.0, 0.0)
            add_g(TH[N] - u1, 0.0, 0.0)
            sgn = 1.0 if u1 >= u0 else -1.0
            add_g(sgn * (TH[1:] - TH[:-1]), 0.0, ca.inf)
        if path == "line":
            d = pb - pa
            dn = d / ca.norm_2(d)
            # two unit vectors perpendicular to the line (robust for any direction)
            helper = ca.if_else(ca.fabs(dn[2]) < 0.9, ca.DM([0, 0, 1]), ca.DM([1, 0, 0]))
            e1 = ca.cross(dn, helper)
            e1 = e1 / ca.norm_2(e1)
            e2 = ca.cross(dn, e1)
            # at the nodes only: per interval the n jerks leave n − 2 free directions (progress
            # and redundancy); also imposing the midpoints would fix the motion completely
            for q, _, _ in pts[1:-1]:
                r = fk(q)[0] - pa
                add_g(ca.vertcat(ca.dot(r, e1), ca.dot(r, e2)), 0.0, 0.0)
                add_g(ca.dot(r, dn) / ca.norm_2(d), -0.02, 1.02)
        acts = spec.joints
        Aa = np.array([j.actuator.area_a for j in acts])
        Ab = np.array([j.actuator.area_b for j in acts])
        dbl = np.array([j.actuator.acting == "double" for j in acts])
        Qm = spec.pump.max_flow
        energy = 0
        need_energy = objective in ("energy", "blend")
        if pump or need_energy:
            checks = pts + mids if pump else pts
            powers = []
            for idx, (q, v, a) in enumerate(checks):
                _, dxdq = crane.f_stroke(q)
                xd = dxdq * v
                # flows drawn from the pump as fractions of Q_max: extending (piston side) and
                # retracting (annulus; none for a single-acting cylinder lowering)
                sp = ca.SX.sym(f"sp{idx}", n)
                add_w(sp, 0.0, 10.0)
                add_g(Qm * sp - Aa * xd, 0.0, ca.inf)
                flows = [sp]
                if dbl.any():
                    sm = ca.SX.sym(f"sm{idx}", int(dbl.sum()))
                    add_w(sm, 0.0, 10.0)
                    add_g(Qm * sm + Ab[dbl] * xd[np.flatnonzero(dbl)], 0.0, ca.inf)
                    flows.append(sm)
                total = sum(ca.sum1(f_) for f_ in flows)
                if pump:
                    add_g(total, -ca.inf, 1 - pump_margin)
                if need_energy and idx <= N:
                    F = crane.f_id(q, v, a, payload) / dxdq
                    p = ca.SX.sym(f"p{idx}")  # pump pressure [MPa]
                    if spec.pump.kind == "load_sensing":
                        add_w(p, spec.pump.standby / 1e6, 1e3)
                        mg = spec.pump.margin / 1e6
                        # load sensing: a function raises the pump pressure only while it
                        # draws flow. Which ones do is the activity mask (a parameter, updated
                        # from the solution and re-solved: see solve); inactive ones are
                        # relaxed by a big M, so every constraint is smooth
                        base = idx * (n + n_dbl)
                        m_pos = act_mask[base:base + n]
                        add_g(p - mg - F / Aa / 1e6 + 1e3 * (1 - m_pos), 0.0, ca.inf)
                        if dbl.any():
                            k = np.flatnonzero(dbl)
                            m_neg = act_mask[base + n:base + n + n_dbl]
                            add_g(p - mg + F[k] / Ab[k] / 1e6 + 1e3 * (1 - m_neg), 0.0, ca.inf)
                    else:
                        add_w(p, spec.pump.pressure / 1e6, spec.pump.pressure / 1e6)
                    powers.append(p * 1e6 * Qm * total / spec.pump.efficiency)
            if need_energy:
                energy = h * (sum(powers[1:-1]) + 0.5 * (powers[0] + powers[-1]))
        # ε·∫j² dt: joints that do not decide the time would otherwise be free (a flat,
        # non-unique optimum where IPOPT stalls); ε = 1e-6 moves T by ~1e-5 relative
        smooth = reg * h * ca.sumsqr(U)
        if objective == "time":
            f = T + smooth
        elif objective == "energy":
            add_g(T - Tmax, -ca.inf, 0.0)
            f = energy * 1e-5 + smooth
        else:
            f = T + lam * energy + smooth
        if path == "curve":
            add_w(th_vars, lo_u, hi_u)  # last block: θ per node
        wv = ca.vertcat(*w)
        self._energy_fn = ca.Function("E", [wv, P], [energy])
        opts = {"expand": True, "print_time": False,
                "ipopt": {"print_level": 0, "sb": "yes", "max_iter": 1000, "tol": 1e-7,
                          "acceptable_tol": 1e-5, "mu_strategy": "adaptive",
                          "max_wall_time": 60.0}}
        if ipopt_options:
            opts["ipopt"].update(ipopt_options)
        self.solver = ca.nlpsol("move", "ipopt", {"x": wv, "p": P, "f": f,
                                                  "g": ca.vertcat(*g)}, opts)
        self.lbw, self.ubw = np.array(lbw), np.array(ubw)
        self.lbg, self.ubg = np.array(lbg), np.array(ubg)
        self.nw = wv.shape[0]
        self._last = None
        self._plain = (None, None)   # (key, _plain_traj result) of the last move: built once

    # ------------------------------------------------------------------------ guesses
    def guess_from(self, traj) -> np.ndarray:
        """Primal guess from any Trajectory (resampled to the NLP's grid; slacks at bounds)."""
        N = self.N
        t = np.linspace(traj.t[0], traj.t[-1], N + 1)
        q, qd, qdd, _ = traj.sample(t)
        X = np.vstack([q.T, qd.T, qdd.T])
        h = (t[-1] - t[0]) / N
        U = np.diff(qdd, axis=0).T / h
        w0 = np.zeros(self.nw)
        w0[:self._nx] = X.ravel(order="F")
        w0[self._nx:self._nx + self._nu] = U.ravel(order="F")
        w0[self._nx + self._nu] = traj.duration
        rest = self._nx + self._nu + 1
        w0[rest:] = np.clip(0.0, self.lbw[rest:], self.ubw[rest:])  # slacks: the solver lifts them
        if self.curve is not None:  # θ per node: the nearest point of the curve to each tip
            u = np.linspace(*self.curve.u_range, 4001)
            P = np.asarray(self.curve.p(u))
            tips = self.crane.fk(q)
            k = np.argmin(((tips[:, None, :] - P[None, :, :]) ** 2).sum(-1), axis=1)
            th = np.maximum.accumulate(u[k]) if u[-1] > u[0] else np.minimum.accumulate(u[k])
            th[0], th[-1] = u[0], u[-1]
            w0[-(N + 1):] = th
        return w0

    def default_guess(self, start, goal):
        """Free path: Ruckig rest-to-rest between the ends at the lower bound's best telescope
        values, slowed to the pump bound when the pump limits. Line: a coarse DP along the line
        retimed by TOPP-RA (velocity, acceleration, pump)."""
        crane = self.crane
        lb = lower_bound(crane, start, goal)
        if self.path in ("line", "curve"):
            from planner.geometry.paths import Line
            from planner.methods.dp import dp
            from planner.methods.topp import retime
            geo = self.curve if self.path == "curve" else Line(start, goal)
            d = dp(crane, geo, step=0.05, tele_step=0.05, window=3)
            if not d.ok:
                raise ValueError(d.reason)
            t = retime(crane, d.path_q, gridpoints=100)
            if not t.ok:
                raise ValueError(t.reason)
            return self.guess_from(t.trajectory), lb
        return self._plain_guess(start, goal, lb), lb

    def _plain_guess(self, start, goal, lb):
        """Ruckig rest-to-rest at the bound's best telescopes, slowed to the pump bound."""
        return self.guess_from(self._plain_traj(start, goal, lb)[0])

    def _plain_traj(self, start, goal, lb):
        """(the guess trajectory: Ruckig slowed to 1.05 × the combined bound when faster, the
        Ruckig move itself). Kept for the last move: the guess and the exact-move check share it."""
        key = (tuple(map(float, start)), tuple(map(float, goal)), lb.tele_start, lb.tele_goal,
               lb.combined_s)
        if self._plain[0] != key:
            crane = self.crane
            tr = rest_to_rest(crane, crane.ik(start, lb.tele_start),
                              crane.ik(goal, lb.tele_goal)).trajectory
            slow = stretch(tr, 1.05 * lb.combined_s) if 1.05 * lb.combined_s > tr.duration else tr
            self._plain = (key, (slow, tr))
        return self._plain[1]

    def _prefer_exact(self, res, start, goal, lb, t0):
        """Minimum time, free path: the jerk-limited rest-to-rest move (Ruckig) the guess comes
        from, when it is faster than the NLP's solution and itself feasible — every limit of
        the NLP (the pump too) on a 1 kHz resampling, clear of the obstacles. N equal intervals
        cannot put the jerk switches of a long, one-joint-dominated move where they belong (up
        to about one interval is lost); Ruckig's switch times are exact. The move is kept at
        its switch times only: between them every joint is a cubic, which the quintic
        interpolation reproduces exactly."""
        from planner.trajectory import evaluate
        try:
            exact = self._plain_traj(start, goal, lb)[1]
        except ValueError:
            return res
        if res.ok and exact.duration >= res.duration_s * (1 - 1e-6):
            return res
        ts = np.asarray(exact.meta["switch_times"])
        q, qd, qdd, _ = exact.sample(ts)
        kinds = ("position", "velocity", "acceleration", "jerk") + (
            ("pump_flow",) if self.pump else ())
        tr = Trajectory(ts, q, qd, qdd, joint_names=tuple(self.crane.names), method="nlp",
                        objective="time", limits=kinds,
                        meta=dict(N=self.N, path="free", winner="rest-to-rest (Ruckig)",
                                  nlp=(f"{res.duration_s:.4f} s" if res.ok else res.status)))
        ev = evaluate(self.crane, tr, kinds=kinds)
        if ev.max_limit_violation > 1e-4 or (self.obstacles and not self.clears(tr)):
            return res
        return _result("ok", trajectory=tr, duration_s=tr.duration, iterations=res.iterations,
                         ipopt_status=res.ipopt_status, stats=dict(winner="ruckig"),
                         solve_time_s=_time.perf_counter() - t0)

    def _vias(self, start, goal) -> list:
        """Via tips above the obstacles the move meets, in the order it meets them."""
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        vias = [v for ob in self.obstacles for v in ob.vias(start, goal)]
        vias.sort(key=lambda v: (abs(v[2] - start[2]), abs(v[0] - start[0])))
        return vias

    def _guess_over_walls(self, start, goal, lb):
        """Rest-to-rest Ruckig segments through a via point above every wall crossed (at the
        wall's r, 1.5 clearances above its top, slew interpolated): a guess on the right side
        of the obstacles (a guess through a wall leaves IPOPT in a poor local optimum)."""
        crane = self.crane
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        tips = [start] + self._vias(start, goal) + [goal]
        qs = [crane.ik(tips[0], lb.tele_start)]
        for k, tip in enumerate(tips[1:], 1):
            tele = lb.tele_goal if k == len(tips) - 1 else None
            qs.append(crane.ik(tip, tele))
        segs = [rest_to_rest(crane, a, b).trajectory for a, b in zip(qs[:-1], qs[1:])]
        t, q, qd, qdd, off = [], [], [], [], 0.0
        for s in segs:
            t.append(s.t[1:] + off if t else s.t)
            for lst, arr in ((q, s.q), (qd, s.qd), (qdd, s.qdd)):
                lst.append(arr[1:] if len(lst) else arr)
            off += s.duration
        tr = Trajectory(np.concatenate(t), np.vstack(q), np.vstack(qd), np.vstack(qdd),
                        joint_names=tuple(crane.names))
        return self.guess_from(tr)

    def _activity(self, w) -> np.ndarray:
        """Which functions draw pump flow at each node (per direction) in the primal ``w``:
        the load-sensing activity mask (threshold as in the evaluator: 1e-4 of Q_max)."""
        from planner.model.hydraulics import ACTIVE_FLOW
        crane, n, N = self.crane, self.crane.n, self.N
        X = w[:self._nx].reshape(3 * n, N + 1, order="F")
        _, dxdq = crane.stroke(X[:n].T)
        xd = dxdq * X[n:2 * n].T
        acts = crane.spec.joints
        Aa = np.array([j.actuator.area_a for j in acts])
        Ab = np.array([j.actuator.area_b for j in acts])
        dbl = np.array([j.actuator.acting == "double" for j in acts])
        eps = ACTIVE_FLOW * crane.spec.pump.max_flow
        pos = (Aa * xd > eps).astype(float)
        neg = (-Ab[dbl] * xd[:, dbl] > eps).astype(float)
        return np.hstack([pos, neg]).ravel()

    # ------------------------------------------------------------------------ solve
    def solve(self, start=None, goal=None, *, T_max: float | None = None, lam: float = 0.0,
              payload: float | None = None, w0=None) -> PlanResult:
        """Solve for tips ``start``/``goal`` (r, z, slew). ``T_max`` [s] (energy), ``lam``
        [s/J] (blend), ``w0`` a primal guess (default: :meth:`default_guess`)."""
        t0 = _time.perf_counter()
        if self.curve is not None and start is None:  # curve mode: the curve's ends
            from planner.geometry.paths import xyz_to_tip
            ends = np.asarray(self.curve.p(np.array(self.curve.u_range)))
            start, goal = xyz_to_tip(ends[0]), xyz_to_tip(ends[1])
        if start is None or goal is None:
            raise ValueError("give start and goal tips (r, z, slew)")
        if self.objective == "energy" and T_max is None:
            raise ValueError("objective 'energy' needs T_max [s]")
        if w0 is None and self.obstacles and self.path == "free":
            # obstacle problems are multimodal: try the plain and (when the move meets an
            # obstacle) the over-the-obstacle guess; keep the fastest solution that clears every
            # obstacle on a fine resampling
            try:
                lb = lower_bound(self.crane, start, goal)
                guesses = [self._plain_guess(start, goal, lb)]
                if self._vias(start, goal):
                    guesses.append(self._guess_over_walls(start, goal, lb))
            except ValueError as e:
                return _result("unreachable", str(e), solve_time_s=_time.perf_counter() - t0)
            res = [self._solve_from(g, start, goal, T_max, lam, payload, t0) for g in guesses]
            good = [r for r in res if r.ok and self.clears(r.trajectory)]
            if good:
                best = min(good, key=lambda r: r.duration_s)
            else:
                best = next((r for r in res if not r.ok), res[0])
                if best.ok:
                    best = _result("obstacle", "no solution clears every obstacle between "
                                     "the check points: raise N or the clearance",
                                     iterations=best.iterations)
            if self._exact_applies(T_max, lam, payload):
                best = self._prefer_exact(best, start, goal, lb, t0)
            best.solve_time_s = _time.perf_counter() - t0
            return best
        try:
            guess, lb = self.default_guess(start, goal) if w0 is None else (w0, None)
        except ValueError as e:  # unreachable end
            return _result("unreachable", str(e), solve_time_s=_time.perf_counter() - t0)
        res = self._solve_from(guess, start, goal, T_max, lam, payload, t0)
        if w0 is None and self.path == "free" and self._exact_applies(T_max, lam, payload):
            res = self._prefer_exact(res, start, goal, lb, t0)
        return res

    def _exact_applies(self, T_max, lam, payload) -> bool:
        return self.objective == "time" and T_max is None and lam == 0 and payload is None

    def clears(self, traj, rate: float = 1000.0) -> bool:
        """True when the tip keeps ≥ 0.96·clearance from every wall on a fine resampling."""
        t = traj.resample(rate)
        cyl = self.crane.tip(traj.sample(t)[0])
        xyz = tip_to_xyz(cyl)
        return all(ob.distance(xyz, cyl).min() >= 0.96 * ob.clearance for ob in self.obstacles)

    def _solve_from(self, guess, start, goal, T_max, lam, payload, t0) -> PlanResult:
        crane = self.crane
        if T_max is not None and self.objective == "energy":
            T0 = guess[self._nx + self._nu]
            if T_max > T0:  # start from the guess slowed down to the budget
                k = T_max / T0
                g = guess.copy()
                X = g[:self._nx].reshape(3 * crane.n, self.N + 1, order="F")
                X[crane.n:2 * crane.n] /= k
                X[2 * crane.n:] /= k ** 2
                g[:self._nx] = X.ravel(order="F")
                g[self._nx:self._nx + self._nu] /= k ** 3
                g[self._nx + self._nu] = T_max
                guess = g
        m = crane.spec.payload.total if payload is None else payload
        P0 = np.concatenate([tip_to_xyz(np.asarray(start, float)),
                             tip_to_xyz(np.asarray(goal, float)),
                             [T_max if T_max is not None else 0.0, lam, m]])
        mask = self._activity(guess)
        iters = 0
        for _round in range(4 if self.objective != "time" else 1):
            P = np.concatenate([P0, mask])
            try:
                sol = self.solver(x0=guess, p=P, lbx=self.lbw, ubx=self.ubw, lbg=self.lbg,
                                  ubg=self.ubg)
            except RuntimeError as e:
                return _result("error", f"IPOPT failed: {e}",
                                 solve_time_s=_time.perf_counter() - t0)
            st = self.solver.stats()
            iters += st.get("iter_count", 0)
            ist = st.get("return_status", "")
            w = np.array(sol["x"]).ravel()
            if ist not in STATUS_OK or self.objective == "time":
                break
            new = self._activity(w)
            if np.array_equal(new, mask):
                break
            mask, guess = np.maximum(mask, new), w  # keep functions once seen active
        st = dict(st, iter_count=iters)
        if ist not in STATUS_OK:
            code = {"Infeasible_Problem_Detected": "infeasible",
                    "Maximum_Iterations_Exceeded": "max_iter",
                    "Restoration_Failed": "restoration_failed",
                    "Maximum_WallTime_Exceeded": "timeout"}.get(ist, "failed")
            return _result(code, f"IPOPT: {ist}", iterations=st.get("iter_count", 0),
                             ipopt_status=ist, solve_time_s=_time.perf_counter() - t0)
        n, N = crane.n, self.N
        X = w[:self._nx].reshape(3 * n, N + 1, order="F").copy()
        U = w[self._nx:self._nx + self._nu].reshape(n, N, order="F")
        T = float(w[self._nx + self._nu])
        t = np.linspace(0.0, T, N + 1)
        h = T / N
        for k in range(N):  # re-integrate exactly: node states consistent with the jerks
            q, v, a = X[:n, k], X[n:2 * n, k], X[2 * n:, k]
            j = U[:, k]
            X[:n, k + 1] = q + h * v + h ** 2 / 2 * a + h ** 3 / 6 * j
            X[n:2 * n, k + 1] = v + h * a + h ** 2 / 2 * j
            X[2 * n:, k + 1] = a + h * j
        traj = Trajectory(t, X[:n].T, X[n:2 * n].T, X[2 * n:].T, joint_names=tuple(crane.names),
                          method="nlp", objective=self.objective,
                          limits=("position", "velocity", "acceleration", "jerk")
                          + (("pump_flow",) if self.pump else ()),
                          meta=dict(N=N, path=self.path, ipopt_status=ist))
        self._last = w
        E = float(self._energy_fn(w, P)) if self.objective != "time" else float("nan")
        return _result("ok", trajectory=traj, duration_s=T, energy_model_J=E,
                         iterations=st.get("iter_count", 0), ipopt_status=ist,
                         solve_time_s=_time.perf_counter() - t0)


def kinematic_line_nlp(crane, start, goal, N: int = 100, w0_traj=None) -> PlanResult:
    """Velocity-limits-only minimum time along the straight line (seed 000's setting, the DP's
    model): piecewise-constant joint rates on N equal time steps, the tip on the line at every
    node, no rest conditions (the seed's DP starts and ends at speed). Warm start: the DP path
    (Δ = 0.02 m) resampled in time, unless ``w0_traj`` is given. For comparisons with the DP."""
    from planner.geometry.paths import Line
    from planner.methods.dp import dp
    t0 = _time.perf_counter()
    n = crane.n
    L = crane.limit_arrays()
    Q = ca.SX.sym("Q", n, N + 1)
    V = ca.SX.sym("V", n, N)
    T = ca.SX.sym("T")
    h = T / N
    pa, pb = tip_to_xyz(np.asarray(start, float)), tip_to_xyz(np.asarray(goal, float))
    d = pb - pa
    dn = d / np.linalg.norm(d)
    helper = np.array([0.0, 0, 1]) if abs(dn[2]) < 0.9 else np.array([1.0, 0, 0])
    e1 = np.cross(dn, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(dn, e1)
    g = [ca.vec(Q[:, 1:] - Q[:, :-1] - h * V)]
    fk = crane.f_fk
    g.append(fk(Q[:, 0])[0] - pa)
    g.append(fk(Q[:, N])[0] - pb)
    for k in range(1, N):
        r = fk(Q[:, k])[0] - pa
        g.append(ca.vertcat(ca.dot(r, e1), ca.dot(r, e2)))
    gv = ca.vertcat(*g)
    w = ca.vertcat(ca.vec(Q), ca.vec(V), T)
    lbw = np.concatenate([np.tile(L["q_min"], N + 1), np.tile(L["qd_min"], N), [1e-3]])
    ubw = np.concatenate([np.tile(L["q_max"], N + 1), np.tile(L["qd_max"], N), [1e3]])
    S = ca.nlpsol("kin", "ipopt", {"x": w, "f": T + 1e-8 * ca.sumsqr(V[:, 1:] - V[:, :-1]),
                                   "g": gv},
                  {"expand": True, "print_time": False,
                   "ipopt": {"print_level": 0, "sb": "yes", "max_iter": 3000, "tol": 1e-9}})
    if w0_traj is None:
        r = dp(crane, Line(start, goal), step=0.02, tele_step=0.02, window=5)
        if not r.ok:
            return _result(r.status, r.reason, solve_time_s=_time.perf_counter() - t0)
        w0_traj = r.trajectory
    tt = np.linspace(0, w0_traj.duration, N + 1)
    q0 = w0_traj.sample(tt)[0]
    v0 = np.diff(q0, axis=0) / (tt[1] - tt[0])
    x0 = np.concatenate([q0.ravel(), v0.ravel(), [w0_traj.duration]])
    sol = S(x0=x0, lbx=lbw, ubx=ubw, lbg=0.0, ubg=0.0)
    st = S.stats()
    ist = st.get("return_status", "")
    if ist not in STATUS_OK:
        return _result("failed", f"IPOPT: {ist}", ipopt_status=ist,
                         solve_time_s=_time.perf_counter() - t0)
    x = np.array(sol["x"]).ravel()
    Qs = x[:n * (N + 1)].reshape(N + 1, n)
    Tn = float(x[-1])
    traj = Trajectory(np.linspace(0, Tn, N + 1), Qs, joint_names=tuple(crane.names),
                      method="nlp", objective="time", interpolation="linear",
                      limits=("position", "velocity"), meta=dict(N=N, path="line",
                                                                 model="kinematic"))
    return _result("ok", trajectory=traj, duration_s=Tn, iterations=st.get("iter_count", 0),
                     ipopt_status=ist, solve_time_s=_time.perf_counter() - t0)


def pareto_front(crane, start, goal, factors=(1.0, 1.1, 1.2, 1.5, 2.0), N: int = 40,
                 time_nlp: MoveNLP | None = None, energy_nlp: MoveNLP | None = None):
    """Time–energy trade-off: the minimum time T_min, then the least pump energy with a time
    budget T ≤ k·T_min for each factor k. Each point is the best candidate within the limits
    (judged by evaluate()): the energy NLP warm-started from the previous point stretched to the
    budget, or the previous point itself (it meets any larger budget) — so the front is
    non-increasing by construction, as min-energy-under-a-budget must be. Returns a list of
    (duration [s], pump energy [J], PlanResult, source) with source "nlp" or "carried"."""
    from planner.trajectory import evaluate
    tn = time_nlp or MoveNLP(crane, "time", "free", N=N)
    en = energy_nlp or MoveNLP(crane, "energy", "free", N=N)
    rt = tn.solve(start, goal)
    if not rt.ok:
        return [(float("nan"), float("nan"), rt, "failed")]
    best = (evaluate(crane, rt.trajectory).energy_J, rt)
    out = [(rt.duration_s, best[0], rt, "nlp")]
    for k in factors:
        if k <= 1.0:
            continue
        T = k * rt.duration_s
        src = "carried"
        r = en.solve(start, goal, T_max=T, w0=en.guess_from(stretch(best[1].trajectory, T)))
        if r.ok:
            ev = evaluate(crane, r.trajectory)
            if ev.max_limit_violation <= 1e-3 and ev.energy_J < best[0]:
                best, src = (ev.energy_J, r), "nlp"
        out.append((best[1].duration_s, best[0], best[1], src))
    return out


def stretch(traj: Trajectory, T: float) -> Trajectory:
    """The same joint path slowed uniformly to duration T ≥ traj.duration: velocities scale by
    1/k, accelerations 1/k², jerks 1/k³, pump flows 1/k — still within every limit."""
    k = T / traj.duration
    return Trajectory(traj.t * k, traj.q, traj.qd / k, traj.qdd / k ** 2,
                      joint_names=traj.joint_names, method=traj.method, objective="stretched",
                      limits=traj.limits, meta=dict(traj.meta, stretched_by=k))


def energy_optimal(crane, start, goal, T_max: float, *, time_result: PlanResult | None = None,
                   time_nlp: MoveNLP | None = None, energy_nlp: MoveNLP | None = None,
                   N: int = 40) -> tuple[PlanResult, dict]:
    """Least pump energy with duration ≤ T_max: the energy NLP warm-started from the
    time-optimal move stretched to T_max (and, if that does not win, from the Ruckig guess),
    judged by evaluate() against two always-feasible
    incumbents — that stretched move and the time-optimal move itself (T_min ≤ T_max); the lowest
    judged energy within the limits wins, so the result never costs more than the time-optimal
    move. With obstacles (``energy_nlp`` built with them) every NLP result must clear them on a
    fine resampling; the incumbents inherit the time-optimal move's clearance (stretching keeps
    the path). Returns (result, info), info["winner"] in {"nlp", "stretched", "time_optimal"}."""
    from planner.trajectory import evaluate
    t0 = _time.perf_counter()
    rt = time_result or (time_nlp or MoveNLP(crane, "time", "free", N=N)).solve(start, goal)
    if not rt.ok:
        return rt, dict(winner=None)
    if T_max < rt.duration_s * (1 - 1e-9):
        return _result("infeasible", f"T_max = {T_max:.3f} s is below the minimum time "
                         f"{rt.duration_s:.3f} s"), dict(winner=None)
    en = energy_nlp or MoveNLP(crane, "energy", "free", N=N)
    inc = stretch(rt.trajectory, T_max)
    e_inc = evaluate(crane, inc)
    best = (e_inc.energy_J, _result("ok", trajectory=inc, duration_s=T_max), "stretched")
    e_t = evaluate(crane, rt.trajectory).energy_J
    if e_t < best[0]:
        best = (e_t, rt, "time_optimal")
    tries = []
    def consider(r):
        nonlocal best
        if r.ok and en.obstacles and not en.clears(r.trajectory):
            r = _result("obstacle", "passes through an obstacle between check points")
        tries.append(r.status)
        if r.ok:
            ev = evaluate(crane, r.trajectory)
            if ev.max_limit_violation <= 1e-3 and ev.energy_J < best[0]:
                best = (ev.energy_J, r, "nlp")
    consider(en.solve(start, goal, T_max=T_max, w0=en.guess_from(inc)))
    if best[2] != "nlp":  # a second start from the independent Ruckig guess
        consider(en.solve(start, goal, T_max=T_max))
    res = best[1]
    res.solve_time_s = _time.perf_counter() - t0
    return res, dict(winner=best[2], energy_J=best[0], stretched_energy_J=e_inc.energy_J,
                     nlp_status=tries)


class NLPPlanner(Planner):
    """``nlp``: the CasADi/IPOPT move NLP (:class:`MoveNLP`), minimum time or least pump energy
    within ``duration`` (required for energy; free path: :func:`energy_optimal`, never above the
    time-optimal move's energy), free path or on the tip line, clear of the request's
    obstacles. Options: ``intervals`` (N, 40); ``time_result`` (energy: the time-optimal
    result of the same move, reused instead of solved again). Each NLP is built once per
    (machine, objective, path, N, obstacles) in this process and solved many times."""
    name = "nlp"
    description = "CasADi/IPOPT NLP: time or energy, free path or tip line, obstacles"
    objectives = ("time", "energy")
    paths = ("free", "line")
    obstacles = True
    uses_duration = True

    def __init__(self):
        self._built: dict = {}

    def check(self, request: PlanRequest) -> None:
        super().check(request)
        if request.objective == "energy" and request.duration is None:
            raise UnsupportedRequest("--method nlp --objective energy needs --duration T [s] "
                                     "(e.g. 1.2 × the minimum time)")

    def built(self, crane, objective: str, path: str = "free", N: int = 40,
              obstacles: tuple = ()) -> MoveNLP:
        """The MoveNLP for this formulation, built on first use and kept for the process."""
        # keyed by the crane object (kept alive with its NLP, so its id is never reused):
        # variants of one machine with other limits share the spec id but not the NLP
        key = (id(crane), objective, path, int(N), tuple(obstacles))
        if key not in self._built:
            nlp = MoveNLP(crane, objective, path, N=N, obstacles=tuple(obstacles))
            self._built[key] = (crane, nlp)
        return self._built[key][1]

    def clear(self) -> None:
        """Forget the NLPs built in this process (a timed build then starts from scratch)."""
        self._built.clear()

    def plan(self, crane, request: PlanRequest) -> PlanResult:
        N = request.option("intervals", 40)
        obs = request.obstacles
        if request.objective == "energy" and request.path == "free":
            res, info = energy_optimal(crane, request.start, request.goal, request.duration,
                                       time_result=request.option("time_result"),
                                       time_nlp=self.built(crane, "time", "free", N, obs),
                                       energy_nlp=self.built(crane, "energy", "free", N, obs))
            res.stats["energy_winner"] = info.get("winner")
            return res
        nlp = self.built(crane, request.objective, request.path, N, obs)
        return nlp.solve(request.start, request.goal, T_max=request.duration)


register(NLPPlanner())
