"""Inverse dynamics: recursive Newton–Euler over the DH chain (symbolic).

Body i is moved by joint i and fixed to DH frame i+1; its COM and inertia are given in that
frame. Gravity enters as an upward acceleration of the base (the usual RNEA trick). The payload
(load + grapple) is a point mass at the tip. Actuator masses are lumped onto the links at model
build time (see :func:`lumped_links`).
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from planner.model.spec import CraneSpec
from planner.model.kinematics import joint_transforms


def _rot_z(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _rot_x(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def lumped_links(spec: CraneSpec):
    """Per-body (mass, com[3], inertia 3×3 about com) with actuator masses lumped.

    Assumed lumping: a triangle or lever cylinder's mass is split half to the base pin (parent
    body) and half to the rod / lever-link pin (child body); telescope, rotary and rack actuators
    put their whole mass at the child's COM. Point masses add parallel-axis inertia.
    """
    bodies = []
    for j in spec.joints:
        bodies.append([j.mass, np.array(j.com, float), np.diag(j.inertia).astype(float)])

    def add_point(k, m, p):
        if m <= 0 or k < 0:
            return
        M, c, I = bodies[k]
        Mn = M + m
        cn = (M * c + m * p) / Mn
        d1, d2 = c - cn, p - cn
        In = (I + M * (d1 @ d1 * np.eye(3) - np.outer(d1, d1))
              + m * (d2 @ d2 * np.eye(3) - np.outer(d2, d2)))
        bodies[k] = [Mn, cn, In]

    for i, j in enumerate(spec.joints):
        act = j.actuator
        if act.mass <= 0:
            continue
        if act.kind in ("triangle", "lever"):
            # parent side: base pin in frame i = frame of body i-1
            add_point(i - 1, act.mass / 2, np.array([act.base[0], act.base[1], 0.0]))
            pin = act.rod if act.kind == "triangle" else act.lever_link
            # child side: pin in frame i rotated by θ; in frame i+1: Rot_x(α)ᵀ(p - (a, 0, d))
            p = _rot_x(j.dh.alpha).T @ (np.array([pin[0], pin[1], 0.0])
                                        - np.array([j.dh.a, 0.0, j.dh.d]))
            add_point(i, act.mass / 2, p)
        else:
            add_point(i, act.mass, bodies[i][1].copy())
    return [(float(m), c, I) for m, c, I in bodies]


def rnea(spec: CraneSpec, q, qd, qdd, payload, bodies=None, gravity=None):
    """Joint torques/forces τ [N·m | N] for motion (q, qd, qdd) with a tip point mass ``payload``
    [kg]. All arguments may be CasADi symbols; returns an n-vector."""
    n = spec.n
    g = spec.gravity if gravity is None else gravity
    bodies = lumped_links(spec) if bodies is None else bodies
    A = joint_transforms(spec, q)
    z = ca.DM([0, 0, 1])
    R = [Ai[:3, :3] for Ai in A]
    p = [Ai[:3, 3] for Ai in A]
    w = ca.DM.zeros(3)
    dw = ca.DM.zeros(3)
    acc = ca.DM([0, 0, g])  # base acceleration = -gravity
    F, N, pstar, acc_o = [], [], [], []
    for i, j in enumerate(spec.joints):
        Rt = R[i].T
        ps = Rt @ p[i]
        if j.revolute:
            w_new = Rt @ (w + z * qd[i])
            dw_new = Rt @ (dw + z * qdd[i] + ca.cross(w, z * qd[i]))
            acc = Rt @ acc + ca.cross(dw_new, ps) + ca.cross(w_new, ca.cross(w_new, ps))
        else:
            w_new = Rt @ w
            dw_new = Rt @ dw
            acc = (Rt @ (acc + z * qdd[i]) + ca.cross(dw_new, ps)
                   + 2 * ca.cross(w_new, Rt @ z * qd[i])
                   + ca.cross(w_new, ca.cross(w_new, ps)))
        w, dw = w_new, dw_new
        m, c, I = bodies[i]
        c = ca.DM(c)
        I = ca.DM(I)
        ac = acc + ca.cross(dw, c) + ca.cross(w, ca.cross(w, c))
        F.append(m * ac)
        N.append(I @ dw + ca.cross(w, I @ w))
        pstar.append(ps)
        acc_o.append(acc)
    # payload: point mass at the origin of the last frame
    f_next = payload * acc_o[-1]
    n_next = ca.DM.zeros(3)
    R_next = ca.DM.eye(3)
    tau = []
    for i in reversed(range(n)):
        m, c, _ = bodies[i]
        f_in = R_next @ f_next
        f_i = f_in + F[i]
        n_i = (R_next @ n_next + ca.cross(pstar[i], f_in)
               + ca.cross(pstar[i] + ca.DM(c), F[i]) + N[i])
        axis = R[i].T @ z
        tau.append(ca.dot(n_i, axis) if spec.joints[i].revolute else ca.dot(f_i, axis))
        f_next, n_next, R_next = f_i, n_i, R[i]
    return ca.vertcat(*reversed(tau))


def potential_energy(spec: CraneSpec, q, payload, bodies=None):
    """Σ m·g·z_com over bodies plus the tip payload [J]; an independent check of rnea()."""
    bodies = lumped_links(spec) if bodies is None else bodies
    T = ca.SX.eye(4) if isinstance(q, ca.SX) else ca.MX.eye(4)
    E = 0
    for (m, c, _), A in zip(bodies, joint_transforms(spec, q)):
        T = T @ A
        E += m * spec.gravity * (T[2, :3] @ ca.DM(c) + T[2, 3])
    return E + payload * spec.gravity * T[2, 3]
