"""A work cycle refined as one (issue 27, the work cycle): the chain of
``bench_refine_robust.py`` refined on the twin with :func:`planner.refine.refine_cycle` — each
move from the state the refined move before it leaves (position, residual motion, trapped
chamber pressures) — and replayed back to back as one **Exudyn** recording (the judge), on the
spec's machine and on the first drawn machine of ``refine_robust.json`` (m1: parameters the
twin was not given). Beside it, from ``refine_robust.json``: the same chain with the nominal
commands and with the moves refined alone (each from rest).

    python benchmarks/bench_cycle_refine.py --work DIR [--gap 3.0]

``DIR``: the ``--work`` folder of ``bench_refine_robust.py`` (its ``sel.h5`` and
``chain.json``). The cycle-refined commands go into ``DIR/sel-cycle.h5`` (a copy of
``sel.h5``; kept, so a rerun only replays). Writes benchmarks/results/cycle_refine.md / .json.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_refine_robust import TOL, cycle_task  # noqa: E402
from planner.io import atomic_write_text  # noqa: E402
from planner.library.query import library_crane  # noqa: E402
from planner.library.refined import entry_commands, refined_info, write_refined  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.refine import RefineOptions  # noqa: E402
from planner.refine.cycle import refine_cycle  # noqa: E402

RESULTS = Path(__file__).parent / "results"


def refine(work: Path, gap: float) -> dict:
    """The chain refined as one into DIR/sel-cycle.h5 (skipped when already there)."""
    chain = json.loads((work / "chain.json").read_text())
    dst = work / "sel-cycle.h5"
    if not dst.exists():
        shutil.copyfile(work / "sel.h5", dst)
    with LibraryStore.open(dst, "r") as db:
        done = all((refined_info(db, i) or {}).get("cycle") for i in chain)
    if done:
        return dict(refined_now=False)
    c0, w0 = time.process_time(), time.perf_counter()
    with LibraryStore.open(dst, "a") as db:
        crane = library_crane(db.spec_toml)
        moves = []
        for i in chain:
            tr = db.trajectory(i)
            t_u, u = entry_commands(db, i, tr, "nominal")[:2]
            moves.append((tr, np.asarray(t_u), np.asarray(u)))
        refs, starts = refine_cycle(crane, moves, options=RefineOptions(), gap=gap)
        for k, (i, r) in enumerate(zip(chain, refs)):
            info = dict(r.info(), cycle=dict(position=k, previous=chain[k - 1] if k else None,
                                             gap_s=gap, from_rest=starts[k] is None))
            write_refined(db, i, r.t_u, r.u, info)
    return dict(refined_now=True, refine_cpu_s=time.process_time() - c0,
                refine_wall_s=time.perf_counter() - w0,
                twin=[r.predicted.get("refined") for r in refs],
                statuses=[str(r.status) for r in refs])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", required=True)
    ap.add_argument("--gap", type=float, default=3.0)
    ap.add_argument("--out", default=str(RESULTS))
    a = ap.parse_args(argv)
    work = Path(a.work)
    rob = json.loads((RESULTS / "refine_robust.json").read_text())
    chain = json.loads((work / "chain.json").read_text())
    if chain != rob["chain"] or abs(rob["gap"] - a.gap) > 1e-12:
        raise SystemExit(f"--work {work}: its chain or gap is not the one of "
                         "refine_robust.json (run bench_refine_robust.py on it first)")
    info = refine(work, a.gap)
    machines = [m for m in rob["machines"] if m["name"] in ("spec", "m1")]
    cycles = []
    for m in machines:
        t0 = time.perf_counter()
        c = cycle_task(str(work / "sel-cycle.h5"), chain, "refined", m, a.gap)
        c.update(commands="refined as a cycle", wall_s=time.perf_counter() - t0)
        cycles.append(c)
        print(m["name"], c["status"], f"{c['wall_s']:.0f} s", flush=True)
    rep = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
               argv=" ".join(sys.argv[1:]) if argv is None else " ".join(argv),
               load=os.getloadavg(), chain=chain, gap=a.gap, **info,
               cycles=cycles + [c for c in rob["cycles"] if c["machine"] in ("spec", "m1")])
    out = Path(a.out)
    atomic_write_text(out / "cycle_refine.json", json.dumps(rep, indent=1, default=str))
    atomic_write_text(out / "cycle_refine.md", markdown(rep))
    print(markdown(rep))


def _landed(r) -> bool:
    return (r.get("offset_m") is not None and r["offset_m"] <= TOL
            and r["peak_osc_m"] < TOL)


def markdown(rep) -> str:
    L = ["# A work cycle refined as one, judged on Exudyn (issue 27)", "",
         f"{rep['date']}, `python benchmarks/bench_cycle_refine.py {rep['argv']}`. Judge: the "
         f"**Exudyn plant**. The {len(rep['chain'])} chained s100f entries of "
         "`refine_robust.md` back to back as one recording, the valves closed "
         f"{rep['gap']:g} s between moves; landed = at rest within 5 mm of the goal (mean tip "
         "over the 1.5 s before the next move) and ringing under 5 mm. Machines: `spec` (the "
         "spec's parameters), `m1` (drawn within ±30 %, with a pressure-dependent bulk "
         "modulus; the twin was not given them).", "",
         "| machine | commands | landed | rest offset median / p90 / max [mm] | the move's "
         "own offset, median [mm] | tip error during the move, median [mm] |",
         "| --- | --- | ---: | --- | ---: | ---: |"]
    order = {"nominal": 0, "refined": 1, "refined as a cycle": 2}
    for c in sorted(rep["cycles"], key=lambda c: (c["machine"], order.get(c["commands"], 9))):
        rows = c["rows"]
        if not rows:
            L.append(f"| {c['machine']} | {c['commands']} | {c['status']}: {c['reason']} | | | |")
            continue
        off = np.array([r["offset_m"] for r in rows]) * 1e3
        own = np.array([r["own_m"] for r in rows]) * 1e3
        trk = np.array([r["max_track_m"] for r in rows]) * 1e3
        n_ok = sum(_landed(r) for r in rows)
        label = {"refined": "refined alone (from rest)"}.get(c["commands"], c["commands"])
        L.append(f"| {c['machine']} | {label} | {n_ok} of {len(rows)} | "
                 f"{np.median(off):.1f} / {np.percentile(off, 90):.1f} / {off.max():.1f} | "
                 f"{np.median(own):.1f} | {np.median(trk):.1f} |")
    if rep.get("refined_now"):
        L += ["", f"Refined as a cycle in {rep['refine_wall_s']:.0f} s wall "
              f"({rep['refine_cpu_s']:.0f} s CPU, one process, {len(rep['chain'])} moves)."]
    L += ["", "Per move, the rest offset [mm] in the cycle (nominal / refined alone / refined "
          "as a cycle), on the spec's machine:", "",
          "| # | entry | nominal | alone | as a cycle |", "| ---: | --- | ---: | ---: | ---: |"]
    by = {c["commands"]: c for c in rep["cycles"] if c["machine"] == "spec"}
    if all(k in by and by[k]["rows"] for k in order):
        for k, i in enumerate(rep["chain"]):
            v = [by[w]["rows"][k]["offset_m"] * 1e3 for w in order]
            L.append(f"| {k} | {i} | {v[0]:.1f} | {v[1]:.1f} | {v[2]:.1f} |")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    main()
