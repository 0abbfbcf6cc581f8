"""Plans that start, pass or end on a joint limit, replayed on the Exudyn plant (issue 26,
defect 1): does the judge run every legitimate plan?

Per machine: Ruckig rest-to-rest moves between configurations with a random subset of joints
exactly on a limit (start, goal, and a two-leg move that passes a limit at rest), and NLP
minimum-time tip moves (random start/goal tips; kept when the plan's start or goal has a joint
within 1e-6 of a limit), each replayed open loop from its 50 Hz feed-forward with 0.5 s to
settle. Counts runs that finish (status ok) and the failures with their reasons.

    python benchmarks/bench_exudyn_limits.py [--moves 8] [--nlp 12] [--out benchmarks/results]

Runs on any checkout of the project (it uses ``integrate`` or, on older code, ``run``), so the
same script measured the code before the fix.
"""
from __future__ import annotations

import argparse
import datetime
import platform
import sys
import time
from pathlib import Path

import numpy as np

from planner.feedforward import commands
from planner.methods import PlanRequest, plan
from planner.methods.ruckig import rest_to_rest
from planner.model import Crane

MACHINES = ("cat215b", "cranab850", "s100f", "umea-lab")


def on_limit(crane, q, tol=1e-6):
    L = crane.limit_arrays()
    return [crane.names[i] for i in range(crane.n)
            if min(abs(q[i] - L["q_min"][i]), abs(q[i] - L["q_max"][i])) < tol]


def limit_pose(crane, rng):
    L = crane.limit_arrays()
    q = rng.uniform(L["q_min"] + 0.1 * (L["q_max"] - L["q_min"]),
                    L["q_max"] - 0.1 * (L["q_max"] - L["q_min"]))
    k = rng.integers(1, crane.n + 1)
    for i in rng.choice(crane.n, size=k, replace=False):
        q[i] = L["q_max"][i] if rng.uniform() < 0.5 else L["q_min"][i]
    return q


def replay(crane, trajs):
    """Commands of the trajectories back to back (each from rest) and their start."""
    from planner.simulation.dynamic.exudyn_plant import ExudynPlant
    ts, us, t0 = [], [], 0.0
    for tr in trajs:
        ff = commands(crane, tr, 50.0)
        ts.append(t0 + ff.t - ff.t[0])
        us.append(ff.u)
        t0 = ts[-1][-1] + 0.02
    t_u = np.append(np.concatenate(ts), t0)
    u = np.vstack(us + [np.zeros((1, crane.n))])
    p = ExudynPlant(crane)
    go = getattr(p, "integrate", None) or p.run
    w = time.perf_counter()
    run = go(t_u, u, trajs[0].q[0], t_end=t_u[-1] + 0.5, max_wall_s=600.0)
    return run, time.perf_counter() - w


def cases(crane, rng, moves, nlp):
    out = []
    for k in range(moves):
        qa, qb, qc = limit_pose(crane, rng), limit_pose(crane, rng), limit_pose(crane, rng)
        r1, r2 = rest_to_rest(crane, qa, qb), rest_to_rest(crane, qb, qc)
        if r1.ok and r2.ok:
            out.append((f"ruckig-{k}", [r1.trajectory, r2.trajectory],
                        sorted(set(on_limit(crane, qa) + on_limit(crane, qb)
                                   + on_limit(crane, qc)))))
    L = crane.limit_arrays()
    tried = 0
    while tried < nlp:
        tried += 1
        q0, q1 = (rng.uniform(L["q_min"], L["q_max"]) for _ in range(2))
        tips = []
        for q in (q0, q1):
            x, y, z = np.asarray(crane.fk(q)).ravel()[:3]
            tips.append((float(np.hypot(x, y)), float(z), float(np.arctan2(y, x))))
        try:
            res = plan(crane, PlanRequest(*tips), method="nlp")
        except ValueError:
            continue
        if not res.ok:
            continue
        tr = res.trajectory
        hit = sorted(set(on_limit(crane, tr.q[0]) + on_limit(crane, tr.q[-1])))
        if hit:
            out.append((f"nlp-{tried}", [tr], hit))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=8)
    ap.add_argument("--nlp", type=int, default=12)
    ap.add_argument("--seed", type=int, default=26)
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--name", default="exudyn_limits.md")
    a = ap.parse_args(argv)
    rows, fails = [], []
    for mid in MACHINES:
        crane = Crane.from_id(mid)
        rng = np.random.default_rng(a.seed)
        cs = cases(crane, rng, a.moves, a.nlp)
        ok = 0
        wall = 0.0
        for name, trajs, hit in cs:
            run, w = replay(crane, trajs)
            wall += w
            ok += run.ok
            if not run.ok:
                fails.append(f"| {mid} | {name} | {', '.join(hit)} | {run.status} at "
                             f"{run.t_fail:.3f} s: {run.reason} |")
            print(mid, name, hit, run.status, f"{w:.1f}s", flush=True)
        rows.append(f"| {mid} | {len(cs)} | {ok} | {len(cs) - ok} | {wall:.0f} |")
    text = "\n".join([
        "# Plans on joint limits, replayed on the Exudyn plant",
        "",
        f"`python benchmarks/bench_exudyn_limits.py --moves {a.moves} --nlp {a.nlp} --seed "
        f"{a.seed}` — {datetime.date.today()}, {platform.machine()}, Python "
        f"{sys.version.split()[0]}. Judge: the Exudyn plant (does it run the plan to the end?).",
        "",
        "Cases per machine: Ruckig two-leg moves between poses with random joints exactly on a "
        "limit (start, pass at rest, end), and NLP minimum-time tip moves whose start or goal "
        "has a joint within 1e-6 of a limit; 50 Hz feed-forward, 0.5 s to settle.",
        "",
        "| machine | plans | ran to the end | stopped | wall s |",
        "| --- | --- | --- | --- | --- |", *rows, "",
        "Failures:" if fails else "No failures.", "",
        *(["| machine | case | joints on a limit | reason |", "| --- | --- | --- | --- |",
           *fails] if fails else []), ""])
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / a.name).write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
