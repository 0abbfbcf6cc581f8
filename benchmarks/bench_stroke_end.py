"""Stroke ends and the discrepancy workflow (issue 26, defect 2): is a recording that runs a
cylinder to its end read as well as one that stays clear of the ends?

Two sets of ``--n`` recordings each, paired (recording i of both sets: the same machine, seed,
duration and hidden effect):

* **through an end**: a test sequence whose first move takes every joint at full speed to one
  of its limits (the stroke ends, sides drawn from the seed), holds there, then the moves of
  :func:`planner.calibration.trials.excitation` (random poses in the inner 70 % of the ranges);
* **clear of the ends**: :func:`planner.calibration.trials.excitation` itself (its first move
  crosses only the inner range).

Each recording is made twice on the fast plant with seed 001's sensor noise: clean, and with one
hidden effect from the issue's list (joint offset, pressure offset, delay, Coulomb friction,
payload, dead band, flow gain, pump limit, leakage; recording i gets the (i mod 9)-th) at the
magnitude and on the joint the trials draw (:func:`planner.calibration.trials.draw`, i.e.
``Effect.trial``). Measured: the clean recordings read ``explained``, and the effect named
(``named`` with the right effect and joint, or ``ambiguous`` with the truth among the
candidates: ``judge`` of ``bench_discrepancy_open.py``). Both before (``--before REF``, default
``main``: its ``planner/`` exported by ``git archive`` into a temporary folder) and after (this
working tree). The judge is the fast quasi-static plant itself (the recordings are made with it):
nothing here speaks for unmodelled dynamics.

    python benchmarks/bench_stroke_end.py [--n 20] [--duration 30] [--workers 2] [--before main]

(``--before 47b5389``: main as the issue found it, this branch's base.)
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "stroke_end.md"
MACHINES = ("umea-lab", "cat215b", "s100f", "cranab850")
EFFECTS = ("joint_offset", "pressure_offset", "time_delay", "coulomb_friction", "payload_mass",
           "valve_deadband", "flow_gain", "pump_flow_limit", "leakage")


def through_end(crane, duration, seed, rate=50.0, margin=0.15):
    """(plan, feed-forward): full speed to the limits, a hold there, then the trials' moves."""
    from planner.calibration.trials import SequenceBuilder
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + margin * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - margin * (L["q_max"] - L["q_min"])
    b = SequenceBuilder(crane, 0.5 * (lo + hi), rate)
    b.hold(rng.uniform(0.5, 1.0))
    b.move(np.where(rng.uniform(size=crane.n) < 0.5, L["q_min"], L["q_max"]), 1.0)
    b.hold(rng.uniform(0.5, 2.0))
    while b.t_now < duration:
        b.move(rng.uniform(lo, hi), float(rng.uniform(0.3, 1.0)))
        b.hold(rng.uniform(0.5, 2.0))
    return b.finish(dict(seed=seed, duration=duration, through_end=True))


def case(i, kind, duration):
    """One paired recording: machine, seed and effect of index ``i``; ``kind`` its set."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from planner import Crane
    from planner.calibration.discrepancy import Discrepancy
    from planner.calibration.trials import TrialSequence, draw, excitation, record
    from planner.simulation.plant import respond
    from bench_discrepancy_open import judge
    machine, seed, name = MACHINES[i % len(MACHINES)], 100 + i, EFFECTS[i % len(EFFECTS)]
    crane = Crane.from_id(machine)
    plan, ff = (through_end if kind == "through" else excitation)(crane, duration, seed=seed)
    truth = draw(crane, name, np.random.default_rng(seed + 7919), None,
                 TrialSequence(crane, plan, ff))
    out = dict(i=i, kind=kind, machine=machine, seed=seed, effect=name, joint=truth.joint,
               values=truth.values, duration=float(plan.duration))
    L = crane.limit_arrays()
    out["plan_at_limit_s"] = float(np.sum(np.any((plan.q <= L["q_min"] + 1e-9) |
                                                 (plan.q >= L["q_max"] - 1e-9), axis=1))
                                   * float(np.median(np.diff(plan.t))))
    for label, effects in (("clean", ()), ("hidden", (truth,))):
        r = respond(crane, ff.t, ff.u, plan.q[0], effects, t_end=ff.t[-1])
        clipped = sum(b - a for v in r.meta["clipped"].values() for a, b in v)
        rec = record(crane, plan, ff, effects, seed=seed)
        t0 = time.perf_counter()
        res = Discrepancy(crane).fit(rec)
        o = dict(group="in" if effects else "clean", verdict=res.verdict, effect=res.effect,
                 joint=res.joint, candidates=[(c["effect"], c["joint"]) for c in res.candidates],
                 truth=dict(effect=name, joint=truth.joint))
        out[label] = dict(verdict=res.verdict, effect=res.effect, joint=res.joint,
                          candidates=o["candidates"], ok=judge(o)["ok"],
                          message=res.message[:200], plant_clipped_s=float(clipped),
                          runtime_s=time.perf_counter() - t0)
    return out


def run(args):
    """Every case on the ``planner`` this process imports (``--run``: a child of main())."""
    sys.path.insert(0, str(HERE))
    jobs = [(i, kind) for kind in ("through", "clear") for i in range(args.n)]
    rows = []
    with ProcessPoolExecutor(args.workers) as ex:
        futs = [ex.submit(case, i, kind, args.duration) for i, kind in jobs]
        for f in as_completed(futs):
            r = f.result()
            rows.append(r)
            print(f"  {r['kind']:7s} {r['i']:2d} {r['machine']:9s} {r['effect']:16s} clean "
                  f"{r['clean']['verdict']:11s} hidden {r['hidden']['verdict']:11s} "
                  f"ok={r['hidden']['ok']}", file=sys.stderr, flush=True)
    rows.sort(key=lambda r: (r["kind"], r["i"]))
    Path(args.rows).write_text(json.dumps(rows, indent=1, default=str))


def pct(a, b):
    return f"{100.0 * a / b:.0f} % ({a}/{b})" if b else "–"


def report(results, args, wall):
    L = ["# A clean recording through a stroke end (issue 26, defect 2)", "",
         f"`python benchmarks/bench_stroke_end.py --n {args.n} --duration {args.duration:g} "
         f"--workers {args.workers} --before {args.before}`"
         + (" (the two codes' rows run concurrently, each by the same command's `--run "
            "--rows FILE` with PYTHONPATH at that code, then `--from-rows BEFORE AFTER`)"
            if args.from_rows else "") + ", "
         f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.platform()}, "
         f"{os.cpu_count()} CPUs (shared), {wall / 60:.1f} min wall. Judge: the fast "
         "quasi-static plant (`planner.simulation.plant.respond`; the recordings are made with "
         "it, seed 001's sensor noise), so nothing here speaks for unmodelled dynamics.", "",
         f"{args.n} paired recordings of {args.duration:g} s per set, the machines "
         f"{', '.join(MACHINES)} in turn; *through an end*: the first move takes every joint "
         "to one of its limits at full speed and holds there; *clear*: the trials' own "
         "excitation (inner 70 % of every range). Recording i hides the (i mod 9)-th of "
         f"{', '.join(EFFECTS)}, drawn by `Effect.trial`. Effect named = `named` right "
         "(effect and joint) or `ambiguous` with the truth among the candidates.", "",
         "| code | set | clean `explained` | effect named | recordings the plant held at a stop "
         "(clean / hidden) |",
         "| --- | --- | ---: | ---: | ---: |"]
    for label, rows in results.items():
        for kind, name in (("through", "through an end"), ("clear", "clear of the ends")):
            sub = [r for r in rows if r["kind"] == kind]
            L.append(f"| {label} | {name} | "
                     f"{pct(sum(r['clean']['verdict'] == 'explained' for r in sub), len(sub))} | "
                     f"{pct(sum(r['hidden']['ok'] for r in sub), len(sub))} | "
                     f"{sum(r['clean']['plant_clipped_s'] > 0 for r in sub)} / "
                     f"{sum(r['hidden']['plant_clipped_s'] > 0 for r in sub)} |")
    L += ["", "## Every recording", "",
          "| code | set | i | machine | hidden | joint | clean verdict | hidden verdict | "
          "named | ok |", "| --- | --- | ---: | --- | --- | --- | --- | --- | --- | --- |"]
    for label, rows in results.items():
        for r in rows:
            h = r["hidden"]
            L.append(f"| {label} | {r['kind']} | {r['i']} | {r['machine']} | {r['effect']} | "
                     f"{r['joint'] or ''} | {r['clean']['verdict']} | {h['verdict']} | "
                     f"{(h['effect'] or '') + ('@' + h['joint'] if h['joint'] else '')} | "
                     f"{'yes' if h['ok'] else 'no'} |")
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=20, help="recordings per set (20)")
    ap.add_argument("--duration", type=float, default=30.0, help="seconds per recording (30)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--before", default="main",
                    help="git ref whose planner/ is the 'before' code ('' : none)")
    ap.add_argument("--run", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--rows", help=argparse.SUPPRESS)
    ap.add_argument("--from-rows", nargs=2, metavar=("BEFORE.json", "AFTER.json"),
                    help="write the report from rows already computed (each by a run with "
                         "--run --rows FILE on that code, e.g. concurrently on a busy machine)")
    ap.add_argument("--wall", type=float, default=0.0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.run:
        return run(args)
    t0 = time.perf_counter()
    results = {}
    if args.from_rows:
        for label, f in zip((f"before ({args.before})", "after (this tree)"), args.from_rows):
            results[label] = json.loads(Path(f).read_text())
        return write(results, args, args.wall)
    with tempfile.TemporaryDirectory() as tmp:
        codes = []
        if args.before:
            base = Path(tmp) / "before"
            base.mkdir()
            # the package and, where that version keeps them outside it, the machines
            paths = [p for p in ("planner", "problems") if subprocess.run(
                ["git", "-C", str(ROOT), "cat-file", "-e", f"{args.before}:{p}"]).returncode == 0]
            tar = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, *paths],
                                 check=True, capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", str(base)], input=tar, check=True)
            codes.append((f"before ({args.before})", base))
        codes.append(("after (this tree)", ROOT))
        for label, path in codes:
            rows = Path(tmp) / "rows.json"
            print(f"{label}: {path}", file=sys.stderr, flush=True)
            env = dict(os.environ, PYTHONPATH=str(path))
            subprocess.run([sys.executable, __file__, "--run", "--rows", str(rows), "--n",
                            str(args.n), "--duration", str(args.duration), "--workers",
                            str(args.workers)], env=env, check=True, cwd=tmp)
            results[label] = json.loads(rows.read_text())
    write(results, args, time.perf_counter() - t0)


def write(results, args, wall):
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.with_suffix(".json").write_text(json.dumps(results, indent=1, default=str))
    OUT.write_text(report(results, args, wall))
    print(OUT.read_text())


if __name__ == "__main__":
    main()
