"""Fit the Cranab 850 link lengths d0, d1, d2 (lost with a figure of seed 000) to the three DP
times of Table 8.1 (A–B 1.15 s, B–C 0.89 s, A–C 1.18 s).

Method: the seed's DP (Δr = Δz = 0.01 m, Δd3 = 0.01 m, q = 5, kinematic: joint speed limits
only) run on the spec with (d0, d1, d2) replaced; minimise the sum of squared relative time
errors, first on a coarse grid of the DP (Δ = 0.02 m, q = 3 — cheap), then Nelder–Mead at the
seed's grid from the best coarse points. Conventions fixed before fitting: z measured from the
slew base (d0 = height of the boom foot), elbow-up branch (sin θ2 ≥ 0, seed eq. 7.1–7.6).

Optional constraint (--require-retracted-ab): on A–B the distance ρ from the maximum-lifting-
capacity circle centre (3.5, 0.65) stays below ρ_min = 3.5 m, so that law would drive A–B with
the telescope retracted (d3 = 0): every point of A–B reachable with d3 = 0. Measured: with it
the best DP-time fit has an RMS error of ≈ 18 % (loss 0.093), without it ≈ 3 % — the seed's
max-lift parameters and its DP times are not consistent under this model, so the default fit
uses the DP times alone and reports whether the constraint holds.

    python tools/fit_cranab850.py [--out benchmarks/results]
"""
from __future__ import annotations

import argparse
import copy
import itertools
import json
import time
import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from planner.methods.dp import dp
from planner.model import Crane
from planner.geometry.paths import Line
from planner.model.spec import parse_spec
from planner.problems import crane_path

POINTS = dict(A=(1.5, 1.0, 0.0), B=(5.5, 1.0, 0.0), C=(5.5, -3.0, 0.0))
MOVES = (("A", "B"), ("B", "C"), ("A", "C"))
TABLE_8_1 = np.array([1.15, 0.89, 1.18])  # seed 000, DP row


def crane_with(d0, d1, d2, base=None):
    data = copy.deepcopy(base or tomllib.loads(crane_path("cranab850").read_text()))
    data["joint"][0]["dh"]["d"] = float(d0)
    data["joint"][1]["dh"]["a"] = float(d1)
    data["joint"][3]["dh"]["d"] = float(d2)
    return Crane(parse_spec(data, f"cranab850(d0={d0:.4f}, d1={d1:.4f}, d2={d2:.4f})"))


def seed_stages(a, b, delta):
    pa, pb = POINTS[a], POINTS[b]
    return int(round(max(abs(pb[0] - pa[0]), abs(pb[1] - pa[1])) / delta))


def dp_times(crane, delta=0.01, window=5):
    out = []
    for a, b in MOVES:
        r = dp(crane, Line(POINTS[a], POINTS[b]), stages=seed_stages(a, b, delta),
               tele_step=delta, window=window, pump=False)
        out.append(r.duration_s if r.ok else np.inf)
    return np.array(out)


def retracted_ab_ok(crane):
    """Seed consistency: the whole line A–B reachable with the telescope retracted."""
    pts = Line(POINTS["A"], POINTS["B"]).tip(np.linspace(0, 4.0, 81))
    _, reason = crane.ik_batch(pts, 0.0, explain=False)
    return bool(np.all(reason == ""))


def loss(times):
    e = (times - TABLE_8_1) / TABLE_8_1
    return float(np.sum(e * e)) if np.all(np.isfinite(e)) else 1e6


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--require-retracted-ab", action="store_true")
    args = ap.parse_args()
    need = args.require_retracted_ab
    t0 = time.perf_counter()
    base = tomllib.loads(crane_path("cranab850").read_text())
    coarse = []
    rejected = 0
    for d0, d1, d2 in itertools.product(np.arange(0.0, 1.21, 0.2), np.arange(3.6, 6.01, 0.2),
                                        np.arange(1.6, 4.01, 0.2)):
        try:
            c = crane_with(d0, d1, d2, base)
        except ValueError:
            continue
        if need and not retracted_ab_ok(c):
            rejected += 1
            continue
        coarse.append((loss(dp_times(c, delta=0.02, window=3)), d0, d1, d2))
    coarse.sort()
    print(f"coarse grid: {len(coarse)} geometries kept, {rejected} rejected (A–B not reachable "
          f"retracted); best {[tuple(np.round(c, 4)) for c in coarse[:3]]}")
    best = None
    for _, *x0 in coarse[:3]:
        def objective(x):
            c = crane_with(*x, base)
            return loss(dp_times(c)) if (not need or retracted_ab_ok(c)) else 1e6
        res = minimize(objective, x0, method="Nelder-Mead",
                       options=dict(xatol=2e-3, fatol=1e-6, maxiter=120, initial_simplex=[
                           x0, [x0[0] + 0.05, x0[1], x0[2]], [x0[0], x0[1] + 0.1, x0[2]],
                           [x0[0], x0[1], x0[2] + 0.1]]))
        print(f"  from {np.round(x0, 3)}: {np.round(res.x, 4)} loss {res.fun:.3e}")
        if best is None or res.fun < best.fun:
            best = res
    d0, d1, d2 = (round(float(v), 3) for v in best.x)
    times = dp_times(crane_with(d0, d1, d2, base))
    rel = (times - TABLE_8_1) / TABLE_8_1
    report = dict(d0=d0, d1=d1, d2=d2, dp_times_s=times.round(4).tolist(),
                  table_8_1_s=TABLE_8_1.tolist(), relative_error=rel.round(4).tolist(),
                  rms_relative_error=float(np.sqrt(np.mean(rel ** 2))),
                  method="coarse grid (Δ=0.02, q=3) over d0∈[0,1.2], d1∈[3.6,6.0], "
                         "d2∈[1.6,4.0] (0.2 m steps), then Nelder–Mead at the seed grid "
                         "(Δ=0.01, q=5) from the three best",
                  conventions="z from the slew base (d0 = boom-foot height); elbow up",
                  retracted_ab_constraint=need,
                  retracted_ab_reachable=retracted_ab_ok(crane_with(d0, d1, d2, base)),
                  seconds=round(time.perf_counter() - t0, 1))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cranab850_fit.json").write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
