"""Seed 003's re-planning to start (and end) at rest: Ruckig transitions into and out of the
nominal phase-plane profile.

:func:`from_rest` replaces the seed's quintic transitions by Ruckig state-to-state transitions
(:mod:`planner.methods.ruckig`, community edition, no waypoints): from rest at the path start
into the nominal profile (:class:`~planner.methods.phase.envelope.Profile`) at
θ_int = inf θ + 0.05·span and (non-periodic paths) from the nominal profile at
inf θ + 0.95·span back to rest at the path end, matching position, velocity and acceleration
at the junctions. By default the transition is planned for the path parameter (1 DOF: the tip
stays on the path, the phase-plane picture of the seed); ``space="joint"`` plans it for the
four joints instead (the tip leaves the path in between).

Acceleration and jerk limits in the spec of umea-lab are assumptions (seed 003 gives none).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planner.methods.phase.envelope import CLAIMS, Profile, path_states
from planner.methods.ruckig import NO_JERK, sample, state_to_state_relaxed
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Junction", "FromRest", "from_rest", "V_HEADROOM", "SPEED_RATIO_MAX"]

V_HEADROOM = 1.02  # θ-space velocity cap at least 2 % above the junction speed (still < envelope)
SPEED_RATIO_MAX = 0.999  # θ-space transitions: θ̇ ≤ this × envelope at the samples


@dataclass
class Junction:
    """How well a transition meets the nominal profile at a junction."""
    where: str           # "start" (rest -> nominal) or "end" (nominal -> rest)
    theta: float
    t: float             # time of the junction in the from-rest trajectory [s]
    pos_err: float       # max |Δq| between the transition's end state and the nominal [rad | m]
    vel_err: float       # max |Δq̇|
    acc_err: float       # max |Δq̈|
    path_err: tuple      # |Δθ|, |Δθ̇|, |Δθ̈| (theta space; NaN for joint-space transitions)

    @property
    def max_err(self) -> float:
        return max(self.pos_err, self.vel_err, self.acc_err)

    def as_dict(self):
        return dict(where=self.where, theta=self.theta, t=self.t, pos_err=self.pos_err,
                    vel_err=self.vel_err, acc_err=self.acc_err,
                    path_err=[float(v) for v in self.path_err])


@dataclass
class FromRest:
    """A from-rest motion: transitions and the nominal section joined into one trajectory."""
    trajectory: Trajectory
    duration: float
    space: str
    junctions: list            # Junction per joint-over point
    transitions: list          # dicts: where, duration, Ruckig limits, speed over envelope
    transition_trajectories: list  # the transitions alone (Trajectory each), for evaluate()
    phase: tuple               # (t, θ, θ̇) of the whole motion (θ̇ NaN in joint-space transitions)
    max_path_deviation: float  # max tip distance from the path [m]
    nominal_part: tuple        # (θ_start, θ_end) of the nominal section

    def summary(self) -> dict:
        return dict(space=self.space, duration_s=self.duration,
                    junctions=[j.as_dict() for j in self.junctions],
                    max_junction_error=max(j.max_err for j in self.junctions),
                    transitions=self.transitions,
                    max_path_deviation_m=self.max_path_deviation,
                    nominal_theta=[float(v) for v in self.nominal_part])


def _jerk_for(v, a, vmin, vmax, forward: bool):
    """Smallest jerk with which a state (v, a) does not inevitably leave [vmin, vmax]: forward
    in time (a current state) or backward (a target state). Ruckig rejects such states."""
    v, a = np.asarray(v, float), np.asarray(a, float)
    grow = (a > 0) if forward else (a < 0)          # velocity keeps moving away from v
    room = np.where(grow, vmax - v, v - vmin)
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.where(a != 0, a * a / (2 * np.maximum(room, 1e-12)), 0.0)
    return need * (1 + 1e-6)


def _transition(crane: Crane, profile, where, th_rest, th_j, junction, space, rate, accel_scale):
    """Ruckig transition between rest at θ = th_rest and the nominal state at θ = th_j.
    ``junction`` = ((f, f f'), (q, q̇, q̈)) of the nominal there. Returns samples in local
    time (t, q, qd, qdd, θ, θ̇), the Junction (with t relative to the transition) and info."""
    path = profile.path
    L = crane.limit_arrays()
    jmax_j = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], NO_JERK)
    (fj, aj), (qj, vj, accj) = junction
    fj, aj = float(fj[0]), float(aj[0])
    qj, vj, accj = qj[0], vj[0], accj[0]
    start = where == "start"
    if space == "theta":
        lo, hi = sorted((th_rest, th_j))
        m = (profile.theta >= lo) & (profile.theta <= hi)
        _, dq_ab, _, f_ab, _ = path_states(crane, path, profile.tele, profile.coef,
                                       np.array([lo, hi]), profile.fraction)
        dmax = np.max(np.abs(np.vstack([profile.dq[m], dq_ab])), axis=0)
        env_min = float(min(profile.f[m].min(initial=np.inf), f_ab.min()))  # fraction·env
        vcap = max(env_min, V_HEADROOM * fj)
        with np.errstate(divide="ignore"):
            a_der = accel_scale * float(np.min(L["qdd_max"] / dmax))
            j_der = float(np.min(jmax_j / dmax))
        amax = max(a_der, abs(aj) * (1 + 1e-9))
        jmax = max(j_der, float(_jerk_for(fj, aj, 0.0, vcap, forward=not start)))
        j_req_state = float(_jerk_for(fj, aj, 0.0, vcap, forward=not start))
        rest = ([th_rest], [0.0], [0.0])
        nom = ([th_j], [fj], [aj])
        a_req, j_req = abs(aj) * (1 + 1e-9), j_req_state  # the junction state needs these
        slow = 1.0
        for _ in range(40):
            # the cap is a constant: where the envelope is lower than at the junction (e.g.
            # rising from the path start) the transition is slowed down (acceleration and jerk
            # limits × 0.8) until θ̇ stays under the envelope
            a_try, j_try = max(amax * slow, a_req), max(jmax * slow, j_req)
            tr, scale = state_to_state_relaxed(*((rest, nom) if start else (nom, rest)), [vcap],
                                        [0.0], [a_try], [j_try])
            t, th, thd, thdd = sample(tr, rate)
            th, thd, thdd = th[:, 0], thd[:, 0], thdd[:, 0]
            env = path_states(crane, path, profile.tele, profile.coef, th, 1.0)[3]
            if np.max(thd / env) <= SPEED_RATIO_MAX or (a_try <= a_req and j_try <= j_req):
                break
            slow *= 0.8
        amax, jmax = a_try, j_try
        q, qd, qdd = profile.joint_state(crane, th, thd, thdd)
        k = -1 if start else 0
        perr = (abs(th[k] - th_j), abs(thd[k] - fj), abs(thdd[k] - aj))
        info = dict(where=where, duration_s=tr.duration, space=space,
                    junction_theta_dot=fj, junction_theta_ddot=aj,
                    limits=dict(theta_dot_max=vcap, theta_dot_min=0.0,
                                theta_ddot_max=amax * scale, theta_dddot_max=jmax * scale,
                                theta_ddot_from_joints=a_der, theta_dddot_from_joints=j_der),
                    limit_scale=scale, slow_down=slow,
                    max_speed_over_envelope=float(np.max(thd / env)),
                    min_theta_dot=float(thd.min()),
                    theta_range=[float(th.min()), float(th.max())])
    else:
        q_rest = profile.joint_state(crane, np.array([th_rest]), np.zeros(1), np.zeros(1))[0][0]
        amax = np.maximum(L["qdd_max"], np.abs(accj) * (1 + 1e-9))
        jmax = np.maximum(jmax_j, _jerk_for(vj, accj, L["qd_min"], L["qd_max"],
                                            forward=not start))
        z = np.zeros(crane.n)
        rest, nom = (q_rest, z, z), (qj, vj, accj)
        tr, scale = state_to_state_relaxed(*((rest, nom) if start else (nom, rest)), L["qd_max"],
                                    L["qd_min"], amax, jmax)
        t, q, qd, qdd = sample(tr, rate)
        th = path.theta_of(crane.fk(q))
        thd = np.full_like(th, np.nan)
        k = -1 if start else 0
        perr = (math.nan,) * 3
        info = dict(where=where, duration_s=tr.duration, space=space,
                    junction_theta_dot=fj, junction_theta_ddot=aj,
                    limits=dict(qdd_max=(amax * scale).tolist(),
                                qddd_max=(jmax * scale).tolist()),
                    limit_scale=scale)
    junc = Junction(where, float(th_j), float(t[k]), float(np.max(np.abs(q[k] - qj))),
                    float(np.max(np.abs(qd[k] - vj))), float(np.max(np.abs(qdd[k] - accj))),
                    tuple(float(v) for v in perr))
    return (t, q, qd, qdd, th, thd), junc, info


def from_rest(crane: Crane, profile: Profile, *, start_frac: float = 0.05,
              end_frac: float | None = None, space: str = "theta",
              sample_rate: float = 200.0, accel_scale: float = 1.0) -> FromRest:
    """Start from rest at the path start and join the nominal profile at
    θ_int = θ0 + start_frac·span; for non-periodic paths (or with ``end_frac``) leave it at
    θ0 + end_frac·span (default 0.95) and come to rest at the path end. A periodic path keeps
    the nominal profile to the end of the revolution (it "remains in a cycle"): the motion
    then ends moving.

    ``space="theta"`` (default): 1-DOF Ruckig on the path parameter (the tip stays on the
    path), θ̇ ∈ [0, max(fraction·min envelope on the transition, 1.02·f(θ_int))] (never backwards
    along the path), θ̈ and θ⃛ limits from the joints' (assumed) acceleration/jerk limits divided
    by max |Φ'_i| on the transition (``accel_scale`` scales the acceleration), each raised where
    the nominal junction state needs it (its acceleration; a jerk with which the state can be
    reached without leaving the velocity range — Ruckig rejects it otherwise).
    ``space="joint"``: 4-DOF Ruckig between the rest configuration Φ(θ0) (Φ(θ1)) and the
    nominal joint state under the joints' velocity/acceleration/jerk limits (raised likewise
    where the junction state needs it); the tip leaves the path during the transition.

    Junction errors compare the transition's own end state (Ruckig's ``at_time``, mapped to
    the joints) with the nominal joint state at the junction.
    """
    if space not in ("theta", "joint"):
        raise ValueError("space must be 'theta' or 'joint'")
    path = profile.path
    if end_frac is None and not path.periodic:
        end_frac = 0.95
    th_s = path.theta0 + start_frac * path.span
    th_e = path.theta0 + end_frac * path.span if end_frac is not None else None
    th_end = th_e if th_e is not None else path.theta1

    nom_s = profile.nominal_state(crane, np.array([th_s]), side=+1)
    nom_e = profile.nominal_state(crane, np.array([th_end]), side=-1 if th_e is not None else 0)

    # ---- rest at θ0 -> nominal at θ_s
    p1, j1, i1 = _transition(crane, profile, "start", path.theta0, th_s, nom_s, space,
                             sample_rate, accel_scale)
    T1 = p1[0][-1]
    pieces = [p1]
    trans = [p1]
    junctions, transitions = [j1], [i1]

    # ---- nominal θ_s .. θ_end (junction knots: the nominal's own states)
    k_in = np.flatnonzero((profile.theta > th_s + 1e-9) & (profile.theta < th_end - 1e-9))
    f_in = profile.f[k_in]
    thn = np.concatenate([[th_s], profile.theta[k_in], [th_end]])
    fn = np.concatenate([nom_s[0][0], f_in, nom_e[0][0]])
    tn = T1 + np.concatenate([[0.0], np.cumsum(0.5 * (1 / fn[1:] + 1 / fn[:-1]) * np.diff(thn))])
    qn = np.vstack([nom_s[1][0], profile.q[k_in], nom_e[1][0]])
    qdn = np.vstack([nom_s[1][1], profile.dq[k_in] * f_in[:, None], nom_e[1][1]])
    qddn = np.vstack([nom_s[1][2], profile.ddq[k_in] * (f_in ** 2)[:, None]
                      + profile.dq[k_in] * (f_in * profile.df[k_in])[:, None], nom_e[1][2]])
    # the start knot is the transition's last sample; replace it by the nominal state there
    pieces[0] = tuple(a[:-1] for a in p1)
    pieces.append((tn, qn, qdn, qddn, thn, fn))
    T2 = tn[-1]

    # ---- nominal at θ_e -> rest at θ1
    if th_e is not None:
        p2, j2, i2 = _transition(crane, profile, "end", path.theta1, th_e, nom_e, space,
                                 sample_rate, accel_scale)
        j2.t += T2
        pieces.append((T2 + p2[0][1:],) + tuple(a[1:] for a in p2[1:]))
        trans.append(p2)
        junctions.append(j2)
        transitions.append(i2)

    t = np.concatenate([p[0] for p in pieces])
    q = np.vstack([p[1] for p in pieces])
    qd = np.vstack([p[2] for p in pieces])
    qdd = np.vstack([p[3] for p in pieces])
    th = np.concatenate([p[4] for p in pieces])
    thd = np.concatenate([p[5] for p in pieces])
    meta = dict(path=path.name, fraction=profile.fraction, space=space, start_frac=start_frac,
                end_frac=end_frac)
    traj = Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names), method="phase+ruckig",
                      objective="time", limits=CLAIMS, meta=meta)
    ttraj = [Trajectory(p[0], p[1], p[2], p[3], joint_names=tuple(crane.names),
                        method="ruckig-transition", objective="time", limits=CLAIMS,
                        meta=meta)
             for p in trans]
    # tip deviation from the path: nearest point of a dense sample of the path
    dense = path.xyz(np.linspace(path.theta0, path.theta1, 20001))
    dev = float(np.max(cKDTree(dense).query(crane.fk(q))[0]))
    return FromRest(traj, traj.duration, space, junctions, transitions, ttraj, (t, th, thd),
                    dev, (th_s, th_end))


