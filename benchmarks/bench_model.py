#!/usr/bin/env python3
"""Speed of the model foundation: build, kinematics, evaluate(), batched IK, lower bound.

    python benchmarks/bench_model.py [--out benchmarks/results]

For every shipped machine (planner.problems.crane_ids()) this measures

a) model build time ``Crane(load_spec(path))`` (includes compiling the stroke map, which the
   constructor uses for its actuator checks) and the first-call (compile) time of the numeric
   functions behind ``kinematics``, ``hydraulics``, ``tip`` and ``potential_energy``;
b) ``crane.kinematics(q)`` (FK + Jacobian + stroke map) for ONE configuration, timeit-style
   (loops of 2000 calls, 7 repeats; median and min per call)        target ≤ 50 µs;
c) ``evaluate(crane, traj, rate=1000)`` of a 10 s rest-to-rest minimum-jerk joint move sampled
   at 100 Hz (median of 15 after one warm-up)                        target ≤ 50 ms;
d) ``crane.ik_batch`` on 10 000 random reachable tips (µs per point);
e) ``lower_bound(crane, start_tip, goal_tip)`` for one move (ms).

(b) and (c) are repeated with the CasADi JIT disabled (CRANE_PLANNER_JIT=0) in a child process
(this script re-invoked with --no-jit-child; it prints its JSON on one stdout line).

Writes <out>/model_speed.json and <out>/model_speed.md (atomically) and prints the table.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
import timeit
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(ROOT) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from planner.bounds import lower_bound  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.model import Crane  # noqa: E402
from planner.model.spec import load_spec  # noqa: E402
from planner.trajectory import Trajectory, evaluate  # noqa: E402
from planner.problems import crane_ids, crane_path  # noqa: E402

SEED = 20240611
KIN_NUMBER, KIN_REPEAT = 2000, 7       # (b) timeit loops
EVAL_REPEAT = 15                       # (c) timed runs after one warm-up
EVAL_DURATION, EVAL_SAMPLE_RATE, EVAL_RATE = 10.0, 100.0, 1000.0
IK_POINTS, IK_REPEAT = 10_000, 7       # (d)
BOUND_REPEAT = 7                       # (e) timed runs after one warm-up
BUILD_REPEAT = 3                       # (a) fresh builds (each compiles the stroke map)
TARGET_KIN_US = 50.0
TARGET_EVAL_MS = 50.0
CHILD_FLAG = "--no-jit-child"
CHILD_TAG = "BENCH_MODEL_JSON:"


# ---------------------------------------------------------------------------------- helpers
def _limits(crane):
    return np.array([j.limits.q for j in crane.spec.joints], dtype=float)


def _at_fraction(crane, frac):
    lim = _limits(crane)
    return lim[:, 0] + frac * (lim[:, 1] - lim[:, 0])


def _stats(samples, scale=1.0, digits=3):
    s = [x * scale for x in samples]
    return dict(median=round(statistics.median(s), digits), min=round(min(s), digits),
                max=round(max(s), digits), n=len(s))


def _min_jerk_trajectory(crane, q0, q1, duration=EVAL_DURATION, rate=EVAL_SAMPLE_RATE):
    """Rest-to-rest quintic q0 -> q1: s(τ) = 10τ³ − 15τ⁴ + 6τ⁵, sampled at ``rate`` Hz."""
    t = np.linspace(0.0, duration, int(round(duration * rate)) + 1)
    tau = (t / duration)[:, None]
    dq = (q1 - q0)[None, :]
    s = tau ** 3 * (10 - 15 * tau + 6 * tau ** 2)
    sd = 30 * tau ** 2 * (1 - tau) ** 2 / duration
    sdd = 60 * tau * (1 - 3 * tau + 2 * tau ** 2) / duration ** 2
    return Trajectory(t=t, q=q0[None, :] + s * dq, qd=sd * dq, qdd=sdd * dq,
                      joint_names=tuple(crane.names), method="bench-min-jerk")


def _time_kinematics(crane, q):
    crane.kinematics(q)  # compiled already, make sure
    per_call = [x / KIN_NUMBER for x in
                timeit.repeat(lambda: crane.kinematics(q), number=KIN_NUMBER, repeat=KIN_REPEAT)]
    out = _stats(per_call, 1e6, 2)
    out.update(number=KIN_NUMBER, repeat=KIN_REPEAT)
    return out


def _time_evaluate(crane):
    traj = _min_jerk_trajectory(crane, _at_fraction(crane, 0.3), _at_fraction(crane, 0.7))
    ev = evaluate(crane, traj, rate=EVAL_RATE)  # warm-up
    times = []
    for _ in range(EVAL_REPEAT):
        t0 = time.perf_counter()
        evaluate(crane, traj, rate=EVAL_RATE)
        times.append(time.perf_counter() - t0)
    out = _stats(times, 1e3, 3)
    out.update(repeat=EVAL_REPEAT, input_samples=int(traj.t.size), fine_samples=int(ev.t.size),
               max_limit_violation=ev.max_limit_violation, energy_J=round(ev.energy_J, 3))
    return out


def _first_call(fn):
    t0 = time.perf_counter()
    fn()
    return round(time.perf_counter() - t0, 4)


# ---------------------------------------------------------------------------------- benchmarks
def bench_crane(crane_id, rng, full=True):
    """All measurements for one machine; ``full=False`` only (a) build, (b) and (c)."""
    path = crane_path(crane_id)
    builds = []
    for _ in range(BUILD_REPEAT if full else 1):
        t0 = time.perf_counter()
        crane = Crane(load_spec(path))
        builds.append(time.perf_counter() - t0)
    res = dict(n_joints=crane.n, joints=list(crane.names))
    res["build_s"] = dict(first=round(builds[0], 4), **_stats(builds, 1.0, 4))

    q_mid = _at_fraction(crane, 0.5)
    res["first_call_s"] = first = dict(
        kinematics=_first_call(lambda: crane.kinematics(q_mid)),
        hydraulics=_first_call(lambda: crane.hydraulics(q_mid, 0 * q_mid, 0 * q_mid)))
    if full:
        first["tip"] = _first_call(lambda: crane.tip(q_mid))
        first["potential_energy"] = _first_call(lambda: crane.potential_energy(q_mid))
    res["jit_active"] = crane.numeric_status()

    res["kinematics_us"] = _time_kinematics(crane, q_mid)
    res["evaluate_ms"] = _time_evaluate(crane)
    if not full:
        return res

    # (d) batched IK on tips of random in-limit configurations, with their telescope values
    lim = _limits(crane)
    Q = lim[:, 0] + rng.random((IK_POINTS, crane.n)) * (lim[:, 1] - lim[:, 0])
    tips = crane.tip(Q)
    tele = Q[:, crane.chain.tele] if crane.chain.tele is not None else None
    q_ik, reason = crane.ik_batch(tips, tele)  # warm-up + correctness
    times = []
    for _ in range(IK_REPEAT):
        t0 = time.perf_counter()
        crane.ik_batch(tips, tele)
        times.append(time.perf_counter() - t0)
    ok = reason == ""
    tip_err = np.abs(crane.tip(q_ik[ok]) - tips[ok]) if ok.any() else np.zeros((0, 3))
    tip_err[:, 2] = np.abs((tip_err[:, 2] + np.pi) % (2 * np.pi) - np.pi)  # slew is an angle
    res["ik"] = dict(points=IK_POINTS, repeat=IK_REPEAT,
                     us_per_point=_stats([t / IK_POINTS for t in times], 1e6, 3),
                     batch_ms=_stats(times, 1e3, 3),
                     solved_fraction=round(float(ok.mean()), 4),
                     same_configuration_fraction=round(float(np.mean(
                         ok & np.all(np.abs(np.nan_to_num(q_ik) - Q) < 1e-6, axis=1))), 4),
                     max_tip_roundtrip_error=float(tip_err.max()) if tip_err.size else None,
                     note="unsolved = the random configuration lies on the elbow branch that "
                          "the spec excludes (or its mirror leaves the joint limits)")

    # (e) lower bound for one move: tips of the 30 % and 70 % configurations
    start, goal = crane.tip(_at_fraction(crane, 0.3)), crane.tip(_at_fraction(crane, 0.7))
    first["lower_bound"] = _first_call(lambda: lower_bound(crane, start, goal))
    lb = lower_bound(crane, start, goal)
    times = []
    for _ in range(BOUND_REPEAT):
        t0 = time.perf_counter()
        lower_bound(crane, start, goal)
        times.append(time.perf_counter() - t0)
    res["bound_ms"] = dict(**_stats(times, 1e3, 3), repeat=BOUND_REPEAT,
                           start_tip=start.round(6).tolist(), goal_tip=goal.round(6).tolist(),
                           result={k: (round(v, 6) if isinstance(v, float) else v)
                                   for k, v in lb.as_dict().items()})
    return res


def run_child():
    """--no-jit-child: (b) and (c) only, one JSON line on stdout."""
    rng = np.random.default_rng(SEED)
    out = dict(env_CRANE_PLANNER_JIT=os.environ.get("CRANE_PLANNER_JIT"),
               cranes={cid: bench_crane(cid, rng, full=False) for cid in crane_ids()})
    sys.stdout.write(CHILD_TAG + json.dumps(out) + "\n")
    sys.stdout.flush()


def run_no_jit_child():
    env = dict(os.environ, CRANE_PLANNER_JIT="0")
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, str(Path(__file__).resolve()), CHILD_FLAG],
                       env=env, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - t0
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith(CHILD_TAG)]
    if p.returncode != 0 or not lines:
        sys.stderr.write(p.stderr)
        raise RuntimeError(f"the no-JIT child failed (exit {p.returncode}); stderr above")
    data = json.loads(lines[-1][len(CHILD_TAG):])
    data["wall_s"] = round(wall, 2)
    return data


# ---------------------------------------------------------------------------------- report
def machine_facts():
    import casadi
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass  # no /proc/cpuinfo (not Linux): the CPU model stays unknown
    return dict(platform=platform.platform(), python=platform.python_version(),
                python_implementation=platform.python_implementation(), cpu=cpu,
                cpu_count=os.cpu_count(), casadi=casadi.__version__, numpy=np.__version__,
                env_CRANE_PLANNER_JIT=os.environ.get("CRANE_PLANNER_JIT"),
                loadavg_end=[round(x, 2) for x in os.getloadavg()],
                date=datetime.now(timezone.utc).isoformat(timespec="seconds"))


def verdicts(results):
    out = {}
    for key, metric, target, unit in (("kinematics", "kinematics_us", TARGET_KIN_US, "µs"),
                                      ("evaluate", "evaluate_ms", TARGET_EVAL_MS, "ms")):
        per = {cid: r[metric]["median"] for cid, r in results.items()}
        best = {cid: r[metric]["min"] for cid, r in results.items()}
        worst = max(per, key=per.get)
        out[key] = dict(target=target, unit=unit, per_crane=per, per_crane_min=best, worst=worst,
                        worst_value=per[worst], worst_min=best[worst],
                        per_crane_pass={c: v <= target for c, v in per.items()},
                        passed=all(v <= target for v in per.values()))
    return out


def markdown(report):
    res, nj = report["cranes"], report["no_jit"]["cranes"]
    m = report["machine"]
    lines = [
        "# Model speed",
        "",
        f"{m['date']} · {m['platform']} · {m['cpu']} ({m['cpu_count']} CPUs) · Python "
        f"{m['python']} · CasADi {m['casadi']} · NumPy {m['numpy']} · seed {report['settings']['seed']}",
        "",
        "| machine | build s | kinematics µs (median) | evaluate 10 s @1 kHz ms | IK µs/pt "
        "| bound ms | evaluate without JIT ms |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for cid, r in res.items():
        lines.append(
            f"| {cid} | {r['build_s']['median']:.3f} | {r['kinematics_us']['median']:.1f} "
            f"| {r['evaluate_ms']['median']:.1f} | {r['ik']['us_per_point']['median']:.2f} "
            f"| {r['bound_ms']['median']:.2f} | {nj[cid]['evaluate_ms']['median']:.1f} |")
    lines.append("")
    v = report["verdicts"]
    for key, label in (("kinematics", "kinematics(q) (FK + Jacobian + stroke map, one "
                                      "configuration, median)"),
                       ("evaluate", "evaluate() of a 10 s trajectory at 1 kHz (median)")):
        d = v[key]
        lines.append(f"- Target {label} ≤ {d['target']:g} {d['unit']}: "
                     f"**{'PASS' if d['passed'] else 'FAIL'}** (worst {d['worst']} "
                     f"{d['worst_value']:.1f} {d['unit']}, its fastest repeat "
                     f"{d['worst_min']:.1f} {d['unit']})")
    nk = {c: r["kinematics_us"]["median"] for c, r in nj.items()}
    lines += [
        f"- Load average before / after the run (1 min): {m['loadavg_start'][0]} / "
        f"{m['loadavg_end'][0]} on {m['cpu_count']} CPUs (the run itself adds up to ≈ 1; other "
        "processes on the host inflate the medians; the fastest repeats are in the JSON).",
        "",
        "Without JIT (CRANE_PLANNER_JIT=0, informational): kinematics µs (median) "
        + ", ".join(f"{c} {x:.1f}" for c, x in nk.items()) + ".",
        "",
        "Build = `Crane(load_spec(path))`, median of "
        f"{report['settings']['build_repeat']} fresh builds (includes the JIT compile of the "
        "stroke map used by the constructor's actuator checks). First-call (compile) times are "
        "in model_speed.json. kinematics: timeit loops of "
        f"{KIN_NUMBER} calls × {KIN_REPEAT}; evaluate: median of {EVAL_REPEAT} after a warm-up "
        f"({EVAL_SAMPLE_RATE:g} Hz min-jerk move 30 % → 70 % of every joint range, resampled to "
        f"{EVAL_RATE:g} Hz); IK: {IK_POINTS} tips of random in-limit configurations (their "
        "telescope values given); bound: `lower_bound` between the tips of the 30 % and 70 % "
        "configurations.",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE / "results",
                    help="output folder (default: benchmarks/results)")
    ap.add_argument(CHILD_FLAG, action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.no_jit_child:
        run_child()
        return 0

    t_start = time.perf_counter()
    load_start = [round(x, 2) for x in os.getloadavg()]
    rng = np.random.default_rng(SEED)
    results = {}
    for cid in crane_ids():
        print(f"[bench_model] {cid} ...", file=sys.stderr, flush=True)
        results[cid] = bench_crane(cid, rng)
    print("[bench_model] no-JIT child (CRANE_PLANNER_JIT=0) ...", file=sys.stderr, flush=True)
    no_jit = run_no_jit_child()

    report = dict(
        schema="crane-planner/model_speed/1",
        machine=dict(machine_facts(), loadavg_start=load_start),
        settings=dict(seed=SEED, build_repeat=BUILD_REPEAT, kinematics_number=KIN_NUMBER,
                      kinematics_repeat=KIN_REPEAT, evaluate_repeat=EVAL_REPEAT,
                      evaluate_duration_s=EVAL_DURATION, evaluate_input_rate_hz=EVAL_SAMPLE_RATE,
                      evaluate_rate_hz=EVAL_RATE, ik_points=IK_POINTS, ik_repeat=IK_REPEAT,
                      bound_repeat=BOUND_REPEAT),
        targets=dict(kinematics_us=TARGET_KIN_US, evaluate_ms=TARGET_EVAL_MS),
        cranes=results,
        no_jit=no_jit,
    )
    report["verdicts"] = verdicts(results)
    report["verdicts_no_jit"] = verdicts(no_jit["cranes"])
    report["wall_s"] = round(time.perf_counter() - t_start, 2)

    md = markdown(report)
    atomic_write_text(args.out / "model_speed.json", dumps(report) + "\n")
    atomic_write_text(args.out / "model_speed.md", md)
    print(md)
    print(f"wrote {args.out / 'model_speed.json'} and {args.out / 'model_speed.md'} "
          f"({report['wall_s']:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
