"""Twin vs Exudyn on the four machines (issue 27, item 1): agreement and the twin's speed.

Each machine runs the same commands on the Exudyn plant (the judge, its default step) and on
the dynamic twin (its default step, and a finer one to separate discretisation from physics):

* ``slow``: the 50 Hz feed-forward of a Ruckig rest-to-rest move at 40 % of the limits between
  two poses a third of each joint range apart, plus 2 s of rest with the valves closed;
* ``fast``: the same move at 100 % of the limits, plus 2 s of rest;
* ``step``: valve steps — the boom at +0.6 for 0.8 s, then every joint at ±1 for 0.4 s (the
  pump saturates), then closed for 2 s.

Reported per run: the largest tip distance between the two over the run and at the end [mm]
(tip = the model's forward kinematics of each plant's joints), the largest chamber-pressure
difference as a share of that chamber's range on Exudyn over the run (range at least 1 MPa),
the largest rest-pressure difference [MPa] at the end, and the twin's CPU time per simulated
second on one core (``time.process_time`` of a run with the compiled step already loaded).

    python benchmarks/bench_twin.py [--machines cat215b,...] [--out benchmarks/results/twin_validation.md]
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from planner.feedforward import commands
from planner.methods.ruckig import rest_to_rest
from planner.model import Crane
from planner.model.twin import Twin
from planner.simulation.dynamic.exudyn_plant import ExudynPlant

MACHINES = ["cat215b", "cranab850", "s100f", "umea-lab"]
REST = 2.0


def poses(crane):
    L = crane.limit_arrays()
    span = L["q_max"] - L["q_min"]
    return L["q_min"] + 0.35 * span, L["q_min"] + 0.68 * span


def planned(crane, scale):
    qa, qb = poses(crane)
    res = rest_to_rest(crane, qa, qb, scale=scale)
    assert res.ok, res.reason
    ff = commands(crane, res.trajectory, 50.0)
    t_u = ff.t - ff.t[0]
    u = np.vstack([ff.u, np.zeros((1, crane.n))])
    t_u = np.append(t_u, t_u[-1] + 0.02)
    return t_u, u, qa, t_u[-1] + REST


def steps(crane):
    qa, _ = poses(crane)
    t_u = np.arange(0.0, 1.2, 0.02)
    u = np.zeros((len(t_u), crane.n))
    u[:40, 1] = 0.6
    u[40:60] = np.where(np.arange(crane.n) % 2 == 0, 1.0, -1.0)
    t_u = np.append(t_u, 1.2)
    return t_u, np.vstack([u, np.zeros((1, crane.n))]), qa, 1.2 + REST


def compare(crane, ex, tw):
    t = ex.t
    q = np.column_stack([np.interp(t, tw.t, tw.q[:, i]) for i in range(crane.n)])
    pa = np.column_stack([np.interp(t, tw.t, tw.p_a[:, i]) for i in range(crane.n)])
    pb = np.column_stack([np.interp(t, tw.t, tw.p_b[:, i]) for i in range(crane.n)])
    d = np.linalg.norm(crane.fk(q) - crane.fk(ex.q), axis=1)
    rng_a = np.maximum(np.ptp(ex.p_a, axis=0), 1e6)
    rng_b = np.maximum(np.ptp(ex.p_b, axis=0), 1e6)
    share = max(np.max(np.abs(pa - ex.p_a) / rng_a), np.max(np.abs(pb - ex.p_b) / rng_b))
    rest = max(np.max(np.abs(pa[-1] - ex.p_a[-1])), np.max(np.abs(pb[-1] - ex.p_b[-1])))
    return dict(tip_max_mm=1e3 * float(d.max()), tip_end_mm=1e3 * float(d[-1]),
                p_share=float(share), rest_dp_MPa=float(rest) / 1e6)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machines", default=",".join(MACHINES))
    ap.add_argument("--out", default="benchmarks/results/twin_validation.md")
    ap.add_argument("--fine", type=float, default=5e-4, help="the finer twin step [s]")
    a = ap.parse_args(argv)
    rows, speed = [], []
    for cid in a.machines.split(","):
        crane = Crane.from_id(cid)
        tw, twf = Twin(crane), Twin(crane, step=a.fine)
        ex = ExudynPlant(crane)
        for name, (t_u, u, q0, t_end) in (("slow", planned(crane, 0.4)),
                                          ("fast", planned(crane, 1.0)),
                                          ("step", steps(crane))):
            c0 = time.process_time()
            r = tw.simulate(t_u, u, q0, t_end=t_end)
            cpu = time.process_time() - c0
            rf = twf.simulate(t_u, u, q0, t_end=t_end)
            e = ex.integrate(t_u, u, q0, t_end=t_end)
            row = dict(machine=cid, move=name, duration_s=float(t_end), twin_ok=r.ok,
                       exudyn_ok=e.ok, twin_cpu_s=cpu, realtime=float(t_end) / cpu,
                       refined_chunks=int(tw.stepper.refined))
            row.update(compare(crane, e, r))
            row["fine"] = compare(crane, e, rf)
            rows.append(row)
            speed.append((float(t_end), cpu))
            print(json.dumps(row), flush=True)
    total_t, total_cpu = sum(s[0] for s in speed), sum(s[1] for s in speed)
    out = Path(a.out)
    lines = [
        "# Dynamic twin vs the Exudyn plant (issue 27, item 1)", "",
        f"Produced by `python benchmarks/bench_twin.py --machines {a.machines}` on "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.node()} "
        f"({platform.machine()}, Python {platform.python_version()}); CPU times are "
        "`time.process_time` of one process (one core), the compiled step loaded.", "",
        "Same spec parameters, same 50 Hz commands, from rest at the same pose. Tip: distance "
        "between the two plants' tips (the model's forward kinematics of each one's joints); "
        "p: the largest chamber-pressure difference as a share of that chamber's range on "
        "Exudyn (at least 1 MPa); rest Δp: the largest chamber-pressure difference at the end "
        "(after 2 s with the valves closed). Twin at its default step of 2 ms (BDF2) and, in "
        f"brackets, at {a.fine * 1e3:g} ms; Exudyn at its default 2 ms.", "",
        "| machine | move | s | tip max [mm] | tip end [mm] | p [% range] | rest Δp [MPa] "
        "| twin × real time |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        f = r["fine"]
        lines.append(
            f"| {r['machine']} | {r['move']} | {r['duration_s']:.1f} | {r['tip_max_mm']:.1f} "
            f"({f['tip_max_mm']:.1f}) | {r['tip_end_mm']:.1f} ({f['tip_end_mm']:.1f}) | "
            f"{100 * r['p_share']:.1f} ({100 * f['p_share']:.1f}) | {r['rest_dp_MPa']:.2f} "
            f"({f['rest_dp_MPa']:.2f}) | {r['realtime']:.0f} |")
    lines += ["", f"Twin speed over all runs: {total_t:.1f} s simulated in {total_cpu:.2f} s "
              f"CPU = **{total_t / total_cpu:.0f}× real time** on one core (a 10 s move: "
              f"{10 * total_cpu / total_t:.3f} s).", ""]
    out.write_text("\n".join(lines) + "\n")
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
