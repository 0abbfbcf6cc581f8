"""Seed 002's test cycles h, v, d as time-based tip commands (for ``follow_command``).

Seed facts (digest of seed 002): 5 s rest, then two sections of extend/retract along one straight
line; section 1 pauses 3 s at the reversal, section 2 reverses at once; 3 s between the sections;
per-axis tip speed 0.5 or 1 m/s, the fast cycles halve the motion times (same path; the rests and
pauses keep their length); the vertical and diagonal cycles start with a preliminary move.

| cycle | motion (per-axis speed v)                  | times at 0.5 m/s [s]                   |
| ----- | ------------------------------------------ | -------------------------------------- |
| h     | r: +6, −6, +6, −6 m                        | out 5–17, 35–47; in 20–32, 47–59       |
| v     | prelim. r +3 m; z: +6, −6, +6, −6 m        | pre 5–11; up 11–23, 41–53; down 26–38, 53–65 |
| d     | prelim. r +3 m; (r, z): +3/+3, −3/−3 m, …  | pre 5–11; out 11–17, 29–35; in 20–26, 35–41 |

The preliminary moves' length and direction are not given by the seed: ASSUMED +3 m in r (a 6 s
move at 0.5 m/s fills the 5–11 s slot of the table for both the v and the d cycle).

Start positions are not given by the seed either: :data:`START` holds the ASSUMED ones for s100f
(boom foot at r = 0.3 m, z = 2.0 m; reach ≈ 10.4 m). They were chosen so that every path lies
in the part of the workspace where most of the telescope range is reachable (see the table in
:data:`START_REASON`) and every law of :mod:`planner.methods.laws_energy` keeps every joint
inside its limits for the whole cycle at both speeds, with and without the transformer
(checked by ``benchmarks/seed002_table.py``).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

CYCLES = ("h", "v", "d")
SPEEDS = (0.5, 1.0)
REST_S = 5.0         # seed 002: rest before the first motion
PAUSE_S = 3.0        # seed 002: pause at the reversal of section 1 and between the sections

# ASSUMED start tips (r, z, slew) [m, m, rad] and the telescope [m] the laws start with.
START = {
    "h": (3.0, 0.0, 0.0),    # out to r = 9.0 m at the pillar-base height
    "v": (4.0, -1.5, 0.0),   # preliminary out to r = 7.0 m, then z = -1.5 .. 4.5 m
    "d": (2.5, -1.0, 0.0),   # preliminary out to r = 5.5 m, then to (8.5, 2.0) m
}
START_TELE = {"h": 1.2, "v": 1.0, "d": 1.2}
START_REASON = (
    "assumed (seed 002 gives no start positions): chosen on the s100f workspace so that every "
    "straight section stays where the boom and jib are well inside their ranges and the "
    "telescope is free over most of its range; every law keeps every joint within its limits "
    "over the whole cycle at 0.5 and 1 m/s, with and without the transformer")

# (Δr, Δz) per unit of the per-axis speed's displacement, and which motions pause afterwards
_MOTIONS = {
    # cycle: list of (label, Δr, Δz, pause after [s])
    "h": [("out", 6.0, 0.0, PAUSE_S), ("in", -6.0, 0.0, PAUSE_S),
          ("out", 6.0, 0.0, 0.0), ("in", -6.0, 0.0, 0.0)],
    "v": [("preliminary", 3.0, 0.0, 0.0),
          ("up", 0.0, 6.0, PAUSE_S), ("down", 0.0, -6.0, PAUSE_S),
          ("up", 0.0, 6.0, 0.0), ("down", 0.0, -6.0, 0.0)],
    "d": [("preliminary", 3.0, 0.0, 0.0),
          ("out", 3.0, 3.0, PAUSE_S), ("in", -3.0, -3.0, PAUSE_S),
          ("out", 3.0, 3.0, 0.0), ("in", -3.0, -3.0, 0.0)],
}


class Section(NamedTuple):
    """One straight-line motion of a cycle: start and end tip (r, z, slew), start/end time [s]."""
    start: np.ndarray
    end: np.ndarray
    t0: float
    t1: float

    @property
    def length(self) -> float:
        return float(np.hypot(*(self.end[:2] - self.start[:2])))

    @property
    def path_speed(self) -> float:
        """Tip speed along the line [m/s] (per-axis speed · √2 on the diagonal)."""
        return self.length / (self.t1 - self.t0)


def cycle(name: str, speed: float, start_tip=None):
    """Seed 002 cycle ``name`` ('h', 'v', 'd') at per-axis tip speed ``speed`` [m/s].

    Returns ``(command, duration, sections)``: ``command(t) -> (ref_tip, ref_vel)`` (both
    (r, z, slew) arrays; piecewise-linear reference, constant velocity during a motion, zero at
    rest), the cycle duration [s] and the list of :class:`Section` (the preliminary move first
    for v and d). ``start_tip`` defaults to the assumed :data:`START` tip."""
    if name not in _MOTIONS:
        raise ValueError(f"unknown cycle {name!r}; allowed: {', '.join(CYCLES)}")
    if speed <= 0:
        raise ValueError(f"speed must be > 0 m/s, got {speed}")
    tip = np.array(START[name] if start_tip is None else start_tip, dtype=float)
    if tip.shape != (3,):
        raise ValueError("start_tip must be (r, z, slew)")
    sections: list[Section] = []
    t = REST_S
    for label, dr, dz, pause in _MOTIONS[name]:
        T = max(abs(dr), abs(dz)) / speed  # per-axis speed: both axes move together on d
        end = tip + np.array([dr, dz, 0.0])
        sections.append(Section(tip.copy(), end, t, t + T))
        tip = end
        t += T + pause
    duration = sections[-1].t1
    t0s = np.array([s.t0 for s in sections])

    def command(tt: float):
        k = int(np.searchsorted(t0s, tt, side="right")) - 1
        if k < 0:
            return sections[0].start.copy(), np.zeros(3)
        s = sections[k]
        if tt >= s.t1:
            return s.end.copy(), np.zeros(3)
        vel = (s.end - s.start) / (s.t1 - s.t0)
        return s.start + vel * (tt - s.t0), vel

    return command, duration, sections


def labels(name: str) -> list[str]:
    """Labels of the sections of a cycle ('preliminary', 'out', 'in', 'up', 'down')."""
    return [m[0] for m in _MOTIONS[name]]
