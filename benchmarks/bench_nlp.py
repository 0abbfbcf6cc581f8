"""NLP on random feasible moves: success, limits (evaluate), gap to the analytic bound, speed.

Moves: start and goal tips of random in-limit configurations (so both are reachable), slew
included; fixed seed. For each: the analytic lower bound (min over the telescope at both
ends), the time-optimal free-path NLP (built once per machine), judged by evaluate(). With
--energy K, the first K moves are also solved energy-optimally at 1.2 × T_min.

    python benchmarks/bench_nlp.py [--moves 200] [--energy 20] [--out benchmarks/results]
    python benchmarks/bench_nlp.py --recheck   # only the fine-bound check of the stored JSON

The bound is a search over the telescope at both ends (grid + local refinement); a move that
ends below it is re-checked against a much finer search (FINE), and the table counts both:
below the default search's bound, and below the fine one (which would be a real error).
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


FINE = dict(n_grid=961, refine=6, starts=64)


def fine_check(crane, rows) -> int:
    """Moves ending below their default bound get ``bound_fine_s`` (the FINE search); returns
    how many end below that too."""
    n = 0
    for r in rows:
        if r["status"] == "ok" and r["duration_s"] < r["bound_s"] * (1 - 1e-4):
            r["bound_fine_s"] = lower_bound(crane, r["start"], r["goal"], **FINE).combined_s
            n += r["duration_s"] < r["bound_fine_s"] * (1 - 1e-4)
    return n


def run(cid, moves, n_energy, N):
    crane = Crane.from_id(cid)
    t0 = time.perf_counter()
    nlp = MoveNLP(crane, "time", "free", N=N, cache="off")   # a build, not a cache read
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
                below_fine_bound=fine_check(crane, rows),
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


def markdown(report) -> list:
    N, n_energy = report["N"], report["energy_moves"]
    md = ["# Time-optimal NLP on random moves", "",
          f"{report['machine']['date']}, {report['machine']['platform']}, "
          f"{report['machine']['cpus']} CPUs; N = {N} intervals, free path, pump limit on. "
          "Judges: `evaluate()` at 1 kHz for the limits, the analytic lower bound (a telescope "
          "search at both ends) for the duration; moves below the default search's bound are "
          f"re-checked against a finer search ({FINE}).",
          "", "| machine | moves | success | all pass evaluate (≤ 0.1 %) | below bound (default "
          "search / fine search) | median T / bound | p90 T / bound | median solve [s] | p90 "
          "solve [s] | build [s] (cache off) |",
          "| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for cid, d in report["machines"].items():
        summ = d["summary"]
        md.append(f"| {cid} | {summ['moves']} | {100 * summ['success']:.1f} % | "
                  f"{summ['all_pass_evaluate']} (worst {100 * summ['worst_violation']:.4f} %) | "
                  f"{summ['below_bound']} / {summ.get('below_fine_bound', '–')} | "
                  f"{summ['median_ratio']:.4f} | {summ['p90_ratio']:.4f} | "
                  f"{summ['median_solve_s']:.3f} | {summ['p90_solve_s']:.3f} | "
                  f"{summ['build_s']:.2f} |")
        if summ["failures"]:
            md.append("|  | failures: " + "; ".join(f"#{f['i']} {f['status']}"
                                                     for f in summ["failures"]) + " |" + " |" * 8)
    if n_energy:
        md += ["", f"Energy-optimal at 1.2 × T_min on the first {n_energy} moves:", "",
               "| machine | success | uses less energy than time-optimal | all pass evaluate | "
               "NLP beat the stretched incumbent | median saving | median solve [s] |",
               "| --- | ---: | ---: | --- | ---: | ---: | ---: |"]
        for cid, d in report["machines"].items():
            s = d["summary"]
            md.append(f"| {cid} | {100 * s['energy_success']:.0f} % | {s['energy_less']} / "
                      f"{s['energy_moves']} | {s['energy_all_pass']} | {s['energy_nlp_wins']} | "
                      f"{100 * (s['energy_median_saving'] or 0):.1f} % | "
                      f"{s['energy_median_solve_s']:.2f} |")
    return md


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--moves", type=int, default=200)
    ap.add_argument("--energy", type=int, default=0)
    ap.add_argument("--N", type=int, default=40)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--recheck", action="store_true",
                    help="re-check the stored JSON's below-bound moves against the fine bound")
    args = ap.parse_args()
    if args.recheck:
        path = Path(args.out) / "nlp_random_moves.json"
        report = json.loads(path.read_text())
        report.setdefault("energy_moves", args.energy)
        report.setdefault("N", args.N)
        for cid, d in report["machines"].items():
            d["summary"]["below_fine_bound"] = fine_check(Crane.from_id(cid), d["moves"])
        atomic_write_text(path, json.dumps(report, indent=2) + "\n")
        atomic_write_text(path.with_suffix(".md"), "\n".join(markdown(report)) + "\n")
        print("\n".join(markdown(report)))
        return
    report = dict(machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                               date=datetime.datetime.now().isoformat(timespec="seconds")),
                  machines={})
    for k, cid in enumerate(("s100f", "umea-lab")):
        crane = Crane.from_id(cid)
        summ, rows = run(cid, random_moves(crane, args.moves, seed=100 + k), args.energy, args.N)
        report["machines"][cid] = dict(summary=summ, moves=rows)
    report["energy_moves"], report["N"] = args.energy, args.N
    md = markdown(report)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "nlp_random_moves.json", json.dumps(report, indent=2) + "\n")
    atomic_write_text(out / "nlp_random_moves.md", "\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
