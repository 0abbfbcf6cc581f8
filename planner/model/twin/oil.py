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
correction along a plan: the extra stroke δx(t) whose rate is added to the plan's.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from planner.model.dynamics_spec import P_ATM

__all__ = ["BULK_MODULUS", "OIL_STIFFNESS", "oil_stiffness", "oil_stroke"]


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


def oil_stiffness(per: dict, sc: dict, i: int, x, p_a, p_b):
    """κ_a, κ_b of actuator ``i`` at strokes ``x`` and chamber pressures ``p_a``, ``p_b``
    (symbols or arrays (M,)); ``per``/``sc`` a :class:`~planner.model.twin.params.TwinParams`'
    per-actuator and machine-wide values (or the twin's symbols)."""
    g = [per[k][i] for k in ("hose_a", "hose_b", "swept", "area_a", "area_b", "x_lo", "x_hi")]
    s = [sc[k] for k in _LAW]
    if isinstance(x, (ca.SX, ca.MX)):
        return OIL_STIFFNESS(x, p_a, p_b, *g, *s)
    row = (lambda a: np.atleast_1d(np.asarray(a, float))[None, :])
    ka, kb = OIL_STIFFNESS(row(x), row(p_a), row(p_b), *g, *s)
    return np.asarray(ka, float).ravel(), np.asarray(kb, float).ravel()


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
