"""The dynamic twin's calibratable parameters (issue 28): which physical numbers a fit from
logs may change, how each is scaled for the optimiser, and the machine they describe.

Every parameter is one number of the spec that the twin (:mod:`planner.model.twin`) reads:

==========================  ======  ===========================================================
name                        unit    where it lives
==========================  ======  ===========================================================
``bulk_modulus``            Pa      ``[dynamics] bulk_modulus`` (oil + hoses + air, effective)
``bulk_low``, ``bulk_high`` 1       ``[dynamics]`` its pressure law's clip (1, 1: constant)
``bulk_reference_pressure`` Pa      ``[dynamics]`` the law's pivot p_ref
``spool_time_constant``     s       ``[dynamics] spool_time_constant`` (every valve)
``pump_time_constant``      s       ``[dynamics] pump_time_constant`` (LS regulator)
``command_delay``           s       ``[dynamics] command_delay`` (command -> valves, every one)
``hose_a.<joint>``          m³      ``[dynamics.joint.<joint>] hose_volume[0]`` (piston side)
``hose_b.<joint>``          m³      ``[dynamics.joint.<joint>] hose_volume[1]`` (rod side)
``coulomb.<joint>``         N|N·m   ``[dynamics.joint.<joint>] coulomb``
``viscous.<joint>``         N·s/m   ``[dynamics.joint.<joint>] viscous`` (N·m·s/rad rotary)
``leakage.<joint>``         m³/s/Pa ``[dynamics.joint.<joint>] leakage`` (loaded chamber)
``deadband.<joint>``        1       ``[[joint]] actuator.deadband`` (share of the command range)
==========================  ======  ===========================================================

Groups (``--parameters`` names a group or a parameter): ``oil`` (bulk modulus and its
pressure law), ``hoses``,
``valves`` (command delay, spool lag and dead bands), ``pump``, ``friction``, ``leakage``; ``all``.

Scaling: a quantity that is positive by nature (bulk modulus, time constants, hose volumes) is
fitted as z = ln(value / spec's value), bounded to a factor range; one whose true value may be
0 (friction, leakage, dead band) as z = value / scale with a physical scale (the spec's value
where it is not 0, else a typical size, "assumed" below), bounded to [0, hi]. Both make one
unit of z a comparable, dimensionless change for the optimiser and its intervals.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import dataclass, replace

import numpy as np

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["TwinParameter", "GROUPS", "twin_parameters", "select", "machine_of",
           "TYPICAL_LEAKAGE", "TYPICAL_DEADBAND", "TYPICAL_DELAY"]

#: assumed size of a worn seal's leakage [m³/(s·Pa)]: 0.06 L/min at 100 bar
TYPICAL_LEAKAGE = 1e-14
#: assumed size of a command delay: 10 ms (a CAN bus and a controller cycle of a few ms each;
#: the drawn machines of the loop have 0–30 ms)
TYPICAL_DELAY = 0.01
#: assumed size of a valve's dead band: 1 % of the command range (what an electronic
#: dead-band compensation typically leaves)
TYPICAL_DEADBAND = 0.01
#: assumed size of seal friction where the spec has none: the force of 0.1 MPa on the
#: smaller area (rotary: on the motor's displacement per radian)
_FRICTION_PRESSURE = 1e5

GROUPS = {
    "oil": ("bulk_modulus", "bulk_low", "bulk_high", "bulk_reference_pressure"),
    "hoses": ("hose_a", "hose_b"),
    "valves": ("command_delay", "spool_time_constant", "deadband"),
    "pump": ("pump_time_constant",),
    "friction": ("coulomb", "viscous"),
    "leakage": ("leakage",),
}


@dataclass(frozen=True)
class TwinParameter:
    """One calibratable number (module doc): ``name`` (``kind`` or ``kind.<joint>``),
    ``unit``, the spec's ``nominal`` value, ``log`` (fitted as ln(value/nominal) within
    [lo, hi] × nominal) or linear (value/``scale`` within [lo, hi] in value units)."""
    name: str
    kind: str
    joint: str | None
    unit: str
    nominal: float
    lo: float
    hi: float
    log: bool
    scale: float = 1.0

    def to_z(self, value: float) -> float:
        return math.log(value / self.nominal) if self.log else value / self.scale

    def to_value(self, z: float) -> float:
        return self.nominal * math.exp(z) if self.log else z * self.scale

    @property
    def z_bounds(self) -> tuple[float, float]:
        return (self.to_z(self.lo), self.to_z(self.hi))


def twin_parameters(crane: Crane, dynamics=None) -> list[TwinParameter]:
    """Every calibratable parameter of ``crane`` (module doc), the spec's values nominal."""
    dyn = crane.spec.dynamics if dynamics is None else dynamics
    if dyn is None:
        raise ValueError(f"crane '{crane.spec.id}' ({crane.spec.path}): field 'dynamics': "
                         "missing section; calibrating the twin needs [dynamics]")
    out = [TwinParameter("bulk_modulus", "bulk_modulus", None, "Pa", dyn.bulk_modulus,
                         0.2 * dyn.bulk_modulus, min(3.0 * dyn.bulk_modulus, 5e9), True),
           TwinParameter("bulk_low", "bulk_low", None, "1", dyn.bulk_low,
                         min(0.2, dyn.bulk_low), 1.0, True),
           TwinParameter("bulk_high", "bulk_high", None, "1", dyn.bulk_high, 1.0,
                         max(3.0, dyn.bulk_high), True),
           TwinParameter("bulk_reference_pressure", "bulk_reference_pressure", None, "Pa",
                         dyn.bulk_reference_pressure, 1e6, 3e7, True),
           TwinParameter("spool_time_constant", "spool_time_constant", None, "s",
                         dyn.spool_time_constant, 0.2 * dyn.spool_time_constant,
                         min(5.0 * dyn.spool_time_constant, 1.0), True),
           TwinParameter("pump_time_constant", "pump_time_constant", None, "s",
                         dyn.pump_time_constant, 0.2 * dyn.pump_time_constant,
                         min(5.0 * dyn.pump_time_constant, 5.0), True),
           TwinParameter("command_delay", "command_delay", None, "s", dyn.command_delay,
                         0.0, 0.2, False, max(dyn.command_delay, TYPICAL_DELAY))]
    for j in crane.spec.joints:
        jd = dyn.joints[j.name]
        a = j.actuator
        rotary = a.kind == "rotary"
        f_unit, v_unit = ("N·m", "N·m·s/rad") if rotary else ("N", "N·s/m")
        area = min(a.area_a, a.area_b)          # rotary: the motor's displacement [m³/rad]
        v_full = a.flow_gain / area if math.isfinite(a.flow_gain) else 1.0
        f_typ = _FRICTION_PRESSURE * area
        for side, v in zip("ab", jd.hose_volume):
            if side == "b" and a.acting == "single":
                continue        # a single-acting cylinder's rod side is vented: no oil to fit
            out.append(TwinParameter(f"hose_{side}.{j.name}", f"hose_{side}", j.name, "m³", v,
                                     0.2 * v, 10.0 * v, True))
        # the bound: 20 typical sizes, and never below 20 assumed ones (a spec's small seal
        # friction, 300 N·m on the s100f slew, bounded the fit at 6 kN·m where the
        # catalogue's own Coulomb trial reaches 0.5 MPa on the area, 7.5 kN·m there)
        fc = jd.coulomb if jd.coulomb > 0 else f_typ
        out.append(TwinParameter(f"coulomb.{j.name}", "coulomb", j.name, f_unit, jd.coulomb,
                                 0.0, 20.0 * max(fc, f_typ), False, fc))
        fv = jd.viscous if jd.viscous > 0 else f_typ / v_full
        out.append(TwinParameter(f"viscous.{j.name}", "viscous", j.name, v_unit, jd.viscous,
                                 0.0, 20.0 * max(fv, f_typ / v_full), False, fv))
        out.append(TwinParameter(f"leakage.{j.name}", "leakage", j.name, "m³/(s·Pa)",
                                 jd.leakage, 0.0, 1e-11, False,
                                 max(jd.leakage, TYPICAL_LEAKAGE)))
        out.append(TwinParameter(f"deadband.{j.name}", "deadband", j.name, "1",
                                 a.deadband, 0.0, 0.4, False,
                                 max(a.deadband, TYPICAL_DEADBAND)))
    return out


def select(params: list[TwinParameter], names=None) -> list[TwinParameter]:
    """The parameters named by ``names`` (None or "all": every one): group names
    (:data:`GROUPS`), kinds (``hose_a``, ``coulomb``, …) or full names (``coulomb.boom``).
    ValueError naming the unknown entry and what is allowed."""
    if names is None:
        return list(params)
    if isinstance(names, str):
        names = [s.strip() for s in names.split(",") if s.strip()]
    kinds = {p.kind for p in params}
    full = {p.name for p in params}
    chosen = set()
    for s in names:
        if s == "all":
            chosen |= full
        elif s in GROUPS:
            chosen |= {p.name for p in params if p.kind in GROUPS[s]}
        elif s in kinds:
            chosen |= {p.name for p in params if p.kind == s}
        elif s in full:
            chosen.add(s)
        else:
            raise ValueError(f"parameters: {s!r} unknown; allowed: all, groups "
                             f"{', '.join(GROUPS)}, kinds {', '.join(sorted(kinds))} or a "
                             f"name such as {sorted(full)[0]}")
    if not chosen:
        raise ValueError("parameters: empty; allowed: all, a group, a kind or a name")
    return [p for p in params if p.name in chosen]


def machine_of(crane: Crane, values: dict, dynamics=None):
    """(``[dynamics]`` with ``values`` (name -> value) in place of the spec's, dead bands
    (n,)): the machine a set of parameter values describes. Unknown names: ValueError."""
    dyn = crane.spec.dynamics if dynamics is None else dynamics
    known = {p.name for p in twin_parameters(crane, dyn)}
    bad = sorted(set(values) - known)
    if bad:
        raise ValueError(f"parameters: {bad[0]!r} unknown; allowed: {', '.join(sorted(known))}")
    top = {k: float(values[k]) for k in ("bulk_modulus", "spool_time_constant",
                                         "pump_time_constant", "bulk_low", "bulk_high",
                                         "bulk_reference_pressure", "command_delay")
           if k in values}
    joints = {}
    for name, jd in dyn.joints.items():
        hv = (float(values.get(f"hose_a.{name}", jd.hose_volume[0])),
              float(values.get(f"hose_b.{name}", jd.hose_volume[1])))
        joints[name] = replace(jd, hose_volume=hv,
                               coulomb=float(values.get(f"coulomb.{name}", jd.coulomb)),
                               viscous=float(values.get(f"viscous.{name}", jd.viscous)),
                               leakage=float(values.get(f"leakage.{name}", jd.leakage)))
    deadband = np.array([float(values.get(f"deadband.{j.name}", j.actuator.deadband))
                         for j in crane.spec.joints])
    return replace(dyn, joints=joints, **top), deadband
