"""Local (resolved-rate) control laws: integrate a commanded tip velocity into a joint trajectory.

The driver :func:`follow` moves a reference point along a path at the commanded tip speed; each
control step (fixed rate) the law turns the tip velocity command (path tangent · speed plus a
small correction towards the reference point) into joint rates, possibly scaling the command by
β ≤ 1 when joints saturate — then the reference advances only β·v·dt. The result is the common
:class:`~planner.trajectory.Trajectory` (piecewise linear: the rates are held over each step).
When the rates ask for more oil than the pump delivers, every function slows in proportion
(load-sensing flow sharing, :func:`flow_share`), so law trajectories respect the pump limit.

Laws (seed 000): ``least_norm`` (plain pseudo-inverse, uniform speed scaling — the baseline),
``max_velocity`` (weighted pseudo-inverse with the pin-the-saturated-joint logic of section 5.2),
``max_lift`` (telescope set by the distance from a circle centre, section 6). The seed-002
cylinder-space laws live in :mod:`planner.methods.laws_energy`.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time as _time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from planner.geometry.paths import Line, Path
from planner.methods.base import (Planner, PlanRequest, PlanResult, PlanStatus,
                                  UnsupportedRequest)
from planner.methods.registry import register
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

DEFAULT_TIP_SPEED = 1.0   # [m/s] a law's tip speed when the request gives none
MAX_STEPS = 100_000       # nominal control steps of one law move (1000 s at 100 Hz)


@dataclass
class Step:
    """What a law sees each control step: configuration, tip (r, z, slew), Jacobian (3 × n),
    strokes and dx/dq, the allowed joint-rate box (already reduced near position limits), the
    step length [s], the previous rates and a per-run scratch dict."""
    q: np.ndarray
    tip: np.ndarray
    J: np.ndarray
    x: np.ndarray
    dxdq: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    dt: float
    qd_prev: np.ndarray
    memo: dict = field(default_factory=dict)


class Law(ABC):
    """A local redundancy resolution: ``rates(crane, step, v)`` -> (q̇, β) for the commanded
    tip velocity v = (ṙ, ż, slew rate). β ∈ [0, 1] is the factor the command was scaled by."""
    name = "law"

    def start_tele(self, crane: Crane, tip) -> float | None:
        """Telescope value the law needs at the start tip (None: any)."""
        return None

    def missing(self, crane: Crane) -> str:
        """What this machine lacks for the law ("" when it has everything)."""
        return ""

    @abstractmethod
    def rates(self, crane: Crane, st: Step, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Joint rates [rad/s | m/s] and the command scale β."""

    def __repr__(self):
        return f"{type(self).__name__}()"


def planar_slew_split(crane: Crane):
    """Indices of the slew joint and of the planar joints (boom, jib[, tele])."""
    pc = crane.chain
    planar = [pc.boom, pc.jib] + ([pc.tele] if pc.tele is not None else [])
    return pc.slew, np.array(planar)


def rate_box(crane: Crane, q):
    """Allowed joint-rate box: velocity limits, reduced near a position limit so the joint can
    still stop there with its acceleration limit (v ≤ sqrt(2·a·distance)); zero at the limit."""
    L = crane.limit_arrays()
    up = np.sqrt(2 * L["qdd_max"] * np.maximum(L["q_max"] - q, 0.0))
    dn = np.sqrt(2 * L["qdd_max"] * np.maximum(q - L["q_min"], 0.0))
    return np.maximum(L["qd_min"], -dn), np.minimum(L["qd_max"], up)


def flow_share(crane: Crane, q, qd, payload=None):
    """Load-sensing flow sharing: when the actuators ask for more than the pump delivers, every
    function slows in proportion (flow-sharing valves). Returns (q̇ scaled, factor ≤ 1)."""
    Q = crane.hydraulics(q, qd, np.zeros_like(qd), payload)["q_pump"]
    qmax = crane.spec.pump.max_flow
    if Q <= qmax:
        return qd, 1.0
    k = qmax / Q
    return qd * k, k


def _tip_error(e, r):
    """Planar tip error [m] including the slew part (arc length r·Δslew)."""
    return float(np.sqrt(e[0] ** 2 + e[1] ** 2 + (r * e[2]) ** 2))


def _ratio(qd, lo, hi):
    """Saturation ratio α_i = q̇_i / limit in the direction of motion (inf if limit is 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(qd >= 0, qd / hi, qd / lo)
    return np.where(np.abs(qd) < 1e-15, 0.0, np.where(np.isnan(a), np.inf, a))


def weighted_pinv_saturated(J, v, lo, hi, w):
    """Seed 000 section 5.2, for any number of joints: weighted least-norm rates
    q̇ = W⁻¹Jᵀ(JW⁻¹Jᵀ)⁻¹v; while a joint exceeds its limit, pin the most saturated one at its
    limit and re-solve the others (exactly when as many free joints as task rows remain); when
    fewer remain, scale the command by β (eq. 5.19–5.23). Returns (q̇, β)."""
    m, n = J.shape
    free = list(range(n))
    qd = np.zeros(n)
    beta = 1.0
    while True:
        pinned = [i for i in range(n) if i not in free]
        rhs = v - J[:, pinned] @ qd[pinned] if pinned else v.copy()
        Jf = J[:, free]
        if len(free) > m:
            Wi = 1.0 / w[free]
            A = (Jf * Wi) @ Jf.T
            qd[free] = Wi * (Jf.T @ np.linalg.solve(A, rhs))
        elif len(free) == m:
            qd[free] = np.linalg.lstsq(Jf, rhs, rcond=None)[0]  # exact unless singular
        else:
            # unknowns: free rates and β:  J_f q̇_f − β v = −J_p q̇_p
            k = J[:, pinned] @ qd[pinned]
            sol, *_ = np.linalg.lstsq(np.column_stack([Jf, -v]), -k, rcond=None)
            qd[free] = sol[:-1]
            a = _ratio(qd[free], lo[free], hi[free])
            if np.all(a <= 1 + 1e-9) and 0.0 <= sol[-1] <= 1.0 and \
                    np.allclose(J @ qd, sol[-1] * v, atol=1e-9):
                return qd, float(sol[-1])
            return _max_beta_lp(J, v, lo, hi)
        a = _ratio(qd[free], lo[free], hi[free])
        k = int(np.argmax(a))
        if a[k] <= 1 + 1e-12:
            return qd, beta
        i = free.pop(k)
        qd[i] = hi[i] if qd[i] > 0 else lo[i]


def _max_beta_lp(J, v, lo, hi):
    """Largest β ∈ [0, 1] with J·q̇ = β·v and lo ≤ q̇ ≤ hi (keeps the commanded direction);
    the fallback when pinning runs out of free joints."""
    from scipy.optimize import linprog
    n = J.shape[1]
    c = np.zeros(n + 1)
    c[-1] = -1.0
    res = linprog(c, A_eq=np.column_stack([J, -v]), b_eq=np.zeros(J.shape[0]),
                  bounds=[(lo[i], hi[i]) for i in range(n)] + [(0.0, 1.0)], method="highs")
    if res.status != 0:
        return np.zeros(n), 0.0
    return res.x[:n], float(res.x[-1])


def scale_into_box(qd, lo, hi):
    """Uniform scaling of the rates (and of the command) so that no joint exceeds its box."""
    a = float(np.max(_ratio(qd, lo, hi), initial=0.0))
    if a <= 1.0:
        return qd, 1.0
    if not np.isfinite(a):
        return np.zeros_like(qd), 0.0
    return qd / a, 1.0 / a


class LeastNorm(Law):
    """Plain pseudo-inverse q̇ = J⁺v on the planar joints, uniform scaling at saturation."""
    name = "least_norm"

    def rates(self, crane: Crane, st, v):
        s, P = planar_slew_split(crane)
        qd = np.zeros(crane.n)
        qd[P] = np.linalg.pinv(st.J[:2, P]) @ v[:2]
        qd[s] = (v[2] - st.J[2, P] @ qd[P]) / st.J[2, s]
        return scale_into_box(qd, st.lo, st.hi)


class MaxVelocity(Law):
    """Seed 000's maximum-velocity law: weighted pseudo-inverse, W from the spec's
    ``[laws] weights`` (seed: diag(1.5, 1, 8)), saturated joints pinned, then β scaling;
    the slew (Cartesian mode) scales everything by 1/α0 when it saturates."""
    name = "max_velocity"

    def __init__(self, weights=None):
        self.weights = weights

    def rates(self, crane: Crane, st, v):
        s, P = planar_slew_split(crane)
        wmap = self.weights or crane.spec.laws.weights
        w = np.array([wmap.get(crane.names[i], 1.0) for i in P])
        qd = np.zeros(crane.n)
        qd[P], beta = weighted_pinv_saturated(st.J[:2, P], v[:2], st.lo[P], st.hi[P], w)
        qd[s] = (beta * v[2] - st.J[2, P] @ qd[P]) / st.J[2, s]
        a0 = float(_ratio(np.array([qd[s]]), st.lo[[s]], st.hi[[s]])[0])
        if a0 > 1:
            qd, beta = qd / a0, beta / a0
        return qd, beta


class MaxLift(Law):
    """Seed 000's maximum-lifting-capacity law: the telescope follows the distance ρ of the tip
    from (rc, zc): retracted for ρ < ρmin, extended for ρ > ρmax, a cubic in between; its rate
    ḋ3 = f·ṙ + g·ż (f, g = ∂d3/∂r, ∂d3/∂z), the boom and jib solve the remaining 2×2 system
    (the seed's P matrix, eq. 6.13, derived from the Jacobian); uniform scaling at saturation."""
    name = "max_lift"

    def __init__(self, rc=None, zc=None, rho_min=None, rho_max=None, gain=5.0):
        self.p = dict(rc=rc, zc=zc, rho_min=rho_min, rho_max=rho_max)
        self.gain = gain  # [1/s] pulls the telescope onto d3(ρ) (numerical drift only)

    def _params(self, crane: Crane):
        p = {k: (v if v is not None else crane.spec.laws.max_lift.get(k))
             for k, v in self.p.items()}
        if any(v is None for v in p.values()):
            raise ValueError(f"max_lift needs rc, zc, rho_min, rho_max (crane '{crane.spec.id}' "
                             "has no [laws] max_lift table)")
        return p

    def missing(self, crane: Crane) -> str:
        if crane.chain.tele is None:
            return "it moves a telescope, and the machine has none"
        try:
            self._params(crane)
        except ValueError as e:
            return str(e)
        return ""

    def tele_of(self, crane: Crane, r, z):
        """(d3, ∂d3/∂r, ∂d3/∂z) at tip (r, z) — the seed's cubic d3(ρ)."""
        p = self._params(crane)
        lo, hi = crane.tele_range
        d3max = hi - lo
        rho = math.hypot(r - p["rc"], z - p["zc"])
        pm, qh = 0.5 * (p["rho_max"] + p["rho_min"]), 0.5 * (p["rho_max"] - p["rho_min"])
        if rho <= p["rho_min"]:
            return lo, 0.0, 0.0
        if rho >= p["rho_max"]:
            return hi, 0.0, 0.0
        u = rho - pm
        d3 = lo + 0.5 * d3max * (1 + 1.5 * u / qh - 0.5 * u ** 3 / qh ** 3)
        c = 0.75 * d3max / qh * (1 - u * u / (qh * qh))  # dd3/dρ (the digest's /2q² is garbled)
        return d3, c * (r - p["rc"]) / rho, c * (z - p["zc"]) / rho

    def start_tele(self, crane: Crane, tip):
        return self.tele_of(crane, tip[0], tip[1])[0]

    def rates(self, crane: Crane, st, v):
        s, P = planar_slew_split(crane)
        t = crane.chain.tele
        if t is None:
            raise ValueError("max_lift needs a telescope")
        d3, f, g = self.tele_of(crane, st.tip[0], st.tip[1])
        qd = np.zeros(crane.n)
        qd[t] = f * v[0] + g * v[1] + self.gain * (d3 - st.q[t])
        bj = [crane.chain.boom, crane.chain.jib]
        qd[bj] = np.linalg.solve(st.J[:2, bj], v[:2] - st.J[:2, t] * qd[t])
        qd[s] = (v[2] - st.J[2, P] @ qd[P]) / st.J[2, s]
        return scale_into_box(qd, st.lo, st.hi)


LAWS = {c.name: c for c in (LeastNorm, MaxVelocity, MaxLift)}


def _result(status: PlanStatus, reason: str = "", **kw) -> PlanResult:
    """A law's result: status "ok", "unreachable" (start not reachable), "stalled" (the law
    stopped moving along the path) or "timeout"; stats ``min_beta`` (least path-speed ratio β)
    and ``max_path_error_m``; the trajectory's ``meta`` holds the β statistics."""
    kw.setdefault("min_beta", math.nan)
    kw.setdefault("max_path_error_m", math.nan)
    return PlanResult(status, reason, **kw)


def _tip_rate_along(path, s, h=1e-4):
    a = path.tip(np.array([min(s + h, path.length)]))[0]
    b = path.tip(np.array([max(s - h, 0.0)]))[0]
    d = a - b
    d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
    return d / (min(s + h, path.length) - max(s - h, 0.0))


def follow(crane: Crane, path: Path, law: Law, tip_speed: float, *, q0=None, tele0=None,
           rate: float = 100.0, gain: float = 5.0, max_time: float | None = None) -> PlanResult:
    """Drive the tip along ``path`` at ``tip_speed`` [m/s] with ``law`` at ``rate`` [Hz].

    Start configuration: ``q0``, else the IK of the path start with ``tele0``; without
    ``tele0`` the law's preferred telescope (max-lift: d3(ρ); others: mid-range), or — when that
    is unreachable — the nearest reachable value (seed 000 does not state its start telescope).
    ``gain`` [1/s] corrects drift from the reference point. Stops at the end of the path (last
    step shortened to land on it)."""
    t_start = _time.perf_counter()
    if not (math.isfinite(tip_speed) and tip_speed > 0):
        raise ValueError(f"tip_speed = {tip_speed!r} m/s: allowed a finite number > 0")
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate = {rate!r} Hz: allowed a finite number > 0")
    start = path.tip(np.array([0.0]))[0]
    if q0 is None:
        tele = crane._tele_default(tele0 if tele0 is not None else law.start_tele(crane, start))
        q, reason = crane.ik_batch(start[None, :], tele)
        if reason[0] and tele0 is None and crane.tele_range is not None:
            grid = np.linspace(*crane.tele_range, 281)
            qs, rs = crane.ik_batch(np.tile(start, (len(grid), 1)), grid)
            ok = np.flatnonzero(rs == "")
            if ok.size:
                k = ok[np.argmin(np.abs(grid[ok] - tele))]
                q, reason = qs[k:k + 1], rs[k:k + 1]
        if reason[0]:
            return _result(PlanStatus.UNREACHABLE, f"start tip (r={start[0]:.3f} m, "
                           f"z={start[1]:.3f} m, slew={start[2]:.3f} rad) is unreachable: "
                           f"{reason[0]}", solve_time_s=_time.perf_counter() - t_start)
        q = q[0]
    else:
        q = np.asarray(q0, float).copy()
    dt = 1.0 / rate
    max_time = max_time if max_time is not None else 20.0 * path.length / tip_speed + 10.0
    s, t = 0.0, 0.0
    Ts, Qs, QDs, betas, errs = [0.0], [q.copy()], [], [], []
    qd_prev = np.zeros(crane.n)
    memo: dict = {}
    stall = 0
    while s < path.length - 1e-12:
        tip, J, x, dxdq = crane.kinematics(q)
        ref = path.tip(np.array([s]))[0]
        e = ref - tip
        e[2] = (e[2] + math.pi) % (2 * math.pi) - math.pi
        errs.append(_tip_error(e, tip[0]))
        v = tip_speed * _tip_rate_along(path, s) + gain * e
        lo, hi = rate_box(crane, q)
        qd, beta = law.rates(crane, Step(q, tip, J, x, dxdq, lo, hi, dt, qd_prev, memo), v)
        qd, share = flow_share(crane, q, qd)
        beta *= share
        ds = beta * tip_speed * dt
        h = dt
        if s + ds > path.length:
            h = dt * (path.length - s) / ds
            ds = path.length - s
        q = q + qd * h
        s += ds
        t += h
        Ts.append(t)
        Qs.append(q.copy())
        QDs.append(qd)
        betas.append(beta)
        qd_prev = qd
        stall = stall + 1 if beta < 1e-3 else 0
        if stall > rate:  # a full second without progress
            return _result(PlanStatus.STALLED, f"{law.name} stopped at s = {s:.3f} m of "
                             f"{path.length:.3f} m (joints saturated or at their limits)",
                             solve_time_s=_time.perf_counter() - t_start)
        if t > max_time:
            return _result(PlanStatus.TIMEOUT, f"{law.name} did not finish within {max_time:.1f} s",
                             solve_time_s=_time.perf_counter() - t_start)
    traj = Trajectory(np.array(Ts), np.array(Qs), joint_names=tuple(crane.names),
                      method=f"law:{law.name}", objective="tracking", interpolation="linear",
                      limits=("position", "velocity", "pump_flow"),
                      meta=dict(law=law.name, tip_speed=tip_speed, rate_hz=rate,
                                start_q=Qs[0].tolist(),
                                min_beta=float(min(betas)), mean_beta=float(np.mean(betas)),
                                path=path.name, path_length_m=path.length))
    return _result(PlanStatus.OK, trajectory=traj, duration_s=t, min_beta=float(min(betas)),
                     max_path_error_m=float(max(errs)),
                     solve_time_s=_time.perf_counter() - t_start)


def follow_command(crane: Crane, law: Law, command, duration: float, *, q0, rate: float = 100.0,
                   gain: float = 5.0, payload: float | None = None) -> PlanResult:
    """Run ``law`` for ``duration`` [s] on a time-based command: ``command(t)`` returns the
    reference tip (r, z, slew) and its velocity at time t (e.g. seed 002's h/v/d cycles with
    pauses). When the law must scale the command (β < 1) the tip lags the reference and the
    correction ``gain`` [1/s] pulls it back; the largest lag is reported."""
    t_start = _time.perf_counter()
    q = np.asarray(q0, float).copy()
    n_steps = int(math.ceil(duration * rate - 1e-9))
    dt = duration / n_steps
    Ts, Qs, betas, errs = [0.0], [q.copy()], [], []
    qd_prev = np.zeros(crane.n)
    memo: dict = {"payload": payload}
    for k in range(n_steps):
        t = k * dt
        tip, J, x, dxdq = crane.kinematics(q)
        ref, vref = command(t)
        e = np.asarray(ref, float) - tip
        e[2] = (e[2] + math.pi) % (2 * math.pi) - math.pi
        errs.append(_tip_error(e, tip[0]))
        v = np.asarray(vref, float) + gain * e
        lo, hi = rate_box(crane, q)
        qd, beta = law.rates(crane, Step(q, tip, J, x, dxdq, lo, hi, dt, qd_prev, memo), v)
        qd, share = flow_share(crane, q, qd, payload)
        beta *= share
        q = q + qd * dt
        Ts.append((k + 1) * dt)
        Qs.append(q.copy())
        betas.append(beta)
        qd_prev = qd
    traj = Trajectory(np.array(Ts), np.array(Qs), joint_names=tuple(crane.names),
                      method=f"law:{law.name}", objective="tracking", interpolation="linear",
                      limits=("position", "velocity", "pump_flow"),
                      meta=dict(law=law.name, rate_hz=rate, min_beta=float(min(betas)),
                                mean_beta=float(np.mean(betas))))
    return _result(PlanStatus.OK, trajectory=traj, duration_s=duration, min_beta=float(min(betas)),
                     max_path_error_m=float(max(errs)),
                     solve_time_s=_time.perf_counter() - t_start)


class LawPlanner(Planner):
    """``law:NAME``: a local control law driving the tip along the straight line at the
    request's ``tip_speed`` (default 1 m/s; at most :data:`MAX_STEPS` control steps per move).
    Options: ``rate`` [Hz] (control rate, 100),
    ``tele0`` [m] (start telescope; default: the law's choice)."""
    objectives = ("time",)
    paths = ("line",)
    uses_tip_speed = True

    def __init__(self, law_cls):
        self.law_cls = law_cls
        self.name = f"law:{law_cls.name}"
        self.description = f"local law {law_cls.name} along the tip line at a set tip speed"

    def check(self, request: PlanRequest) -> None:
        """Also refuses a move whose nominal control-step count (line length / tip speed ·
        rate) exceeds :data:`MAX_STEPS`: the law integrates step by step, so a near-zero tip
        speed would otherwise run for hours."""
        super().check(request)
        if request.start == request.goal:
            return
        speed = request.tip_speed if request.tip_speed is not None else DEFAULT_TIP_SPEED
        rate = request.option("rate", 100.0)
        length = Line(request.start, request.goal).length
        steps = length / speed * rate
        if steps > MAX_STEPS:
            raise UnsupportedRequest(
                f"`tip_speed` {speed:g} m/s: {self.name} would take {steps:.3g} control steps "
                f"for the {length:.3g} m line at {rate:g} Hz; allowed at most {MAX_STEPS} "
                f"(`tip_speed` >= {length * rate / MAX_STEPS:.3g} m/s at this rate)")

    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        """Raises :class:`UnsupportedRequest` when the machine lacks what the law needs (the
        ``max_lift`` law's [laws] table and a telescope)."""
        law = self.law_cls()
        why = law.missing(crane)
        if why:
            raise UnsupportedRequest(f"{self.name} does not plan on {crane.spec.id}: {why}")
        speed = request.tip_speed if request.tip_speed is not None else DEFAULT_TIP_SPEED
        return follow(crane, Line(request.start, request.goal), law, speed,
                      rate=request.option("rate", 100.0), tele0=request.option("tele0"))


for _law in LAWS.values():
    register(LawPlanner(_law))
