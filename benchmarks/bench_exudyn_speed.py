#!/usr/bin/env python3
"""Where the Exudyn plant's time goes (issue 13, item 5): a 60 s recording of s100f (4 joints,
step 2 ms, output at 50 Hz; the recording of benchmarks/bench_exudyn.py's speed check),
timed as CPU time of the process (what one core delivers, whatever else runs) and as wall
time (what this loaded machine gave), then once under cProfile for the split by function.

    python benchmarks/bench_exudyn_speed.py [--repeat 3] [--out benchmarks/results]

Writes <out>/exudyn_speed.md and .json.
"""
from __future__ import annotations

import argparse
import cProfile
import os
import platform
import pstats
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent
for p in (HERE.parent, HERE):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from bench_exudyn import _poses  # noqa: E402
from planner import Crane  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.methods.ruckig import rest_to_rest  # noqa: E402
from planner.simulation.dynamic.exudyn_plant import ExudynPlant  # noqa: E402
from planner.simulation.dynamic.simulate import simulate_trajectory, slowed  # noqa: E402

GROUPS = (("circuit right-hand side (pressures)", ("circuit.py", "rhs")),
          ("circuit force", ("circuit.py", "force")),
          ("stroke table lookups", ("exudyn_plant.py", "__call__")),
          ("plant callbacks (rhs, force wrappers)", ("exudyn_plant.py", "rhs")),
          ("plant callbacks (force wrapper)", ("exudyn_plant.py", "force")),
          ("pre-step (spool, recording, checks)", ("exudyn_plant.py", "pre_step")),
          ("engine: node reads", ("~", "GetNodeOutput")),
          ("engine: solver itself", ("~", "SolveSystem")))


def one(crane, traj):
    plant = ExudynPlant(crane)
    c0, w0 = time.process_time(), time.perf_counter()
    run, *_ = simulate_trajectory(crane, traj, 50.0, plant=plant,
                                  settle=max(60.0 - traj.duration, 0.0))
    return dict(sim_s=float(run.t[-1] - run.t[0]), cpu_s=time.process_time() - c0,
                wall_s=time.perf_counter() - w0, steps=run.meta["steps"], status=run.status)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    crane = Crane.from_id("s100f")
    q0, q1 = _poses(crane, 1)
    traj = slowed(rest_to_rest(crane, q0, q1, scale=0.5).trajectory, 4.0)
    runs = [one(crane, traj) for _ in range(args.repeat)]
    pr = cProfile.Profile()
    pr.enable()
    prof_run = one(crane, traj)
    pr.disable()
    st = pstats.Stats(pr).stats
    total = sum(v[2] for v in st.values())          # own time of every function
    split = {}
    for label, (fname, func) in GROUPS:
        split[label] = dict(own_s=sum(v[2] for k, v in st.items()
                                      if k[0].endswith(fname) and k[2] == func
                                      or fname == "~" and func in k[2]),
                            calls=sum(v[1] for k, v in st.items()
                                      if k[0].endswith(fname) and k[2] == func
                                      or fname == "~" and func in k[2]))
    steps = prof_run["steps"]
    load = os.getloadavg()
    res = dict(runs=runs, profiled=prof_run, profile_total_s=total, split=split, load=load)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "exudyn_speed.json", dumps(res))
    cpu = sorted(r["cpu_s"] for r in runs)
    wall = sorted(r["wall_s"] for r in runs)
    L = ["# Exudyn plant: where the time goes (issue 13, item 5)", "",
         f"Produced by `python benchmarks/bench_exudyn_speed.py {' '.join(sys.argv[1:])}`".rstrip()
         + f" on {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {platform.node()} "
         f"({platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}); "
         f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} at the end (wall "
         "times grow with other jobs on the machine; the CPU times are what one core "
         "needs).", "",
         f"A {runs[0]['sim_s']:.1f} s recording of s100f (4 joints, step 2 ms = {steps} steps, "
         "output at 50 Hz): the target is ≤ 30 s on one core.", "",
         "| run | CPU time of the process [s] | wall time [s] |", "| --- | ---: | ---: |"]
    for k, r in enumerate(runs):
        L.append(f"| {k + 1} | {r['cpu_s']:.1f} | {r['wall_s']:.1f} |")
    L += ["", f"Best CPU time {cpu[0]:.1f} s, median {cpu[len(cpu) // 2]:.1f} s; wall "
          f"{wall[0]:.1f}–{wall[-1]:.1f} s.", "",
          f"Under cProfile (which slows the Python parts; {total:.1f} s of own time in all):", "",
          "| part | own time [s] | share | calls | calls per step |",
          "| --- | ---: | ---: | ---: | ---: |"]
    for label, d in split.items():
        L.append(f"| {label} | {d['own_s']:.2f} | {100 * d['own_s'] / total:.0f} % | "
                 f"{d['calls']} | {d['calls'] / steps:.1f} |")
    per = split["circuit right-hand side (pressures)"]["calls"] / steps
    L += ["", "The Python callbacks (the circuit's right-hand side and force, the stroke "
          f"lookups, the wrappers that read the engine's nodes) are called ~{per:.0f} times per "
          "step: "
          "the implicit integrator's numerical Jacobian (2n + 1 pressure columns and the joint "
          "columns) and its Newton iterations. Moving them into compiled code (Exudyn's "
          "symbolic user functions) or giving the engine an analytic Jacobian of the pressure "
          "block is where a further speed-up would come from; a longer step does not help (at "
          "4–5 ms the tour move's replay costs the same CPU time: more Newton iterations)."]
    atomic_write_text(args.out / "exudyn_speed.md", "\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
