"""The twin's numbers: one machine's dynamic data gathered into the parameter vector of the
compiled right-hand side (:mod:`planner.model.twin.ode`).

Everything hydraulic is an *input* of the compiled functions, not a constant baked into them:
one compiled copy serves every valves-stage or dynamics-stage effect (a gain error, a dead
band, the oil's stiffness, hose volumes, friction, leakage, the pump's limit) and a calibration
that fits them. Only the rigid-body data (DH chain, link masses and inertias, the stroke map)
are part of the expression, because the model's RNEA is written over them.

Per actuator i (arrays (n,), spec order), the fields of :data:`PER_ACTUATOR`; machine-wide the
fields of :data:`SCALARS`. Where they come from:

* valve section (:func:`planner.model.valves.valve_circuit`, the one valve definition's data):
  flow gain (× the valves-stage gain factor), dead band, both areas, single-acting, the
  meter-out margin, the compensators' drops, tank pressure;
* ``[dynamics]`` (:class:`~planner.model.dynamics_spec.DynamicsSpec`, after the dynamics-stage
  effects): bulk modulus and its pressure law, hose volumes, Coulomb and viscous friction, leakage, the spool and
  pump time constants, the pump line volume;
* ``[pump]``: load sensing or constant pressure, maximum flow (× the valves-stage pump factor),
  LS margin, standby, set and relief pressures;
* ``ls_ramp``: 0 (the machine: a valve signals its meter-in pressure to the load-sensing pump
  as soon as it opens past ``OPEN_EPS``); > 0 only in the optimisation twin of
  :mod:`planner.refine` (:mod:`planner.model.twin.ode`);
* the stroke geometry: a cylinder's chambers are measured from its own ends (0 and its stroke,
  where it bottoms out); a rack's from the strokes of the joint limits; a rotary motor keeps its
  hose volumes and has no end stop (its ports' oil does not change with the angle).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass

import numpy as np

from planner.model.actuators import stroke_range
from planner.model.valves import valve_circuit

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["PER_ACTUATOR", "SCALARS", "TwinParams", "twin_params", "param_index",
           "COULOMB_SMOOTHING"]

#: per-actuator parameters, in the order of the parameter vector
PER_ACTUATOR = ("gain", "deadband", "area_a", "area_b", "single", "leak", "hose_a", "hose_b",
                "coulomb", "viscous", "v_smooth", "x_lo", "x_hi", "stop", "swept")
#: machine-wide parameters, after the per-actuator block
SCALARS = ("beta", "margin", "dp_c", "dp_out", "p_tank", "load_sensing", "q_max", "ls_margin",
           "standby", "p_const", "p_relief", "tau_pump", "v_pump", "tau_spool", "payload",
           "beta_lo", "beta_hi", "beta_pref", "ls_ramp")
#: Coulomb friction is tanh(ẋ/v_s)-smoothed over this fraction of the full-command speed
COULOMB_SMOOTHING = 0.01


@dataclass(frozen=True)
class TwinParams:
    """The parameter values of one machine (see the module doc): ``per`` maps each name of
    :data:`PER_ACTUATOR` to an array (n,), ``scalar`` each name of :data:`SCALARS` to a
    float. :meth:`vector` is the compiled functions' parameter input."""
    n: int
    per: dict
    scalar: dict

    def vector(self) -> np.ndarray:
        return np.concatenate([np.asarray(self.per[k], float) for k in PER_ACTUATOR]
                              + [np.array([float(self.scalar[k]) for k in SCALARS])])

    @property
    def size(self) -> int:
        return len(PER_ACTUATOR) * self.n + len(SCALARS)


def param_index(n: int, name: str) -> int:
    """Position of the machine-wide parameter ``name`` (one of :data:`SCALARS`) in the
    parameter vector of an n-joint machine."""
    if name not in SCALARS:
        raise ValueError(f"twin parameter {name!r}: allowed {', '.join(SCALARS)}")
    return len(PER_ACTUATOR) * n + SCALARS.index(name)


def joint_limit_strokes(crane: Crane):
    """Strokes at the joint limits (lo, hi), each (n,) (ordered: lo ≤ hi)."""
    L = crane.limit_arrays()
    x, _ = crane.stroke(np.vstack([L["q_min"], L["q_max"]]))
    return x.min(axis=0), x.max(axis=0)


def twin_params(crane: Crane, dynamics, payload: float, gain_scale=1.0, deadband=None,
                pump_scale: float = 1.0) -> TwinParams:
    """The :class:`TwinParams` of ``crane`` with ``dynamics`` (a
    :class:`~planner.model.dynamics_spec.DynamicsSpec`), the tip ``payload`` [kg] and the
    valves-stage changes: per-valve gain factors, dead bands (None: the spec's), the pump-flow
    factor. ValueError naming the field when a value is unusable."""
    spec = crane.spec
    n = spec.n
    missing = [j.name for j in spec.joints if j.name not in dynamics.joints]
    if missing:
        raise ValueError(f"crane '{spec.id}': dynamics.joint.{missing[0]}: missing; the twin "
                         "needs every joint's hose volumes")
    jd = [dynamics.joints[j.name] for j in spec.joints]
    leak = np.array([d.leakage for d in jd])
    vc = valve_circuit(crane, dynamics, gain_scale=gain_scale, deadband=deadband, leak=leak)
    acts = [j.actuator for j in spec.joints]
    lo, hi = joint_limit_strokes(crane)
    cyl = np.array([a.kind in ("triangle", "lever", "telescope") for a in acts])
    ends = np.array([stroke_range(a) if c else (0.0, 0.0) for a, c in zip(acts, cyl)])
    motor = np.array([a.kind == "rotary" for a in acts])
    nominal_gain = np.array([a.flow_gain for a in acts])
    if not (np.isfinite(payload) and payload >= 0):
        raise ValueError(f"twin: payload = {payload!r} kg; allowed: a finite mass >= 0")
    pump = spec.pump
    per = dict(gain=vc.gain, deadband=vc.deadband, area_a=vc.area_a, area_b=vc.area_b,
               single=vc.single.astype(float), leak=vc.leak,
               hose_a=np.array([d.hose_volume[0] for d in jd]),
               hose_b=np.array([d.hose_volume[1] for d in jd]),
               coulomb=np.array([d.coulomb for d in jd]),
               viscous=np.array([d.viscous for d in jd]),
               v_smooth=COULOMB_SMOOTHING * nominal_gain / np.minimum(vc.area_a, vc.area_b),
               x_lo=np.where(cyl, ends[:, 0], lo), x_hi=np.where(cyl, ends[:, 1], hi),
               stop=(~motor).astype(float), swept=(~motor).astype(float))
    scalar = dict(beta=dynamics.bulk_modulus, margin=vc.margin, dp_c=vc.dp_c,
                  dp_out=vc.dp_out, p_tank=vc.p_tank,
                  load_sensing=float(pump.kind == "load_sensing"),
                  q_max=pump.max_flow * float(pump_scale), ls_margin=pump.margin,
                  standby=pump.standby, p_const=pump.pressure,
                  p_relief=min(pump.max_pressure, 1e9),
                  tau_pump=dynamics.pump_time_constant, v_pump=dynamics.pump_line_volume,
                  tau_spool=dynamics.spool_time_constant, payload=float(payload),
                  beta_lo=dynamics.bulk_low, beta_hi=dynamics.bulk_high,
                  beta_pref=dynamics.bulk_reference_pressure, ls_ramp=0.0)
    for k, v in list(per.items()):
        per[k] = np.broadcast_to(np.asarray(v, float), (n,)).copy()
    return TwinParams(n=n, per=per, scalar=scalar)
