#!/usr/bin/env python3
"""Where the pump energy of the Exudyn plant differs from ``evaluate()``'s (issue 13): the gap
broken down by loss term, on the library entries of ``bench_exudyn_claims.py`` (s100f).

    python benchmarks/bench_exudyn_energy_gap.py [--library LIB.h5] [--limit K]
                                                 [--out benchmarks/results]

For every ok entry of the claims' forwarder-cycle subset library (built with the project's
builder, afresh, unless ``--library`` names one) the stored 50 Hz commands are replayed open loop on the
Exudyn plant (valves closed 3 s after the plan's end) and the plan is judged by ``evaluate()``
(1 kHz). Both figures are hydraulic pump work (before the pump's efficiency, which both divide
by alike). The quasi-static work splits into meter-in throttling (Σ (p_pump − p_load,i)·Q_i),
the change of the crane's mechanical energy from start to goal (ΔE: potential, both ends at
rest) and what the loads took and gave away again (braking, lowering: Σ p_load,i·Q_i − ΔE,
which the quasi-static model lets vanish in the return line); the Exudyn work into the terms
of its energy balance (:func:`planner.simulation.dynamic.energy.energy_balance`). The gap is
then exactly

    W_exudyn − W_quasi-static = friction + (meter-out throttling, Exudyn − what the
    quasi-static loads gave away) + (meter-in throttling, Exudyn − quasi-static)
    + (oil compression, make-up, leakage, end stops, pump line)
    + (ΔE Exudyn − ΔE plan: the open-loop replay ends elsewhere) + (the balance's residual).

The quasi-static figure is priced as the crane prices it by default — the machine pricing of
issue 30 (:mod:`planner.model.pricing`); each row also carries the seed pricing's figure
(``w_qs_seed_J``) and the machine pricing's without its effects with memory, the held chamber
pair and the closing spools' tails (``w_qs_static_J``: sample by sample), and the report
gives the ratio Exudyn / evaluate() under each (median, p90, range; the target of issue 30:
within 5 %).

Writes <out>/exudyn_energy_gap.md and .json.
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

from bench_exudyn_claims import build_library, subset_suite  # noqa: E402
from planner import Crane, evaluate  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.simulation.dynamic.claims import replay_move, stored_commands  # noqa: E402
from planner.simulation.dynamic.energy import energy_balance  # noqa: E402
from planner.simulation.dynamic.exudyn_plant import ExudynPlant  # noqa: E402

#: the Exudyn balance's terms the quasi-static model has no counterpart of
DYNAMIC_ONLY = ("friction_J", "meter_out_J", "makeup_J", "leakage_J", "end_stops_J",
                "tank_return_J", "oil_J", "pump_line_J")
COLUMNS = ("friction_J", "meter_out_diff_J", "meter_in_diff_J", "oil_J", "other_dynamic_J",
           "mechanical_diff_J", "residual_J")


def _integral(t, y):
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def entry_gap(crane, plant, traj, seed=None, keep=False):
    """The gap of one plan (module doc), in J (``seed``: the crane under the seed pricing,
    whose figure is added as ``w_qs_seed_J``; ``keep``: return (row, evaluation, Exudyn run),
    the last two None when the replay failed)."""
    ev = evaluate(crane, traj)
    h = ev.hyd
    w_qs = _integral(ev.t, h["p_pump"] * h["q_pump"])
    throttle_qs = _integral(ev.t, h["throttle_loss"])
    t_u, u = stored_commands(traj)
    m, run, _ = replay_move(crane, traj, t_u=t_u, u=u, settle=3.0, plant=plant, keep_runs=True)
    if m.status != "ok":
        row = dict(status=m.status, reason=m.reason)
        return (row, None, None) if keep else row
    b = energy_balance(plant, run)
    mech = b["kinetic_J"] + b["potential_J"] + b.get("grapple_swing_J", 0.0)
    pe = crane.potential_energy(traj.q[[0, -1]])
    d_plan = float(pe[1] - pe[0])
    given_away = (w_qs - throttle_qs) - d_plan
    row = dict(status="ok", w_qs_J=w_qs, w_exudyn_J=b["pump_work_J"],
               throttle_qs_J=throttle_qs, load_work_qs_J=w_qs - throttle_qs,
               delta_e_plan_J=d_plan, given_away_qs_J=given_away,
               meter_in_exudyn_J=b["meter_in_J"], meter_out_exudyn_J=b["meter_out_J"],
               mechanical_exudyn_J=mech, friction_J=b["friction_J"], oil_J=b["oil_J"],
               other_dynamic_J=sum(b[k] for k in DYNAMIC_ONLY
                                   if k not in ("friction_J", "meter_out_J", "oil_J")),
               meter_out_diff_J=b["meter_out_J"] - given_away,
               meter_in_diff_J=b["meter_in_J"] - throttle_qs,
               mechanical_diff_J=mech - d_plan, residual_J=b["residual_J"])
    if seed is not None:
        es = evaluate(seed, traj)
        row["w_qs_seed_J"] = _integral(es.t, es.hyd["p_pump"] * es.hyd["q_pump"])
    qs = crane.hydraulics(ev.q, ev.qd, ev.qdd)   # sample by sample: no held pair, no tail
    row["w_qs_static_J"] = _integral(ev.t, qs["p_pump"] * qs["q_pump"])
    row["gap_J"] = row["w_exudyn_J"] - w_qs
    row["closure_J"] = row["gap_J"] - sum(row[k] for k in COLUMNS)   # 0 by construction
    return (row, ev, run) if keep else row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--library", type=Path, help="an existing library of the claims subset")
    ap.add_argument("--limit", type=int, default=0, help="first K ok entries (0: all)")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--work", type=Path, default=Path(os.environ.get("TMPDIR", "/tmp"))
                    / "crane-energy-gap")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    crane = Crane.from_id("s100f")
    args.work.mkdir(parents=True, exist_ok=True)
    lib = args.library or build_library(args.work, subset_suite(
        args.work / "forwarder-cycle-claims.toml"))[0]
    seed = Crane.from_id("s100f", pricing="seed")
    plant = ExudynPlant(crane)
    rows = []
    with LibraryStore.open(lib) as store:
        ids = [r["id"] for r in store.index_rows() if r["status"] == "ok"]
        ids = ids[:args.limit] if args.limit else ids
        for k, eid in enumerate(ids):
            r = dict(id=eid, objective=store.entry_attrs(eid).get("objective"),
                     **entry_gap(crane, plant, store.trajectory(eid), seed))
            rows.append(r)
            if r["status"] == "ok":
                print(f"{k + 1}/{len(ids)} {eid}: quasi-static {r['w_qs_J'] / 1e3:.1f} kJ, "
                      f"Exudyn {r['w_exudyn_J'] / 1e3:.1f} kJ", file=sys.stderr, flush=True)
    res = dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
               pricing=crane.pricing,
               machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            load=list(os.getloadavg())),
               library=str(lib), rows=rows, wall_s=time.perf_counter() - t_start)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "exudyn_energy_gap.json", dumps(res))
    atomic_write_text(args.out / "exudyn_energy_gap.md", "\n".join(markdown(res)))
    print(f"wrote {args.out / 'exudyn_energy_gap.md'}", file=sys.stderr)


def markdown(res) -> list:
    ok = [r for r in res["rows"] if r["status"] == "ok"]
    L = ["# The pump-energy gap between the Exudyn plant and `evaluate()`, by loss term "
         "(issue 13)", "",
         f"{res['date']}, {res['machine']['platform']}, {res['machine']['cpus']} CPUs. "
         f"`python benchmarks/bench_exudyn_energy_gap.py` ({res['wall_s'] / 60:.1f} min): "
         f"{len(ok)} of {len(res['rows'])} library entries of the forwarder-cycle subset "
         "(s100f, time and energy NLP) replayed open loop from their stored 50 Hz commands "
         "on the Exudyn plant; hydraulic pump work of the replay against `evaluate()`'s "
         "quasi-static figure for the plan. The gap splits exactly (see the script's doc) into "
         "the terms below; 'meter-out' is the return-side throttling of the Exudyn run minus "
         "the energy the quasi-static loads give away on braking and lowering (which that "
         "model lets vanish at no pump cost): what the load-holding valves' counter-pressure "
         "costs the pump.", ""]
    labels = dict(friction_J="actuator friction",
                  meter_out_diff_J="meter-out throttling, Exudyn − given away quasi-statically",
                  meter_in_diff_J="meter-in throttling, Exudyn − quasi-static",
                  oil_J="oil compression (chambers)",
                  other_dynamic_J="make-up, leakage, end stops, pump line",
                  mechanical_diff_J="ΔE mechanical, Exudyn − plan (ends elsewhere)",
                  residual_J="energy balance residual (Exudyn)")
    L += ratio_table(ok, res.get("pricing", "seed"))
    for obj in ("time", "energy", None):
        rs = [r for r in ok if obj is None or r["objective"] == obj]
        if not rs:
            continue
        qs = np.array([r["w_qs_J"] for r in rs])
        ex = np.array([r["w_exudyn_J"] for r in rs])
        gap = ex - qs
        L += [f"## {'all entries' if obj is None else obj + ' entries'} ({len(rs)})", "",
              f"Sum over the entries: quasi-static {qs.sum() / 1e3:.1f} kJ, Exudyn "
              f"{ex.sum() / 1e3:.1f} kJ (× {ex.sum() / qs.sum():.3f}; per entry median × "
              f"{np.median(ex / qs):.3f}, range {np.min(ex / qs):.3f}–{np.max(ex / qs):.3f}); "
              f"gap {gap.sum() / 1e3:.1f} kJ.", "",
              "| term | sum kJ | share of the gap | per entry median kJ | per entry range kJ |",
              "| --- | ---: | ---: | ---: | --- |"]
        for k in COLUMNS:
            v = np.array([r[k] for r in rs])
            L.append(f"| {labels[k]} | {v.sum() / 1e3:.2f} | "
                     f"{100 * v.sum() / gap.sum():.0f} % | {np.median(v) / 1e3:.2f} | "
                     f"{v.min() / 1e3:.2f} … {v.max() / 1e3:.2f} |")
        L.append("")
        if obj is None:
            closure = max(abs(r["closure_J"]) for r in rs)
            L += [f"The split closes to {closure:.1e} J per entry (by construction). "
                  "Quasi-static meter-in throttling over the entries: "
                  f"{sum(r['throttle_qs_J'] for r in rs) / 1e3:.1f} kJ (Exudyn "
                  f"{sum(r['meter_in_exudyn_J'] for r in rs) / 1e3:.1f} kJ), its load work "
                  f"{sum(r['load_work_qs_J'] for r in rs) / 1e3:.1f} kJ of which "
                  f"{sum(r['given_away_qs_J'] for r in rs) / 1e3:.1f} kJ given away again "
                  f"(Exudyn meter-out throttling "
                  f"{sum(r['meter_out_exudyn_J'] for r in rs) / 1e3:.1f} kJ).", ""]
    return L


def ratio_table(ok, pricing) -> list:
    """Exudyn / evaluate() pump work per entry, under the crane's pricing and the seed's."""
    L = ["## Exudyn / evaluate() pump work per entry (issue 30: within 5 %)", "",
         "| entries | pricing | median | p90 | range | sum ratio |",
         "| --- | --- | ---: | ---: | --- | ---: |"]
    for obj in ("time", "energy", None):
        rs = [r for r in ok if obj is None or r["objective"] == obj]
        if not rs:
            continue
        ex = np.array([r["w_exudyn_J"] for r in rs])
        for name, key in ((pricing, "w_qs_J"),
                          (f"{pricing}, per sample (no held pair, no spool tail)",
                           "w_qs_static_J"),
                          ("seed", "w_qs_seed_J")):
            if key != "w_qs_J" and (pricing == "seed" or key not in rs[0]):
                continue
            qs = np.array([r[key] for r in rs])
            ratio = ex / qs
            L.append(f"| {'all' if obj is None else obj} ({len(rs)}) | {name} | "
                     f"{np.median(ratio):.3f} | {np.percentile(ratio, 90):.3f} | "
                     f"{ratio.min():.3f}–{ratio.max():.3f} | {ex.sum() / qs.sum():.3f} |")
    return L + [""]


if __name__ == "__main__":
    main()
