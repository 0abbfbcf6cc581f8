#!/usr/bin/env python3
"""Where evaluate() and the Exudyn plant part on the energy entries: the pressure the pump
pushes against, per function and per phase (issue 30, the held chamber pressure).

    python benchmarks/bench_energy_held.py --library LIB.h5 [--entries ID ...] [--worst K]
                                           [--out benchmarks/results]

For each named entry of a claims-subset library (default: the ``--worst`` K entries of
``energy_machine_held.json`` by Exudyn / evaluate() before the held pressure, plus the moves
whose energy entry cost more than its time entry there) the stored 50 Hz commands are
replayed open loop on the Exudyn plant (3 s settle, as ``bench_exudyn_energy_gap.py``) and the
plan is priced three ways: **Exudyn** (the plant's recorded chamber and pump pressures),
**evaluate()** (the machine pricing with the held chamber pair,
:func:`planner.model.pricing.held_pressures`) and **quasi-static** (the same pricing sample
by sample, without the held pair: what evaluate() gave before).

Per function and phase, over the plan's duration while the function's valve is open on the
plant: the phase is **held** where the plant's outlet chamber sits more than ``HELD_DP`` above
the quasi-static outlet pressure (the load-holding valve still carries an earlier, higher
load: after braking, after a load that lightened, after a stop), else **free**. Reported: the
time, the mean meter-in pressure (the pressure the LS pump must reach for that function) on
the plant, by evaluate() and quasi-statically, the mean outlet pressure likewise, and the pump
work above the quasi-static pump pressure while that function sets the plant's LS pressure
(Exudyn's p_s − the quasi-static pump pressure, times the plant's pump flow).

Writes <out>/energy_held.md and .json.
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

from planner import Crane, evaluate  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.simulation.dynamic.claims import replay_move, stored_commands  # noqa: E402
from planner.simulation.dynamic.energy import energy_balance  # noqa: E402
from planner.simulation.dynamic.exudyn_plant import ExudynPlant  # noqa: E402

#: a plant outlet this far above the quasi-static outlet pressure [Pa] is "held"
HELD_DP = 1.0e6


def _integral(t, y):
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def _work(t, hyd):
    return _integral(t, hyd["p_pump"] * hyd["q_pump"])


def diagnose(crane, plant, traj) -> dict:
    """Per function and phase (module doc) of one plan; pump work by each judge [J]."""
    ev = evaluate(crane, traj)
    qs = crane.hydraulics(ev.q, ev.qd, ev.qdd)
    t_u, u = stored_commands(traj)
    m, run, _ = replay_move(crane, traj, t_u=t_u, u=u, settle=3.0, plant=plant,
                            keep_runs=True)
    if m.status != "ok":
        return dict(status=m.status, reason=m.reason)
    C = run.circuit
    spool = np.vstack([run.spool[1:], run.spool[-1:]])
    o = C.opening(spool)
    fl = C.flows(run.p_a, run.p_b, run.p_s, o)
    k = run.t <= traj.duration
    t = run.t[k]
    o, pa, pb, ps = o[k], run.p_a[k], run.p_b[k], run.p_s[k]
    q_in = fl["q_in"][k]
    ext = o > 0
    p_in = np.where(ext, pa, pb)
    p_out = np.where(ext, pb, pa)
    setter = np.argmax(np.where(np.abs(o) > 0, p_in, -np.inf), axis=1)

    def at(h, name, j):
        return np.interp(t, ev.t, np.asarray(h[name])[:, j])

    pump_qs = np.interp(t, ev.t, qs["p_pump"])
    excess = np.maximum(ps - pump_qs, 0.0) * q_in.sum(axis=1)
    dt = np.gradient(t)
    funcs = []
    for j, name in enumerate(crane.names):
        e_pa, e_pb = at(ev.hyd, "p_a", j), at(ev.hyd, "p_b", j)
        s_pa, s_pb = at(qs, "p_a", j), at(qs, "p_b", j)
        e_in, e_out = np.where(ext[:, j], e_pa, e_pb), np.where(ext[:, j], e_pb, e_pa)
        s_in, s_out = np.where(ext[:, j], s_pa, s_pb), np.where(ext[:, j], s_pb, s_pa)
        is_open = np.abs(o[:, j]) > 0
        held = is_open & (p_out[:, j] > s_out + HELD_DP)
        row = dict(function=name)
        for ph, mask in (("held", held), ("free", is_open & ~held)):
            w = dt * mask
            T = float(w.sum())

            def mean(y):
                return float(np.sum(y * w) / T) if T > 0 else float("nan")
            row[ph] = dict(time_s=T, p_in_exudyn=mean(p_in[:, j]), p_in_eval=mean(e_in),
                           p_in_qs=mean(s_in), p_out_exudyn=mean(p_out[:, j]),
                           p_out_eval=mean(e_out), p_out_qs=mean(s_out),
                           excess_J=_integral(t, excess * mask * (setter == j)))
        funcs.append(row)
    b = energy_balance(plant, run)
    return dict(status="ok", w_exudyn_J=b["pump_work_J"], w_eval_J=_work(ev.t, ev.hyd),
                w_qs_J=_work(ev.t, qs), functions=funcs)


def default_entries(path: Path, worst: int) -> list[str]:
    """The ``worst`` entries by Exudyn / evaluate() of an earlier bench_energy_machine.py
    result, and the energy entries that cost more than their time entry there."""
    res = json.loads(path.read_text())
    ok = [r for r in res["rows"] if r["status"] == "ok"]
    ok.sort(key=lambda r: -r["w_exudyn_J"] / r["w_qs_J"])
    ids = [r["id"] for r in ok[:worst]]
    for mv in res["summary"]["exudyn"]["costlier"]:
        for obj in ("energy", "time"):
            if f"{mv}:{obj}" not in ids:
                ids.append(f"{mv}:{obj}")
    return ids


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--library", type=Path, required=True)
    ap.add_argument("--entries", nargs="*", default=None)
    ap.add_argument("--worst", type=int, default=6)
    ap.add_argument("--before", type=Path, default=HERE / "results" / "energy_machine_held.json",
                    help="the earlier result the default entries are drawn from")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    crane = Crane.from_id("s100f")
    plant = ExudynPlant(crane)
    ids = args.entries or default_entries(args.before, args.worst)
    rows = []
    with LibraryStore.open(args.library) as store:
        for eid in ids:
            r = dict(id=eid, **diagnose(crane, plant, store.trajectory(eid)))
            rows.append(r)
            if r["status"] == "ok":
                print(f"{eid}: Exudyn {r['w_exudyn_J'] / 1e3:.1f} kJ, evaluate() "
                      f"{r['w_eval_J'] / 1e3:.1f} kJ, quasi-static {r['w_qs_J'] / 1e3:.1f} kJ",
                      file=sys.stderr, flush=True)
    res = dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
               command=" ".join(["python", *sys.argv]), library=str(args.library),
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=list(os.getloadavg())),
               rows=rows, wall_s=time.perf_counter() - t0)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "energy_held.json", dumps(res))
    atomic_write_text(args.out / "energy_held.md", "\n".join(markdown(res)) + "\n")
    print(f"wrote {args.out / 'energy_held.md'}", file=sys.stderr)


def markdown(res) -> list:
    m = res["machine"]
    L = ["# The pressure the pump pushes against: Exudyn against evaluate(), per function and "
         "phase (issue 30)", "",
         f"{res['date']}, {m['platform']}, {m['cpus']} CPUs, load average "
         f"{' / '.join(f'{x:.1f}' for x in m['load'])}. `{res['command']}` "
         f"({res['wall_s'] / 60:.1f} min), library `{res['library']}`. Judges: **Exudyn** = "
         "the independent plant, the stored 50 Hz commands replayed open loop; "
         "**evaluate()** = the machine pricing with the held chamber pair; **quasi-static** = "
         "the same pricing sample by sample (what evaluate() gave before the held pair). "
         f"Phase **held**: the plant's outlet more than {HELD_DP / 1e6:g} MPa above the "
         "quasi-static outlet pressure while the valve is open; **free**: the rest of the "
         "open time. Pressures in MPa are time means over the phase; 'excess' is the plant's "
         "pump work above the quasi-static pump pressure while that function sets the plant's "
         "LS pressure.", "",
         "| entry | pump work Exudyn / evaluate() / quasi-static [kJ] | Exudyn ÷ evaluate() | "
         "Exudyn ÷ quasi-static |", "| --- | --- | ---: | ---: |"]
    ok = [r for r in res["rows"] if r["status"] == "ok"]
    for r in ok:
        L.append(f"| {r['id']} | {r['w_exudyn_J'] / 1e3:.1f} / {r['w_eval_J'] / 1e3:.1f} / "
                 f"{r['w_qs_J'] / 1e3:.1f} | {r['w_exudyn_J'] / r['w_eval_J']:.3f} | "
                 f"{r['w_exudyn_J'] / r['w_qs_J']:.3f} |")
    L += ["", "| entry | function | phase | time [s] | inlet: Exudyn / evaluate() / quasi-static "
          "| outlet: Exudyn / evaluate() / quasi-static | excess [kJ] |",
          "| --- | --- | --- | ---: | --- | --- | ---: |"]
    for r in ok:
        for f in r["functions"]:
            for ph in ("held", "free"):
                d = f[ph]
                if d["time_s"] < 0.05:
                    continue
                L.append(f"| {r['id']} | {f['function']} | {ph} | {d['time_s']:.2f} | "
                         f"{d['p_in_exudyn'] / 1e6:.2f} / {d['p_in_eval'] / 1e6:.2f} / "
                         f"{d['p_in_qs'] / 1e6:.2f} | {d['p_out_exudyn'] / 1e6:.2f} / "
                         f"{d['p_out_eval'] / 1e6:.2f} / {d['p_out_qs'] / 1e6:.2f} | "
                         f"{d['excess_J'] / 1e3:.1f} |")
    tot = {}
    for r in ok:
        for f in r["functions"]:
            for ph in ("held", "free"):
                k = (f["function"], ph)
                a = tot.setdefault(k, [0.0, 0.0])
                a[0] += f[ph]["time_s"]
                a[1] += f[ph]["excess_J"]
    L += ["", "Over these entries: time [s] and excess [kJ] per function and phase.", "",
          "| function | held: time / excess | free: time / excess |", "| --- | --- | --- |"]
    for name in dict.fromkeys(k[0] for k in tot):
        h, f = tot[(name, "held")], tot[(name, "free")]
        L.append(f"| {name} | {h[0]:.1f} s / {h[1] / 1e3:.1f} kJ | {f[0]:.1f} s / "
                 f"{f[1] / 1e3:.1f} kJ |")
    return L


if __name__ == "__main__":
    main()
