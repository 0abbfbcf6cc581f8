"""Seed 000's setting as an NLP: minimum time along the straight tip line under velocity limits
only (the DP's model), for comparisons with the Bellman DP (:mod:`planner.methods.dp`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import time as _time

import casadi as ca
import numpy as np

from planner.geometry.paths import Line, tip_to_xyz
from planner.methods.base import PlanResult, PlanStatus
from planner.methods.dp import dp
from planner.methods.nlp.transcription import STATUS_OK, nlp_result
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["kinematic_line_nlp"]


def kinematic_line_nlp(crane: Crane, start, goal, N: int = 100, w0_traj=None) -> PlanResult:
    """Velocity-limits-only minimum time along the straight line (seed 000's setting, the DP's
    model): piecewise-constant joint rates on N equal time steps, the tip on the line at every
    node, no rest conditions (the seed's DP starts and ends at speed). Warm start: the DP path
    (Δ = 0.02 m) resampled in time, unless ``w0_traj`` is given. For comparisons with the DP."""
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
            return nlp_result(r.status, r.reason, solve_time_s=_time.perf_counter() - t0)
        w0_traj = r.trajectory
    tt = np.linspace(0, w0_traj.duration, N + 1)
    q0 = w0_traj.sample(tt)[0]
    v0 = np.diff(q0, axis=0) / (tt[1] - tt[0])
    x0 = np.concatenate([q0.ravel(), v0.ravel(), [w0_traj.duration]])
    sol = S(x0=x0, lbx=lbw, ubx=ubw, lbg=0.0, ubg=0.0)
    st = S.stats()
    ist = st.get("return_status", "")
    if ist not in STATUS_OK:
        return nlp_result(PlanStatus.FAILED, f"IPOPT: {ist}", ipopt_status=ist,
                         solve_time_s=_time.perf_counter() - t0)
    x = np.array(sol["x"]).ravel()
    Qs = x[:n * (N + 1)].reshape(N + 1, n)
    Tn = float(x[-1])
    traj = Trajectory(np.linspace(0, Tn, N + 1), Qs, joint_names=tuple(crane.names),
                      method="nlp", objective="time", interpolation="linear",
                      limits=("position", "velocity"), meta=dict(N=N, path="line",
                                                                 model="kinematic"))
    return nlp_result(PlanStatus.OK, trajectory=traj, duration_s=Tn,
                      iterations=st.get("iter_count", 0), ipopt_status=ist,
                      solve_time_s=_time.perf_counter() - t0)

