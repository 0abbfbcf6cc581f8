"""NLP on random feasible moves: success, limits (evaluate), gap to the analytic bound, speed.

Moves: start and goal tips of random in-limit configurations (so both are reachable), slew
included; fixed seed. For each: the analytic lower bound (min over the telescope at both
ends), the time-optimal free-path NLP (built once per machine), judged by evaluate(). With
--energy K, the first K moves are also solved energy-optimally at 1.2 × T_min.

    python benchmarks/bench_nlp.py [--moves 200] [--energy 20] [--out benchmarks/results]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from planner import Crane
from planner.bounds import lower_bound
from planner.io import atomic_write_text
from planner.methods.nlp import MoveNLP, energy_optimal
from planner.trajectory import evaluate


def random_moves(crane, k, seed, min_dist=1.0):
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + 0.05 * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - 0.05 * (L["q_max"] - L["q_min"])
    out = []
    while len(out) < k:
        a, b = (crane.tip(lo + rng.random(crane.n) * (hi - lo)) for _ in range(2))
        if np.hypot(a[0] - b[0], a[1] - b[1]) >= min_dist:
            out.append((a, b))
    return out


def run(cid, moves, n_energy, N):
    crane = Crane.from_id(cid)
    t0 = time.perf_counter()
    nlp = MoveNLP(crane, "time", "free", N=N)
    build_t = time.perf_counter() - t0
    nle = MoveNLP(crane, "energy", "free", N=N) if n_energy else None
    rows = []
    for i, (a, b) in enumerate(tqdm(moves, desc=cid, unit="move")):
        lb = lower_bound(crane, a, b)
        r = nlp.solve(a, b)
        row = dict(i=i, start=a.tolist(), goal=b.tolist(), bound_s=lb.combined_s,
                   status=r.status, reason=r.reason, solve_s=r.solve_time_s,
                   iterations=r.iterations)
        if r.ok:
            ev = evaluate(crane, r.trajectory)
            row.update(duration_s=r.duration_s, ratio=r.duration_s / lb.combined_s,
                       violation=ev.max_limit_violation, energy_J=ev.energy_J)
            if nle is not None and i < n_energy:
                re, info = energy_optimal(crane, a, b, 1.2 * r.duration_s, time_result=r,
                                          energy_nlp=nle)
                row["energy_status"] = re.status
                row["energy_solve_s"] = re.solve_time_s  # excludes the time-optimal solve
                row["energy_winner"] = info.get("winner")
                if re.ok:
                    eve = evaluate(crane, re.trajectory)
                    row.update(energy_opt_J=eve.energy_J, energy_violation=eve.max_limit_violation)
        rows.append(row)
    ok = [r for r in rows if r["status"] == "ok"]
    summ = dict(machine=cid, moves=len(rows), N=N, build_s=build_t,
                success=len(ok) / len(rows),
                all_pass_evaluate=all(r["violation"] <= 1e-3 for r in ok),
                worst_violation=max((r["violation"] for r in ok), default=None),
                below_bound=sum(r["duration_s"] < r["bound_s"] * (1 - 1e-4) for r in ok),
                median_ratio=statistics.median(r["ratio"] for r in ok),
                p90_ratio=float(np.percentile([r["ratio"] for r in ok], 90)),
                median_solve_s=statistics.median(r["solve_s"] for r in ok),
                p90_solve_s=float(np.percentile([r["solve_s"] for r in ok], 90)),
                failures=[dict(i=r["i"], status=r["status"], reason=r["reason"])
                          for r in rows if r["status"] != "ok"])
    en = [r for r in rows if "energy_status" in r]
    if en:
        eok = [r for r in en if r["energy_status"] == "ok"]
        summ.update(energy_moves=len(en), energy_success=len(eok) / len(en),
                    energy_less=sum(r["energy_opt_J"] < r["energy_J"] for r in eok),
                    energy_all_pass=all(r["energy_violation"] <= 1e-3 for r in eok),
                    energy_nlp_wins=sum(r.get("energy_winner") == "nlp" for r in eok),
                    energy_median_saving=statistics.median(
                        1 - r["energy_opt_J"] / r["energy_J"] for r in eok) if eok else None,
                    energy_median_solve_s=statistics.median(r["energy_solve_s"] for r in en))
    return summ, rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--moves", type=int, default=200)
    ap.add_argument("--energy", type=int, default=0)
    ap.add_argument("--N", type=int, default=40)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    report = dict(machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                               date=datetime.datetime.now().isoformat(timespec="seconds")),
                  machines={})
    md = ["# Time-optimal NLP on random moves", "",
          f"{report['machine']['date']}, {report['machine']['platform']}, "
          f"{report['machine']['cpus']} CPUs; N = {args.N} intervals, free path, pump limit on",
          "", "| machine | moves | success | all pass evaluate (≤ 0.1 %) | below bound | "
          "median T / bound | p90 T / bound | median solve [s] | p90 solve [s] | build [s] |",
          "| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for k, cid in enumerate(("s100f", "umea-lab")):
        crane = Crane.from_id(cid)
        summ, rows = run(cid, random_moves(crane, args.moves, seed=100 + k), args.energy, args.N)
        report["machines"][cid] = dict(summary=summ, moves=rows)
        md.append(f"| {cid} | {summ['moves']} | {100 * summ['success']:.1f} % | "
                  f"{summ['all_pass_evaluate']} (worst {100 * summ['worst_violation']:.4f} %) | "
                  f"{summ['below_bound']} | {summ['median_ratio']:.4f} | {summ['p90_ratio']:.4f} | "
                  f"{summ['median_solve_s']:.3f} | {summ['p90_solve_s']:.3f} | "
                  f"{summ['build_s']:.2f} |")
        if summ["failures"]:
            md.append("|  | failures: " + "; ".join(f"#{f['i']} {f['status']}"
                                                     for f in summ["failures"]) + " |" + " |" * 8)
    if args.energy:
        md += ["", f"Energy-optimal at 1.2 × T_min on the first {args.energy} moves:", "",
               "| machine | success | uses less energy than time-optimal | all pass evaluate | "
               "NLP beat the stretched incumbent | median saving | median solve [s] |",
               "| --- | ---: | ---: | --- | ---: | ---: | ---: |"]
        for cid, d in report["machines"].items():
            s = d["summary"]
            md.append(f"| {cid} | {100 * s['energy_success']:.0f} % | {s['energy_less']} / "
                      f"{s['energy_moves']} | {s['energy_all_pass']} | {s['energy_nlp_wins']} | "
                      f"{100 * (s['energy_median_saving'] or 0):.1f} % | "
                      f"{s['energy_median_solve_s']:.2f} |")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "nlp_random_moves.json", json.dumps(report, indent=2) + "\n")
    atomic_write_text(out / "nlp_random_moves.md", "\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
