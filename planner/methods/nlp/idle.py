"""Idle means idle: the energy NLP's creeping functions, found and held still.

A load-sensing pump sets its pressure by the highest load of the functions whose valves are
open — on the machine any opening, however small (:mod:`planner.model.pricing`, the machine
pricing: a function draws from ``OPEN_EPS``·G on). That makes the pump bill discontinuous in
a function's flow: at zero the function is out of the LS line, at 10⁻⁵ of its flow it may set
the pressure for all the others. The move NLP prices the pump per node through an activity
mask (:mod:`planner.methods.nlp.activity`) and sees neither the flows between its nodes nor
the jump, so its least-energy moves *creep* the functions they do not need: a joint carried
along at 10⁻⁶…10⁻³ of its valve's flow, idle at the nodes by the mask and open in between.
``evaluate()`` charges the creeping function's holding pressure on every drawn litre (so the
NLP's move may lose to the slowed minimum-time move), and on the machine a chamber crept at
such flows does not even reach its quasi-static pressure within the creep (benchmarks/
results/energy_pricing.md), so the bill departs from both.

The discrete choice the NLP cannot make — *use* a function or *close* its valve — is made
here: :func:`creep_nodes` marks, per joint, the runs of at least ``min_run`` consecutive nodes
where the joint's metered flow stays below ``useful`` of its valve's full flow G (a run, not a
single node: a joint passing through zero speed to reverse is working, not creeping), and
:func:`pinned` solves the NLP with those nodes' speeds and accelerations held at zero. With
piecewise-constant jerk, a joint at rest (q̇ = q̈ = 0) at two consecutive nodes has zero jerk
in between, so it is closed over the whole run, not only at its nodes. The caller
(:func:`~planner.methods.nlp.energy.energy_optimal`) judges the held move against the free one
with ``evaluate()``, so holding can only help.

:data:`USEFUL` (1 % of the valve's full flow) is assumed: a proportional valve is not worked
below about a per cent of its stroke past the dead band (its flow there is set by tolerances,
not by the command); every plan's working motions on the shipped specs are far above it.
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import TYPE_CHECKING

import numpy as np

from planner.model.flows import actuator_table

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["USEFUL", "MIN_RUN", "creep_nodes", "pinned"]

USEFUL = 0.01  # assumed: a valve worked below 1 % of its full flow creeps (module doc)
MIN_RUN = 2    # consecutive nodes below USEFUL that make a creep (one node: a reversal)


def creep_nodes(crane: Crane, q, qd, useful: float = USEFUL,
                min_run: int = MIN_RUN) -> np.ndarray:
    """(K, n) bool: where the joint positions ``q`` and rates ``qd`` (K, n) at the NLP's nodes
    show a joint crept along (module doc): |metered flow| < ``useful``·G for at least
    ``min_run`` consecutive nodes (the metered area: A_a extending or for a single-acting
    cylinder, A_b retracting). A joint without a valve (G not finite) never creeps."""
    if not 0.0 < useful < 1.0:
        raise ValueError(f"useful: {useful!r} is not a fraction of the valve flow; allowed: "
                         "0 < useful < 1")
    if int(min_run) != min_run or min_run < 1:
        raise ValueError(f"min_run: {min_run!r} is not a count of nodes; allowed: an integer "
                         "≥ 1")
    T = actuator_table(crane.spec)
    G = np.array([j.actuator.flow_gain for j in crane.spec.joints], float)
    _, dxdq = crane.stroke(np.asarray(q, float))
    xd = dxdq * np.asarray(qd, float)
    area = np.where((xd >= 0) | T.single, T.area_a, T.area_b)
    valve = np.isfinite(G) & (G > 0)
    small = (np.abs(area * xd) < useful * np.where(valve, G, np.inf)) & valve
    out = np.zeros_like(small)
    for i in range(small.shape[1]):
        k = 0
        while k < len(small):
            if not small[k, i]:
                k += 1
                continue
            e = k
            while e + 1 < len(small) and small[e + 1, i]:
                e += 1
            if e - k + 1 >= min_run:
                out[k:e + 1, i] = True
            k = e + 1
    return out


@contextmanager
def pinned(nlp, idle, w0):
    """Within the block, ``nlp`` (a :class:`~planner.methods.nlp.move.MoveNLP`) solves with
    the speeds and accelerations of the joints ``idle`` ((N + 1, n) bool, node × joint) held
    at zero; yields the primal guess ``w0`` with those entries zeroed (so that the activity
    mask the NLP starts from leaves them out). The bounds are restored on leaving."""
    n, N = nlp.crane.n, nlp.N
    idle = np.asarray(idle, bool)
    if idle.shape != (N + 1, n):
        raise ValueError(f"idle: shape {idle.shape}; allowed: ({N + 1}, {n}) (nodes × joints)")
    lay = nlp.layout
    X0 = lay.slice("X").start
    k, i = np.nonzero(idle)
    rows = np.concatenate([X0 + 3 * n * k + n + i, X0 + 3 * n * k + 2 * n + i])
    lbw, ubw = nlp.lbw, nlp.ubw
    g = np.array(w0, float, copy=True)
    g[rows] = 0.0
    nlp.lbw, nlp.ubw = lbw.copy(), ubw.copy()
    nlp.lbw[rows] = 0.0
    nlp.ubw[rows] = 0.0
    try:
        yield g
    finally:
        nlp.lbw, nlp.ubw = lbw, ubw
