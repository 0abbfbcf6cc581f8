#!/usr/bin/env python3
"""The tail of the pump-work ratio Exudyn / evaluate(): where and why the plant pays more
than the quasi-static model on the library entries that differ by more than 5 % (issue 30).

    python benchmarks/bench_energy_tail.py --rows benchmarks/results/energy_machine_X.json
                                           [--library LIB.h5] [--above 1.05] [--tag NAME]

Reads the per-entry rows of ``bench_energy_machine.py`` (its library, unless ``--library``
names one), takes the entries whose Exudyn/evaluate() pump work exceeds ``--above``, and for
each replays the stored 50 Hz commands on the Exudyn plant (3 s settle, as that bench) and on
the model's dynamic twin. Three judges, named on every number: **Exudyn** (the independent
plant), **evaluate()** (the quasi-static model, the machine pricing with the held pair),
**twin** (the model's dynamic twin, :class:`planner.model.twin.Twin`, the same commands).

Per entry:

* the excess pump work ∫ max(p_s − p_pump,plan, 0)·Q_pump dt (Exudyn's p_s and pump flow,
  evaluate()'s pump pressure at the same instant; the flow's own difference is reported
  apart: ∫ p_pump,plan·(Q_pump − Q_plan) dt), split by the function that sets the plant's LS
  pressure (the drawing valve with the highest meter-in pressure, by the judge's own rule:
  open past 10⁻⁶; none: standby) and by that function's phase in
  the plan: *accelerating* (q̇·q̈ > 0), *braking* (q̇·q̈ < 0), *cruising* (|q̈| under 5 % of
  its peak), *at rest* (|q̇| under 0.1 % of its peak: the plant moves where the plan stands);
* for the main setter, the excess-weighted mean of its meter-in and outlet pressures on the
  plant and in evaluate() (which pressure the pump pushes against), and its stroke-rate error
  on the plant (RMS over the plan, relative to its peak rate);
* the twin's pump work over evaluate()'s — as specified, and with one property changed at a
  time: the oil 30 × stiffer (bulk modulus: the oil-spring modes √30 × faster, but the held
  pair also bleeds 30 × faster, ṗ ∝ m·β), the oil 30 × stiffer with the return cap's margin
  m / 30 (the modes as fast, the held pair's bleed m·β as specified: only the ringing goes),
  the margin 10 × (the held pair bleeds 10 × faster), the spool 10 × faster. The change that
  brings the twin to evaluate()'s figure names the physics evaluate() lacks.

Writes <out>/energy_tail[_TAG].md and .json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for p in (str(ROOT), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

from planner import Crane, evaluate  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.methods.nlp.twin_judge import twin_pump_energy  # noqa: E402
from planner.model.twin import Twin  # noqa: E402
from planner.simulation.dynamic.claims import replay_move, stored_commands  # noqa: E402
from planner.simulation.dynamic.exudyn_plant import ExudynPlant  # noqa: E402

PHASES = ("accelerating", "cruising", "braking", "at rest")
#: the twin's variants: name -> the [dynamics] fields changed (factor on the spec's value)
VARIANTS = {"as specified": {}, "oil 30x stiffer": {"bulk_modulus": 30.0},
            "oil 30x stiffer, margin /30": {"bulk_modulus": 30.0, "meter_out_margin": 1 / 30},
            "margin 10x": {"meter_out_margin": 10.0}, "spool 10x faster":
            {"spool_time_constant": 0.1}}


def _integral(t, y):
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def phases(t_plan, qd, qdd, t):
    """Phase index (PHASES) of every joint of the plan at the times ``t`` (M, n)."""
    v = np.stack([np.interp(t, t_plan, qd[:, i], right=0.0) for i in range(qd.shape[1])], 1)
    a = np.stack([np.interp(t, t_plan, qdd[:, i], right=0.0) for i in range(qd.shape[1])], 1)
    vmax = np.maximum(np.abs(qd).max(0), 1e-12)
    amax = np.maximum(np.abs(qdd).max(0), 1e-12)
    ph = np.where(v * a > 0, 0, 2)
    ph = np.where(np.abs(a) < 0.05 * amax, 1, ph)
    return np.where(np.abs(v) < 1e-3 * vmax, 3, ph)


def anatomy(crane, traj, ev, run) -> dict:
    """The excess of the Exudyn run over the plan (module doc), in J and Pa."""
    C = run.circuit
    spool = np.vstack([run.spool[1:], run.spool[-1:]])   # the opening in force over a step
    o = C.opening(spool)
    fl = C.flows(run.p_a, run.p_b, run.p_s, o)
    Q = fl["q_in"].sum(axis=1)
    p_in = np.where(o > 0, run.p_a, run.p_b)
    p_out = np.where(o > 0, run.p_b, run.p_a)
    pl = fl["p_load"]                  # the judge's own LS rule: a valve open past 1e-6
    setter = np.where(pl.max(axis=1) > 0, np.argmax(pl, axis=1), -1)   # -1: standby
    t = run.t
    h = ev.hyd
    p_plan = np.interp(t, ev.t, h["p_pump"], right=0.0)
    q_plan = np.interp(t, ev.t, h["q_pump"], right=0.0)
    x = np.maximum(run.p_s - p_plan, 0.0) * Q
    ph = phases(ev.t, ev.qd, ev.qdd, t)[np.arange(len(t)), np.maximum(setter, 0)]
    n = crane.n
    by = np.array([[_integral(t, x * (setter == i) * (ph == k)) for k in range(len(PHASES))]
                   for i in range(n)])
    j = int(np.argmax(by.sum(1)))
    xd_plan = np.interp(t, ev.t, h["xd"][:, j], right=0.0)
    ext = np.where(o[:, j] != 0, o[:, j] > 0, xd_plan > 0)
    pa = np.interp(t, ev.t, h["p_a"][:, j], right=h["p_a"][-1, j])
    pb = np.interp(t, ev.t, h["p_b"][:, j], right=h["p_b"][-1, j])
    wj = x * (setter == j)
    w = wj / max(wj.sum(), 1e-30)
    k = t <= traj.duration
    qd_plan = np.interp(t[k], ev.t, ev.qd[:, j])
    err = np.sqrt(np.mean((run.qd[k, j] - qd_plan) ** 2)) / max(np.abs(ev.qd[:, j]).max(), 1e-12)
    return dict(excess_J=_integral(t, x), flow_diff_J=_integral(t, p_plan * (Q - q_plan)),
                by_setter_phase_J=by.tolist(), main_setter=j,
                main_p_in_exudyn=float(np.sum(w * p_in[:, j])),
                main_p_in_eval=float(np.sum(w * np.where(ext, pa, pb))),
                main_p_out_exudyn=float(np.sum(w * p_out[:, j])),
                main_p_out_eval=float(np.sum(w * np.where(ext, pb, pa))),
                main_rate_error=float(err))


def twins(crane) -> dict:
    dyn = crane.spec.dynamics
    out = {}
    for name, ch in VARIANTS.items():
        kw = {k: getattr(dyn, k) * f for k, f in ch.items()}
        out[name] = Twin(crane, dynamics=replace(dyn, **kw))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=Path, required=True, help="bench_energy_machine.py's json")
    ap.add_argument("--library", type=Path, help="default: the one that json names")
    ap.add_argument("--above", type=float, default=1.05, help="Exudyn/evaluate() threshold")
    ap.add_argument("--tag", default="")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    if not args.above > 0:
        raise SystemExit(f"--above: {args.above} is not a ratio; allowed: > 0")
    t_start = time.perf_counter()
    src = json.loads(args.rows.read_text())
    lib = args.library or Path(src["library"])
    tail = sorted((r for r in src["rows"] if r["status"] == "ok"
                   and r["w_exudyn_J"] > args.above * r["w_qs_J"]),
                  key=lambda r: -r["w_exudyn_J"] / r["w_qs_J"])
    crane = Crane.from_id("s100f")
    eta = crane.spec.pump.efficiency
    plant = ExudynPlant(crane)
    tw = twins(crane)
    rows = []
    with LibraryStore.open(lib) as store:
        for k, src_row in enumerate(tail):
            eid = src_row["id"]
            traj = store.trajectory(eid)
            ev = evaluate(crane, traj)
            w_ev = _integral(ev.t, ev.hyd["p_pump"] * ev.hyd["q_pump"])
            t_u, u = stored_commands(traj)
            m, run, _ = replay_move(crane, traj, t_u=t_u, u=u, settle=3.0, plant=plant,
                                    keep_runs=True)
            if m.status != "ok":
                rows.append(dict(id=eid, status=m.status))
                continue
            C = run.circuit
            o = C.opening(np.vstack([run.spool[1:], run.spool[-1:]]))
            w_ex = _integral(run.t, run.p_s * C.flows(run.p_a, run.p_b, run.p_s, o)["q_in"]
                             .sum(axis=1))
            r = dict(id=eid, status="ok", objective=src_row["objective"], w_eval_J=w_ev,
                     w_exudyn_J=w_ex, **anatomy(crane, traj, ev, run))
            r["twin_J"] = {}
            for name, T in tw.items():
                w = twin_pump_energy(crane, traj, twin=T)
                r["twin_J"][name] = None if w is None else w * eta
            rows.append(r)
            print(f"{k + 1}/{len(tail)} {eid}: Exudyn/evaluate() {w_ex / w_ev:.3f}, twin "
                  + ", ".join(f"{n} {v / w_ev:.3f}" for n, v in r["twin_J"].items()
                              if v is not None), file=sys.stderr, flush=True)
    res = dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
               command=" ".join(["python", *sys.argv]), rows_from=str(args.rows),
               library=str(lib), above=args.above,
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=list(os.getloadavg())),
               names=list(crane.names), rows=rows, wall_s=time.perf_counter() - t_start)
    args.out.mkdir(parents=True, exist_ok=True)
    name = "energy_tail" + (f"_{args.tag}" if args.tag else "")
    atomic_write_text(args.out / f"{name}.json", dumps(res))
    atomic_write_text(args.out / f"{name}.md", "\n".join(markdown(res)) + "\n")
    print(f"wrote {args.out / name}.md", file=sys.stderr)


def markdown(res) -> list:
    ok = [r for r in res["rows"] if r["status"] == "ok"]
    names = res["names"]
    m = res["machine"]
    L = ["# The tail of Exudyn / evaluate() pump work: where and why (issue 30)", "",
         f"{res['date']}, {m['platform']}, {m['cpus']} CPUs, load average "
         f"{' / '.join(f'{x:.1f}' for x in m['load'])} at the end. `{res['command']}` "
         f"({res['wall_s'] / 60:.1f} min). Entries of `{res['rows_from']}` whose Exudyn / "
         f"evaluate() pump work exceeds {res['above']:g} ({len(ok)}), library "
         f"`{res['library']}`. Judges: **Exudyn** = the independent plant (stored 50 Hz "
         "commands, open loop, 3 s settle); **evaluate()** = the quasi-static model (machine "
         "pricing, held pair); **twin** = the model's dynamic twin on the same commands. Pump "
         "work is hydraulic.", "",
         "## Pump work against evaluate()'s", "",
         "| entry | Exudyn | twin | " + " | ".join(f"twin, {n}" for n in VARIANTS
                                                  if n != "as specified") + " |",
         "| --- | ---: | ---: | " + " | ".join("---:" for _ in range(len(VARIANTS) - 1)) + " |"]
    for r in ok:
        tw = r["twin_J"]
        L.append(f"| {r['id']} | {r['w_exudyn_J'] / r['w_eval_J']:.3f} | "
                 + " | ".join("—" if tw[n] is None else f"{tw[n] / r['w_eval_J']:.3f}"
                              for n in VARIANTS) + " |")
    for n in VARIANTS:
        x = np.array([r["twin_J"][n] / r["w_eval_J"] for r in ok if r["twin_J"][n]])
        if x.size:
            L.append(f"| **median (max)**, twin {n} | | {np.median(x):.3f} ({x.max():.3f}) |"
                     + " |" * (len(VARIANTS) - 1))
    L += ["", "## Where: the excess over the plan's pump pressure (Exudyn against evaluate())",
          "", "Excess pump work by the function setting the plant's LS pressure and its phase "
          "in the plan [kJ]; the main setter's excess-weighted meter-in / outlet pressure "
          "[MPa] on Exudyn and in evaluate(); its stroke-rate error on Exudyn (RMS over the "
          "plan / peak rate); the flow's own difference ∫ p_plan·(Q − Q_plan) dt [kJ].", "",
          "| entry | excess | flow diff | main setter | by phase: " + ", ".join(PHASES)
          + " | its p_in Exudyn / evaluate() | its p_out Exudyn / evaluate() | rate error |",
          "| --- | ---: | ---: | --- | --- | --- | --- | ---: |"]
    tot = np.zeros((len(names), len(PHASES)))
    for r in ok:
        by = np.array(r["by_setter_phase_J"])
        tot += by
        j = r["main_setter"]
        L.append(f"| {r['id']} | {r['excess_J'] / 1e3:.1f} | {r['flow_diff_J'] / 1e3:.1f} | "
                 f"{names[j]} ({100 * by[j].sum() / max(r['excess_J'], 1e-30):.0f} %) | "
                 + " / ".join(f"{v / 1e3:.1f}" for v in by[j]) + " | "
                 f"{r['main_p_in_exudyn'] / 1e6:.1f} / {r['main_p_in_eval'] / 1e6:.1f} | "
                 f"{r['main_p_out_exudyn'] / 1e6:.1f} / {r['main_p_out_eval'] / 1e6:.1f} | "
                 f"{r['main_rate_error']:.2f} |")
    L += ["", "Summed over the tail [kJ]:", "",
          "| setter | " + " | ".join(PHASES) + " | all |", "| --- |" + " ---: |" * 5]
    for i, nm in enumerate(names):
        L.append(f"| {nm} | " + " | ".join(f"{v / 1e3:.1f}" for v in tot[i])
                 + f" | {tot[i].sum() / 1e3:.1f} |")
    return L


if __name__ == "__main__":
    main()
