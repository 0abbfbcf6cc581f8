"""Analytic minimum-time (and minimum-energy) lower bounds for a point-to-point move.

For fixed end configurations (q_s, q_g), with Δq = q_g − q_s:
* velocity:      T ≥ max_i |Δq_i| / v_i            (v_i: the limit in the direction of motion)
* rest to rest:  T ≥ max_i T_i(|Δq_i|, v_i, a_i, j_i), the time-optimal 1-DOF profile with
                 velocity, acceleration (and jerk) limits (equals Ruckig's independent minimum)
* pump:          T ≥ V / Q_max, V = Σ swept oil volumes (piston area extending, annulus
                 retracting, nothing for single-acting lowering; transformer flow credited:
                 :func:`planner.model.flows.swept_volume`)
* energy:        E ≥ (ΔE_potential)⁺ / η            (load sensing, no recovery)
For a redundant crane the ends are tip positions with the telescope free; every bound is
minimised over the telescope at both ends (grid, then zoomed refinements around several
starting pairs per bound). A grid search approaches the exact minimum from above: with the
defaults (121 points, 3 refinements to 1e-4 m of telescope) the reported values exceed it by at
most ~1e-5 relative (measured against an NLP landing exactly on the velocity bound); compare
with a 1e-4 relative tolerance.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.bounds.profiles import rest_to_rest_time
from planner.bounds.ramps import ramp_bound
from planner.model import Crane, UnreachableError
from planner.model.flows import swept_volume


@dataclass
class LowerBound:
    """Lower bounds [s] (and [J]) for a move, each minimised over the redundancy at both ends.

    ``combined_s`` = min over end configurations of max(rest-to-rest, pump) — tighter than the
    max of the separate minima. ``ramps_s`` (with ``ramps=True``): the pump-aware bound of
    :mod:`planner.bounds.ramps` (flow sharing under the ramp limits; never below max(rest-to-
    rest, pump) of any end pair), ``ramps_binding`` what binds there; None when not computed
    or not applicable (an enabled hydraulic transformer). ``tele_start`` / ``tele_goal`` are the telescope values [m] at
    which ``combined_s`` is attained (None when the ends were joint configurations)."""
    velocity_s: float
    rest_to_rest_s: float
    pump_s: float
    combined_s: float
    energy_J: float
    tele_start: float | None
    tele_goal: float | None
    ramps_s: float | None = None
    ramps_binding: str | None = None

    @property
    def certified_s(self) -> float:
        """The tightest time bound with acceleration limits: the ramp bound when it was
        computed (``ramps=True``), else the combined one."""
        return self.combined_s if self.ramps_s is None else self.ramps_s

    def as_dict(self):
        return dict(self.__dict__)


def _end_configs(crane: Crane, tip, q, tele):
    """Candidate configurations for one end: the joint vector ``q`` if given (fixed), else the
    IK of ``tip`` (r, z, slew) for each telescope value in ``tele`` (unreachable ones dropped)."""
    return _ends_configs(crane, ((tip, q),), tele)[0]


def _ends_configs(crane: Crane, ends, tele):
    """:func:`_end_configs` of several ends ``ends`` ((tip, q) pairs) on one telescope grid:
    the tips' IK in one call (it is elementwise, so the same numbers as one call per end);
    the reasons are spelled out only for an end with no reachable point, to raise with."""
    tele = np.asarray(tele, float)
    out, tips = [None] * len(ends), []
    for k, (tip, q) in enumerate(ends):
        if q is not None:
            q = np.asarray(q, float)
            if q.shape != (crane.n,):
                raise ValueError(f"a joint configuration needs {crane.n} values, got "
                                 f"{q.tolist()}")
            out[k] = (q[None, :], np.array([np.nan]))
            continue
        tip = np.asarray(tip, float)
        if tip.shape != (3,):
            raise ValueError(f"a tip is (r, z, slew), got {tip.tolist()}")
        tips.append((k, tip))
    if tips:
        G = len(tele)
        qq, reason = crane.ik_batch(np.repeat([t for _, t in tips], G, axis=0),
                                    np.tile(tele, len(tips)), explain=False)
        for m, (k, tip) in enumerate(tips):
            ok = reason[m * G:(m + 1) * G] == ""
            if not ok.any():
                _, why = crane.ik_batch(np.tile(tip, (G, 1)), tele)   # explained
                raise UnreachableError(
                    f"{crane.spec.id}: tip (r={tip[0]:.3f} m, z={tip[1]:.3f} m, "
                    f"slew={tip[2]:.3f} rad) is unreachable for every telescope value: "
                    f"{why[len(why) // 2]}")
            out[k] = (qq[m * G:(m + 1) * G][ok], tele[ok])
    return out


def _limits(crane: Crane, jerk: bool) -> dict:
    """The crane's limit arrays; without jerk limits (qddd_max = inf) when ``jerk`` is False."""
    L = dict(crane.limit_arrays())
    if not jerk:
        L["qddd_max"] = np.full(crane.n, np.inf)
    return L


def _pair_bounds(crane: Crane, qs, qg, jerk: bool = True):
    """Bounds for all pairs: arrays (Ns, Ng) of velocity, r2r, pump times and energy."""
    L = _limits(crane, jerk)
    spec = crane.spec
    dq = qg[None, :, :] - qs[:, None, :]
    v = np.where(dq >= 0, L["qd_max"], -L["qd_min"])
    T_vel = np.max(np.abs(dq) / v, axis=-1)
    T_r2r = np.max(rest_to_rest_time(dq, v, L["qdd_max"], L["qddd_max"]), axis=-1)
    xs, _ = crane.stroke(qs)
    xg, _ = crane.stroke(qg)
    V = swept_volume(spec, xg[None, :, :] - xs[:, None, :])
    T_pump = V.sum(axis=-1) / spec.pump.max_flow
    es = crane.potential_energy(qs)
    eg = crane.potential_energy(qg)
    E = np.maximum(eg[None, :] - es[:, None], 0) / spec.pump.efficiency
    return T_vel, T_r2r, T_pump, E


def _end_grids(crane: Crane, tip, q, grids):
    """Candidate configurations for one end at every telescope value of ``grids`` (S, G), all
    S grids in one IK call: joints (S, G, n), telescope values (S, G) and the reachable mask;
    a fixed end (``q`` given) is the one configuration (S, 1, n). Raises like
    :func:`_end_configs` when a grid has no reachable point."""
    return _ends_grids(crane, ((tip, q, grids),))[0]


def _ends_grids(crane: Crane, ends):
    """:func:`_end_grids` of several ends ((tip, q, grids) triples), the tips' IK in one call
    (elementwise: the same numbers as one call per end)."""
    out, asks = [None] * len(ends), []
    for k, (tip, q, grids) in enumerate(ends):
        S = grids.shape[0]
        if q is not None:
            q = np.asarray(q, float)
            out[k] = (np.broadcast_to(q, (S, 1, crane.n)), np.full((S, 1), np.nan),
                      np.ones((S, 1), bool))
        else:
            asks.append((k, np.asarray(tip, float), grids))
    if asks:
        qq, reason = crane.ik_batch(
            np.concatenate([np.tile(tip, (g.size, 1)) for _, tip, g in asks]),
            np.concatenate([g.ravel() for _, _, g in asks]), explain=False)
        off = 0
        for k, tip, grids in asks:
            S, G = grids.shape
            ok = (reason[off:off + S * G] == "").reshape(S, G)
            for s in np.flatnonzero(~ok.any(axis=1)):
                _end_configs(crane, tip, None, grids[s])  # raises with the explained reason
            out[k] = (qq[off:off + S * G].reshape(S, G, crane.n), grids, ok)
            off += S * G
    return out


def _pair_bounds_batch(crane: Crane, A, B, jerk: bool = True, timing_only: bool = False):
    """:func:`_pair_bounds` for S grid pairs at once: ends ``A`` = (joints (S, Gs, n),
    telescopes, mask) from :func:`_end_grids` and ``B`` likewise; returns (S, Gs, Gg) arrays,
    +inf where an end is unreachable. ``timing_only``: the rest-to-rest and pump times only
    (velocity and energy None: what the combined bound needs)."""
    (qs, _, oks), (qg, _, okg) = A, B
    L = _limits(crane, jerk)
    spec = crane.spec

    def per_config(Q, ok):  # strokes and potential energy of the reachable configurations
        x = np.full(Q.shape[:2] + (crane.n,), np.nan)
        e = np.full(Q.shape[:2], np.nan)
        x[ok] = crane.stroke(Q[ok])[0]
        if not timing_only:
            e[ok] = crane.potential_energy(Q[ok])
        return x, e
    xs, es = per_config(qs, oks)
    xg, eg = per_config(qg, okg)
    dq = qg[:, None, :, :] - qs[:, :, None, :]
    v = np.where(dq >= 0, L["qd_max"], -L["qd_min"])
    T_vel = E = None
    with np.errstate(invalid="ignore"):
        if not timing_only:
            T_vel = np.max(np.abs(dq) / v, axis=-1)
            E = np.maximum(eg[:, None, :] - es[:, :, None], 0) / spec.pump.efficiency
        T_r2r = np.max(rest_to_rest_time(dq, v, L["qdd_max"], L["qddd_max"]), axis=-1)
        V = swept_volume(spec, xg[:, None, :, :] - xs[:, :, None, :])
        T_pump = V.sum(axis=-1) / spec.pump.max_flow
    bad = ~(oks[:, :, None] & okg[:, None, :])
    return tuple(None if m is None else np.where(bad, np.inf, m)
                 for m in (T_vel, T_r2r, T_pump, E))


def lower_bound(crane: Crane, start=None, goal=None, *, q_start=None, q_goal=None,
                n_grid: int = 121, refine: int = 3, starts: int = 8,
                jerk: bool = True, combined_only: bool = False,
                ramps: bool = False) -> LowerBound:
    """Lower bounds for a move between tips ``start``/``goal`` (r, z, slew) — or fixed joint
    configurations ``q_start``/``q_goal``.

    Free telescope values are searched on an ``n_grid`` grid at each free end; the best grid
    pairs of every bound (they are not convex in the telescope values: several basins) are then
    refined ``refine`` times on 5× finer local grids; the smallest values found are returned.
    The refinements of all starting pairs run together (one IK call per end and level).
    ``jerk=False`` leaves the spec's jerk limits out of the rest-to-rest (and combined) bound:
    the bound of a method that does not plan with jerk limits (TOPP-RA, the DP, the laws),
    which may legitimately be faster than the jerk-limited bound. ``combined_only`` refines
    only the combined bound (and its telescopes; the other fields keep their ``n_grid``
    values, which a refinement could only lower): what a guess taken at the bound needs.
    ``ramps`` adds the pump-aware bound (:func:`planner.bounds.ramps.ramp_bound`, seeded also
    at the combined bound's telescopes): the certificate of a minimum-time plan."""
    if (start is None) == (q_start is None) or (goal is None) == (q_goal is None):
        raise ValueError("give each end either as a tip (start/goal) or as joints (q_start/q_goal)")
    tr = crane.tele_range
    grid = np.linspace(*tr, n_grid) if tr else np.zeros(1)
    (qs, ts), (qg, tg) = _ends_configs(crane, ((start, q_start), (goal, q_goal)), grid)
    Tv, Tr, Tp, E = _pair_bounds(crane, qs, qg, jerk)
    comb = np.maximum(Tr, Tp)
    best = dict(vel=Tv.min(), r2r=Tr.min(), pump=Tp.min(), comb=comb.min(), E=E.min())
    i, k = np.unravel_index(np.argmin(comb), comb.shape)
    arg = (ts[i], tg[k])
    if tr:
        # every reported bound is minimised on its own: refine around the best grid pairs of
        # each (the combined one gets ``starts`` of them, the others 3)
        step = (tr[1] - tr[0]) / (n_grid - 1)
        metrics = dict(comb=comb) if combined_only else dict(comb=comb, vel=Tv, r2r=Tr,
                                                             pump=Tp, E=E)
        seeds = [(key, flat) for key, m in metrics.items()
                 for flat in np.argsort(m, axis=None)[:starts if key == "comb" else 3]]
        keys = [key for key, _ in seeds]
        centres = np.array([(ts[i], tg[k]) for i, k in
                            (np.unravel_index(flat, comb.shape) for _, flat in seeds)])
        levels = []   # per level: (telescope grids, comb (S, Gs, Gg)) for the arg update
        for _ in range(refine):
            grids = [np.clip(np.linspace(c - 2 * step, c + 2 * step, 21, axis=1), *tr)
                     for c in centres.T]   # a fixed end (NaN centre) ignores its grid
            A, B = _ends_grids(crane, ((start, q_start, grids[0]), (goal, q_goal, grids[1])))
            Tv2, Tr2, Tp2, E2 = _pair_bounds_batch(crane, A, B, jerk, combined_only)
            comb2 = np.maximum(Tr2, Tp2)
            m2 = dict(comb=comb2, vel=Tv2, r2r=Tr2, pump=Tp2, E=E2)
            for s, key in enumerate(keys):   # each start moves to its own metric's minimum
                a, b = np.unravel_index(np.argmin(m2[key][s]), comb2.shape[1:])
                centres[s] = (A[1][s, a], B[1][s, b])
            levels.append((A[1], B[1], comb2))
            best["comb"] = min(best["comb"], comb2.min())
            if not combined_only:   # (combined only: the rest keep their grid values)
                best.update(vel=min(best["vel"], Tv2.min()), r2r=min(best["r2r"], Tr2.min()),
                            pump=min(best["pump"], Tp2.min()), E=min(best["E"], E2.min()))
            step /= 5
        # the telescopes of the smallest combined bound, in the order the starts were
        # refined one after another (start-major: the first strict improvement wins ties)
        run = float(comb.min())
        for s in range(len(seeds)):
            for ga, gb, c2 in levels:
                ac, bc = np.unravel_index(np.argmin(c2[s]), c2.shape[1:])
                if c2[s, ac, bc] < run:
                    arg, run = (ga[s, ac], gb[s, bc]), float(c2[s, ac, bc])

    def none_if_nan(v):
        return None if (not tr or np.isnan(v)) else float(v)
    out = LowerBound(velocity_s=float(best["vel"]), rest_to_rest_s=float(best["r2r"]),
                     pump_s=float(best["pump"]), combined_s=float(best["comb"]),
                     energy_J=float(best["E"]), tele_start=none_if_nan(arg[0]),
                     tele_goal=none_if_nan(arg[1]))
    if ramps:
        seed = [(np.nan if out.tele_start is None else out.tele_start,
                 np.nan if out.tele_goal is None else out.tele_goal)] if tr else []
        rb = ramp_bound(crane, start, goal, q_start=q_start, q_goal=q_goal, jerk=jerk,
                        extra=seed)
        if rb is not None:
            out.ramps_s, out.ramps_binding = rb.bound_s, rb.binding
    return out
