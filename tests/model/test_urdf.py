"""problems urdf: the URDF generated from the DH spec loads in a URDF parser (yourdfpy), its
forward kinematics match the model's (≤ 1e-9 m), and its masses and inertias give the model's
potential and kinetic energy; the ROS JointTrajectory export of a library entry."""
import json
import math

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.model.urdf import urdf_xml
from tests.conftest import MACHINES, random_configs

yourdfpy = pytest.importorskip("yourdfpy")  # the dev extra


def _load(tmp_path, crane):
    p = tmp_path / f"{crane.spec.id}.urdf"
    p.write_text(urdf_xml(crane))
    robot = yourdfpy.URDF.load(str(p), build_scene_graph=True, load_meshes=False,
                               build_collision_scene_graph=False)
    assert robot.validate()
    return robot


def _frames(robot, crane, q):
    robot.update_cfg({name: float(v) for name, v in zip(crane.names, q)})
    return {link: robot.get_transform(link, "base_link")
            for link in ["base_link", *crane.names, "tip"]}


@pytest.mark.parametrize("cid", MACHINES)
def test_urdf_forward_kinematics_match_the_model(tmp_path, cid):
    crane = Crane.from_id(cid)
    robot = _load(tmp_path, crane)
    assert list(robot.actuated_joint_names) == list(crane.names)
    for q in random_configs(crane, 25, seed=11):
        F = _frames(robot, crane, q)
        tip = F["tip"][:3, 3]
        assert np.max(np.abs(tip - crane.fk(q))) <= 1e-9
        r, z, slew = crane.tip(q)
        assert math.hypot(tip[0], tip[1]) == pytest.approx(r, abs=1e-9)
        assert tip[2] == pytest.approx(z, abs=1e-9)
        # every joint's link sits on its DH frame's origin (frames 0..n-1; the tip is frame n)
        o = crane.frame_origins(q)
        for i, name in enumerate(crane.names):
            if crane.spec.joints[i].revolute:
                assert np.max(np.abs(F[name][:3, 3] - o[i])) <= 1e-9
        assert np.max(np.abs(F["tip"][:3, 3] - o[-1])) <= 1e-9


@pytest.mark.parametrize("cid", MACHINES)
def test_urdf_limits_match_the_spec(tmp_path, cid):
    crane = Crane.from_id(cid)
    robot = _load(tmp_path, crane)
    L = crane.limit_arrays()
    for i, j in enumerate(crane.spec.joints):
        uj = robot.joint_map[j.name]
        assert uj.type == ("revolute" if j.revolute else "prismatic")
        assert uj.limit.lower == L["q_min"][i] and uj.limit.upper == L["q_max"][i]
        assert uj.limit.velocity == min(-j.limits.qd[0], j.limits.qd[1])
        # effort: the actuator at the pump's maximum pressure through its largest lever arm,
        # checked against a finite difference of the stroke map
        qs = np.linspace(L["q_min"][i], L["q_max"][i], 201)
        Q = np.tile(0.5 * (L["q_min"] + L["q_max"]), (len(qs), 1))
        Q[:, i] = qs
        h = 1e-6
        dx = (crane.stroke(Q + h * np.eye(crane.n)[i])[0][:, i]
              - crane.stroke(Q - h * np.eye(crane.n)[i])[0][:, i]) / (2 * h)
        a = j.actuator
        want = crane.spec.pump.max_pressure * max(a.area_a, a.area_b) * np.max(np.abs(dx))
        assert uj.limit.effort == pytest.approx(want, rel=1e-5)


@pytest.mark.parametrize("cid", MACHINES)
def test_urdf_masses_give_the_model_energies(tmp_path, cid):
    """Potential energy Σ m g z_com and kinetic energy Σ ½ m v² + ½ ωᵀIω from the URDF's
    inertials (velocities by central differences of the parser's FK) against the model's
    potential energy and ½ q̇ᵀ M(q) q̇ with M from its inverse dynamics (payload: the tool)."""
    crane = Crane.from_id(cid)
    robot = _load(tmp_path, crane)
    tool = crane.spec.payload.tool_mass
    g = crane.spec.gravity
    inertials = {name: robot.link_map[name].inertial for name in [*crane.names, "tip"]}
    rng = np.random.default_rng(5)
    for q in random_configs(crane, 4, seed=21):
        qd = rng.uniform(-1, 1, crane.n) * crane.limit_arrays()["qd_max"]
        F = _frames(robot, crane, q)
        pe = sum(ine.mass * g * (F[k] @ ine.origin)[2, 3] for k, ine in inertials.items()
                 if ine is not None)
        assert pe == pytest.approx(float(crane.potential_energy(q, payload=tool)), rel=1e-9,
                                   abs=1e-6)
        h = 1e-6
        Fp, Fm = _frames(robot, crane, q + h * qd), _frames(robot, crane, q - h * qd)
        ke = 0.0
        for k, ine in inertials.items():
            if ine is None:
                continue
            Cp, Cm = Fp[k] @ ine.origin, Fm[k] @ ine.origin
            v = (Cp[:3, 3] - Cm[:3, 3]) / (2 * h)
            W = (Cp[:3, :3] @ Cm[:3, :3].T - Cm[:3, :3] @ Cp[:3, :3].T) / (4 * h)  # ω×
            w = np.array([W[2, 1], W[0, 2], W[1, 0]])
            R = F[k][:3, :3] @ ine.origin[:3, :3]
            ke += 0.5 * ine.mass * v @ v + 0.5 * w @ (R @ ine.inertia @ R.T) @ w
        z = np.zeros(crane.n)
        g0 = crane.inverse_dynamics(q, z, z, payload=tool)
        M = np.column_stack([crane.inverse_dynamics(q, z, e, payload=tool) - g0
                             for e in np.eye(crane.n)])
        assert ke == pytest.approx(0.5 * qd @ M @ qd, rel=1e-6)


def test_problems_urdf_cli(tmp_path, capsys):
    out = tmp_path / "c.urdf"
    assert main(["problems", "urdf", "cat215b", "--out", str(out), "--json", "-"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["crane_id"] == "cat215b" and doc["joints"] == ["swing", "boom", "stick"]
    assert out.read_text() == urdf_xml(Crane.from_id("cat215b"))
    assert main(["problems", "urdf", "umea-lab"]) == 0
    assert capsys.readouterr().out.startswith("<?xml")
    assert main(["problems", "urdf", "no-such-crane"]) == 2
