"""Does warm-starting a library move from the nearest already-solved entry pay (issue 15)?

The first ``--moves`` moves of the forwarder-cycle suite (s100f, minimum time, the headboard
obstacle), in suite order. Each move is solved from the NLP's own default (the plain and the
over-the-obstacle starts, the faster clearing solution kept) and from the nearest earlier solved
move (distance between the (start, goal) tip pairs), its joint path shifted linearly so that its
ends are this move's ends; both results side by side: solve time, IPOPT iterations, duration.

    python benchmarks/bench_library_warmstart.py [--moves 24]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from planner import Crane
from planner.io import atomic_write_text
from planner.methods.nlp.move import MoveNLP
from planner.tasks.suites import load_suite
from planner.trajectory import Trajectory


def shifted(tr: Trajectory, qa, qb) -> Trajectory:
    """``tr``'s joint path with its ends moved to ``qa`` and ``qb`` (a linear blend in time)."""
    s = (tr.t - tr.t[0]) / (tr.t[-1] - tr.t[0])
    q = tr.q + np.outer(1 - s, qa - tr.q[0]) + np.outer(s, qb - tr.q[-1])
    return Trajectory(tr.t, q, tr.qd, tr.qdd, joint_names=tr.joint_names)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--moves", type=int, default=24)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    meta, moves = load_suite("forwarder-cycle")
    crane = Crane.from_id("s100f")
    nlp = MoveNLP(crane, "time", "free", N=40, obstacles=meta["obstacles"])
    solved, rows = {}, []
    for i, m in enumerate(moves[:args.moves]):
        t = time.perf_counter()
        r = nlp.solve(m.start, m.goal)
        t_default = time.perf_counter() - t
        if solved and r.ok:
            key = np.r_[m.start, m.goal]
            j = min(solved, key=lambda k: np.linalg.norm(np.r_[moves[k].start, moves[k].goal]
                                                         - key))
            g = shifted(solved[j], r.trajectory.q[0], r.trajectory.q[-1])
            t = time.perf_counter()
            w = nlp.solve(m.start, m.goal, w0=nlp.guess_from(g))
            t_warm = time.perf_counter() - t
            rows.append(dict(move=m.id, neighbour=moves[j].id, default_s=t_default,
                             warm_s=t_warm, default_iter=r.stats.get("iterations"),
                             warm_iter=w.stats.get("iterations"), default_T=r.duration_s,
                             warm_T=w.duration_s if w.ok else float("nan"), warm_ok=w.ok))
            print(rows[-1], flush=True)
        if r.ok:
            solved[i] = r.trajectory
    d = np.array([r["default_s"] for r in rows])
    w = np.array([r["warm_s"] for r in rows])
    dT = np.array([(r["warm_T"] - r["default_T"]) / r["default_T"] for r in rows])
    rep = dict(date=datetime.datetime.now().isoformat(timespec="seconds"),
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=os.getloadavg()), rows=rows,
               median_default_s=float(np.median(d)), median_warm_s=float(np.median(w)),
               warm_faster=int(np.sum(w < d)), worse_duration=int(np.sum(dT > 1e-4)),
               max_duration_increase=float(np.nanmax(dT)))
    out = Path(args.out)
    atomic_write_text(out / "library_warmstart.json", json.dumps(rep, indent=1))
    L = ["# Library: warm start from the nearest solved entry (issue 15)", "",
         f"{rep['date']}, {rep['machine']['platform']}, {rep['machine']['cpus']} CPUs, load "
         f"{rep['machine']['load'][0]:.1f} (other work on the machine: read the ratio). "
         f"`python benchmarks/bench_library_warmstart.py --moves {args.moves}`: s100f, "
         "forwarder-cycle in suite order, minimum time with the headboard obstacle, N = 40.", "",
         "| | default start (plain + over-the-obstacle) | warm start from the nearest solved move |",
         "| --- | ---: | ---: |",
         f"| median solve time | {rep['median_default_s']:.3f} s | {rep['median_warm_s']:.3f} s |",
         f"| faster than the default | | {rep['warm_faster']} of {len(rows)} |",
         f"| longer move than the default's (a worse local optimum) | | "
         f"{rep['worse_duration']} of {len(rows)}, up to +{100 * rep['max_duration_increase']:.1f} % |",
         "", "Verdict: not used by the library build. The warm start saves nothing in the median "
         "and often ends in a worse local optimum than the default's two starts find (the "
         "moves with the headboard obstacle are multimodal). It would also make an entry "
         "depend on which entries happened to finish first, which the build must not (every "
         "executor writes identical entries).", ""]
    atomic_write_text(out / "library_warmstart.md", "\n".join(L))
    print("\n".join(L))


if __name__ == "__main__":
    main()
