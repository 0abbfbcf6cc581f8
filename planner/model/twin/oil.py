"""The oil spring of each actuator, written once: its chambers' stiffness β(p)/V, used by the
twin's right-hand side (:mod:`planner.model.twin.ode`) and by the feed-forward that fills it
(:func:`planner.feedforward.commands` with ``oil=True``).

A chamber of volume V (its hose plus the swept part, V_a = V_hose,a + A_a·(x − x_lo), V_b =
V_hose,b + A_b·(x_hi − x), x clipped to the ends; a motor keeps its hose volumes) holding oil
of bulk modulus β(p) = β·clip((p + p_atm)/(p_ref + p_atm), low, high) changes its pressure at
ṗ = (β(p)/V)·(net inflow): :data:`OIL_STIFFNESS` returns κ_a, κ_b = β(p_a)/V_a, β(p_b)/V_b
[Pa/m³].

**Why the feed-forward needs it.** Both valve edges of a function are flow controlled (the
compensated meter-in edge a flow source, the load-holding meter-out edge capped at
(1 + m) × the matched outflow), so the load rides on the oil between them: a command that
asks only for the stroke rate of the plan, Q = A·ẋ, leaves no oil to raise the pressures the
plan's accelerations and loads need, and the function lags, catches up and rings at its
oil-spring frequency (benchmarks/results/energy_round7.md: the ringing is most of the plant's
pump work above the quasi-static price). The inflow that makes the chambers follow the plan's
pressures is A_a·ẋ + ṗ_a/κ_a into side a and A_b·ẋ − ṗ_b/κ_b out of side b; one spool meters
both, so the command asks for the stroke rate ẋ + ṗ_a/(κ_a·A_a) − ṗ_b/(κ_b·A_b) (a
single-acting rod side is vented: no second term). :func:`oil_stroke` integrates that
correction along a plan: the extra stroke δx(t) whose rate is added to the plan's;
:func:`oil_stroke_rate` holds it per control period and :func:`filled_commands` turns the
plan's rates plus it into valve commands (a closed valve stays closed, none is reversed, and
the oil such periods would have taken is delivered in the joint's open periods).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from planner.model.dynamics_spec import P_ATM
from planner.model.valves import stroke_rate_to_command

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["BULK_MODULUS", "OIL_STIFFNESS", "oil_stiffness", "oil_stroke", "fills_oil",
           "oil_stroke_rate", "filled_commands"]


_LAW = ("beta", "beta_pref", "beta_lo", "beta_hi")


def _bulk():
    p = ca.SX.sym("p")
    g = {k: ca.SX.sym(k) for k in _LAW}
    r = (p + P_ATM) / (g["beta_pref"] + P_ATM)
    return ca.Function("bulk_modulus", [p, *g.values()],
                       [g["beta"] * ca.fmin(ca.fmax(r, g["beta_lo"]), g["beta_hi"])],
                       ["p", *_LAW], ["beta_p"])


#: β(p) [Pa]: the [dynamics] pressure law of the oil's bulk modulus (module doc); inputs p and
#: beta, beta_pref, beta_lo, beta_hi
BULK_MODULUS = _bulk()


def _build():
    x, pa, pb = ca.SX.sym("x"), ca.SX.sym("p_a"), ca.SX.sym("p_b")
    names = ("hose_a", "hose_b", "swept", "area_a", "area_b", "x_lo", "x_hi", *_LAW)
    g = {k: ca.SX.sym(k) for k in names}

    def bulk(p):
        return BULK_MODULUS(p, *(g[k] for k in _LAW))
    xc = ca.fmin(ca.fmax(x, g["x_lo"]), g["x_hi"])
    va = g["hose_a"] + g["swept"] * g["area_a"] * (xc - g["x_lo"])
    vb = g["hose_b"] + g["swept"] * g["area_b"] * (g["x_hi"] - xc)
    return ca.Function("oil_stiffness", [x, pa, pb, *g.values()],
                       [bulk(pa) / va, bulk(pb) / vb], ["x", "p_a", "p_b", *names],
                       ["kappa_a", "kappa_b"])


#: κ_a, κ_b = β(p_a)/V_a, β(p_b)/V_b [Pa/m³] of one actuator (module doc); inputs x, p_a, p_b
#: and its data: hose_a, hose_b, swept, area_a, area_b, x_lo, x_hi, beta, beta_pref, beta_lo,
#: beta_hi (the names of :mod:`planner.model.twin.params`)
OIL_STIFFNESS = _build()
_FACE = None


def oil_stiffness(per: dict, sc: dict, i: int, x, p_a, p_b):
    """κ_a, κ_b of actuator ``i`` at strokes ``x`` and chamber pressures ``p_a``, ``p_b``
    (symbols or arrays (M,)); ``per``/``sc`` a :class:`~planner.model.twin.params.TwinParams`'
    per-actuator and machine-wide values (or the twin's symbols)."""
    g = [per[k][i] for k in ("hose_a", "hose_b", "swept", "area_a", "area_b", "x_lo", "x_hi")]
    s = [sc[k] for k in _LAW]
    if isinstance(x, (ca.SX, ca.MX)):
        return OIL_STIFFNESS(x, p_a, p_b, *g, *s)
    global _FACE
    if _FACE is None:          # the compiled elementwise face, built on first numeric use
        from planner.model.numeric import Elementwise
        _FACE = Elementwise(OIL_STIFFNESS, sizes=(1024, 8192))
    ka, kb = _FACE(np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(p_a, float)),
                   np.atleast_1d(np.asarray(p_b, float)), *(float(v) for v in (*g, *s)))
    return ka, kb


def oil_stroke(params, x, p_a, p_b) -> np.ndarray:
    """The extra stroke δx (M, n) [m | rad] whose rate fills the oil spring along a plan
    sampled at M instants (module doc): the strokes ``x`` and the chamber pressures ``p_a``,
    ``p_b`` (M, n) the plan asks for; ``params`` a
    :class:`~planner.model.twin.params.TwinParams`. δx(t_0) = 0; each step adds
    Δp_a/(κ̄_a·A_a) − Δp_b/(κ̄_b·A_b) with 1/κ̄ the mean of its ends' 1/κ."""
    x, p_a, p_b = (np.atleast_2d(np.asarray(a, float)) for a in (x, p_a, p_b))
    per, sc = params.per, params.scalar
    dx = np.zeros_like(x)
    for i in range(x.shape[1]):
        ka, kb = oil_stiffness(per, sc, i, x[:, i], p_a[:, i], p_b[:, i])
        ca_ = 0.5 * (1.0 / ka[1:] + 1.0 / ka[:-1])
        cb_ = 0.5 * (1.0 / kb[1:] + 1.0 / kb[:-1])
        step = (np.diff(p_a[:, i]) * ca_ / per["area_a"][i]
                - (1.0 - per["single"][i]) * np.diff(p_b[:, i]) * cb_ / per["area_b"][i])
        dx[1:, i] = np.cumsum(step)
    return dx


def fills_oil(crane: Crane) -> bool:
    """True where the feed-forward can fill ``crane``'s oil springs: its spec has
    ``[dynamics]`` (hose volumes, bulk modulus) and no enabled transformer."""
    spec = crane.spec
    ht = spec.transformer
    return spec.dynamics is not None and not (ht is not None and ht.enabled)


def oil_stroke_rate(crane: Crane, t_plan, x, p_a, p_b, t, hold: str) -> np.ndarray:
    """The stroke rate (M, n) that fills the oil springs at the control instants ``t`` (M,)
    of a plan sampled at ``t_plan`` with strokes ``x`` and chamber pressures ``p_a``, ``p_b``
    (the plan's, ``evaluate()``'s): :func:`oil_stroke` held per period like the plan's own
    rate — ``hold`` "mean" (its change over the period; none past the plan's end) or
    "sample" (its rate at t_k)."""
    from planner.model.twin.params import twin_params
    params = twin_params(crane, crane.spec.dynamics, crane.spec.payload.total)
    dx = oil_stroke(params, x, p_a, p_b)
    if hold == "mean":
        dt = float(t[1] - t[0])
        d = np.column_stack([np.interp(np.append(t, t[-1] + dt), t_plan, dx[:, i])
                             for i in range(crane.n)])
        return np.diff(d, axis=0) / dt
    r = np.gradient(dx, t_plan, axis=0)
    return np.column_stack([np.interp(t, t_plan, r[:, i], right=0.0) for i in range(crane.n)])


def filled_commands(vp, xd, r):
    """Commands and flows (M, n) for the plan's stroke rates ``xd`` plus the oil's ``r`` per
    period (``vp``: :func:`planner.model.valves.valve_params`). A period whose filled command
    would open a valve the plain one keeps closed (a crept valve sets the load-sensing pump's
    pressure) or reverse it (a reversal signals the other chamber) is closed; the stroke it
    would have delivered — and the oil a held joint's chambers take while its valve is closed,
    its sag — is spread over the joint's open periods in proportion to their plain stroke, so
    that the move delivers the plan's stroke plus all of its oil."""
    plain, _ = stroke_rate_to_command(vp, xd)
    want = xd + r
    u, _ = stroke_rate_to_command(vp, want)
    keep = (np.sign(u) == np.sign(plain)) & (plain != 0)
    missed = np.where(keep, 0.0, want).sum(axis=0)
    w = np.where(keep, np.abs(xd), 0.0)
    total = w.sum(axis=0)
    share = np.divide(missed, total, out=np.zeros_like(missed), where=total > 0)
    u, flow = stroke_rate_to_command(vp, want + share * w)
    keep &= np.sign(u) == np.sign(plain)
    return np.where(keep, u, 0.0), np.where(keep, flow, 0.0)
