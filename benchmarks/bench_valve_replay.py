#!/usr/bin/env python3
"""The fast replay's cost and results with the valve model as compiled CasADi faces (issue 26:
the valve physics written once): per machine, 4 seeded Ruckig moves; for each, the
feed-forward at 50 Hz, three replays (nominal; gain +3 %, dead band 0.05, pump −40 %;
start offset and gain −10 %), the kinematic prediction and the library's robustness score
(the default perturbation set: ~30 replays). Times are CPU seconds of this process, best of
``--repeat``.

    python benchmarks/bench_valve_replay.py --save A.npz [--compare B.npz] [--out DIR]

Run it on two checkouts (before / after a change) with ``--save``, then once more with
``--compare`` naming the other's file: the report gives both timings and the largest
difference of every result (commands, flows, replayed joint positions, scores). ``--out``
writes <DIR>/valve_replay.md and .json.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from planner import Crane, PlanRequest, plan  # noqa: E402
from planner.feedforward import commands, predict_motion  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.simulation.replay import Plant, replay, robustness  # noqa: E402
from problems import crane_ids  # noqa: E402


def _moves(crane, rng, count=4):
    L = crane.limit_arrays()
    out = []
    while len(out) < count:
        q = L["q_min"] + (0.1 + 0.8 * rng.random((2, crane.n))) * (L["q_max"] - L["q_min"])
        tips = crane.tip(q)
        try:
            r = plan(crane, PlanRequest(tuple(tips[0]), tuple(tips[1])), method="ruckig")
        except Exception:      # an unreachable or unsupported draw: draw again
            continue
        if r.trajectory is not None:
            out.append(r.trajectory)
    return out


def _best(fn, repeat):
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def run(repeat: int):
    arrays, timing = {}, {}
    rng = np.random.default_rng(7)
    for cid in crane_ids():
        crane = Crane.from_id(cid)
        plants = [Plant(), Plant(flow_gain_scale=1.03, deadband=0.05, pump_flow_scale=0.6),
                  Plant(q0_offset=0.01 * np.ones(crane.n), flow_gain_scale=0.9)]
        t_rep, t_rob, t_ff = [], [], []
        for k, tr in enumerate(_moves(crane, rng)):
            ff = commands(crane, tr, 50.0)
            key = f"{cid}/{k}"
            arrays[f"{key}/u_raw"], arrays[f"{key}/flow"] = ff.u_raw, ff.flow
            for i, p in enumerate(plants):
                arrays[f"{key}/replay{i}"] = replay(crane, ff.t, ff.u, tr.q[0], p).q
            arrays[f"{key}/predict"] = predict_motion(crane, ff.t, ff.u, tr.q[0],
                                                      flow_scale=0.97, substeps=3).q
            arrays[f"{key}/score"] = np.array([robustness(crane, tr)["score_m"]])
            t_ff.append(_best(lambda: commands(crane, tr, 50.0), 3 * repeat))
            t_rep.append(_best(lambda: replay(crane, ff.t, ff.u, tr.q[0]), 3 * repeat))
            t_rob.append(_best(lambda: robustness(crane, tr), repeat))
        timing[cid] = dict(feedforward_ms=1e3 * np.median(t_ff), replay_ms=1e3 * np.median(t_rep),
                           robustness_ms=1e3 * np.median(t_rob))
    return arrays, timing


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--save", required=True, help="npz of this run's results and timings")
    ap.add_argument("--compare", help="npz of another checkout's run")
    ap.add_argument("--compare-label", default="other", help="what that run was, for the report")
    ap.add_argument("--out", help="directory for valve_replay.md / .json")
    a = ap.parse_args(argv)
    arrays, timing = run(a.repeat)
    np.savez(a.save, **arrays, _timing=np.array(dumps(timing)))
    rows = ["| machine | feed-forward ms | replay ms | robustness ms |"
            + (f" {a.compare_label}: feed-forward / replay / robustness ms |" if a.compare
               else ""),
            "| --- | --- | --- | --- |" + (" --- |" if a.compare else "")]
    other, diff = None, {}
    if a.compare:
        with np.load(a.compare) as z:
            import json
            other = json.loads(str(z["_timing"]))
            for k in arrays:
                kind = k.rsplit("/", 1)[1]
                diff[kind] = max(diff.get(kind, 0.0), float(np.max(np.abs(arrays[k] - z[k]))))
    for cid, t in timing.items():
        row = (f"| {cid} | {t['feedforward_ms']:.2f} | {t['replay_ms']:.2f} | "
               f"{t['robustness_ms']:.1f} |")
        if other:
            o = other[cid]
            row += (f" {o['feedforward_ms']:.2f} / {o['replay_ms']:.2f} / "
                    f"{o['robustness_ms']:.1f} |")
        rows.append(row)
    text = "\n".join(rows)
    if diff:
        text += f"\n\nLargest difference to {a.compare_label}: " + ", ".join(
            f"{k} {v:.2g}" for k, v in sorted(diff.items()))
    text += ("\n\nLoad average (1 min) at the end of this run: "
             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs.")
    print(text)
    if a.out:
        out = Path(a.out)
        atomic_write_text(out / "valve_replay.json", dumps(dict(
            timing=timing, other=other, other_label=a.compare_label, max_difference=diff)))
        atomic_write_text(out / "valve_replay.md", "# Fast replay with the compiled valve "
                          "faces (issue 26)\n\n" + __doc__.split("\n\n")[0] + "\n\n" + text
                          + "\n")


if __name__ == "__main__":
    main()
