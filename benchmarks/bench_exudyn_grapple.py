#!/usr/bin/env python3
"""The load swinging on its grapple link, on the Exudyn plant (issue 13): what each planning
method leaves swinging after arrival, and what the jerk limit buys for it. s100f.

    python benchmarks/bench_exudyn_grapple.py [--moves 8] [--length 1.5] [--zeta 0.05]
                                              [--settle 6] [--out benchmarks/results]

The moves and methods are those of ``bench_exudyn_claims.py`` part B (the forwarder cycle's
pick-up → drop and drop → pick-up moves over the headboard; ruckig, the time NLP and its jerk
sweep, TOPP-RA on the DP path, DP, the JLA and max-velocity laws). Every plan is replayed open
loop (its 50 Hz valve commands) on the Exudyn plant with the grapple and its load (880 kg) on
a passive two-axis link of ``--length`` m with ``--zeta`` of critical damping at its pins
(the ``grapple_swing`` effect). Measured from the tree's own kinematics: the load's horizontal
swing under the boom tip (during the move, its peak after arrival, what is left ``--settle`` s
after arrival), the tip's own residual oscillation beside it. Judge: the Exudyn plant.

Writes <out>/exudyn_grapple.md and .json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for p in (str(ROOT), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

from bench_exudyn_claims import method_runners, subset_suite  # noqa: E402
from planner import Crane  # noqa: E402
from planner.bench import runners as br  # noqa: E402
from planner.bench.context import Ctx, Settings  # noqa: E402
from planner.bench.suites import build_suite  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.model.dynamics_spec import GYRATION  # noqa: E402
from planner.model.effects import make  # noqa: E402
from planner.simulation.dynamic.claims import replay_move  # noqa: E402
from planner.simulation.dynamic.exudyn_plant import ExudynPlant  # noqa: E402
from planner.simulation.dynamic.grapple import link_frames  # noqa: E402

TOL_M = 0.005


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def load_swing(plant, run, length):
    """(K,) horizontal distance [m] of the load's centre of mass from under the boom tip."""
    n = plant.crane.n
    _, links = link_frames(plant.tree, np.hstack([run.q, run.grapple_q]))
    com = (links[-1] @ np.array([length, 0.0, 0.0, 1.0]))[:, :3]
    return np.linalg.norm(com[:, :2] - links[n][:, :2, 3], axis=1)


def measure(plant, run, t_arrive, length, settle):
    s = load_swing(plant, run, length)
    during, after = run.t <= t_arrive, run.t >= t_arrive
    end = run.t >= t_arrive + settle - 1.0        # the last second of the record
    return dict(swing_during_m=float(s[during].max()), swing_after_m=float(s[after].max()),
                swing_left_m=float(s[end].max()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moves", type=int, default=8)
    ap.add_argument("--length", type=float, default=1.5, help="link length [m]")
    ap.add_argument("--zeta", type=float, default=0.05, help="pin damping, share of critical")
    ap.add_argument("--settle", type=float, default=6.0, help="valves closed after arrival [s]")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--work", type=Path, default=Path(os.environ.get("TMPDIR", "/tmp"))
                    / "crane-grapple")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    crane = Crane.from_id("s100f")
    m_load = crane.spec.payload.total
    I = args.length ** 2 + GYRATION ** 2
    omega = np.sqrt(crane.spec.gravity * args.length / I)
    damping = 2 * args.zeta * m_load * I * omega
    effect = make("grapple_swing", length=args.length, damping=round(damping, 1))
    plant = ExudynPlant(crane, [effect])
    args.work.mkdir(parents=True, exist_ok=True)
    st = Settings(forwarder_moves=10 ** 6)
    suite = build_suite(str(subset_suite(args.work / "forwarder-cycle-claims.toml")), st)
    ctx = Ctx(crane, st, suite)
    moves = []
    for first in ("p", "d"):
        ms = sorted((m for m in suite.moves if m.id.startswith(first)), key=lambda m: m.id)
        want = args.moves // 2 if first == "p" else args.moves - args.moves // 2
        moves += [ms[int(i)] for i in np.linspace(0, len(ms) - 1, want).round()]
    rows = []
    for name, (run_method, jerk) in method_runners(ctx).items():
        for mv in moves:
            try:
                o = run_method(ctx, mv)
            except Exception as e:            # a method's failure is a row, not a crash
                o = br.Outcome("error", f"{type(e).__name__}: {e}")
            row = dict(method=name, move=mv.id, jerk_limited=jerk, status=o.status)
            if o.ok:
                tr = o.pieces[0][1]
                m, run, _ = replay_move(crane, tr, settle=args.settle, tol=TOL_M, plant=plant,
                                        keep_runs=True)
                row.update(duration_s=float(tr.duration), status=m.status)
                if m.status == "ok":
                    row.update(tip_osc_m=m.exudyn["peak_osc_m"],
                               **measure(plant, run, float(tr.duration), args.length,
                                         args.settle))
            rows.append(row)
            log(f"{name:20s} {mv.id:28s} {row['status']:8s} "
                + (f"T={row['duration_s']:.2f} s swing after {row['swing_after_m'] * 1e3:.0f} mm"
                   if "swing_after_m" in row else ""))
    res = dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=list(os.getloadavg())),
               args={k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
               effect=dict(effect.values), pendulum_hz=float(omega / (2 * np.pi)),
               moves=[m.id for m in moves], rows=rows, wall_s=time.perf_counter() - t_start)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "exudyn_grapple.json", dumps(res))
    atomic_write_text(args.out / "exudyn_grapple.md", "\n".join(markdown(res)))
    log(f"wrote {args.out / 'exudyn_grapple.md'} ({res['wall_s'] / 60:.1f} min)")


def markdown(res) -> list:
    a, rows = res["args"], res["rows"]
    ok = [r for r in rows if "swing_after_m" in r]
    L = ["# The load swinging on its grapple link, on the Exudyn plant (issue 13)", "",
         f"{res['date']}, {res['machine']['platform']}, {res['machine']['cpus']} CPUs, load "
         f"{res['machine']['load'][0]:.1f}. `python benchmarks/bench_exudyn_grapple.py --moves "
         f"{a['moves']} --length {a['length']:g} --zeta {a['zeta']:g} --settle {a['settle']:g}` "
         f"({res['wall_s'] / 60:.1f} min). s100f with its 880 kg grapple + load on a passive "
         f"two-axis link of {a['length']:g} m ({res['effect']['damping']:.0f} N·m·s/rad at "
         f"each pin, {a['zeta'] * 100:g} % of critical; pendulum {res['pendulum_hz']:.2f} Hz); "
         f"{len(res['moves'])} forwarder moves over the headboard, every plan's 50 Hz valve "
         "commands replayed open loop. Swing: the horizontal distance of the load's centre "
         f"of mass from under the boom tip; 'left': its peak in the last second of the "
         f"{a['settle']:g} s after arrival with the valves closed. Judge: the Exudyn plant.",
         "", "| method | jerk-limited | ok / moves | duration s (median) | swing during move mm "
         "(median / max) | swing after arrival mm (median / max) | swing left mm (median / "
         "max) | tip residual oscillation mm (median) |",
         "| --- | --- | ---: | ---: | --- | --- | --- | ---: |"]
    for name in dict.fromkeys(r["method"] for r in rows):
        rs = [r for r in ok if r["method"] == name]
        n = sum(r["method"] == name for r in rows)
        if not rs:
            L.append(f"| {name} | | 0 / {n} | | | | | |")
            continue

        def mm(k):
            v = np.array([r[k] for r in rs]) * 1e3
            return f"{np.median(v):.0f} / {v.max():.0f}"
        L.append(f"| {name} | {'yes' if rs[0]['jerk_limited'] else 'no'} | {len(rs)} / {n} | "
                 f"{np.median([r['duration_s'] for r in rs]):.2f} | {mm('swing_during_m')} | "
                 f"{mm('swing_after_m')} | {mm('swing_left_m')} | "
                 f"{np.median([r['tip_osc_m'] for r in rs]) * 1e3:.0f} |")
    # paired: each method against the time NLP on the moves both replayed
    by = {}
    for r in ok:
        by.setdefault(r["method"], {})[r["move"]] = r
    L += ["", "Paired with the time NLP on the same moves (median of the per-move ratios):", "",
          "| method | moves | duration ratio | swing after arrival ratio | lower swing than NLP |",
          "| --- | ---: | ---: | ---: | ---: |"]
    for name, d in by.items():
        if name == "nlp":
            continue
        common = sorted(set(d) & set(by.get("nlp", {})))
        if not common:
            continue
        tr = np.median([d[m]["duration_s"] / by["nlp"][m]["duration_s"] for m in common])
        sr = np.median([d[m]["swing_after_m"] / max(by["nlp"][m]["swing_after_m"], 1e-6)
                        for m in common])
        lo = sum(d[m]["swing_after_m"] < by["nlp"][m]["swing_after_m"] for m in common)
        L.append(f"| {name} | {len(common)} | {tr:.2f} | {sr:.2f} | {lo} / {len(common)} |")
    return L + [""]


if __name__ == "__main__":
    main()
