"""Units: angle strings and other human-friendly input -> SI.

Everything inside the package is SI (m, rad, s, Pa, m³/s, J). Human input may write angles as
``"30deg"`` / ``"30°"`` / ``"0.5rad"``; a plain number is already SI.
"""
from __future__ import annotations

import math
from typing import Any, Protocol, Sequence

__all__ = ["parse_angle", "parse_point", "check_tip", "check_joint_units", "check_joint_range",
           "checked_trajectory", "DEG", "CraneLike"]


class CraneLike(Protocol):
    """What the model's building blocks below :class:`planner.model.Crane` read of a machine
    (units checks, the effects' hooks): its validated spec and its joint names. A ``Crane``
    is one; they take this protocol because ``Crane`` is built from them."""
    spec: Any

    @property
    def names(self) -> Sequence[str]: ...

DEG = math.pi / 180.0
SLEW_TOL = 1e-9   # [rad] slack on the ±π range of a tip's slew (rounding of "180deg")


def parse_angle(value: Any) -> float:
    """A number (SI: rad) or a string like ``"30deg"`` / ``"0.5rad"`` -> radians."""
    if isinstance(value, bool):
        raise ValueError("expected a number or an angle string like '30deg'")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        s = value.strip().lower()
        for suffix, scale in (("deg", DEG), ("°", DEG), ("rad", 1.0)):
            if s.endswith(suffix):
                return float(s[: -len(suffix)].strip()) * scale
        return float(s)
    raise ValueError("expected a number or an angle string like '30deg'")


def parse_point(text: str) -> tuple[float, float, float]:
    """A tip point ``"r,z[,slew]"`` -> (r [m], z [m], slew [rad]); slew may be written ``30deg``
    and defaults to 0. ValueError (quoting ``text``) for anything but 2 or 3 finite numbers."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise ValueError(f"expected r,z[,slew], got {text!r}")
    try:
        r, z = float(parts[0]), float(parts[1])
        s = parse_angle(parts[2]) if len(parts) == 3 else 0.0
    except ValueError:
        raise ValueError(f"expected numbers in r,z[,slew], got {text!r}") from None
    if not all(math.isfinite(v) for v in (r, z, s)):
        raise ValueError(f"non-finite value in {text!r}")
    if len(parts) == 3 and parts[2].lower().endswith(("deg", "°")) and \
            abs(s) > math.pi + SLEW_TOL:   # written in degrees: answered in degrees
        same = math.remainder(s, 2 * math.pi)
        raise ValueError(f"{text!r}: slew = {parts[2]} ({s:.6g} rad) is outside [-pi, pi]; "
                         f"allowed: -180deg ... 180deg (the same direction in range: "
                         f"{math.degrees(same):.6g}deg, {same:.6g} rad)")
    return check_tip((r, z, s), repr(text))


def check_tip(tip, field: str = "tip") -> tuple[float, float, float]:
    """A tip (r [m], z [m], slew [rad]) as three floats, or ValueError naming ``field``: every
    value finite and the slew inside [-π, π] (±180°). A slew outside that range is
    refused rather than wrapped: 170 is far more often 170° typed without ``deg`` than a
    27-turn rotation, and a wrapped value would be echoed as one thing and planned as another.
    """
    try:
        r, z, s = (float(v) for v in tip)
    except (TypeError, ValueError):
        raise ValueError(f"{field}: expected three numbers r, z, slew, got {tip!r}") from None
    if not all(math.isfinite(v) for v in (r, z, s)):
        raise ValueError(f"{field}: non-finite value in ({r:g}, {z:g}, {s:g}); "
                         "allowed: finite numbers")
    if abs(s) > math.pi + SLEW_TOL:
        wrapped = math.remainder(s, 2 * math.pi)
        raise ValueError(f"{field}: slew = {s:g} rad is outside [-pi, pi] (±180deg); write "
                         f"degrees with a suffix ({s:g}deg) or the same direction in range "
                         f"({wrapped:.6g} rad)")
    return r, z, s


def _columns(joints, names, q):
    """(joint, its column of q, range low, range high) for each joint that has a column."""
    names = list(names)
    for j in joints:
        if j.name in names:
            yield (j, q[:, names.index(j.name)], *j.limits.q)


def check_joint_units(joints, names, q, source: str = "trajectory") -> None:
    """Refuse joint positions that look like the wrong unit. ``joints``: the spec's joints
    (``.name``, ``.type``, ``.limits.q``); ``names``: the joint name of each column of ``q``
    (samples × columns). A column outside its joint's range by more than the range's own width
    (at least 1 rad or 1 m) raises ValueError naming the column and ``source``: a revolute
    column in degrees, a prismatic one in millimetres. Values just outside the range (a
    measured overshoot) pass."""
    for j, col, lo, hi in _columns(joints, names, q):
        far = (col < lo - max(hi - lo, 1.0)) | (col > hi + max(hi - lo, 1.0))
        if not far.any():
            continue
        k = int(far.argmax())
        unit, hint = (("rad", "looks like degrees; write radians") if j.type == "revolute"
                      else ("m", "looks like millimetres; write metres"))
        raise ValueError(f"{source}: column q_{j.name} = {col[k]:g} {unit} in data row "
                         f"{k + 1} is far outside the joint range [{lo:.4g}, {hi:.4g}] "
                         f"{unit}: {hint}")


RANGE_TOL = 0.05   # slack on a joint range, a fraction of its width (overshoot, interpolation)


def check_joint_range(joints, names, q, source: str = "trajectory") -> None:
    """Refuse positions outside the machine's joint ranges: a column leaving its joint's range
    [lo, hi] by more than :data:`RANGE_TOL` of the width (at least 1e-6) raises ValueError
    naming the column, the value, the data row and the range. A trajectory planned for another
    machine with the same joint names (s100f's 2.30 m telescope on umea-lab's 1.55 m) is caught
    here rather than replayed."""
    for j, col, lo, hi in _columns(joints, names, q):
        tol = max(RANGE_TOL * (hi - lo), 1e-6)
        out = (col < lo - tol) | (col > hi + tol)
        if out.any():
            k = int(out.argmax())
            unit = "rad" if j.type == "revolute" else "m"
            raise ValueError(f"{source}: q_{j.name} = {col[k]:.6g} {unit} in data row {k + 1} "
                             f"is outside the joint range [{lo:.4g}, {hi:.4g}] {unit} (slack "
                             f"{tol:.2g}); allowed: a trajectory of this machine")


def checked_trajectory(crane: CraneLike, traj, source: str = "trajectory",
                       crane_id: str | None = None):
    """``traj`` (a :class:`~planner.trajectory.Trajectory` read for ``crane``) checked against
    the machine where a trajectory file is read: the recorded ``crane_id`` (a library entry's)
    is ``crane``'s, the joints are the machine's (names and count), the positions are not in
    the wrong unit (:func:`check_joint_units`) and stay inside the joint ranges
    (:func:`check_joint_range`). ValueError naming ``source`` otherwise."""
    spec = crane.spec
    if crane_id is not None and crane_id != spec.id:
        raise ValueError(f"{source}: crane_id = {crane_id!r} (the machine it was planned for); "
                         f"allowed: {spec.id!r}, the machine given (replay it on {crane_id})")
    names = [j.name for j in spec.joints]
    if list(traj.joint_names) != names:
        raise ValueError(f"{source}: joints {', '.join(traj.joint_names) or 'none'}; allowed: "
                         f"{spec.id}'s {len(names)} joints {', '.join(names)}")
    check_joint_units(spec.joints, traj.joint_names, traj.q, source)
    check_joint_range(spec.joints, traj.joint_names, traj.q, source)
    return traj
