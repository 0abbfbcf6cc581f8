"""Inverse dynamics (RNEA) against hand calculations and independent formulations."""
import copy
import math
import tomllib

import casadi as ca
import numpy as np
import pytest

from planner import Crane
from planner.model.dynamics import rnea
from planner.model.kinematics import joint_transforms
from planner.model.spec import parse_spec
from planner.problems import crane_path

from tests.conftest import random_configs

G = 9.81


def _variant(cid, edit):
    data = tomllib.loads(crane_path(cid).read_text())
    data = copy.deepcopy(data)
    edit(data)
    return Crane(parse_spec(data, file=f"{cid}-variant"))


def _no_actuator_mass(d):
    for j in d["joint"]:
        j["actuator"]["mass"] = 0.0


def test_static_holding_torque_by_hand():
    """cranab850 stretched horizontally (θ1 = 90°, θ2 = 0, d3 = 0): gravity moments by hand."""
    crane = _variant("cranab850", _no_actuator_mass)
    q = np.array([0.0, math.pi / 2, 0.0, 0.0])
    tau = crane.inverse_dynamics(q, np.zeros(4), np.zeros(4))
    J = crane.spec.joints
    d1, d2 = J[1].dh.a, J[3].dh.d
    m_pay = crane.spec.payload.total
    mb, mj, mt = J[1].mass, J[2].mass, J[3].mass
    cb, cj, ct = -J[1].com[0], J[2].com[2], -J[3].com[2]  # distances along the straight boom
    # boom COM cb from the pivot, jib COM d1 + cj, tele COM d1 + d2 − ct, payload at d1 + d2
    boom = G * (mb * cb + mj * (d1 + cj) + mt * (d1 + d2 - ct) + m_pay * (d1 + d2))
    jib = G * (mj * cj + mt * (d2 - ct) + m_pay * d2)
    # θ1 grows downward (from the vertical): the actuator holds against gravity with τ < 0
    np.testing.assert_allclose(tau, [0.0, -boom, -jib, 0.0], atol=1e-6)


def test_static_torque_is_potential_energy_gradient(crane):
    """τ(q, 0, 0) = ∂V/∂q, V from link COM heights (actuator masses included)."""
    h = 1e-6
    for q in random_configs(crane, 10, seed=7):
        tau = crane.inverse_dynamics(q, np.zeros(crane.n), np.zeros(crane.n))
        grad = [(crane.potential_energy(q + h * e) - crane.potential_energy(q - h * e)) / (2 * h)
                for e in np.eye(crane.n)]
        np.testing.assert_allclose(tau, grad, rtol=1e-6, atol=1e-3)


def _point_mass_oracle(crane, traj_q, t, k):
    """τ = Σ_bodies m Jcᵀ(a_c + g) for bodies that are point masses (zero inertia), with COM
    positions from the DH frames and accelerations by finite differences in time."""
    spec = crane.spec

    def coms(q):
        T = np.eye(4)
        out = []
        for (m, c, _), A in zip(crane.bodies, joint_transforms(spec, q.tolist())):
            T = T @ np.array(A, dtype=float)
            out.append((m, (T @ np.append(c, 1.0))[:3]))
        out.append((spec.payload.total, T[:3, 3]))
        return out
    dt = t[1] - t[0]
    q = traj_q[k]
    tau = np.zeros(crane.n)
    for b in range(len(coms(q))):
        m = coms(q)[b][0]
        pm, p0, pp = (coms(traj_q[k + s])[b][1] for s in (-1, 0, 1))
        acc = (pp - 2 * p0 + pm) / dt ** 2 + np.array([0, 0, G])
        Jc = np.zeros((3, crane.n))
        for i in range(crane.n):
            e = np.zeros(crane.n)
            e[i] = 1e-6
            Jc[:, i] = (coms(q + e)[b][1] - coms(q - e)[b][1]) / 2e-6
        tau += m * Jc.T @ acc
    return tau


def test_rnea_matches_point_mass_newton_formulation():
    """With rotational inertias zeroed, RNEA equals Σ m Jᵀ(a + g) over the COM point masses
    (Coriolis, centripetal and prismatic terms included)."""
    def edit(d):
        for j in d["joint"]:
            j["inertia"] = [0.0, 0.0, 0.0]
    crane = _variant("s100f", edit)
    crane.bodies = [(m, c, 0 * I) for (m, c, I) in crane.bodies]  # lumped actuators: no inertia
    q_, qd_, qdd_ = (ca.SX.sym(n, 4) for n in ("q", "qd", "qdd"))
    f = ca.Function("f", [q_, qd_, qdd_], [rnea(crane.spec, q_, qd_, qdd_,
                                                 crane.spec.payload.total, crane.bodies)])
    dt = 1e-4
    t = np.arange(-2, 3) * dt + 0.7
    w = np.array([0.4, -0.3, 0.5, 0.6])
    q0 = np.array([0.2, -0.4, 0.3, 1.0])
    Q = q0 + np.sin(np.outer(t, w) * 2.0) * 0.5
    Qd = np.cos(np.outer(t, w) * 2.0) * 2.0 * w * 0.5
    Qdd = -np.sin(np.outer(t, w) * 2.0) * (2.0 * w) ** 2 * 0.5
    k = 2
    tau = np.array(f(Q[k], Qd[k], Qdd[k])).ravel()
    oracle = _point_mass_oracle(crane, Q, t, k)
    np.testing.assert_allclose(tau, oracle, rtol=2e-4, atol=0.5)


def test_power_balance_with_inertia():
    """q̇ᵀ(τ − τ_g) = d/dt(½ q̇ᵀ M q̇), M from RNEA columns: checks Coriolis against M."""
    crane = Crane.from_id("cat215b")
    n = crane.n
    z = np.zeros(n)

    def M(q):
        g = crane.inverse_dynamics(q, z, z)
        return np.column_stack([crane.inverse_dynamics(q, z, e) - g for e in np.eye(n)])
    w = np.array([0.7, 0.5, -0.9])

    def state(t):
        q = np.array([0.1, 0.2, -1.5]) + 0.4 * np.sin(w * t)
        return q, 0.4 * w * np.cos(w * t), -0.4 * w ** 2 * np.sin(w * t)
    t0, h = 0.8, 1e-5
    q, qd, qdd = state(t0)
    Mq = M(q)
    np.testing.assert_allclose(Mq, Mq.T, rtol=1e-9, atol=1e-6)
    assert np.all(np.linalg.eigvalsh(Mq) > 0)
    power = qd @ (crane.inverse_dynamics(q, qd, qdd) - crane.inverse_dynamics(q, z, z))

    def ke(t):
        qq, qqd, _ = state(t)
        return 0.5 * qqd @ M(qq) @ qqd
    dke = (ke(t0 + h) - ke(t0 - h)) / (2 * h)
    assert power == pytest.approx(dke, rel=1e-5)


def test_payload_parameter_adds_tip_weight():
    crane = Crane.from_id("s100f")
    q = np.array([0.0, -0.3, 0.4, 1.0])
    z = np.zeros(4)
    d = crane.inverse_dynamics(q, z, z, payload=1000.0) - crane.inverse_dynamics(q, z, z, payload=0.0)
    J = crane.jacobian(q, coords="xyz")
    np.testing.assert_allclose(d, 1000.0 * G * J[2], rtol=1e-9, atol=1e-6)
