#!/usr/bin/env python3
"""Energy entries rebuilt under the machine pricing, judged on the Exudyn plant (issue 30).

    python benchmarks/bench_energy_machine.py [--library LIB.h5] [--workers 2] [--limit K]
                                              [--plant-margin M] [--tag NAME]
                                              [--out benchmarks/results]

The claims subset of ``bench_exudyn_claims.py`` (s100f, 36 forwarder moves × time, energy NLP
entries) is built afresh with the project's library builder — the crane under its default
pricing, the machine's (:mod:`planner.model.pricing`), so the energy entries minimise the pump
work the machine pays, within 1.2 × the minimum time — unless ``--library`` names one. Every
ok entry's stored 50 Hz commands are replayed open loop on the Exudyn plant (valves closed 3 s
after the plan's end, as ``bench_exudyn_energy_gap.py`` does; its :func:`entry_gap` is reused)
and its plan is judged by ``evaluate()`` under the machine and the seed pricing. All figures
are hydraulic pump work (before the pump efficiency, which every judge divides by alike).

Two judges, named on every number: **Exudyn** — the independent dynamic plant; **evaluate()**
— the quasi-static model. Reported:

* per move, the energy entry's saving against its own time entry, 1 − W_energy/W_time, on
  Exudyn and by evaluate(): median over the moves and over the sums; the moves where the energy
  entry costs more than the time entry on Exudyn (issue 30: ≥ 25 %, and none);
* Exudyn / evaluate() pump work per entry (median, p90, range; issue 30: within 5 %);
* the *creep* of the plans: how long the LS pump pressure is set by a function whose valve is
  open below ``USEFUL`` of its full flow (an "idle" joint crept along; on the plant its chambers
  do not reach their quasi-static pressures, see benchmarks/results/energy_pricing.md);
* where the plant's pump pressure exceeds the plan's: the excess pump work
  ∫ max(p_s − p_pump,plan, 0)·Q_pump dt over the plan's duration (Exudyn's p_s and pump flow,
  the plan's evaluate() pressure at the same instant), split by the function that sets the
  plant's LS pressure (the open valve with the highest meter-in pressure) and by whether the
  plan prices that function's load pressure at its floor (below ``FLOOR`` Pa: a light or
  overrunning load, whose meter-in chamber the quasi-static model puts at tank or just above).

``--plant-margin M`` replays on a plant whose load-holding (meter-out) edges pass up to M
overspeed instead of the spec's ``meter_out_margin`` (their orifices scaled by (1 + M)/(1 + m),
as ``bench_exudyn_claims.py``'s drift anatomy does): a sensitivity of the judge, not of the
plans — evaluate() keeps the spec's figures.

Writes <out>/energy_machine[_TAG].md and .json.
"""
from __future__ import annotations

import argparse
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

from bench_exudyn_claims import subset_suite  # noqa: E402
from bench_exudyn_energy_gap import entry_gap  # noqa: E402
from planner import Crane, evaluate  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.simulation.dynamic.exudyn_plant import ExudynPlant  # noqa: E402

#: a valve opening below this fraction of its full flow counts as a creep (not a working motion)
USEFUL = 0.01
#: a planned load pressure below this [Pa] is "at the floor" (light or overrunning load)
FLOOR = 1.5e6


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def build(work: Path, workers: int, limit: int | None) -> tuple[Path, float]:
    """The subset library built afresh by the project's builder (default pricing)."""
    from planner.library.build import build as lib_build
    suite = subset_suite(work / "forwarder-cycle-claims.toml")
    lib = work / "claims-library.h5"
    lib.unlink(missing_ok=True)
    t0 = time.perf_counter()
    lib_build("s100f", str(suite), lib, objectives=("time", "energy"), robustness=False,
              progress=False, workers=workers, limit=limit)
    return lib, time.perf_counter() - t0


def creep(crane, traj) -> dict:
    """How long [s] the plan's LS pump pressure is set by a creeping function (open, drawing,
    below ``USEFUL`` of its full flow) and how much pump work [J] that costs by evaluate()
    against pricing the same instants at the highest *working* function's pressure."""
    ev = evaluate(crane, traj)
    h = ev.hyd
    G = np.array([j.actuator.flow_gain for j in crane.spec.joints], float)
    q = np.asarray(h["q_act"])
    drawing = q > crane.prices.active
    working = q > USEFUL * G
    crawling = drawing & ~working
    pl = np.asarray(h["p_load"])
    top_crawl = np.max(np.where(crawling, pl, 0.0), axis=1)
    top_work = np.max(np.where(working, pl, 0.0), axis=1)
    sets = crawling.any(axis=1) & (top_crawl > top_work)
    dt = np.gradient(ev.t)
    pump = crane.spec.pump
    p_alt = np.maximum(pump.standby, np.where(working.any(axis=1), top_work + pump.margin, 0.0))
    extra = np.sum(np.maximum(h["p_pump"] - p_alt, 0.0) * h["q_pump"] * sets * dt)
    return dict(creep_set_s=float(np.sum(dt * sets)),
                creep_joint_s=float(np.sum(dt[:, None] * crawling)), creep_extra_J=float(extra))


def _integral(t, y):
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def excess_by_setter(crane, traj, ev, run) -> dict:
    """The Exudyn run's pump work above the plan's pump pressure (module doc), in J: total,
    while the plant's LS setter is a function the plan prices at its floor, and per joint."""
    C = run.circuit
    spool = np.vstack([run.spool[1:], run.spool[-1:]])   # the opening in force over a step
    o = C.opening(spool)
    q_in = C.flows(run.p_a, run.p_b, run.p_s, o)["q_in"].sum(axis=1)
    p_in = np.where(o > 0, run.p_a, run.p_b)
    setter = np.argmax(np.where(np.abs(o) > 0, p_in, -np.inf), axis=1)
    k = run.t <= traj.duration
    t, setter = run.t[k], setter[k]
    h = ev.hyd
    p_plan = np.interp(t, ev.t, h["p_pump"])
    pl_plan = np.stack([np.interp(t, ev.t, h["p_load"][:, i]) for i in range(crane.n)], 1)
    x = np.maximum(run.p_s[k] - p_plan, 0.0) * q_in[k]
    floor = pl_plan[np.arange(len(t)), setter] < FLOOR
    return dict(excess_J=_integral(t, x), excess_floor_J=_integral(t, x * floor),
                excess_by_setter_J=[_integral(t, x * (setter == i)) for i in range(crane.n)])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--library", type=Path, help="an existing library of the claims subset")
    ap.add_argument("--workers", type=int, default=2, help="library builder workers")
    ap.add_argument("--limit", type=int, default=None, help="first K moves of the subset")
    ap.add_argument("--plant-margin", type=float, default=None,
                    help="replay on a plant with this meter-out margin (sensitivity)")
    ap.add_argument("--tag", default="", help="suffix of the result files")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--work", type=Path, default=Path(os.environ.get("TMPDIR", "/tmp"))
                    / "crane-energy-machine")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    crane = Crane.from_id("s100f")
    seed = Crane.from_id("s100f", pricing="seed")
    args.work.mkdir(parents=True, exist_ok=True)
    build_s = None
    lib = args.library
    if lib is None:
        lib, build_s = build(args.work, args.workers, args.limit)
        log(f"built {lib} in {build_s:.0f} s")
    plant = ExudynPlant(crane)
    if args.plant_margin is not None:
        if not 0.0 <= args.plant_margin < 1.0:
            raise SystemExit(f"--plant-margin: {args.plant_margin} is not a margin; allowed: "
                             "0 <= M < 1")
        c, f = plant.circuit, (1.0 + args.plant_margin) / (1.0 + plant.dyn.meter_out_margin)
        plant.circuit = replace(c, k_out_a=c.k_out_a * f, k_out_b=c.k_out_b * f)
    rows = []
    with LibraryStore.open(lib) as store:
        ids = [r["id"] for r in store.index_rows() if r["status"] == "ok"]
        for k, eid in enumerate(ids):
            a = store.entry_attrs(eid)
            traj = store.trajectory(eid)
            gap, ev, run = entry_gap(crane, plant, traj, seed, keep=True)
            r = dict(id=eid, move=eid.rsplit(":", 1)[0], objective=a.get("objective"),
                     duration_s=float(traj.duration), winner=a.get("energy_winner"),
                     **gap, **creep(crane, traj),
                     **(excess_by_setter(crane, traj, ev, run) if run is not None else {}))
            rows.append(r)
            if r["status"] == "ok":
                log(f"{k + 1}/{len(ids)} {eid}: evaluate() {r['w_qs_J'] / 1e3:.1f} kJ, Exudyn "
                    f"{r['w_exudyn_J'] / 1e3:.1f} kJ, creep sets the pump "
                    f"{r['creep_set_s']:.2f} s")
    res = dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
               pricing=crane.pricing, plant_margin=args.plant_margin,
               command=" ".join(["python", *sys.argv]),
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=list(os.getloadavg())),
               library=str(lib), build_s=build_s, rows=rows,
               summary=summary(rows), wall_s=time.perf_counter() - t_start)
    args.out.mkdir(parents=True, exist_ok=True)
    name = "energy_machine" + (f"_{args.tag}" if args.tag else "")
    atomic_write_text(args.out / f"{name}.json", dumps(res))
    atomic_write_text(args.out / f"{name}.md", "\n".join(markdown(res)) + "\n")
    log(f"wrote {args.out / name}.md")


# ------------------------------------------------------------------------------ summaries
def pairs(rows) -> list[dict]:
    """Per move with both entries ok: the time and energy entries' pump work by each judge."""
    by = {}
    for r in rows:
        if r["status"] == "ok":
            by.setdefault(r["move"], {})[r["objective"]] = r
    out = []
    for mv, d in sorted(by.items()):
        if "time" in d and "energy" in d:
            t, e = d["time"], d["energy"]
            out.append(dict(move=mv, exudyn_time_J=t["w_exudyn_J"],
                            exudyn_energy_J=e["w_exudyn_J"], eval_time_J=t["w_qs_J"],
                            eval_energy_J=e["w_qs_J"], winner=e.get("winner"),
                            T_time_s=t["duration_s"], T_energy_s=e["duration_s"]))
    return out


def saving(p, judge) -> tuple[np.ndarray, float]:
    t = np.array([x[f"{judge}_time_J"] for x in p])
    e = np.array([x[f"{judge}_energy_J"] for x in p])
    return 1.0 - e / t, float(1.0 - e.sum() / t.sum())


def summary(rows) -> dict:
    ok = [r for r in rows if r["status"] == "ok"]
    p = pairs(rows)
    s = dict(entries=len(rows), ok=len(ok), moves=len(p))
    for judge in ("exudyn", "eval"):
        per, tot = saving(p, judge)
        s[judge] = dict(median=float(np.median(per)) if p else np.nan, sum=tot,
                        min=float(per.min()) if p else np.nan,
                        max=float(per.max()) if p else np.nan,
                        costlier=[x["move"] for x, v in zip(p, per) if v < 0])
    ratios = {}
    for obj in ("time", "energy", None):
        rs = [r for r in ok if obj is None or r["objective"] == obj]
        if not rs:
            continue
        ex = np.array([r["w_exudyn_J"] for r in rs])
        for pricing, key in (("machine", "w_qs_J"),
                             ("machine, per sample (no held pair, no spool tail)",
                              "w_qs_static_J"), ("seed", "w_qs_seed_J")):
            if key not in rs[0]:
                continue
            qs = np.array([r[key] for r in rs])
            x = ex / qs
            ratios[f"{obj or 'all'}/{pricing}"] = dict(
                n=len(rs), median=float(np.median(x)), p90=float(np.percentile(x, 90)),
                min=float(x.min()), max=float(x.max()), sum=float(ex.sum() / qs.sum()))
    s["ratio"] = ratios
    s["excess"] = {obj: dict(excess_J=float(sum(r["excess_J"] for r in ok
                                                 if r["objective"] == obj)),
                             floor_J=float(sum(r["excess_floor_J"] for r in ok
                                               if r["objective"] == obj)),
                             by_setter_J=np.sum([r["excess_by_setter_J"] for r in ok
                                                 if r["objective"] == obj], axis=0).tolist())
                   for obj in ("time", "energy")}
    s["creep"] = {obj: dict(entries_with=sum(r["creep_set_s"] > 0 for r in ok
                                             if r["objective"] == obj),
                            set_s_sum=float(sum(r["creep_set_s"] for r in ok
                                                if r["objective"] == obj)),
                            extra_J_sum=float(sum(r["creep_extra_J"] for r in ok
                                                  if r["objective"] == obj)))
                  for obj in ("time", "energy")}
    return s


def markdown(res) -> list:
    s = res["summary"]
    m = res["machine"]
    L = ["# Energy entries under the machine pricing, judged on the Exudyn plant (issue 30)", "",
         f"{res['date']}, {m['platform']}, {m['cpus']} CPUs, load average "
         f"{' / '.join(f'{x:.1f}' for x in m['load'])} at the end. `{res['command']}` "
         f"({res['wall_s'] / 60:.1f} min"
         + (f"; library built in {res['build_s'] / 60:.1f} min" if res.get("build_s") else "")
         + f"). Library: `{res['library']}` — {s['ok']} of {s['entries']} entries ok, "
         f"{s['moves']} moves with both a time and an energy entry; crane pricing "
         f"'{res['pricing']}'"
         + (f"; **the plant's meter-out margin set to {res['plant_margin']:g}** (a sensitivity "
            "of the judge)" if res.get("plant_margin") is not None else "")
         + ". Pump work is hydraulic (before the pump efficiency). Judges: "
         "**Exudyn** = the independent plant, the entry's stored 50 Hz commands replayed open "
         "loop, 3 s settle; **evaluate()** = the quasi-static model's figure for the plan.", "",
         "## Energy entry against its own time entry (issue 30: ≥ 25 %, none costlier)", "",
         "| judge | saving, median over moves | saving over the summed work | range | "
         "moves where the energy entry costs more |",
         "| --- | ---: | ---: | --- | ---: |"]
    for judge, name in (("exudyn", "Exudyn"), ("eval", "evaluate() (machine pricing)")):
        d = s[judge]
        L.append(f"| {name} | {100 * d['median']:.1f} % | {100 * d['sum']:.1f} % | "
                 f"{100 * d['min']:.1f} … {100 * d['max']:.1f} % | {len(d['costlier'])}"
                 + (f" ({', '.join(d['costlier'])})" if d["costlier"] else "") + " |")
    L += ["", "## Exudyn / evaluate() pump work per entry (issue 30: within 5 %)", "",
          "| entries | evaluate() pricing | median | p90 | range | sum ratio |",
          "| --- | --- | ---: | ---: | --- | ---: |"]
    for k, d in s["ratio"].items():
        obj, pricing = k.split("/")
        L.append(f"| {obj} ({d['n']}) | {pricing} | {d['median']:.3f} | {d['p90']:.3f} | "
                 f"{d['min']:.3f}–{d['max']:.3f} | {d['sum']:.3f} |")
    L += ["", f"## Creep (a function open below {100 * USEFUL:g} % of its flow sets the LS "
          "pump pressure)", "",
          "| entries | entries with creep setting the pump | time it sets the pump, sum [s] | "
          "evaluate()'s pump work for it, sum [kJ] |", "| --- | ---: | ---: | ---: |"]
    for obj, d in s["creep"].items():
        L.append(f"| {obj} | {d['entries_with']} | {d['set_s_sum']:.2f} | "
                 f"{d['extra_J_sum'] / 1e3:.2f} |")
    names = Crane.from_id("s100f").names
    L += ["", "## Where the plant's pump pressure exceeds the plan's (Exudyn against evaluate())",
          "", f"Pump work above the plan's pump pressure over the plan's duration, by the "
          f"function that sets the plant's LS pressure; 'at the plan's floor': that function's "
          f"planned load pressure is below {FLOOR / 1e6:g} MPa (light or overrunning load).", "",
          "| entries | excess [kJ] | of it, setter at the plan's floor [kJ] | by setter: "
          + ", ".join(names) + " [kJ] |", "| --- | ---: | ---: | --- |"]
    for obj, d in s["excess"].items():
        L.append(f"| {obj} | {d['excess_J'] / 1e3:.1f} | {d['floor_J'] / 1e3:.1f} "
                 f"({100 * d['floor_J'] / d['excess_J']:.0f} %) | "
                 + " / ".join(f"{v / 1e3:.1f}" for v in d["by_setter_J"]) + " |")
    L += ["", "## Per move (pump work [kJ]; saving = 1 − energy/time)", "",
          "| move | T time / energy [s] | energy winner | evaluate() time / energy | saving "
          "(evaluate()) | Exudyn time / energy | saving (Exudyn) |",
          "| --- | --- | --- | --- | ---: | --- | ---: |"]
    for x in pairs(res["rows"]):
        L.append(f"| {x['move']} | {x['T_time_s']:.2f} / {x['T_energy_s']:.2f} | "
                 f"{x['winner']} | {x['eval_time_J'] / 1e3:.1f} / "
                 f"{x['eval_energy_J'] / 1e3:.1f} | "
                 f"{100 * (1 - x['eval_energy_J'] / x['eval_time_J']):.1f} % | "
                 f"{x['exudyn_time_J'] / 1e3:.1f} / {x['exudyn_energy_J'] / 1e3:.1f} | "
                 f"{100 * (1 - x['exudyn_energy_J'] / x['exudyn_time_J']):.1f} % |")
    return L


if __name__ == "__main__":
    main()
