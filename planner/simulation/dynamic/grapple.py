"""The grapple on its passive two-axis link, as two more joints of the Exudyn kinematic tree.

When the spec's ``[dynamics]`` (or the ``grapple_swing`` effect) gives a
:class:`~planner.model.dynamics_spec.GrappleLink`, the grapple and its load are no longer a
point mass merged into the last link: the tree gets

* joint n, revolute, at the boom tip about the boom's **pitch axis** (the axis of the first
  joint after the slew, as it lies in the last link's frame): the swing in the boom plane;
* joint n+1, revolute, about the axis perpendicular to the pitch axis and to the link: the swing
  out of the boom plane;
* link n+1, the grapple with its load: mass m (the payload), centre of mass at ``length`` along
  the link's x axis, inertia m·k² about every axis through it (``gyration`` k); link n (the
  cross between the two pins) has no mass.

Both pins have viscous damping. At rest the load hangs straight down under the tip
(:func:`hanging_angles`), so the static joint torques are those of a point mass at the tip and
the plant's load-holding initial pressures stay right. :func:`swing_energy` gives what the
swinging load adds to the mechanical energy of the point-mass model (for the energy balance),
from the tree's own kinematics (a serial chain: every joint velocity adds its axis × lever arm).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["extend_tree", "hanging_angles", "link_frames", "swing_energy"]

# joint n+1's frame in link n's: x kept, z = link n's y (perpendicular to the pitch axis)
_CROSS = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def _motion(kind: str, q) -> np.ndarray:
    """(…, 4, 4) transformation of a joint's own motion about / along its z."""
    q = np.asarray(q, float)
    T = np.broadcast_to(np.eye(4), q.shape + (4, 4)).copy()
    if kind == "revolute":
        c, s = np.cos(q), np.sin(q)
        T[..., 0, 0], T[..., 0, 1], T[..., 1, 0], T[..., 1, 1] = c, -s, s, c
    else:
        T[..., 2, 3] = q
    return T


def link_frames(tree: dict, q) -> tuple:
    """(joint frames, link frames), each a list of (…, 4, 4) world transformations, of the
    tree's links at the configurations ``q`` (…, links) (the plant's convention: joint i's
    frame is its parent link's frame times ``hts[i]``; link i's is that times the motion)."""
    q = np.asarray(q, float)
    joints, links = [], []
    for i, (kind, H) in enumerate(zip(tree["types"], tree["hts"])):
        parent = links[i - 1] if i else np.broadcast_to(np.eye(4), q.shape[:-1] + (4, 4))
        J = parent @ H
        joints.append(J)
        links.append(J @ _motion(kind, q[..., i]))
    return joints, links


def extend_tree(tree: dict, payload: float, grapple) -> dict:
    """The tree data of :func:`~planner.simulation.dynamic.bodies.tree_parameters` (built
    without the payload) with the two grapple joints and the hanging load appended."""
    n = len(tree["types"])
    first_pitch = next((i for i in range(1, n) if tree["types"][i] == "revolute"), None)
    if first_pitch is None:
        raise ValueError("grapple link: the machine has no revolute joint after the first "
                         "(no boom pitch axis to hang the grapple's first pin on)")
    joints, links = link_frames(tree, np.zeros(n))
    R_last = links[-1][:3, :3]
    a1 = R_last.T @ joints[first_pitch][:3, 2]          # the pitch axis in the last link
    a1 /= np.linalg.norm(a1)
    e = np.eye(3)[int(np.argmin(np.abs(a1)))]
    x = np.cross(a1, e)
    x /= np.linalg.norm(x)
    cross_frame = np.eye(4)
    cross_frame[:3, :3] = np.column_stack([x, np.cross(a1, x), a1])
    cross_frame[:3, 3] = tree["tip"]
    pin2 = np.eye(4)
    pin2[:3, :3] = _CROSS
    m, k = float(payload), float(grapple.gyration)
    return dict(types=tree["types"] + ["revolute", "revolute"],
                hts=tree["hts"] + [cross_frame, pin2],
                masses=tree["masses"] + [0.0, m],
                coms=tree["coms"] + [np.zeros(3), np.array([grapple.length, 0.0, 0.0])],
                inertias=tree["inertias"] + [np.zeros((3, 3)), m * k * k * np.eye(3)],
                tip=tree["tip"], grapple=grapple, crane_links=n)


def hanging_angles(tree: dict, q) -> list:
    """The two pin angles [rad] at which the load hangs straight down under the tip with the
    crane at ``q`` (n,)."""
    n = tree["crane_links"]
    full = np.concatenate([np.asarray(q, float), [0.0, 0.0]])
    joints, _ = link_frames(tree, full)
    w = joints[n][:3, :3].T @ np.array([0.0, 0.0, -1.0])  # down, in the cross's joint frame
    # the link's direction is (cos b cos a, cos b sin a, -sin b) for pin angles a, b
    return [math.atan2(w[1], w[0]), -math.asin(max(-1.0, min(1.0, w[2])))]


def swing_energy(tree: dict, q, qd, gravity: float) -> np.ndarray:
    """(…,) kinetic + potential energy [J] of the load on its link minus that of the same
    mass as a point at the tip, at the full tree states ``q``, ``qd`` (…, n+2): what the
    point-mass model misses."""
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    n, g = tree["crane_links"], tree["grapple"]
    m, k = tree["masses"][-1], g.gyration
    joints, links = link_frames(tree, q)
    com = (links[-1] @ np.array([g.length, 0.0, 0.0, 1.0]))[..., :3]
    tip = links[n][..., :3, 3]
    v_com, v_tip, omega = (np.zeros(q.shape[:-1] + (3,)) for _ in range(3))
    for j, kind in enumerate(tree["types"]):
        z, o = joints[j][..., :3, 2], joints[j][..., :3, 3]
        r = qd[..., j:j + 1]
        if kind == "revolute":
            omega += z * r
            v_com += np.cross(z, com - o) * r
            v_tip += np.cross(z, tip - o) * r
        else:
            v_com += z * r
            v_tip += z * r
    e_load = 0.5 * m * (np.sum(v_com ** 2, -1) + k * k * np.sum(omega ** 2, -1)) + m * gravity * com[..., 2]
    e_point = 0.5 * m * np.sum(v_tip ** 2, -1) + m * gravity * tip[..., 2]
    return e_load - e_point
