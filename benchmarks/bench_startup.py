"""Start-up (issue 31): what a user waits for, every call a whole fresh process.

    python benchmarks/bench_startup.py [--pairs 10] [--help-runs 15] [--N 40]

* ``crane-planner --help`` (run as ``python -m planner --help``): wall clock of the whole
  process, median of ``--help-runs``; ``python -c pass`` beside it (the interpreter alone).
* a one-off ``crane-planner plan umea-lab … --method nlp --json -`` with an NLP cache hit (the
  solver compiled once into a temporary cache first, as ``plan --compile`` does), against a
  fresh process that builds and solves the plain CasADi Opti problem of the same size
  (benchmarks/opti_baseline.py: triple integrator, N intervals, the machine's limits, minimum
  time, no pump):
  - ``opti``: imports CasADi and numpy only; the move's joint configurations, limits and
    starting duration are given as numbers (what a user who writes the Opti by hand runs);
  - ``opti+planner``: benchmarks/bench_nlp_cache.py's baseline process, which also imports
    the planner to read the machine and compute its lower bound and inverse kinematics.
  The three are interleaved (plan, opti, opti+planner, plan, …); the wall clocks are taken
  by this process around each subprocess; the ratios are pair by pair, medians reported.
* bytecode: the project's modules are compiled once beforehand into a temporary
  ``PYTHONPYCACHEPREFIX`` (an installed package has its .pyc files; a source checkout run with
  ``PYTHONDONTWRITEBYTECODE=1`` compiles ~70 modules in every process instead, 0.1-0.2 s);
  ``--no-bytecode`` measures that instead.
* where a plan's time goes: its own ``build_time_s + solve_time_s`` (from its JSON) and the
  rest (interpreter, imports, reading the machine, evaluate, printing), and one extra run
  under ``python -X importtime`` for the import total and the heaviest imports.

Writes benchmarks/results/startup.md and .json (command, date, machine load before/after).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

from bench_nlp_cache import CRANE, GOAL, OPTI, START, plan_cmd

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results"

# the hand-written Opti process: CasADi + numpy + the shared baseline class, numbers in argv
OPTI_PLAIN = r'''
import json, sys, time
from types import SimpleNamespace
sys.path.insert(0, sys.argv[1])
import numpy as np
from opti_baseline import PlainOpti
d = json.loads(sys.argv[2])
L = {k: np.array(v, float) for k, v in d["limits"].items()}
t1 = time.perf_counter()
base = PlainOpti(SimpleNamespace(n=len(d["q0"]), limit_arrays=lambda: L), np.array(d["q0"]),
                 np.array(d["q1"]), d["N"], guess_T=d["T"])
T, it = base.solve()
print(json.dumps(dict(T=T, iterations=it, build_solve_s=time.perf_counter() - t1)))
'''


def cpu_children() -> float:
    """CPU seconds (user + system) of the finished child processes so far."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def timed(cmd, env) -> tuple[float, str, float]:
    """(wall [s] of the whole process, its stdout, its CPU seconds: less sensitive than the
    wall clock to other work on a shared machine); a failing process stops the benchmark.
    It runs in the checkout its PYTHONPATH names (``-m planner`` puts the folder first)."""
    c0, t0 = cpu_children(), time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=env["PYTHONPATH"])
    wall, cpu = time.perf_counter() - t0, cpu_children() - c0
    if r.returncode != 0:
        raise RuntimeError(f"{shlex.join(cmd)}: {r.stderr[-800:]}")
    return wall, r.stdout, cpu


def move_numbers(N: int) -> dict:
    """The plain Opti's inputs for the benchmark's move (computed here, once, by the planner):
    the end joint configurations at the lower bound's telescopes, the limits, the bound."""
    import numpy as np

    from planner import Crane
    from planner.bounds import lower_bound
    crane = Crane.from_id(CRANE)
    start, goal = (tuple(float(v) for v in p.split(",")) for p in (START, GOAL))
    lb = lower_bound(crane, start, goal)
    q0, q1 = crane.ik(start, lb.tele_start), crane.ik(goal, lb.tele_goal)
    return dict(q0=np.asarray(q0).tolist(), q1=np.asarray(q1).tolist(), N=N, T=lb.combined_s,
                limits={k: np.asarray(v).tolist() for k, v in crane.limit_arrays().items()})


def import_profile(cmd, env, top: int = 8) -> dict:
    """One run of ``cmd`` (a python command) under ``-X importtime``: the total of the
    top-level imports and the ``top`` heaviest of them [s]."""
    r = subprocess.run([cmd[0], "-X", "importtime", *cmd[1:]], capture_output=True, text=True,
                       env=env, cwd=ROOT)
    rows = []
    for line in r.stderr.splitlines():
        if line.startswith("import time:") and line.count("|") == 2:
            _, cum, name = line.split("|")
            if cum.strip().isdigit() and name.startswith(" ") and not name.startswith("  "):
                rows.append((int(cum) * 1e-6, name.strip()))
    rows.sort(reverse=True)
    return dict(total_s=sum(s for s, _ in rows), heaviest={n: s for s, n in rows[:top]})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=10)
    ap.add_argument("--help-runs", type=int, default=15)
    ap.add_argument("--N", type=int, default=40)
    ap.add_argument("--out", default=str(RESULTS))
    ap.add_argument("--help-only", action="store_true", help="only the --help section")
    ap.add_argument("--before", metavar="DIR",
                    help="another checkout of the project (e.g. the commit before a change): "
                         "its --help and plan timed in the same interleaved rounds")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="no compiled bytecode of the project (every process compiles it)")
    args = ap.parse_args(argv)
    command = shlex.join(["python", "benchmarks/bench_startup.py",
                          *(sys.argv[1:] if argv is None else argv)])
    py = sys.executable
    cache = Path(tempfile.mkdtemp(prefix="crane-startup-cache-"))
    env = dict(os.environ, PYTHONPATH=str(ROOT), CRANE_PLANNER_CACHE=str(cache),
               CRANE_PLANNER_NLP_CACHE="use")
    if not args.no_bytecode:
        env["PYTHONPYCACHEPREFIX"] = tempfile.mkdtemp(prefix="crane-startup-pyc-")
        subprocess.run([py, "-m", "compileall", "-q", str(ROOT / "planner"), str(HERE)]
                       + ([str(Path(args.before) / "planner")] if args.before else []),
                       env=env, check=True, capture_output=True)
    env_before = dict(env, PYTHONPATH=str(Path(args.before).resolve())) if args.before else None
    load_before = os.getloadavg()
    t_start = datetime.now(timezone.utc).isoformat()

    helps, bare, helps_cpu, before = [], [], [], []
    for _ in range(args.help_runs):   # interleaved with the bare interpreter (and --before)
        w, _, c = timed([py, "-m", "planner", "--help"], env)
        helps.append(w)
        helps_cpu.append(c)
        bare.append(timed([py, "-c", "pass"], env)[0])
        if env_before:
            before.append(timed([py, "-m", "planner", "--help"], env_before)[0])
    help_res = dict(wall_s=helps, median_s=statistics.median(helps), min_s=min(helps),
                    cpu_s=helps_cpu, cpu_median_s=statistics.median(helps_cpu),
                    bare_python_s=bare, bare_median_s=statistics.median(bare),
                    imports=import_profile([py, "-m", "planner", "--help"], env))
    if before:
        help_res.update(before=args.before, before_wall_s=before,
                        before_median_s=statistics.median(before))
    if args.help_only:
        res = dict(command=command, bytecode=not args.no_bytecode,
                   machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                                date=t_start, python=platform.python_version(),
                                load_before=load_before, load_after=os.getloadavg()),
                   help=help_res)
        text = report(res)
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "startup_help.json").write_text(json.dumps(res, indent=1))
        (Path(args.out) / "startup_help.md").write_text(text + "\n")
        print(text)
        return 0

    compiled = json.loads(timed(plan_cmd(args.N, "--compile", "--json", "-"), env)[1])
    if env_before:   # its own cache entry (the key hashes the NLP's sources): a hit there too
        timed(plan_cmd(args.N, "--compile", "--json", "-"), env_before)
    numbers = json.dumps(move_numbers(args.N))
    plan, opti, opti_pl, plan_before = [], [], [], []
    for _ in range(args.pairs):       # interleaved: plan, opti, opti+planner, plan, ...
        if env_before:
            w, out, c = timed(plan_cmd(args.N, "--json", "-"), env_before)
            plan_before.append(dict(json.loads(out), wall_s=w, cpu_s=c))
        w, out, c = timed(plan_cmd(args.N, "--json", "-"), env)
        plan.append(dict(json.loads(out), wall_s=w, cpu_s=c))
        w, out, c = timed([py, "-c", OPTI_PLAIN, str(HERE), numbers], env)
        opti.append(dict(json.loads(out), wall_s=w, cpu_s=c))
        w, out, c = timed([py, "-c", OPTI, CRANE, str(args.N), START, GOAL, str(HERE)], env)
        opti_pl.append(dict(json.loads(out), wall_s=w, cpu_s=c))
    profile = import_profile(plan_cmd(args.N, "--json", "-"), env)
    load_after = os.getloadavg()

    med = statistics.median
    r_plain = [p["wall_s"] / o["wall_s"] for p, o in zip(plan, opti)]
    r_pl = [p["wall_s"] / o["wall_s"] for p, o in zip(plan, opti_pl)]
    r_cpu = [p["cpu_s"] / o["cpu_s"] for p, o in zip(plan, opti)]
    inside = [p["build_time_s"] + p["solve_time_s"] for p in plan]
    res = dict(
        command=command,
        bytecode=not args.no_bytecode,
        machine=dict(platform=platform.platform(), cpus=os.cpu_count(), date=t_start,
                     python=platform.python_version(), load_before=load_before,
                     load_after=load_after),
        help=help_res,
        move=dict(crane=CRANE, start=START, goal=GOAL, N=args.N),
        compile_call=dict(nlp_cache=compiled.get("nlp_cache"),
                          build_time_s=compiled["build_time_s"]),
        plan=dict(wall_s=[p["wall_s"] for p in plan], median_s=med(p["wall_s"] for p in plan),
                  cpu_s=[p["cpu_s"] for p in plan], cpu_median_s=med(p["cpu_s"] for p in plan),
                  inside_s=inside, inside_median_s=med(inside),
                  nlp_cache=sorted({p.get("nlp_cache") for p in plan}),
                  durations=sorted({p["duration_s"] for p in plan}), imports=profile),
        opti=dict(wall_s=[o["wall_s"] for o in opti], median_s=med(o["wall_s"] for o in opti),
                  cpu_s=[o["cpu_s"] for o in opti], cpu_median_s=med(o["cpu_s"] for o in opti),
                  build_solve_median_s=med(o["build_solve_s"] for o in opti),
                  T=sorted({round(o["T"], 9) for o in opti})),
        opti_planner=dict(wall_s=[o["wall_s"] for o in opti_pl],
                          median_s=med(o["wall_s"] for o in opti_pl),
                          build_solve_median_s=med(o["build_s"] + o["solve_s"] for o in opti_pl)),
        ratio_plain=r_plain, ratio_plain_median=med(r_plain),
        ratio_planner=r_pl, ratio_planner_median=med(r_pl),
        ratio_cpu=r_cpu, ratio_cpu_median=med(r_cpu))
    if plan_before:
        rb = [p["wall_s"] / o["wall_s"] for p, o in zip(plan_before, opti)]
        res["plan_before"] = dict(dir=args.before, wall_s=[p["wall_s"] for p in plan_before],
                                  median_s=med(p["wall_s"] for p in plan_before),
                                  cpu_median_s=med(p["cpu_s"] for p in plan_before),
                                  ratio=rb, ratio_median=med(rb),
                                  nlp_cache=sorted({str(p.get("nlp_cache"))
                                                    for p in plan_before}),
                                  durations=sorted({p["duration_s"] for p in plan_before}))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "startup.json").write_text(json.dumps(res, indent=1))
    (out / "startup.md").write_text(report(res) + "\n")
    print(report(res))
    return 0


def f3(v: float) -> str:
    return f"{v:.3f}"


def report(res: dict) -> str:
    """The markdown report: the --help section, and the plan section when it was run."""
    m, h = res["machine"], res["help"]
    load = lambda t: "/".join(f"{x:.2f}" for x in t)  # noqa: E731
    head = [
        "# Start-up: `--help` and a one-off `plan --method nlp` as whole processes (issue 31)",
        "", f"Command: `{res['command']}`  ",
        f"Machine: {m['platform']}, {m['cpus']} CPUs, Python {m['python']}, {m['date']}; "
        f"load average (1/5/15 min) {load(m['load_before'])} before, "
        f"{load(m['load_after'])} after (shared with other sessions).  ",
        "Judge: wall clocks taken by the benchmark around each subprocess (the whole process: "
        "interpreter, imports, work, exit). "
        + ("The project's bytecode compiled once beforehand (as an installed package has it)."
           if res["bytecode"] else "No bytecode of the project: every process compiles it."),
        "",
        "## `crane-planner --help`", "",
        f"Median **{f3(h['median_s'])} s** over {len(h['wall_s'])} runs (min {f3(h['min_s'])}"
        f" s; target ≤ 0.5 s on a quiet machine); its CPU time (user + system) median "
        f"{f3(h['cpu_median_s'])} s; the interpreter alone (`python -c pass`, interleaved) "
        f"{f3(h['bare_median_s'])} s wall. Its imports (one `-X importtime` run): "
        f"{f3(h['imports']['total_s'])} s in all, none of numpy, scipy, CasADi, matplotlib, "
        "Exudyn, Dask, toppra, Ruckig, h5py (tests/test_startup.py)."]
    if "before" in h:
        head[-1] += (f" The same command from `{h['before']}` (before this change), in the same "
                     f"rounds: median {f3(h['before_median_s'])} s.")
    return "\n".join(head + (["", *plan_report(res)] if "plan" in res else []))


def plan_report(res: dict) -> list:
    p, o, op = res["plan"], res["opti"], res["opti_planner"]
    heavy = ", ".join(f"{k} {v:.3f} s" for k, v in p["imports"]["heaviest"].items())
    return [
        "## A one-off `plan --method nlp`, NLP cache hit", "",
        f"Move {res['move']['crane']} {res['move']['start']} -> {res['move']['goal']}, "
        f"N = {res['move']['N']}, minimum time, free path, pump on; cache "
        f"{', '.join(map(str, p['nlp_cache']))} in every call (compiled once before: "
        f"{res['compile_call']['nlp_cache']}); durations {p['durations']}. "
        f"{len(p['wall_s'])} interleaved rounds.", "",
        "| process | wall median [s] | of which inside (build + solve) [s] |",
        "| --- | ---: | ---: |",
        f"| `crane-planner plan … --method nlp --json -` | {f3(p['median_s'])} | "
        f"{f3(p['inside_median_s'])} (the plan's own build_time_s + solve_time_s) |",
        f"| plain Opti (CasADi + numpy only) | {f3(o['median_s'])} | "
        f"{f3(o['build_solve_median_s'])} |",
        f"| plain Opti importing the planner for the machine (bench_nlp_cache.py's) | "
        f"{f3(op['median_s'])} | {f3(op['build_solve_median_s'])} |", "",
        f"Plan / plain Opti, pair by pair: median **{res['ratio_plain_median']:.2f}×** (min "
        f"{min(res['ratio_plain']):.2f}, max {max(res['ratio_plain']):.2f}; target ≤ 1.5×); "
        f"against the Opti process that imports the planner: "
        f"{res['ratio_planner_median']:.2f}× (min {min(res['ratio_planner']):.2f}, max "
        f"{max(res['ratio_planner']):.2f}). By CPU time (user + system of each process, less "
        f"sensitive to the other work on the machine): plan {f3(p['cpu_median_s'])} s, plain "
        f"Opti {f3(o['cpu_median_s'])} s, ratio median {res['ratio_cpu_median']:.2f}× (min "
        f"{min(res['ratio_cpu']):.2f}, max {max(res['ratio_cpu']):.2f})."
        + (f" The same plan from `{res['plan_before']['dir']}` (before this change), in the "
           f"same rounds: median {f3(res['plan_before']['median_s'])} s wall, "
           f"{f3(res['plan_before']['cpu_median_s'])} s CPU, "
           f"**{res['plan_before']['ratio_median']:.2f}×** the plain Opti (NLP cache "
           f"{', '.join(res['plan_before']['nlp_cache'])}; durations "
           f"{res['plan_before']['durations']})." if "plan_before" in res else ""), "",
        f"Imports of the plan process (one `-X importtime` run): {f3(p['imports']['total_s'])}"
        f" s in all; the heaviest top-level ones: {heavy}.", "",
        "The plain Opti has no pump limit and no model; the plan also reads the machine, "
        "computes its lower bound and first guess, checks the result on a 1 kHz resampling "
        "(evaluate()) and prints JSON (benchmarks/results/nlp_cache.md for the in-process "
        "split)."]


if __name__ == "__main__":
    sys.exit(main())
