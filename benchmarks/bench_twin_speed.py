"""The dynamic twin's speed on one core, warm (issue 27: "a 10 s, 4-joint move in ≤ 0.1 s on one
core, ≥ 100× real time").

Per machine: the twin built and its compiled step loaded (the one-off build is reported
apart), one warm-up run, then each move replayed ``--repeat`` times; CPU time of this process
(``time.process_time``: one core). Moves: Ruckig rest-to-rest moves between poses at 30–70 %
of every joint's range, slow (scale 0.3) and fast (scale 0.9), with their 50 Hz feed-forward,
plus 1 s with the valves closed.

    python benchmarks/bench_twin_speed.py [--repeat 5]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from planner import Crane  # noqa: E402
from planner.feedforward import commands  # noqa: E402
from planner.io import atomic_write_text  # noqa: E402
from planner.methods.ruckig import rest_to_rest  # noqa: E402
from planner.model.twin import Twin  # noqa: E402
from planner.problems import crane_ids  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args()
    rows = []
    for cid in crane_ids():
        crane = Crane.from_id(cid)
        c0 = time.process_time()
        w0 = time.perf_counter()
        twin = Twin(crane)
        build_cpu, build_wall = time.process_time() - c0, time.perf_counter() - w0
        L = crane.limit_arrays()
        for name, (fa, fb, scale) in dict(slow=(0.3, 0.7, 0.3), fast=(0.7, 0.3, 0.9)).items():
            q0, q1 = (L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (fa, fb))
            tr = rest_to_rest(crane, q0, q1, scale=scale).trajectory
            ff = commands(crane, tr, 50.0)
            tu = np.append(ff.t, ff.t[-1] + 0.02)
            uu = np.vstack([ff.u, np.zeros((1, crane.n))])
            t_end = tr.t[-1] + 1.0
            run = twin.simulate(tu, uu, q0, t_end=t_end)          # warm-up
            cpu = []
            for _ in range(a.repeat):
                c1 = time.process_time()
                run = twin.simulate(tu, uu, q0, t_end=t_end)
                cpu.append(time.process_time() - c1)
            sim = t_end - tr.t[0]
            med = float(np.median(cpu))
            rows.append(dict(machine=cid, joints=crane.n, move=name, simulated_s=sim,
                             cpu_s=med, cpu_runs=cpu, x_real_time=sim / med,
                             per_10s=10.0 * med / sim, status=run.status,
                             refined_chunks=twin.stepper.refined, build_cpu_s=build_cpu,
                             build_wall_s=build_wall))
            print(cid, name, f"{sim / med:.0f}x", flush=True)
    rep = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
               platform=platform.platform(), load=os.getloadavg(), repeat=a.repeat, rows=rows)
    L = ["# The dynamic twin's speed, warm, on one core (issue 27)", "",
         f"{rep['date']}, {rep['platform']}, load {rep['load'][0]:.1f} {rep['load'][1]:.1f} "
         f"{rep['load'][2]:.1f} (a shared machine: CPU times of this process, median of "
         f"{a.repeat} runs after a warm-up). `python benchmarks/bench_twin_speed.py`.", "",
         "| machine | joints | move | simulated s | CPU s (median) | × real time | a 10 s move "
         "[s CPU] | status |", "| --- | ---: | --- | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        L.append(f"| {r['machine']} | {r['joints']} | {r['move']} | {r['simulated_s']:.1f} | "
                 f"{r['cpu_s']:.3f} | {r['x_real_time']:.0f} | {r['per_10s']:.3f} | "
                 f"{r['status']} |")
    L += ["", "The one-off build (the right-hand side in CasADi, the compiled step loaded from the "
          "per-user cache or compiled): " + ", ".join(
              f"{r['machine']} {r['build_cpu_s']:.1f} s CPU / {r['build_wall_s']:.1f} s wall"
              for r in rows[::2]) + "."]
    out = Path(a.out)
    atomic_write_text(out / "twin_speed.json", json.dumps(rep, indent=1))
    atomic_write_text(out / "twin_speed.md", "\n".join(L) + "\n")


if __name__ == "__main__":
    main()
