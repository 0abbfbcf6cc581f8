"""Speed of the Bellman DP and the local laws (issue targets), recorded in benchmarks/results/.

* seed-000 DP on one path at the seed grid (Δ = 0.01 m, Δd3 = 0.01 m, q = 5): ≤ 0.25 s, and
  ≥ 50× faster than the per-node Python loop reference (same recursion, measured in this run);
* a local law along a 5 s cycle at 100 Hz: ≤ 0.2 s.

    python benchmarks/bench_dp_laws.py [--out benchmarks/results]
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


from planner import Crane
from planner.io import atomic_write_text
from planner.methods.dp import dp, dp_time_reference
from planner.methods.laws import LAWS, follow
from planner.methods.topp import retime
from planner.geometry.paths import Line

A, B, C = (1.5, 1.0, 0.0), (5.5, 1.0, 0.0), (5.5, -3.0, 0.0)


def seed_stages(a, b):
    return int(round(max(abs(b[0] - a[0]), abs(b[1] - a[1])) / 0.01))


def med(f, reps):
    f()
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), min(ts)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    crane = Crane.from_id("cranab850")
    rows = []
    for name, (a, b) in dict(AB=(A, B), BC=(B, C), AC=(A, C)).items():
        path = Line(a, b)
        n = seed_stages(a, b)
        t_vec, t_vec_min = med(lambda: dp(crane, path, stages=n, pump=False), 7)
        t_pump, _ = med(lambda: dp(crane, path, stages=n), 7)
        r = dp(crane, path, stages=n, pump=False)
        t0 = time.perf_counter()
        ref = dp_time_reference(crane, path, stages=n)
        t_loop = time.perf_counter() - t0
        rows.append(dict(move=name, stages=n, dp_time_s=r.duration_s, reference_time_s=ref,
                         same_result=bool(abs(ref - r.duration_s) < 1e-9),
                         vectorised_s=t_vec, vectorised_min_s=t_vec_min, with_pump_s=t_pump,
                         loop_reference_s=t_loop, speedup=t_loop / t_vec))
        print(rows[-1])
    # a local law along a 5 s cycle at 100 Hz: B–C at 0.8 m/s
    laws = {}
    for name, cls in LAWS.items():
        t, tmin = med(lambda: follow(crane, Line(B, C), cls(), 0.8, rate=100.0, tele0=0.6), 5)
        res = follow(crane, Line(B, C), cls(), 0.8, rate=100.0, tele0=0.6)
        laws[name] = dict(median_s=t, min_s=tmin, duration_s=res.duration_s,
                          steps=len(res.trajectory.t) - 1)
    # TOPP-RA: one pass at 200 grid points with the pump constraint (s100f, where it binds),
    # and the velocity-only retiming of the seed-000 DP paths against the DP time
    s100f = Crane.from_id("s100f")
    rp = dp(s100f, Line((7.0, -1.0, 0.0), (3.0, 2.0, 0.5)), step=0.02, tele_step=0.02, window=3)
    t_topp, _ = med(lambda: retime(s100f, rp.path_q, gridpoints=200, max_iter=1), 15)
    t_topp_v, _ = med(lambda: retime(s100f, rp.path_q, gridpoints=200), 7)
    topp = dict(one_pass_200_pump_s=t_topp, verified_200_pump_s=t_topp_v, dp_paths={})
    for r, (name, (a, b)) in zip(rows, dict(AB=(A, B), BC=(B, C), AC=(A, C)).items()):
        rr = dp(crane, Line(a, b), stages=r["stages"])
        for g in (200, 400):
            tt = retime(crane, rr.path_q, limits=("velocity",), gridpoints=g)
            topp["dp_paths"][f"{name}@{g}"] = dict(dp_s=rr.duration_s, topp_s=tt.duration_s,
                                                    ratio=tt.duration_s / rr.duration_s)
    worst_dp = max(r["vectorised_s"] for r in rows)
    worst_speedup = min(r["speedup"] for r in rows)
    worst_law = max(v["median_s"] for v in laws.values())
    report = dict(
        machine=dict(platform=platform.platform(), python=platform.python_version(),
                     cpus=os.cpu_count(), load=os.getloadavg(),
                     date=datetime.datetime.now().isoformat(timespec="seconds")),
        dp=rows, laws=laws, topp=topp,
        targets=dict(dp_le_0_25_s=worst_dp <= 0.25, dp_speedup_ge_50=worst_speedup >= 50,
                     law_le_0_2_s=worst_law <= 0.2,
                     topp_le_20_ms=t_topp <= 0.020))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "dp_laws_speed.json", json.dumps(report, indent=2) + "\n")
    md = ["# DP and local-law speed (cranab850, seed-000 grid)", "",
          f"{report['machine']['date']}, {report['machine']['platform']}, "
          f"{report['machine']['cpus']} CPUs, load {report['machine']['load'][0]:.2f}", "",
          "| move | stages | DP time [s] | vectorised [s] (median) | with pump limit [s] | "
          "loop reference [s] | speed-up | same result |",
          "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        md.append(f"| {r['move']} | {r['stages']} | {r['dp_time_s']:.4f} | "
                  f"{r['vectorised_s']:.3f} | {r['with_pump_s']:.3f} | "
                  f"{r['loop_reference_s']:.2f} | {r['speedup']:.0f}× | {r['same_result']} |")
    md += ["", "| law (B–C at 0.8 m/s, 100 Hz, 5 s) | median [s] | steps |", "| --- | ---: | ---: |"]
    for k, v in laws.items():
        md.append(f"| {k} | {v['median_s']:.3f} | {v['steps']} |")
    md += ["", f"- DP ≤ 0.25 s: **{'PASS' if report['targets']['dp_le_0_25_s'] else 'FAIL'}** "
               f"(worst {worst_dp:.3f} s)",
           f"- DP ≥ 50× the loop reference: "
           f"**{'PASS' if report['targets']['dp_speedup_ge_50'] else 'FAIL'}** "
           f"(worst {worst_speedup:.0f}×)",
           f"- law along a 5 s cycle at 100 Hz ≤ 0.2 s: "
           f"**{'PASS' if report['targets']['law_le_0_2_s'] else 'FAIL'}** "
           f"(worst {worst_law:.3f} s)"]
    md += ["", "| TOPP-RA | value |", "| --- | ---: |",
           f"| one pass, 200 grid points, pump constraint (s100f) | {1e3 * t_topp:.1f} ms |",
           f"| verified on every interval (retime as called; grid adapted) | {1e3 * t_topp_v:.1f} ms |"]
    for k, v in topp["dp_paths"].items():
        md.append(f"| velocity-only retiming of the DP path {k} grid points: "
                  f"{v['topp_s']:.4f} s vs DP {v['dp_s']:.4f} s | {100 * (v['ratio'] - 1):+.2f} % |")
    md.append(f"- TOPP-RA ≤ 20 ms (one pass, 200 points, pump): "
              f"**{'PASS' if report['targets']['topp_le_20_ms'] else 'FAIL'}**")
    atomic_write_text(out / "dp_laws_speed.md", "\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
