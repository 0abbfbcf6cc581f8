"""Seed 002's local laws in their own setting: closed loop on the Exudyn plant, reading its
joint positions and — for P-optimal — its chamber pressures online (issue 13, item 4).

Every control period the law sees the plant's true joints (the seed's simulation fed the
measured state back), follows the cycle's time-based tip command with the correction gain of
:func:`planner.methods.laws.follow_command`, shares the pump flow like it, and its joint rates
become valve commands through the inverse valve model (:mod:`planner.model.valves`). The
P-optimal criterion reads the plant's pressures in each cylinder's direction of motion instead
of the model's inverse dynamics (:class:`MeasuredPOptimal`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math

import numpy as np

from planner.methods.laws import Step, flow_share, rate_box
from planner.methods.laws_energy import JLA, POptimal, QOptimal
from planner.model.valves import stroke_rate_to_command, valve_params
from planner.simulation.dynamic.energy import energy_balance
from planner.simulation.dynamic.exudyn_plant import ExudynPlant

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["MeasuredPOptimal", "OnlineLaw", "run_online", "make_online_law"]


class MeasuredPOptimal(POptimal):
    """P-optimal whose pressures are the plant's (``memo["measured"]`` = (p_a, p_b) of the
    latest sample) in each cylinder's direction of motion, not the model's."""
    name = "p_optimal"

    def _pressures(self, crane: Crane, c, st, u):
        p_a, p_b = st.memo["measured"]
        P = c["P"]
        return np.where(u >= 0, p_a[P], p_b[P])


def make_online_law(key: str):
    """'jla' | 'q_optimal' | 'p1' | 'p1_5' | 'p2' (P-optimal n = 1, 1.5, 2 on measured
    pressures) -> a law instance with its default gains."""
    if key == "jla":
        return JLA()
    if key == "q_optimal":
        return QOptimal()
    n = {"p1": 1.0, "p1_5": 1.5, "p2": 2.0}.get(key)
    if n is None:
        raise ValueError(f"online law '{key}': allowed jla, q_optimal, p1, p1_5, p2")
    return MeasuredPOptimal(n)


class OnlineLaw:
    """The controller ``(t, q, qd, p_a, p_b) -> u`` of one law on a time-based tip command
    (``command(t) -> (ref tip, ref velocity)``); keeps the largest tip error and the smallest
    scaling factor β."""

    def __init__(self, crane: Crane, law, command, rate: float = 100.0, gain: float = 5.0):
        self.crane, self.law, self.command, self.gain = crane, law, command, gain
        self.dt = 1.0 / rate
        self.vp = valve_params(crane)
        self.qd_prev = np.zeros(crane.n)
        self.memo: dict = {"payload": None}
        self.max_err, self.min_beta, self.sq_err, self.calls = 0.0, 1.0, 0.0, 0

    def __call__(self, t, q, qd, p_a, p_b):
        crane = self.crane
        tip, J, x, dxdq = crane.kinematics(q)
        ref, vref = self.command(t)
        e = np.asarray(ref, float) - tip
        e[2] = (e[2] + math.pi) % (2 * math.pi) - math.pi
        err = float(np.sqrt(e[0] ** 2 + e[1] ** 2 + (tip[0] * e[2]) ** 2))
        self.max_err = max(self.max_err, err)
        self.sq_err += err * err
        self.calls += 1
        v = np.asarray(vref, float) + self.gain * e
        lo, hi = rate_box(crane, q)
        self.memo["measured"] = (np.asarray(p_a, float), np.asarray(p_b, float))
        rates, beta = self.law.rates(crane, Step(q, tip, J, x, dxdq, lo, hi, self.dt,
                                                 self.qd_prev, self.memo), v)
        rates, share = flow_share(crane, q, rates)
        self.min_beta = min(self.min_beta, float(beta * share))
        self.qd_prev = rates
        u, _ = stroke_rate_to_command(self.vp, rates * dxdq)
        return np.clip(u, -1.0, 1.0)


def run_online(crane: Crane, law_key: str, command, duration: float, q0, *, rate: float = 100.0,
               gain: float = 5.0, settle: float = 1.0, plant: ExudynPlant | None = None,
               max_wall_s: float = 900.0) -> dict:
    """One law closed loop on the Exudyn plant for ``duration`` s of ``command`` from ``q0``
    (then ``settle`` s more of the last reference), tip-error correction ``gain`` [1/s].
    Returns status, pump energy at the shaft [J], the energy-balance residual, the largest and
    the RMS tip error [m] and the smallest β."""
    plant = plant or ExudynPlant(crane)
    ctl = OnlineLaw(crane, make_online_law(law_key), command, rate, gain)
    t_end = duration + settle
    t_u = np.arange(0.0, t_end + 1e-9, 1.0 / rate)
    run = plant.integrate(t_u, np.zeros((t_u.size, crane.n)), q0, t_end=t_end,
                          max_wall_s=max_wall_s, controller=ctl)
    out = dict(law=law_key, status=run.status, t_fail=run.t_fail, reason=run.reason,
               gain=gain, max_tip_error_m=ctl.max_err,
               rms_tip_error_m=math.sqrt(ctl.sq_err / max(ctl.calls, 1)),
               min_beta=ctl.min_beta, wall_s=run.wall_s)
    if run.ok:
        eb = energy_balance(plant, run)
        out.update(pump_J=eb["pump_shaft_J"], balance_residual=eb["residual_rel"])
    return out
