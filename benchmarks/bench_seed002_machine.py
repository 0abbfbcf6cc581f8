#!/usr/bin/env python3
"""Seed 002's energy study under the machine pricing, judged on the Exudyn plant (issue 30).

    python benchmarks/bench_seed002_machine.py [--cycle-speeds 0.5 1.0] [--no-online]
                                               [--out benchmarks/results]

The same runs as sections C and E of ``bench_exudyn_claims.py`` (its :func:`cycles` and
:func:`online_laws`), with the crane under both pricings of :mod:`planner.model.pricing`:

* C. seed 002's cycles (h, v, d at ``--cycle-speeds``): law:jla, dp:energy and
  nlp:energy-path planned by the bench's cycle runners on the crane of each pricing (the DP and
  the path NLP minimise that pricing's pump work), every cycle's commands replayed open loop on
  the Exudyn plant (1 s of rest after); the savings against JLA by evaluate() (the pricing the
  plan was made with) and on Exudyn.
* E. the laws (JLA, Q-optimal, P¹, P²) closed loop on the Exudyn plant on v@1 (P-optimal
  reading the plant's pressures), gains 5/s and 1/s, beside the same laws on the quasi-static
  model (evaluate() under each pricing). The Exudyn runs do not depend on the pricing (the laws
  do not read it); only the quasi-static column does.

Judges: **Exudyn** (the independent plant) and **evaluate()** (the quasi-static model, the
pricing named). Writes <out>/seed002_machine.md and .json.
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

from bench_exudyn_claims import cycles, online_laws  # noqa: E402
from planner import Crane  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycle-speeds", type=float, nargs="+", default=[0.5, 1.0])
    ap.add_argument("--pricings", nargs="+", default=["machine", "seed"])
    ap.add_argument("--no-online", action="store_true", help="skip section E")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = dict(command=" ".join(["python", *sys.argv]), cycles={}, online={})
    args.out.mkdir(parents=True, exist_ok=True)
    for pricing in args.pricings:
        crane = Crane.from_id("s100f", pricing=pricing)
        log(f"cycles, {pricing} pricing")
        res["cycles"][pricing] = cycles(crane, args.cycle_speeds)
        save(res, args.out, t0)
    if not args.no_online:
        for pricing in args.pricings:
            log(f"online laws, {pricing} pricing")
            res["online"][pricing] = online_laws(Crane.from_id("s100f", pricing=pricing))
            save(res, args.out, t0)
    log(f"wrote {args.out / 'seed002_machine.md'}")


def save(res, out, t0):
    res.update(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=list(os.getloadavg())),
               wall_s=time.perf_counter() - t0)
    atomic_write_text(out / "seed002_machine.json", dumps(res))
    atomic_write_text(out / "seed002_machine.md", "\n".join(markdown(res)) + "\n")


def _pct(a, b):
    return f"{100 * (1 - a / b):.1f} %" if np.isfinite(a) and np.isfinite(b) and b else ""


def markdown(res) -> list:
    m = res["machine"]
    L = ["# Seed 002's energy study under the machine pricing, on the Exudyn plant (issue 30)",
         "", f"{res['date']}, {m['platform']}, {m['cpus']} CPUs, load average "
         f"{' / '.join(f'{x:.1f}' for x in m['load'])}. `{res['command']}` "
         f"({res['wall_s'] / 60:.1f} min). Judges: **Exudyn** = the independent plant (open "
         "loop from the plan's commands in C, closed loop in E); **evaluate()** = the "
         "quasi-static model under the pricing named (the one the plan was made with). "
         "Pump energy at the shaft.", "",
         "## C. Seed 002's cycles, planned and priced under each pricing", "",
         "| cycle | pricing | method | evaluate() [kJ] | vs JLA (evaluate()) | Exudyn [kJ] | "
         "vs JLA (Exudyn) | Exudyn / evaluate() |",
         "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for pricing, rows in res["cycles"].items():
        for r in rows:
            j = next((x for x in rows if x["cycle"] == r["cycle"] and x["method"] == "law:jla"),
                     None)
            if r["status"] != "ok":
                L.append(f"| {r['cycle']} | {pricing} | {r['method']} | {r['status']}: "
                         f"{r['reason'][:60]} | | | | |")
                continue
            ex = r.get("exudyn", {}).get("pump_J", np.nan)
            ej = j.get("exudyn", {}).get("pump_J", np.nan) if j and j["status"] == "ok" else np.nan
            same = r is j
            L.append(f"| {r['cycle']} | {pricing} | {r['method']} | "
                     f"{r['energy_eval_J'] / 1e3:.1f} | "
                     f"{'' if same or not j else _pct(r['energy_eval_J'], j['energy_eval_J'])} | "
                     f"{ex / 1e3:.1f} | {'' if same else _pct(ex, ej)} | "
                     f"{ex / r['energy_eval_J']:.2f} |")
    if res["online"]:
        L += ["", "## E. The laws closed loop on the Exudyn plant (v@1)", "",
              "| pricing of evaluate() | correction gain [1/s] | law | evaluate() [kJ] | vs JLA "
              "| Exudyn closed loop [kJ] | vs JLA | max tip error [mm] (Exudyn) |",
              "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |"]
        for pricing, rows in res["online"].items():
            for r in rows:
                j = next(x for x in rows if x["gain"] == r["gain"] and x["law"] == "jla")
                same = r is j
                L.append(f"| {pricing} | {r['gain']:g} | {r['law']} | "
                         f"{r['energy_eval_J'] / 1e3:.1f} | "
                         f"{'' if same else _pct(r['energy_eval_J'], j['energy_eval_J'])} | "
                         f"{r.get('pump_J', np.nan) / 1e3:.1f} | "
                         f"{'' if same else _pct(r.get('pump_J', np.nan), j.get('pump_J', np.nan))}"
                         f" | {1e3 * r['max_tip_error_m']:.1f} |")
    return L


if __name__ == "__main__":
    main()
