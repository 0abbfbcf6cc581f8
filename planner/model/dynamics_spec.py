"""The ``[dynamics]`` section of a machine spec: the physical parameters only a dynamic plant
needs (oil compressibility, hose volumes, spool and pump dynamics, valve pressure drops,
actuator friction), parsed and validated like the rest of the spec (errors name the file, the
field, the value and what is allowed).

```toml
[dynamics]
bulk_modulus = 1.4e9            # Pa, effective (oil + hoses + entrained air)
spool_time_constant = 0.04      # s, first-order spool lag of every valve
pump_time_constant = 0.05       # s, load-sensing regulator lag (pressure build-up)
pump_line_volume = 2.0e-3       # m³, oil between pump and valve block
compensator_dp = 1.6e6          # Pa, pressure drop each valve's compensator holds
meter_out_dp = 0.5e6            # Pa, drop at which the return-flow compensator reaches its cap
meter_out_margin = 0.01         # the return cap over the outflow that matches the inflow
bulk_low = 0.6                  # optional: β rises with pressure, β(p) = β·clip((p + p_atm)/
bulk_high = 1.25                #   (p_ref + p_atm), low, high); both 1 (the default): constant
bulk_reference_pressure = 8e6   # Pa, p_ref: where β holds (the law's pivot)
command_delay = 0.0             # s, optional (0): transport delay from the command to the
                                #   valves (bus, controller cycle, pilot stage), every valve
source = "…"
[dynamics.joint.boom]           # one table per joint
hose_volume = [1.0e-3, 1.0e-3]  # m³, piston side, rod side (or motor ports)
coulomb = 1500.0                # N (N·m for rotary drives), seal friction at the actuator
viscous = 2.0e4                 # N·s/m (N·m·s/rad)
leakage = 0.0                   # m³/(s·Pa), loaded chamber to tank (optional, 0)
[dynamics.grapple]              # optional: the load hangs on a passive two-axis link
link_length = 1.2               # m, pivot at the boom tip to the centre of mass of grapple + load
damping = 800.0                 # N·m·s/rad about each of the two pins
gyration = 0.3                  # m, radius of gyration of grapple + load about their centre
swing_max = 0.5                 # m, optional: the operator's limit on the load's horizontal
                                #   offset from under the tip during a move (sway-free plans)
```
Without ``[dynamics.grapple]`` the grapple and its load are a point mass fixed at the tip.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from planner.model.reader import TableReader

__all__ = ["JointDynamics", "GrappleLink", "DynamicsSpec", "parse_dynamics", "DYNAMICS_KEYS"]

DYNAMICS_KEYS = {"bulk_modulus", "spool_time_constant", "pump_time_constant", "pump_line_volume",
                 "compensator_dp", "meter_out_dp", "meter_out_margin", "source",
                 "joint", "grapple", "bulk_low", "bulk_high", "bulk_reference_pressure",
                 "command_delay"}
#: [Pa] the atmosphere in the pressure law of the bulk modulus (pressures are gauge)
P_ATM = 1.0e5
_JOINT_KEYS = {"hose_volume", "coulomb", "viscous", "leakage", "source"}
_GRAPPLE_KEYS = {"link_length", "damping", "gyration", "swing_max", "source"}
#: assumed radius of gyration [m] of grapple + load about their centre of mass: a forestry
#: grapple with its rotator is about 1 m tall and its logs spread ~0.5 m around the axis
GYRATION = 0.3


@dataclass(frozen=True)
class JointDynamics:
    """Per-actuator dynamic data: hose volumes [m³] (piston side, rod side), Coulomb friction
    [N | N·m] and viscous friction [N·s/m | N·m·s/rad] at the actuator, leakage of the loaded
    chamber to tank [m³/(s·Pa)] (0: tight)."""
    hose_volume: tuple[float, float]
    coulomb: float = 0.0
    viscous: float = 0.0
    source: str = ""
    leakage: float = 0.0


@dataclass(frozen=True)
class GrappleLink:
    """The passive two-axis link the grapple hangs on: pivot-to-centre-of-mass ``length``
    [m], viscous ``damping`` [N·m·s/rad] about each pin, radius of ``gyration`` [m] of grapple
    + load about their centre of mass. One pin is parallel to the boom's pitch axis (swing in
    the boom plane), the other perpendicular to it (swing out of the plane). ``swing_max`` [m]:
    the operator's limit on the load's horizontal offset from under the tip during a move
    (None: none; ``nlp-sway`` keeps it unless the request names another)."""
    length: float
    damping: float = 0.0
    gyration: float = GYRATION
    source: str = ""
    swing_max: float | None = None


@dataclass(frozen=True)
class DynamicsSpec:
    """The ``[dynamics]`` section (see the module doc): SI units, every value validated."""
    bulk_modulus: float
    spool_time_constant: float
    pump_time_constant: float
    pump_line_volume: float
    compensator_dp: float
    meter_out_dp: float
    meter_out_margin: float
    joints: dict = field(default_factory=dict)      # joint name -> JointDynamics
    source: str = ""
    grapple: GrappleLink | None = None               # None: the load fixed at the tip
    bulk_low: float = 1.0                   # β(p) law (module doc); 1, 1: constant β
    bulk_high: float = 1.0
    bulk_reference_pressure: float = 8.0e6
    command_delay: float = 0.0              # s, command -> valves (0: none)

    def bulk_factor(self, p):
        """β(p)/β for gauge pressures ``p`` [Pa] (numpy): (p + p_atm)/(p_ref + p_atm)
        clipped to [bulk_low, bulk_high]."""
        import numpy as np
        r = (np.asarray(p, float) + P_ATM) / (self.bulk_reference_pressure + P_ATM)
        return np.clip(r, self.bulk_low, self.bulk_high)


def parse_dynamics(R: TableReader, data: dict, joint_names) -> DynamicsSpec | None:
    """Validate the ``[dynamics]`` table of a parsed spec (``data`` is the whole TOML dict);
    None when the section is absent. Every joint needs its ``[dynamics.joint.<name>]`` table."""
    tbl = R.table(data, "dynamics", "", required=False)
    if tbl is None:
        return None
    w = "dynamics."
    R.keys(tbl, DYNAMICS_KEYS, w)
    kw = dict(
        bulk_modulus=R.num(tbl, "bulk_modulus", w, lo=0, lo_open=True),
        spool_time_constant=R.num(tbl, "spool_time_constant", w, lo=0, lo_open=True, hi=1.0),
        pump_time_constant=R.num(tbl, "pump_time_constant", w, lo=0, lo_open=True, hi=5.0),
        pump_line_volume=R.num(tbl, "pump_line_volume", w, lo=0, lo_open=True),
        compensator_dp=R.num(tbl, "compensator_dp", w, lo=0, lo_open=True),
        meter_out_dp=R.num(tbl, "meter_out_dp", w, lo=0, lo_open=True),
        meter_out_margin=R.num(tbl, "meter_out_margin", w, lo=0.0, hi=0.5),
        bulk_low=R.num(tbl, "bulk_low", w, default=1.0, lo=0.01, hi=1.0),
        bulk_high=R.num(tbl, "bulk_high", w, default=1.0, lo=1.0, hi=10.0),
        bulk_reference_pressure=R.num(tbl, "bulk_reference_pressure", w, default=8.0e6,
                                      lo=1e5, hi=1e8),
        command_delay=R.num(tbl, "command_delay", w, default=0.0, lo=0.0, hi=0.3),
        source=R.text(tbl, "source", w))
    if kw["bulk_modulus"] > 5e9:
        R.fail(w + "bulk_modulus", tbl["bulk_modulus"],
               "must be <= 5e9 Pa (oil is about 1.0–1.8e9 Pa)")
    jt = R.table(tbl, "joint", w)
    for k in jt:
        if k not in joint_names:
            R.fail(f"{w}joint.{k}", jt[k], f"must name a joint: {', '.join(joint_names)}")
    joints = {}
    for name in joint_names:
        jw = f"{w}joint.{name}."
        t = R.table(jt, name, f"{w}joint.")
        R.keys(t, _JOINT_KEYS, jw)
        hv = R.vec(t, "hose_volume", jw, 2)
        if min(hv) <= 0:
            R.fail(jw + "hose_volume", t["hose_volume"],
                   "both hose volumes must be > 0 m³ (a chamber without oil has no stiffness)")
        joints[name] = JointDynamics(hose_volume=tuple(hv),
                                     coulomb=R.num(t, "coulomb", jw, default=0.0, lo=0.0),
                                     viscous=R.num(t, "viscous", jw, default=0.0, lo=0.0),
                                     leakage=R.num(t, "leakage", jw, default=0.0, lo=0.0,
                                                   hi=1e-9),
                                     source=R.text(t, "source", jw, default=""))
    g = R.table(tbl, "grapple", w, required=False)
    if g is not None:
        gw = w + "grapple."
        R.keys(g, _GRAPPLE_KEYS, gw)
        g = GrappleLink(length=R.num(g, "link_length", gw, lo=0, lo_open=True, hi=5.0),
                        damping=R.num(g, "damping", gw, default=0.0, lo=0.0, hi=1e6),
                        gyration=R.num(g, "gyration", gw, default=GYRATION, lo=0.0, hi=2.0),
                        source=R.text(g, "source", gw, default=""),
                        swing_max=(R.num(g, "swing_max", gw, lo=0.0, lo_open=True, hi=5.0)
                                   if "swing_max" in g else None))
    return DynamicsSpec(joints=joints, grapple=g, **kw)
