"""The twin diagnosis' candidates (:mod:`planner.calibration.twin_diagnosis`, its module doc
has their table): catalogue effects written as one twin parameter each, reported in the
catalogue's unit.

**The least size worth naming** (:data:`LEAST`, :meth:`TwinEffect.size`). The twin is a model
of the machine, not the machine: on clean 30 s Exudyn logs a few candidates won the held-out
score at sizes no engineer would act on (a stick's flow gain × 1.0012, the oil × 1.0006, a
boom leaking 0.02 mm/s at 10 MPa — cat215b and s100f, discrepancy_twin_fresh2.md): the
structural differences of two implementations of the same physics, significant in 1500
samples. A fit whose change from the spec's value is below the least size is never named; the
best such fit that scores is the twin within tolerance, and the diagnosis scores the others
against it."""
from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass

import numpy as np

from planner.calibration.twin_params import TwinParameter, twin_parameters

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["KINDS", "LEAST", "TwinEffect", "twin_candidates"]

#: candidate name -> (per joint, reported parameter) (module doc)
KINDS = {
    "bulk_modulus": (False, "scale"), "hose_volume": (True, "scale"),
    "valve_deadband": (True, "width"), "coulomb_friction": (True, "force"),
    "viscous_friction": (True, "coefficient"), "leakage": (True, "coefficient"),
    "spool_lag": (False, "tau"), "pump_lag": (False, "tau"), "flow_gain": (True, "scale"),
    "payload_mass": (False, "mass"), "pump_flow_limit": (False, "scale"),
    "time_delay": (False, "delay")}


#: the least change of each kind the diagnosis names (twin_diagnosis's module doc, "Tolerance"):
#: assumed, an order below the smallest realistic effect the catalogue's trials draw
#: (``Effect.trial_range``) and within a spec number's own precision. Scale factors (bulk
#: modulus, hose volume, flow gain, pump flow): 1 % of the spec's value (trials: a flow gain
#: 5–20 % off, a pump 15–40 % short, the oil × 0.3–0.6); Coulomb friction: the force of
#: 25 kPa on the actuator's smaller area (trials ≥ 150 kPa); viscous friction: 50 kPa at full
#: speed (trials 0.3–1 MPa); leakage: 0.05 mm/s of drift at 10 MPa (trials 0.5–2 mm/s); a
#: dead band 1 % of the command range (trials 8–20 %); a lag or delay 5 ms (trials ≥ 60 ms);
#: a payload 1 % of the spec's load + tool (at least 0.1 kg; trials ≥ 30 %).
LEAST = {"scale": 0.01, "coulomb_pressure": 25e3, "viscous_pressure": 50e3,
         "leak_speed": 0.05e-3, "deadband": 0.01, "time": 0.005, "payload_share": 0.01}


@dataclass(frozen=True)
class _Par:      # a reported parameter's name (what verdict.judge lists)
    name: str


class TwinEffect:
    """One candidate as a twin change: ``name`` (:data:`KINDS`), ``joint``, the twin
    parameter ``param`` (a :class:`TwinParameter`) at scaled value ``z``; ``values`` in the
    reported unit (module doc)."""

    def __init__(self, name: str, joint, param: TwinParameter, z: float):
        self.name, self.joint, self.param, self.z = name, joint, param, float(z)
        v = param.to_value(self.z)
        unit = KINDS[name][1]
        if name == "bulk_modulus":
            v = v / param.nominal
        elif name in ("coulomb_friction", "viscous_friction", "leakage", "payload_mass"):
            v = v - param.nominal
        self.values = {unit: float(v)}
        self.parameters = (_Par(unit),)

    def at(self, z: float) -> "TwinEffect":
        return TwinEffect(self.name, self.joint, self.param, z)

    def to_dict(self) -> dict:
        return dict(name=self.name, joint=self.joint, **self.values)

    def size(self, crane: Crane) -> float:
        """The change from the spec's value in units of the least change worth naming
        (:data:`LEAST`): below 1 the candidate is within the twin's tolerance."""
        par = self.param
        v, v0 = par.to_value(self.z), par.nominal
        name = self.name
        if name in ("bulk_modulus", "hose_volume", "flow_gain", "pump_flow_limit"):
            return abs(v / v0 - 1.0) / LEAST["scale"]
        if name in ("spool_lag", "pump_lag", "time_delay"):
            return abs(v - v0) / LEAST["time"]
        if name == "valve_deadband":
            return abs(v - v0) / LEAST["deadband"]
        if name == "payload_mass":
            return abs(v - v0) / (LEAST["payload_share"] * max(v0, 10.0))
        a = crane.spec.joints[list(crane.names).index(self.joint)].actuator
        area = min(a.area_a, a.area_b)         # rotary: the motor's displacement [m³/rad]
        if name == "coulomb_friction":
            return abs(v - v0) / (LEAST["coulomb_pressure"] * area)
        if name == "viscous_friction":
            v_full = a.flow_gain / area if np.isfinite(a.flow_gain) else 1.0
            return abs(v - v0) * v_full / area / LEAST["viscous_pressure"]
        if name == "leakage":                   # the drift of the loaded chamber at 10 MPa
            return abs(v - v0) * 1e7 / a.area_a / LEAST["leak_speed"]
        raise ValueError(f"candidate {name!r}: no least size (allowed: {', '.join(KINDS)})")

    @property
    def key(self) -> tuple:
        return (self.param.name, round(self.z, 12))


def twin_candidates(crane: Crane, names=None) -> list[TwinEffect]:
    """The candidates (module doc) at the spec's values, per-joint ones on every joint;
    ``names``: only these kinds (ValueError naming an unknown one and what is allowed)."""
    names = list(KINDS) if names is None else list(names)
    bad = [s for s in names if s not in KINDS]
    if bad:
        raise ValueError(f"effects: {bad[0]!r} has no twin counterpart; allowed: "
                         f"{', '.join(KINDS)}")
    tp = {p.name: p for p in twin_parameters(crane)}
    m0 = crane.spec.payload.total
    out = []
    own = {"spool_lag": "spool_time_constant", "pump_lag": "pump_time_constant",
           "time_delay": "command_delay", "valve_deadband": "deadband.{}", "leakage": "leakage.{}",
           "coulomb_friction": "coulomb.{}", "viscous_friction": "viscous.{}"}
    for name in names:
        for j in (crane.names if KINDS[name][0] else [None]):
            if name == "hose_volume":
                p = TwinParameter(f"hose.{j}", "hose", j, "1", 1.0, 0.2, 10.0, True)
            elif name == "flow_gain":
                p = TwinParameter(f"gain.{j}", "gain", j, "1", 1.0, 0.5, 1.5, True)
            elif name == "pump_flow_limit":
                p = TwinParameter("pump_flow", "pump_flow", None, "1", 1.0, 0.1, 1.0, True)
            elif name == "payload_mass":
                p = TwinParameter("payload", "payload", None, "kg", m0, max(m0 - 3000.0, 0.0),
                                  m0 + 5000.0, False, max(m0, 50.0))
            else:
                p = tp[own.get(name, name).format(j)]
            out.append(TwinEffect(name, j, p, p.to_z(p.nominal)))
    return out
