"""The NLP build cache (issue 17): what a one-off `crane-planner plan --method nlp` pays, first
call and later calls, against a plain CasADi Opti problem of the same size built and solved in
the same run.

    python benchmarks/bench_nlp_cache.py [--rounds 5] [--N 40]

Every timed call is a fresh process (as a user running one command pays it):
* ``plan`` — ``crane-planner plan umea-lab --method nlp --json -`` reading ``build_time_s`` and
  ``solve_time_s`` from its JSON: once with an empty cache and ``--compile`` (first call: build,
  generate C, compile, store), then ``rounds`` times loading the stored solver;
* ``opti`` — a plain Opti triple integrator (jerk-limited, no pump, no model: the shared
  baseline of benchmarks/opti_baseline.py) with the umea-lab limits, N intervals, between the
  joint configurations of the same move, minimum time: build
  and solve timed inside the process; the two commands interleaved, medians compared.
Also: byte-identical trajectory CSV with the cache off and on, and two processes building the
same entry at once on an empty cache. Writes benchmarks/results/nlp_cache.md and .json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
CRANE, START, GOAL = "umea-lab", "2.65,2.2,0.2", "3.2,1.6,-0.4"

OPTI = r'''
import json, sys, time
t0 = time.perf_counter()
sys.path.insert(0, sys.argv[5])   # benchmarks/: the shared baseline
from opti_baseline import PlainOpti
from planner import Crane
from planner.bounds import lower_bound
crane = Crane.from_id(sys.argv[1]); N = int(sys.argv[2])
start = tuple(float(v) for v in sys.argv[3].split(",")); goal = tuple(float(v) for v in sys.argv[4].split(","))
lb = lower_bound(crane, start, goal)
q0, q1 = crane.ik(start, lb.tele_start), crane.ik(goal, lb.tele_goal)
t1 = time.perf_counter()
base = PlainOpti(crane, q0, q1, N, guess_T=lb.combined_s)
t2 = time.perf_counter()
T, it = base.solve()
t3 = time.perf_counter()
print(json.dumps(dict(build_s=t2 - t1, solve_s=t3 - t2, T=T, iterations=it,
                      variables=base.variables, constraints=base.constraints)))
'''


def run(cmd, env):
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {r.stderr[-600:]}")
    return r.stdout


def plan_cmd(N, *extra):
    return [sys.executable, "-m", "planner", "plan", CRANE, "--start", START, "--goal", GOAL,
            "--method", "nlp", "--intervals", str(N), *extra]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--N", type=int, default=40)
    ap.add_argument("--out", default=str(RESULTS))
    args = ap.parse_args(argv)
    cache = Path(tempfile.mkdtemp(prefix="crane-nlp-cache-"))
    env = dict(os.environ, CRANE_PLANNER_CACHE=str(cache), CRANE_PLANNER_NLP_CACHE="use")
    first = json.loads(run(plan_cmd(args.N, "--compile", "--json", "-"), env))
    later, opti = [], []
    for _ in range(args.rounds):   # interleaved: A B A B ...
        later.append(json.loads(run(plan_cmd(args.N, "--json", "-"), env)))
        opti.append(json.loads(run([sys.executable, "-c", OPTI, CRANE, str(args.N), START,
                                    GOAL, str(HERE)], env)))
    off = dict(env, CRANE_PLANNER_NLP_CACHE="off")
    nocache = json.loads(run(plan_cmd(args.N, "--json", "-"), off))
    # byte-identical CSV with and without the cache
    tmp = Path(tempfile.mkdtemp())
    run(plan_cmd(args.N, "--out", str(tmp / "off.csv")), off)
    run(plan_cmd(args.N, "--out", str(tmp / "on.csv")), env)
    identical = (tmp / "off.csv").read_bytes() == (tmp / "on.csv").read_bytes()
    # two builders at once on an empty cache (a smaller N keeps the compile short)
    race = Path(tempfile.mkdtemp(prefix="crane-nlp-race-"))
    renv = dict(env, CRANE_PLANNER_CACHE=str(race))
    procs = [subprocess.Popen(plan_cmd(8, "--compile", "--json", "-"), env=renv,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    outs = [p.communicate() for p in procs]
    race_ok = all(p.returncode == 0 for p in procs)
    race_status = [json.loads(o)["nlp_cache"] for o, _ in outs] if race_ok else [e for _, e in outs]
    entries = sorted(x.name for x in (race / "nlp").iterdir()) if (race / "nlp").exists() else []
    after = json.loads(run(plan_cmd(8, "--json", "-"), renv))

    med = statistics.median
    later_total = [d["build_time_s"] + d["solve_time_s"] for d in later]
    opti_total = [d["build_s"] + d["solve_s"] for d in opti]
    ratio = [a / b for a, b in zip(later_total, opti_total)]
    res = dict(
        machine=dict(platform=platform.platform(), processor=platform.processor(),
                     cpus=os.cpu_count(), date=datetime.now(timezone.utc).isoformat()),
        move=dict(crane=CRANE, start=START, goal=GOAL, N=args.N), rounds=args.rounds,
        first_call=dict(build_time_s=first["build_time_s"], solve_time_s=first["solve_time_s"],
                        nlp_cache=first["nlp_cache"]),
        without_cache=dict(build_time_s=nocache["build_time_s"],
                           solve_time_s=nocache["solve_time_s"]),
        later_calls=dict(build_time_s=[d["build_time_s"] for d in later],
                         solve_time_s=[d["solve_time_s"] for d in later],
                         nlp_cache=[d["nlp_cache"] for d in later],
                         duration_s=[d["duration_s"] for d in later]),
        opti=opti, ratio_total=ratio, ratio_median=med(ratio),
        identical_csv=identical, durations_equal=len({d["duration_s"] for d in later}
                                                     | {nocache["duration_s"]}) == 1,
        race=dict(ok=race_ok, statuses=race_status, entries=entries,
                  reload=after["nlp_cache"]))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "nlp_cache.json").write_text(json.dumps(res, indent=1))
    fmt = lambda v: f"{v:.3f}"  # noqa: E731
    L = ["# NLP build cache: a one-off `plan --method nlp` (issue 17)", "",
         f"Machine: {res['machine']['platform']}, {res['machine']['cpus']} CPUs, "
         f"{res['machine']['date']}. Move: {CRANE} {START} -> {GOAL}, N = {args.N}, minimum "
         "time, free path, pump on. Every call a fresh process; medians of "
         f"{args.rounds} interleaved rounds. Judge: wall clocks inside each process.", "",
         "| call | build_time_s | solve_time_s | total |", "| --- | ---: | ---: | ---: |",
         f"| no cache (CRANE_PLANNER_NLP_CACHE=off) | {fmt(nocache['build_time_s'])} | "
         f"{fmt(nocache['solve_time_s'])} | "
         f"{fmt(nocache['build_time_s'] + nocache['solve_time_s'])} |",
         f"| first call, empty cache, --compile | {fmt(first['build_time_s'])} | "
         f"{fmt(first['solve_time_s'])} | {fmt(first['build_time_s'] + first['solve_time_s'])} |",
         f"| later calls (cache hit) | {fmt(med(res['later_calls']['build_time_s']))} | "
         f"{fmt(med(res['later_calls']['solve_time_s']))} | {fmt(med(later_total))} |",
         f"| plain Opti, same size, no pump (build + solve) | "
         f"{fmt(med(d['build_s'] for d in opti))} | {fmt(med(d['solve_s'] for d in opti))} | "
         f"{fmt(med(opti_total))} |", "",
         f"Later call / plain Opti (total, pair by pair): median **{res['ratio_median']:.2f}×** "
         f"(min {min(ratio):.2f}, max {max(ratio):.2f}). The project's `solve_time_s` is the "
         "whole planning call without the build: the lower bound, the Ruckig guess and the "
         "check of the exact Ruckig move at 1 kHz, the IPOPT solve, evaluate().", "",
         f"Same results with and without the cache: trajectory CSV byte-identical: "
         f"**{identical}**; durations equal in every call: {res['durations_equal']}.", "",
         f"Two processes with `--compile` at once on an empty cache (N = 8): both succeeded: "
         f"{race_ok} (statuses {race_status}); entries afterwards: {len(entries)}; a third "
         f"call: `{after['nlp_cache']}`."]
    (out / "nlp_cache.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))
    return 0


if __name__ == "__main__":
    sys.exit(main())
