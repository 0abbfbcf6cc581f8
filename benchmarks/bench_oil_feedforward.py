#!/usr/bin/env python3
"""The feed-forward that fills the oil springs against the plain one, on the same plans, judged
on the Exudyn plant (issue 30).

    python benchmarks/bench_oil_feedforward.py --library LIB.h5 [--limit K] [--tag NAME]
                                               [--machine mN] [--out benchmarks/results]

For every ok entry of ``LIB.h5`` (an s100f library, e.g. the claims library that
``bench_energy_machine.py --work W`` builds), the stored plan's two 50 Hz feed-forwards —
:func:`planner.feedforward.commands` plain (Q = A·ẋ) and with ``oil=True`` (the flow that also
fills each function's oil spring to the plan's pressures) — are replayed open loop on the
Exudyn plant with the spec's parameters (valves closed after the last command, 3 s settle, as
``bench_energy_machine.py``). Judges, named on every number: **Exudyn** (the independent plant:
pump work at the shaft from its energy balance, the tip's path and rest) and **evaluate()**
(the quasi-static model's pump work for the plan, the machine pricing).

``--machine mN``: the replays run on drawn machine mN of the calibration loop
(``calibrate_loop_100t.json``: ``[dynamics]`` values drawn ±30 %, a command delay, one slower
valve; ``bench_calibrate_loop.machine_plant``), whose parameters the planner and its
feed-forward were not given; evaluate() keeps the spec's figures.

Per entry and feed-forward: Exudyn / evaluate() pump work; the largest tip error during the
move; the tip's rest offset from the goal (mean over the last 1.5 s) and its ringing (largest
distance from the rest point after the plan's end). Summaries: median, p10, p90 and how many
entries are within 5 %; the landing measures' median and p90.

Writes <out>/oil_feedforward[_TAG].md and .json.
"""
from __future__ import annotations

import argparse
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
from planner.feedforward import commands  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.simulation.dynamic.claims import replay_move  # noqa: E402
from planner.simulation.dynamic.exudyn_plant import ExudynPlant  # noqa: E402

KINDS = ("plain", "oil")


def drawn_plant(crane, name: str):
    """The Exudyn plant of the calibration loop's drawn machine ``name`` (module doc)."""
    import json
    from bench_calibrate_loop import machine_plant
    machines = json.loads((HERE / "results" / "calibrate_loop_100t.json").read_text())["machines"]
    for m in machines:
        if m["name"] == name:
            return machine_plant(crane, m), m
    raise SystemExit(f"--machine: {name!r}; allowed: {', '.join(m['name'] for m in machines)}")


def replay(crane, plant, traj, oil: bool) -> dict:
    ff = commands(crane, traj, 50.0, oil=oil)
    m = replay_move(crane, traj, t_u=ff.t, u=ff.u, settle=3.0, plant=plant)
    if m.status != "ok":
        return dict(status=m.status)
    e = m.exudyn
    return dict(status="ok", pump_J=e["pump_J"], track_m=e["max_track_m"],
                rest_m=e["offset_m"], ring_m=e["peak_osc_m"])


def summary(rows, kind) -> dict:
    ok = [r for r in rows if r[kind]["status"] == "ok"]
    ratio = np.array([r[kind]["pump_J"] / r["eval_J"] for r in ok])
    pick = (lambda k: 1e3 * np.array([r[kind][k] for r in ok]))
    out = dict(n=len(ok), ratio_median=float(np.median(ratio)),
               ratio_p10=float(np.percentile(ratio, 10)),
               ratio_p90=float(np.percentile(ratio, 90)),
               ratio_min=float(ratio.min()), ratio_max=float(ratio.max()),
               within_5pct=int(np.sum(np.abs(ratio - 1) <= 0.05)),
               sum_ratio=float(sum(r[kind]["pump_J"] for r in ok) / sum(r["eval_J"] for r in ok)))
    by = {r["id"]: r[kind]["pump_J"] for r in ok}
    moves = sorted({i.rsplit(":", 1)[0] for i in by if f"{i.rsplit(':', 1)[0]}:time" in by
                    and f"{i.rsplit(':', 1)[0]}:energy" in by})
    if moves:       # each move's energy entry against its own time entry, on this plant
        e = np.array([by[f"{m}:energy"] for m in moves])
        t = np.array([by[f"{m}:time"] for m in moves])
        out["pairs"] = dict(n=len(moves), saving_median=float(np.median(1 - e / t)),
                            saving_sum=float(1 - e.sum() / t.sum()),
                            costlier=int(np.sum(e > t)))
    for k in ("track_m", "rest_m", "ring_m"):
        v = pick(k)
        out[k.replace("_m", "_mm")] = dict(median=float(np.median(v)),
                                           p90=float(np.percentile(v, 90)), max=float(v.max()))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--library", type=Path, required=True)
    ap.add_argument("--limit", type=int, default=0, help="first K entries only (0: all)")
    ap.add_argument("--tag", default="")
    ap.add_argument("--machine", help="a drawn machine of the calibration loop (m1 … m6)")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    if not args.library.is_file():
        raise SystemExit(f"--library: {args.library} is not a file; allowed: a library .h5")
    if args.limit < 0:
        raise SystemExit(f"--limit: {args.limit}; allowed: >= 0")
    t_start = time.perf_counter()
    crane = Crane.from_id("s100f")
    plant, drawn = (ExudynPlant(crane), None) if not args.machine else \
        drawn_plant(crane, args.machine)
    rows = []
    with LibraryStore.open(args.library, "r") as db:
        ids = [r["id"] for r in db.index_rows() if r.get("status", "ok") == "ok"]
        ids = ids[:args.limit] if args.limit else ids
        for k, eid in enumerate(ids):
            traj = db.trajectory(eid)
            row = dict(id=eid, eval_J=float(evaluate(crane, traj).energy_J))
            for kind in KINDS:
                row[kind] = replay(crane, plant, traj, kind == "oil")
            rows.append(row)
            print(f"{k + 1}/{len(ids)} {eid}: " + ", ".join(
                f"{kind} {row[kind]['pump_J'] / row['eval_J']:.3f} rest "
                f"{1e3 * row[kind]['rest_m']:.1f} mm" if row[kind]["status"] == "ok"
                else f"{kind} {row[kind]['status']}" for kind in KINDS),
                file=sys.stderr, flush=True)
    res = dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
               command=" ".join(["python", *sys.argv]), library=str(args.library),
               machine_drawn=drawn,
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=list(os.getloadavg())),
               summary={k: summary(rows, k) for k in KINDS}, rows=rows,
               wall_s=time.perf_counter() - t_start)
    args.out.mkdir(parents=True, exist_ok=True)
    stem = args.out / ("oil_feedforward" + (f"_{args.tag}" if args.tag else ""))
    for suffix, text in ((".json", dumps(res)), (".md", "\n".join(markdown(res)) + "\n")):
        atomic_write_text(Path(f"{stem}{suffix}"), text)
    print(f"wrote {stem}.md", file=sys.stderr)


def markdown(res) -> list:
    S = res["summary"]
    L = ["# The oil-filling feed-forward against the plain one, same plans, on Exudyn (issue 30)",
         "",
         f"{res['date']}, {res['machine']['platform']}, {res['machine']['cpus']} CPUs, load "
         f"average {' / '.join(f'{x:.1f}' for x in res['machine']['load'])} at the end. "
         f"`{res['command']}` ({res['wall_s'] / 60:.1f} min). Library `{res['library']}`. "
         + ("Judges: **Exudyn** = the independent plant (the spec's parameters; " if not
            res.get("machine_drawn") else
            f"Judges: **Exudyn** = the independent plant as drawn machine "
            f"{res['machine_drawn']['name']} of `calibrate_loop_100t.json` (parameters the "
            f"planner was not given: [dynamics] drawn ±30 %, a command delay of "
            f"{1e3 * res['machine_drawn']['delay']:.1f} ms, the {res['machine_drawn']['lag_joint']}"
            f" valve {1e3 * res['machine_drawn']['lag']:.1f} ms slower; ") +
         "each entry's plan's "
         "50 Hz feed-forward replayed open loop, valves closed after the last command, 3 s "
         "settle; pump work at the shaft from its energy balance); **evaluate()** = the "
         "quasi-static model's pump work for the plan (machine pricing). *plain*: Q = A·ẋ; "
         "*oil*: `commands(..., oil=True)`, the flow that also fills each function's oil spring "
         "to the plan's chamber pressures (`planner/model/twin/oil.py`).", "",
         "| feed-forward | entries | Exudyn / evaluate() pump work: median | p10 | p90 | range "
         "| within 5 % | sum ratio | tip error during the move: median / p90 [mm] | rest offset "
         "from the goal: median / p90 / max [mm] | ringing after the end: median / p90 [mm] |",
         "| --- | ---: | ---: | ---: | ---: | --- | ---: | ---: | --- | --- | --- |"]
    for k in KINDS:
        s = S[k]
        L.append(f"| {k} | {s['n']} | {s['ratio_median']:.3f} | {s['ratio_p10']:.3f} | "
                 f"{s['ratio_p90']:.3f} | {s['ratio_min']:.3f}–{s['ratio_max']:.3f} | "
                 f"{s['within_5pct']} | {s['sum_ratio']:.3f} | {s['track_mm']['median']:.1f} / "
                 f"{s['track_mm']['p90']:.1f} | {s['rest_mm']['median']:.1f} / "
                 f"{s['rest_mm']['p90']:.1f} / {s['rest_mm']['max']:.1f} | "
                 f"{s['ring_mm']['median']:.1f} / {s['ring_mm']['p90']:.1f} |")
    if all("pairs" in S[k] for k in KINDS):
        L += ["", "Energy entries against their own time entries, pump work on this plant:", "",
              "| feed-forward | moves | saving, median | over the sums | energy entry costlier |",
              "| --- | ---: | ---: | ---: | ---: |"]
        for k in KINDS:
            p = S[k]["pairs"]
            L.append(f"| {k} | {p['n']} | {100 * p['saving_median']:.1f} % | "
                     f"{100 * p['saving_sum']:.1f} % | {p['costlier']} |")
    L += ["", "## Per entry", "",
          "| entry | evaluate() [kJ] | plain: Exudyn / evaluate(), rest, ringing [mm] | oil: "
          "Exudyn / evaluate(), rest, ringing [mm] |", "| --- | ---: | --- | --- |"]
    for r in res["rows"]:
        cells = []
        for k in KINDS:
            x = r[k]
            cells.append(x["status"] if x["status"] != "ok" else
                         f"{x['pump_J'] / r['eval_J']:.3f}, {1e3 * x['rest_m']:.1f}, "
                         f"{1e3 * x['ring_m']:.1f}")
        L.append(f"| {r['id']} | {r['eval_J'] / 1e3:.1f} | {cells[0]} | {cells[1]} |")
    return L


if __name__ == "__main__":
    main()
