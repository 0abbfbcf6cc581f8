"""The pump-aware lower bound on the minimum time of a rest-to-rest move: the joints share the
pump's flow while each joint's flow can only ramp up (and down) under its acceleration and
jerk limits.

The analytic bounds of :mod:`planner.bounds` treat the pump as a volume budget (T ≥ V/Q_max)
and the joints' ramps separately (rest to rest); where the pump limits, the optimum is longer
than both because no joint can draw its share of Q_max from the first instant. This module
bounds that loss from below.

Relaxation (each step only enlarges the set of admissible motions, so the minimum time of the
relaxed problem is a lower bound of the true one):

1. Oil. Joint i's stroke x_i(q_i) changes by Δx_i; the pump must deliver at least
   V_i = A_i·|Δx_i| into it (A_i the piston area extending, the annulus retracting, nothing for a
   single-acting cylinder lowering: :func:`~planner.model.flows.swept_volume`). Only the flow f_i
   drawn while the stroke moves in the net direction counts towards V_i; the rest is dropped
   (it only takes pump capacity).
2. Caps. From rest at t = 0 with |q̈| ≤ a, |q⃛| ≤ j (q̈(0) = 0), the speed at time t is at most
   w(t) = min(v, ŵ(t)), ŵ the full-effort speed (j·t²/2, then a·t − a²/2j), and the joint lies
   within D(t) = ∫₀ᵗ w of its start. With κ(t) = min(κ_max, |x′(q_start)| + λ·D(t)) (λ a bound of
   |x″| on the joint's range, κ_max of |x′|) the net-direction flow obeys f_i(t) ≤ A_i·κ(t)·w(t).
   The same holds backwards from the goal. κ and D are nondecreasing, so
   ∫₀^τ f_i ≤ h_i(τ) := A_i·κ(τ)·D(τ) for every τ.
3. Sharing (a max-flow / min-cut condition). For any subset S of the joints, Σ_{i∈S} f_i ≤ Q
   (the pump) and every f_i is capped as above, so on [0, τ′] the pump delivers to S at most
   ∫₀^τ′ min(Q, Σ f_i) ≤ Q·τ′ − (Q·τ′ − Σ h_i(τ′)) — at least g_S(τ′) = Q·τ′ − Σ_{i∈S} h_i(τ′) of
   the pump's capacity is lost to the ramps at the start, for ANY τ′ (no grid resolution
   assumption: a coarse τ′ only gives a smaller loss), and likewise g′_S(τ″) before the end. For
   τ′ + τ″ ≤ T the two stretches are disjoint, so a move of duration T needs
   Q·T ≥ V_S + g_S(τ′) + g′_S(τ″). The bound of S is the least T that passes this test for every
   pair (τ′, τ″) of a nested family with τ′ + τ″ ≤ T (the family is a subset of all pairs:
   a weaker, still valid test); the bound of the move is the largest over S and the joints'
   own rest-to-rest times.
4. Ends. With the telescope free at a tip, the bound is minimised over both ends' telescope
   values: a grid with the edges of the reachable telescope intervals added (a least bound
   often lies on an edge, a joint at its position limit), then local grids halving their step
   around one seed per basin (and around given pairs). A pair's bound is never below its cheap
   value max(rest-to-rest, V/Q), so pairs whose cheap value is not below the best found are
   skipped. A grid search approaches the minimum from above: measured on 30 random umea-lab
   moves against a 241-point search with 24 seeds, at most 5e-5 relative (the valleys of the
   rest-to-rest bound, a max over joints, are narrow and diagonal; a zoom by 5 per level
   stalled in them, 8e-4), but up to 2.9e-4 against moves found elsewhere: the bound over
   free telescopes is lowered by :data:`SEARCH_SLACK` (5e-4).

Exact cases (tests/methods/test_ramps.py): one joint at a constant stroke slope, pump-limited,
gives T = V/Q + the ramp time to the pump-limited speed — the jerk-limited rest-to-rest time at
that speed. The NLP (:mod:`planner.methods.nlp`) plans with a smooth over-estimate of the draw,
with a margin below Q and without the transformer's credit, so its optimum is never below the
true one, which is never below this bound. A crane with an enabled hydraulic transformer (the
target's draw is credited by the source's motion, the joints' flows are not separable) gets no
ramp bound here (None): its callers fall back to the analytic bounds.

Cost: 61 × 61 telescope pairs (cheap values; the full test on the few below the best), then
8 refinements of 9 × 9 around ≤ 5 seeds, 2ⁿ − 1 joint subsets, a 16-step family, the ramp
terms per end configuration and stroke-direction pattern: ~10 ms per move on a quiet core
(benchmarks/results/optimality_gap.md).
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.bounds.profiles import from_rest_distance, rest_to_rest_time
from planner.model.flows import actuator_table

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["RampBound", "ramp_bound", "StrokeSlopes", "stroke_slopes"]

TAU_POINTS = 48     # τ′ grid (quadratic spacing: dense where the ramps start)
FAMILY = 16         # steps of the nested (τ′, τ″) family
# the search over free telescopes approaches the least bound from above (module docstring, 4.):
# the reported bound is lowered by this share. The exact Ruckig move of the NLP's guess, at
# telescopes from another search, came in up to 2.9e-4 below the unlowered bound on 200
# random moves (benchmarks/results/optimality_gap.md); fixed joint ends are not lowered
SEARCH_SLACK = 5e-4
LOCAL = 9           # points per end of a refinement's local grid (± 2 steps)
SHRINK = 2          # each refinement halves the step (a faster zoom stalls in narrow valleys)
SLOPE_GRID = 2001   # points of the stroke-slope table per joint


@dataclass(frozen=True)
class StrokeSlopes:
    """|dx/dq| over each joint's position range: ``kmax`` its largest value (the table's largest
    plus half a table step times ``lip``), ``lip`` a bound on |d²x/dq²| (the largest secant
    slope of dx/dq × 1.1), ``sign`` +1 / −1 where dx/dq keeps its sign over the range, else 0."""
    kmax: np.ndarray
    lip: np.ndarray
    sign: np.ndarray


_SLOPES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def stroke_slopes(crane: Crane) -> StrokeSlopes:
    """The :class:`StrokeSlopes` of a crane (one batched stroke call, kept per crane)."""
    hit = _SLOPES.get(crane)
    if hit is not None:
        return hit
    L = crane.limit_arrays()
    u = np.linspace(0.0, 1.0, SLOPE_GRID)[:, None]
    q = L["q_min"] + u * (L["q_max"] - L["q_min"])
    xp = np.asarray(crane.stroke(q)[1], float)
    dq = (L["q_max"] - L["q_min"]) / (SLOPE_GRID - 1)
    lip = 1.1 * np.max(np.abs(np.diff(xp, axis=0)), axis=0) / dq
    kmax = np.max(np.abs(xp), axis=0) + 0.5 * lip * dq
    sign = np.where(np.all(xp > 0, axis=0), 1, np.where(np.all(xp < 0, axis=0), -1, 0))
    out = StrokeSlopes(kmax=kmax, lip=lip, sign=sign)
    _SLOPES[crane] = out
    return out


@dataclass
class RampBound:
    """The ramp-limited flow-sharing bound of a move: ``bound_s`` [s] (already the larger of
    the pump test and the joints' own rest-to-rest times), the telescopes [m] where it is least
    (None for joint ends or a crane without a telescope) and what binds there (``binding``:
    "rest-to-rest" or the joints sharing the pump, e.g. "pump: boom+jib")."""
    bound_s: float
    tele_start: float | None
    tele_goal: float | None
    binding: str

    def as_dict(self):
        return dict(self.__dict__)


class _Setup:
    """Per call: the crane's limit arrays and areas by stroke direction, the τ′ grid, the
    distance profiles, the joint subsets and their direction combinations."""

    def __init__(self, crane: Crane, jerk: bool):
        self.crane = crane
        L = crane.limit_arrays()
        n = self.n = crane.n
        acts = actuator_table(crane.spec)
        sl = stroke_slopes(crane)
        self.Q = float(crane.spec.pump.max_flow)
        self.j = L["qddd_max"] if jerk else np.full(n, np.inf)
        self.a, self.L, self.slopes = L["qdd_max"], L, sl
        up, down = L["qd_max"], -L["qd_min"]
        fastest = np.maximum(up, down)
        # speed caps by stroke direction (0: extending, 1: retracting)
        self.v = np.stack([np.where(sl.sign > 0, up, np.where(sl.sign < 0, down, fastest)),
                           np.where(sl.sign > 0, down, np.where(sl.sign < 0, up, fastest))])
        self.A = np.stack([np.asarray(acts.area_a, float), np.asarray(acts.draw_b, float)])
        # τ′ up to the slowest joint's time to full speed, quadratic spacing
        t_full = np.max(self.v / self.a + np.where(np.isfinite(self.j), self.a / self.j, 0.0))
        self.tau = 1.5 * t_full * np.linspace(0.0, 1.0, TAU_POINTS) ** 2
        self.D = from_rest_distance(self.tau[:, None, None], self.v[None], self.a, self.j)
        self.Dsym = from_rest_distance(self.tau[:, None], fastest, self.a, self.j)
        self.S = ((np.arange(1, 2 ** n)[:, None] >> np.arange(n)) & 1).astype(bool)  # (nS, n)
        self._columns = {}

    def columns(self, code: int) -> np.ndarray:
        """(2n, nS): which (direction, joint) ramp terms each joint subset sums when the
        strokes move in the directions of ``code`` (bit i set: joint i retracts)."""
        C = self._columns.get(code)
        if C is None:
            n = self.n
            rows = ((code >> np.arange(n)) & 1) * n + np.arange(n)
            s, i = np.nonzero(self.S)
            C = np.zeros((2 * n, len(self.S)))
            C[rows[i], s] = 1.0
            self._columns[code] = C
        return C

    def ends(self, Qc):
        """:class:`_Ends` of the end configurations ``Qc`` (M, n) (NaN rows: unreachable)."""
        sl = self.slopes
        x, xp = self.crane.stroke(Qc)
        x, xp = np.atleast_2d(x), np.atleast_2d(xp)
        kappa = np.minimum(sl.kmax, np.abs(xp)[:, None, :] + sl.lip * self.Dsym)    # (M, G, n)
        h = (self.A[None] * kappa[:, :, None, :] * self.D).reshape(len(Qc), -1, 2 * self.n)
        return _Ends(self, Qc, x, h, {})

    def comb(self, Es, Eg, ip, ig):
        """Per pair (starts ``ip`` of ``Es``, goals ``ig`` of ``Eg``): the rest-to-rest bound,
        the swept volumes (P, n) and the direction bits of the strokes."""
        dq = Eg.q[ig] - Es.q[ip]
        v = np.where(dq >= 0, self.L["qd_max"], -self.L["qd_min"])
        with np.errstate(invalid="ignore"):
            r2r = np.max(rest_to_rest_time(dq, v, self.a, self.j), axis=-1)
        dx = Eg.x[ig] - Es.x[ip]
        V = np.where(dx > 0, self.A[0] * dx, -self.A[1] * dx)
        code = ((dx < 0) << np.arange(self.n)).sum(-1)
        r2r = np.where(np.isnan(r2r), np.inf, r2r)
        return r2r, V, code

    def pump(self, Es, Eg, ip, ig, V, code):
        """Per pair: the pump test's bound (the largest over the joint subsets) and the index
        of the subset that gives it."""
        VS = V @ self.S.T.astype(float)                                  # (P, nS)
        T = np.empty(VS.shape + (FAMILY + 1,))
        G = np.empty_like(T)
        for c in np.unique(code):   # the pairs whose strokes move the same ways
            m = code == c
            (gs, ts), (gg, tg) = Es.family(int(c)), Eg.family(int(c))
            T[m] = ts[ip[m]] + tg[ig[m]]
            G[m] = gs[ip[m]] + gg[ig[m]]
        H = np.maximum.accumulate(G, axis=-1)
        cand = np.maximum(T, (VS[..., None] + H) / self.Q)
        ok = np.ones(cand.shape, bool)
        ok[..., :-1] = cand[..., :-1] < T[..., 1:]    # the candidate lies in its own stretch
        with np.errstate(invalid="ignore"):
            per_subset = np.min(np.where(ok, cand, np.inf), axis=-1)
        per_subset = np.where(np.isnan(per_subset), np.inf, per_subset)
        return per_subset.max(axis=-1), per_subset.argmax(axis=-1)


@dataclass(frozen=True)
class _Ends:
    """End configurations ``q`` (M, n), their strokes ``x`` and ramp terms ``h`` [m³]
    (M, G, 2n): A·κ(τ′)·D(τ′) per τ′ of the grid, stroke direction and joint. ``family(code)``:
    per joint subset the ramp losses g (M, nS, FAMILY + 1) at the family's τ′ (same shape),
    for the stroke directions of ``code`` (kept in ``cache``)."""
    setup: _Setup
    q: np.ndarray
    x: np.ndarray
    h: np.ndarray
    cache: dict

    def family(self, code: int):
        hit = self.cache.get(code)
        if hit is None:
            st = self.setup
            g = np.swapaxes(st.Q * st.tau[:, None] - self.h @ st.columns(code), 1, 2)
            best = np.argmax(np.where(np.isnan(g), -np.inf, g), axis=-1)         # (M, nS)
            idx = (np.arange(FAMILY + 1) * best[..., None]) // FAMILY            # nested
            hit = self.cache[code] = (np.take_along_axis(g, idx, axis=-1), st.tau[idx])
        return hit


class _Search:
    """The least bound over pairs of end configurations, evaluated lazily: a pair's bound is
    never below max(rest-to-rest, V/Q) (the subset of all joints, family step 0), so pairs are
    taken in the order of that cheap value and those not below the best bound found are
    skipped."""

    def __init__(self, st: _Setup):
        self.st, self.best, self.arg = st, np.inf, (np.nan, np.nan, -1)

    def run(self, Es, Eg, ip, ig, ts, tg, first: int = 16):
        """(bounds of the pairs (``ip``, ``ig``) whose cheap value is below the best so far,
        +inf for the others; the cheap values); ``ts``/``tg`` their telescope values. Updates
        the best."""
        st = self.st
        r2r, V, code = st.comb(Es, Eg, ip, ig)
        cheap = np.maximum(r2r, V.sum(-1) / st.Q)
        cheap[np.isnan(cheap)] = np.inf      # an unreachable end
        out = np.full(len(ip), np.inf)
        order = np.argsort(cheap)
        for chunk in (order[:first], order[first:]):
            chunk = chunk[cheap[chunk] < self.best]
            if not len(chunk):
                continue
            pump, which = st.pump(Es, Eg, ip[chunk], ig[chunk], V[chunk], code[chunk])
            val = np.maximum(r2r[chunk], pump)
            out[chunk] = val
            k = int(np.argmin(val))
            if val[k] < self.best:
                self.best = float(val[k])
                self.arg = (ts[chunk[k]], tg[chunk[k]],
                            int(which[k]) if pump[k] > r2r[chunk[k]] else -1)
        return out, cheap


def _seeds(W, starts: int):
    """Flat indices of the ``starts`` smallest local minima of the grid ``W`` (a value no
    larger than its eight neighbours): one seed per basin, best first."""
    P = np.pad(W, 1, constant_values=np.inf)
    rows, cols = W.shape
    low = np.ones(W.shape, bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                low &= W <= P[1 + di:1 + di + rows, 1 + dj:1 + dj + cols]
    flat = np.flatnonzero(low & np.isfinite(W))
    return flat[np.argsort(W.ravel()[flat])][:starts]


def _ends(crane: Crane, tip, q, tele):
    """End configurations (M, n) (NaN rows where unreachable) for the tip ``tip`` at telescope
    values ``tele`` (M,), or the fixed joints ``q`` (1, n)."""
    if q is not None:
        q = np.asarray(q, float)
        if q.shape != (crane.n,):
            raise ValueError(f"a joint configuration needs {crane.n} values, got {q.tolist()}")
        return q[None, :].copy()
    qq, reason = crane.ik_batch(np.tile(np.asarray(tip, float), (len(tele), 1)), tele,
                                explain=False)
    qq = np.array(qq, float)
    qq[reason != ""] = np.nan
    return qq


class _Reach:
    """The reachable telescope values of a tip: intervals [``lo``, ``hi``] (edges located by two
    rounds of 64 points inside each grid cell where reachability changes) and ``grid``, the
    reachable grid points and the edges."""

    def __init__(self, crane: Crane, tip, grid):
        ok = ~np.isnan(_ends(crane, tip, None, grid)).any(axis=1)
        lo, hi = [], []
        for i in np.flatnonzero(ok[:-1] != ok[1:]):
            a, b = grid[i], grid[i + 1]            # a reachable side and an unreachable side
            if not ok[i]:
                a, b = b, a
            for _ in range(2):
                t = np.linspace(a, b, 65)
                good = ~np.isnan(_ends(crane, tip, None, t)).any(axis=1)
                k = int(np.argmin(good)) if not good.all() else 64   # first unreachable
                a, b = t[max(k - 1, 0)], t[min(k, 64)]
            (hi if ok[i] else lo).append(a)
        starts = [grid[0]] if ok[0] else []
        ends = hi + ([grid[-1]] if ok[-1] else [])
        self.lo, self.hi = np.sort(np.array(starts + lo)), np.sort(np.array(ends))
        self.grid = np.unique(np.concatenate([grid[ok], self.lo, self.hi]))

    def snap(self, t):
        """``t`` moved into the nearest reachable interval (unchanged inside one)."""
        d = np.maximum(np.maximum(self.lo - t[..., None], 0.0), t[..., None] - self.hi)
        k = np.argmin(d, axis=-1)
        return np.clip(t, self.lo[k], self.hi[k])


def ramp_bound(crane: Crane, start=None, goal=None, *, q_start=None, q_goal=None,
               jerk: bool = True, n_grid: int = 61, refine: int = 8, starts: int = 4,
               extra=()) -> RampBound | None:
    """The ramp-limited flow-sharing lower bound (module docstring) of the move between tips
    ``start``/``goal`` (r, z, slew) or joint configurations ``q_start``/``q_goal``, minimised
    over free telescopes (``n_grid`` points per end, then ``refine`` local searches (step halved)
    around the ``starts`` best local minima of the grid and the telescope pairs ``extra``, e.g.
    where the analytic bound is least). ``jerk=False``: without the jerk limits (for methods that
    do not plan with them). None when a hydraulic transformer couples two joints' flows, when
    the pump has no finite limit or when no pair of end configurations is reachable (the
    analytic bounds report those)."""
    if (start is None) == (q_start is None) or (goal is None) == (q_goal is None):
        raise ValueError("give each end either as a tip (start/goal) or as joints (q_start/q_goal)")
    if actuator_table(crane.spec).transformer:
        return None
    st = _Setup(crane, jerk)
    if not np.isfinite(st.Q) or st.Q <= 0:
        return None
    tr = crane.tele_range
    search = _Search(st)

    def level(gs, gg):   # gs (b, Gs), gg (b, Gg): the pairs within each row b
        b = gs.shape[0]
        Es = st.ends(_ends(crane, start, q_start, gs.ravel()))
        Eg = st.ends(_ends(crane, goal, q_goal, gg.ravel()))
        ns, ng = len(Es.q) // b, len(Eg.q) // b
        ip = (np.arange(b)[:, None, None] * ns + np.arange(ns)[None, :, None]
              + np.zeros((1, 1, ng), int)).ravel()
        ig = (np.arange(b)[:, None, None] * ng + np.arange(ng)[None, None, :]
              + np.zeros((1, ns, 1), int)).ravel()
        tvals_s = gs.reshape(b, -1)[:, :ns] if ns > 1 else np.full((b, 1), np.nan)
        tvals_g = gg.reshape(b, -1)[:, :ng] if ng > 1 else np.full((b, 1), np.nan)
        ts = np.broadcast_to(tvals_s[:, :, None], (b, ns, ng)).ravel()
        tg = np.broadcast_to(tvals_g[:, None, :], (b, ns, ng)).ravel()
        val, cheap = search.run(Es, Eg, ip, ig, ts, tg)
        return val.reshape(b, ns, ng), cheap.reshape(b, ns, ng), tvals_s, tvals_g
    if tr is None:
        level(np.zeros((1, 1)), np.zeros((1, 1)))
    else:
        grid = np.linspace(*tr, n_grid)
        # the reachable telescope intervals of each free end, their edges found to ~1e-5 m
        # (a least bound often lies on an edge: a joint at its position limit), kept in the
        # grids and the refinements' local grids
        reach = [None if q is not None else _Reach(crane, tip, grid)
                 for tip, q in ((start, q_start), (goal, q_goal))]
        if any(r is not None and not len(r.lo) for r in reach):
            return None
        T, cheap, vs, vg = level(*(grid[None] if r is None else r.grid[None] for r in reach))
        step = (tr[1] - tr[0]) / (n_grid - 1)
        # one seed per basin of the grid (the pruned pairs at their cheap value, a bound of
        # theirs), and the pairs given
        seeds = _seeds(np.where(np.isfinite(T[0]), T[0], cheap[0]), starts)
        centres = np.array([(vs[0, i], vg[0, k]) for i, k in
                            (np.unravel_index(f, T.shape[1:]) for f in seeds)]
                           + [tuple(p) for p in extra]).reshape(-1, 2)
        for _ in range(refine if len(centres) else 0):
            gs, gg = (np.linspace(c - 2 * step, c + 2 * step, LOCAL, axis=1) if r is None
                      else r.snap(np.linspace(c - 2 * step, c + 2 * step, LOCAL, axis=1))
                      for c, r in zip(centres.T, reach))   # a fixed end ignores its grid
            T, cheap, vs, vg = level(gs, gg)
            W = np.where(np.isfinite(T), T, cheap)   # pruned pairs: at their cheap value
            for s in range(len(centres)):
                if np.isfinite(W[s]).any():
                    a, b = np.unravel_index(np.argmin(W[s]), W.shape[1:])
                    centres[s] = (vs[s, a], vg[s, b])
            step /= SHRINK
    if not np.isfinite(search.best):
        return None
    ts, tg, w = search.arg
    binding = "rest-to-rest" if w < 0 else "pump: " + "+".join(
        crane.names[i] for i in np.flatnonzero(st.S[w]))
    free = tr is not None
    return RampBound(bound_s=search.best * (1 - SEARCH_SLACK) if free and (
                         q_start is None or q_goal is None) else search.best,
                     tele_start=float(ts) if free and q_start is None else None,
                     tele_goal=float(tg) if free and q_goal is None else None, binding=binding)
