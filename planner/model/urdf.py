"""A URDF of a crane, generated from its spec's DH table, limits and link inertias (for ROS /
MoveIt and any other URDF tool).

Frames. Standard DH (A_i = Rot_z(θ_i)·Trans_z(d_i)·Trans_x(a_i)·Rot_x(α_i)): joint i moves
about / along z of DH frame i, and DH frame i+1 follows after the constant part of A_i. A URDF
joint moves its child link's frame about an axis *of that frame*, so the DH row is split:

* joint ``<name>``: origin = the previous row's constant tail followed by this row's offset
  (head: Rot_z(θ0) of a revolute row, Rot_z(θ)·Trans_z(d0) of a prismatic one), axis z; the
  tail is Trans_z(d)·Trans_x(a)·Rot_x(α) (revolute) or Trans_x(a)·Rot_x(α) (prismatic);
* link ``<name>``: the joint's frame, i.e. DH frame i · head · (Rot_z(q_i) or Trans_z(q_i));
  DH frame i+1 is this frame · tail;
* a fixed joint ``tip_joint`` to link ``tip``: the last row's tail, so ``tip`` is the last DH
  frame, whose origin is the crane's tip (CONTRACT: tip coordinates are of this point).

The joint variables are the model's q (no offsets to add: the offsets sit in the origins).

Inertias: the dynamics model's bodies (:func:`planner.model.dynamics.lumped_links`: link mass,
centre of mass and principal inertias in DH frame i+1, with the actuator masses lumped in);
each is written in its URDF link's frame (COM and tensor transformed, rpy = 0). The grapple /
rotator (``payload.tool_mass``) is a point mass on ``tip``; the variable load is left out.

Limits: position (q_min, q_max); velocity min(|qd_min|, qd_max) (URDF has one symmetric bound:
the smaller keeps a URDF-based planner within both; the asymmetric pair is in a comment); effort
the largest p_max·A·|dx/dq| over the joint range (the pump's maximum pressure on the larger
piston area through the actuator's lever arm) [N·m | N].
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import xml.etree.ElementTree as ET

import numpy as np

from planner.model.dynamics import lumped_links

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["urdf_xml", "dh_split"]


def _rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _rx(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def _tr(x, y, z):
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def dh_split(joint) -> tuple[np.ndarray, np.ndarray]:
    """(head, tail) 4×4 transforms of a DH row with A(q) = head · M(q) · tail, M(q) = Rot_z(q)
    (revolute) or Trans_z(q) (prismatic): the row's offsets in head, the constant rest in tail."""
    h = joint.dh
    if joint.revolute:
        return _rz(h.theta), _tr(0, 0, h.d) @ _tr(h.a, 0, 0) @ _rx(h.alpha)
    return _rz(h.theta) @ _tr(0, 0, h.d), _tr(h.a, 0, 0) @ _rx(h.alpha)


def _rpy(R) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(yaw)·Ry(pitch)·Rx(roll)) of a rotation matrix."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if abs(math.cos(pitch)) < 1e-12:  # gimbal lock: put everything in yaw
        return 0.0, pitch, math.atan2(-R[0, 1], R[1, 1])
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def _num(v: float) -> str:
    """Shortest round-trip text of a number; round-off residue (|v| < 1e-13) written as 0."""
    v = float(v)
    return "0" if abs(v) < 1e-13 else repr(v)


def _origin(parent, T):
    r, p, y = _rpy(T[:3, :3])
    return ET.SubElement(parent, "origin", xyz=" ".join(_num(v) for v in T[:3, 3]),
                         rpy=" ".join(_num(v) for v in (r, p, y)))


def _inertial(link, mass, com, inertia):
    el = ET.SubElement(link, "inertial")
    ET.SubElement(el, "origin", xyz=" ".join(_num(v) for v in com), rpy="0 0 0")
    ET.SubElement(el, "mass", value=_num(mass))
    ET.SubElement(el, "inertia", ixx=_num(inertia[0, 0]), ixy=_num(inertia[0, 1]),
                  ixz=_num(inertia[0, 2]), iyy=_num(inertia[1, 1]), iyz=_num(inertia[1, 2]),
                  izz=_num(inertia[2, 2]))


def joint_efforts(crane: Crane, n: int = 201) -> np.ndarray:
    """Per joint the largest p_max·max(A_a, A_b)·|dx/dq| over its range [N·m | N] (NaN when
    the pump has no maximum pressure)."""
    spec = crane.spec
    L = crane.limit_arrays()
    s = np.linspace(0.0, 1.0, n)[:, None]
    Q = L["q_min"] + s * (L["q_max"] - L["q_min"])
    _, dxdq = crane.stroke(Q)
    p = spec.pump.max_pressure
    area = np.array([max(j.actuator.area_a, j.actuator.area_b) for j in spec.joints])
    if not math.isfinite(p):
        return np.full(crane.n, math.nan)
    return p * area * np.max(np.abs(dxdq), axis=0)


def urdf_xml(crane: Crane) -> str:
    """The URDF (XML text) of ``crane`` (a :class:`planner.model.Crane`); see the module doc."""
    spec = crane.spec
    L = crane.limit_arrays()
    bodies = lumped_links(spec)
    effort = joint_efforts(crane)
    robot = ET.Element("robot", name=spec.id)
    robot.append(ET.Comment(f" generated by crane-planner from the spec of {spec.name} "
                            f"({spec.id}); SI units "))
    ET.SubElement(robot, "link", name="base_link")
    parent, tail = "base_link", np.eye(4)
    for i, j in enumerate(spec.joints):
        head, new_tail = dh_split(j)
        jt = ET.SubElement(robot, "joint", name=j.name,
                           type="revolute" if j.revolute else "prismatic")
        _origin(jt, tail @ head)
        ET.SubElement(jt, "parent", link=parent)
        ET.SubElement(jt, "child", link=j.name)
        ET.SubElement(jt, "axis", xyz="0 0 1")
        lo, hi = j.limits.qd
        jt.append(ET.Comment(f" velocity limits of the spec: {lo!r} .. {hi!r} "
                             f"{'rad/s' if j.revolute else 'm/s'} "))
        lim = dict(lower=_num(L["q_min"][i]), upper=_num(L["q_max"][i]),
                   velocity=_num(min(abs(lo), hi)))
        lim["effort"] = _num(effort[i]) if math.isfinite(effort[i]) else "0"
        ET.SubElement(jt, "limit", **lim)
        link = ET.SubElement(robot, "link", name=j.name)
        m, c, inertia = bodies[i]
        if m > 0:  # body i lives in DH frame i+1 = this link's frame · tail
            R, o = new_tail[:3, :3], new_tail[:3, 3]
            _inertial(link, m, o + R @ c, R @ inertia @ R.T)
        parent, tail = j.name, new_tail
    jt = ET.SubElement(robot, "joint", name="tip_joint", type="fixed")
    _origin(jt, tail)
    ET.SubElement(jt, "parent", link=parent)
    ET.SubElement(jt, "child", link="tip")
    tip = ET.SubElement(robot, "link", name="tip")
    if spec.payload.tool_mass > 0:
        _inertial(tip, spec.payload.tool_mass, np.zeros(3), np.zeros((3, 3)))
    ET.indent(robot)
    return ('<?xml version="1.0" encoding="utf-8"?>\n'
            + ET.tostring(robot, encoding="unicode") + "\n")
