"""Forward kinematics (symbolic, from the DH table) and the analytic knuckle-boom IK.

Conventions (docs/design.md, "CONTRACT: tip coordinates"): standard DH,
A_i = Rot_z(θ_i)·Trans_z(d_i)·Trans_x(a_i)·Rot_x(α_i); joint i moves about / along z of frame i;
the tip is the origin of the last frame. Tip coordinates (r, z, slew) are cylindrical in
frame 0: r = sqrt(x² + y²), z, slew = atan2(y, x).

The IK is derived from the forward kinematics itself (no second hand-written geometry): at slew
zero the boom and jib rotate about parallel horizontal axes, so in the vertical plane of motion
the tip is  P = E + Rot(σ1 q1 + σ2 q2)·W(t)  with the elbow  E = S + Rot(σ1 q1)·(E0 − S),  where S,
E0, W(t) (t = telescope) and the rotation senses σ are read off the DH chain at q = 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from planner.model.spec import CraneSpec, SpecError


def dh_matrix(theta, d, a, alpha):
    """Symbolic 4×4 standard DH transform (works for SX, MX and floats)."""
    ct, st = ca.cos(theta), ca.sin(theta)
    ca_, sa = math.cos(alpha), math.sin(alpha)
    return ca.vertcat(
        ca.horzcat(ct, -st * ca_, st * sa, a * ct),
        ca.horzcat(st, ct * ca_, -ct * sa, a * st),
        ca.horzcat(0, sa, ca_, d),
        ca.horzcat(0, 0, 0, 1),
    )


def joint_transforms(spec: CraneSpec, q):
    """List of the n symbolic DH transforms A_i(q_i)."""
    out = []
    for i, j in enumerate(spec.joints):
        if j.revolute:
            out.append(dh_matrix(j.dh.theta + q[i], j.dh.d, j.dh.a, j.dh.alpha))
        else:
            out.append(dh_matrix(j.dh.theta, j.dh.d + q[i], j.dh.a, j.dh.alpha))
    return out


def tip_position(spec: CraneSpec, q):
    """Tip position (x, y, z) in frame 0 as a symbolic 3-vector."""
    T = ca.SX.eye(4) if isinstance(q, ca.SX) else ca.MX.eye(4) if isinstance(q, ca.MX) else ca.DM.eye(4)
    for A in joint_transforms(spec, q):
        T = T @ A
    return T[:3, 3]


def cylindrical(p):
    """(x, y, z) -> (r, z, slew)."""
    return ca.vertcat(ca.sqrt(p[0] ** 2 + p[1] ** 2), p[2], ca.atan2(p[1], p[0]))


class UnreachableError(ValueError):
    """A tip position that the crane cannot reach; the message says why."""


def _fk_numeric(spec: CraneSpec, q: np.ndarray) -> list[np.ndarray]:
    """Numeric 4×4 frames T_0..T_n (float64) for one configuration; used once at build time."""
    T = np.eye(4)
    frames = [T.copy()]
    for A in joint_transforms(spec, q.tolist()):
        T = T @ np.array(ca.DM(A))
        frames.append(T.copy())
    return frames


@dataclass(frozen=True)
class PlanarChain:
    """The knuckle-boom structure read off the DH table (all lengths in m, angles in rad).

    Indices: slew, boom, jib (revolute), tele (prismatic or None). In the vertical plane of motion
    (coordinates (ρ, z), ρ along ``h``): S shoulder (boom axis), E0 elbow (jib axis) at q = 0,
    W0 + t·Wt the elbow->tip vector at q = 0 with telescope t; sig_boom / sig_jib rotation senses;
    ``lateral`` the constant out-of-plane offset of the tip; ``psi_h`` the azimuth of h at slew 0.
    """
    slew: int
    boom: int
    jib: int
    tele: int | None
    S: np.ndarray
    E0: np.ndarray
    W0: np.ndarray
    Wt: np.ndarray
    sig_boom: float
    sig_jib: float
    lateral: float
    psi_h: float
    sig_lat: float
    elbow: float  # +1 up, -1 down


def planar_chain(spec: CraneSpec) -> PlanarChain:
    """Extract and verify the knuckle-boom structure (slew, boom, jib[, telescope])."""
    kinds = [j.type for j in spec.joints]
    names = spec.joint_names
    if kinds not in (["revolute"] * 3, ["revolute"] * 3 + ["prismatic"]):
        raise SpecError(spec.path, "joint[*].type", kinds,
                        "a knuckle boom is slew, boom, jib (revolute) [+ telescope (prismatic)]")
    tele = 3 if len(kinds) == 4 else None
    n = spec.n
    q0 = np.zeros(n)
    F = _fk_numeric(spec, q0)
    ez = np.array([0.0, 0.0, 1.0])
    u = F[1][:3, 2]  # boom axis (z of frame 1) at q = 0
    if abs(u @ ez) > 1e-9:
        raise SpecError(spec.path, f"joint[0]({names[0]}).dh.alpha", spec.joints[0].dh.alpha,
                        "the boom axis must be horizontal (perpendicular to the slew axis)")
    if abs(abs(F[2][:3, 2] @ u) - 1.0) > 1e-9:
        raise SpecError(spec.path, f"joint[1]({names[1]}).dh.alpha", spec.joints[1].dh.alpha,
                        "the jib axis must be parallel to the boom axis (alpha 0 or ±π)")
    if tele is not None and abs(F[3][:3, 2] @ u) > 1e-9:
        raise SpecError(spec.path, f"joint[2]({names[2]}).dh.alpha", spec.joints[2].dh.alpha,
                        "the telescope must slide in the plane of boom and jib (alpha ±π/2)")
    h = np.cross(u, ez)
    # orient h so that the tip at mid-range is in front of the slew axis
    qm = np.array([0.5 * (j.limits.q[0] + j.limits.q[1]) for j in spec.joints])
    qm[0] = 0.0
    if _fk_numeric(spec, qm)[-1][:3, 3] @ h < 0:
        h = -h
    nrm = np.cross(h, ez)  # positive rotation about nrm turns h towards ez (CCW in (ρ, z))

    def planar(p):
        return np.array([p @ h, p @ ez])

    S = planar(F[1][:3, 3])
    E0 = planar(F[2][:3, 3])
    tip0 = F[-1][:3, 3]
    lateral = float(tip0 @ u)
    # the lateral offset must not depend on boom/jib/telescope (pure planar structure)
    rng = np.random.default_rng(0)
    for _ in range(5):
        qt = np.array([rng.uniform(*j.limits.q) for j in spec.joints])
        qt[0] = 0.0
        if abs(_fk_numeric(spec, qt)[-1][:3, 3] @ u - lateral) > 1e-9:
            raise SpecError(spec.path, "joint[*].dh", None,
                            "the tip leaves the boom plane: not a knuckle-boom structure")
    W0 = planar(tip0) - E0
    if tele is not None:
        q1 = q0.copy()
        q1[tele] = 1.0
        Wt = planar(_fk_numeric(spec, q1)[-1][:3, 3]) - E0 - W0
    else:
        Wt = np.zeros(2)
    sig_boom = float(np.sign(F[1][:3, 2] @ nrm))
    sig_jib = float(np.sign(F[2][:3, 2] @ nrm))
    psi_h = math.atan2(h[1], h[0])
    sig_lat = float(np.sign(np.cross(h, u) @ ez)) or 1.0
    return PlanarChain(0, 1, 2, tele, S, E0, W0, Wt, sig_boom, sig_jib, lateral, psi_h, sig_lat,
                       1.0 if spec.elbow == "up" else -1.0)


def _wrap_into(q: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Choose q + 2πk closest to the middle of [lo, hi]."""
    mid = 0.5 * (lo + hi)
    return mid + (q - mid + np.pi) % (2 * np.pi) - np.pi


def _ik_one_side(spec: CraneSpec, pc: PlanarChain, r, z, slew, t, behind: bool,
                 explain: bool = True):
    """IK with the tip in front of the slew axis (ρ > 0) or folded behind it (ρ < 0).
    ``explain=False`` marks failures with a short constant text (no per-point formatting)."""
    N = r.shape[0]
    q = np.full((N, spec.n), np.nan)
    reason = np.full(N, "", dtype=object)
    e = pc.lateral
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.sqrt(r * r - e * e) * (-1.0 if behind else 1.0)
        bad = ~(r * r >= e * e)
        reason[bad] = f"out of reach: r closer to the slew axis than the lateral offset {abs(e):.3f} m"
        P = np.stack([rho, z], axis=1)
        W = pc.W0[None, :] + t[:, None] * pc.Wt[None, :]
        L1 = float(np.hypot(*(pc.E0 - pc.S)))
        Lw = np.hypot(W[:, 0], W[:, 1])
        dP = P - pc.S[None, :]
        D = np.hypot(dP[:, 0], dP[:, 1])
        far = D > L1 + Lw + 1e-12
        near = D < np.abs(L1 - Lw) - 1e-12
        for m, txt in ((far, "out of reach: {D:.3f} m from the boom pivot, at most {M:.3f} m"),
                       (near, "out of reach: {D:.3f} m from the boom pivot, at least {m_:.3f} m")):
            if not explain:
                reason[m & (reason == "")] = "out of reach"
                continue
            for k in np.flatnonzero(m & (reason == "")):
                reason[k] = txt.format(D=D[k], M=L1 + Lw[k], m_=abs(L1 - Lw[k]))
        # law of cosines at the shoulder, elbow on the side fixed by the spec (eq. 7.1-7.6 of
        # seed 000 in general form)
        cosb = np.clip((L1 * L1 + D * D - Lw * Lw) / (2 * L1 * D), -1.0, 1.0)
        beta = np.arccos(cosb)
        ang_E = np.arctan2(dP[:, 1], dP[:, 0]) + pc.elbow * beta
        E = pc.S[None, :] + L1 * np.stack([np.cos(ang_E), np.sin(ang_E)], axis=1)
        ang_E0 = math.atan2(*(pc.E0 - pc.S)[::-1])
        q_boom = (ang_E - ang_E0) * pc.sig_boom
        dT = P - E
        q_jib = (np.arctan2(dT[:, 1], dT[:, 0]) - np.arctan2(W[:, 1], W[:, 0])
                 - pc.sig_boom * q_boom) * pc.sig_jib
        q_slew = slew - pc.psi_h - np.arctan2(pc.sig_lat * e, rho)
    J = spec.joints
    q[:, pc.slew] = _wrap_into(q_slew, *J[pc.slew].limits.q)
    q[:, pc.boom] = _wrap_into(q_boom, *J[pc.boom].limits.q)
    q[:, pc.jib] = _wrap_into(q_jib, *J[pc.jib].limits.q)
    if pc.tele is not None:
        q[:, pc.tele] = t
    ok = reason == ""
    for i, jt in enumerate(J):
        lo, hi = jt.limits.q
        v = q[:, i]
        viol = ok & ((v < lo - 1e-9) | (v > hi + 1e-9))
        deg = jt.revolute
        if not explain:
            reason[viol] = "joint limit"
            ok &= ~viol
            continue
        for k in np.flatnonzero(viol):
            val = math.degrees(v[k]) if deg else v[k]
            a, b = (math.degrees(lo), math.degrees(hi)) if deg else (lo, hi)
            unit = "°" if deg else " m"
            reason[k] = (f"joint limit: {jt.name} would be {val:.2f}{unit} "
                         f"(allowed {a:.2f}{unit} .. {b:.2f}{unit})")
        ok &= ~viol
    q[~ok] = np.nan
    return q, reason


def ik_planar(spec: CraneSpec, pc: PlanarChain, r, z, slew, t, _hint=True, explain=True):
    """Vectorised IK. Inputs broadcast; returns (q[N, n], reason[N]) with reason "" when the
    configuration is reachable and inside all joint limits, else a readable explanation.

    The tip in front of the slew axis is preferred; a tip folded behind it (slew turned by π)
    is used only where the front solution fails. ``explain=False`` skips formatting the
    reasons (failures then say only "out of reach" / "joint limit"), for large grids."""
    r, z, slew, t = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float))
                                          for v in (r, z, slew, t)))
    q, reason = _ik_one_side(spec, pc, r, z, slew, t, behind=False, explain=explain)
    fail = np.flatnonzero(reason != "")
    if fail.size:
        qb, rb = _ik_one_side(spec, pc, r[fail], z[fail], slew[fail], t[fail], behind=True,
                              explain=explain)
        good = rb == ""
        q[fail[good]] = qb[good]
        reason[fail[good]] = ""
    lim = np.flatnonzero(np.char.startswith(reason.astype(str), "joint limit"))
    if _hint and explain and lim.size:
        other = PlanarChain(**{**pc.__dict__, "elbow": -pc.elbow})
        _, r2 = ik_planar(spec, other, r[lim], z[lim], slew[lim], t[lim], _hint=False)
        for k, rr in zip(lim, r2):
            if rr == "":
                reason[k] += (f"; the other elbow branch would reach it, but the spec fixes "
                              f"elbow = '{spec.elbow}'")
    return q, reason
