"""The energy NLP's activity rounds started warm vs cold, on library moves (issue 15).

The energy entry of a library move (s100f, forwarder cycle, the headboard obstacle) is
:func:`~planner.methods.nlp.energy_optimal` at 1.2 × the minimum time. Its NLP re-solves while
the set of active pump-draw terms grows (≤ 4 rounds). Cold: every round from the previous
solution but with IPOPT's barrier back at its start (the earlier behaviour,
``CRANE_PLANNER_NLP_WARM_ROUNDS=0``). Warm (default): the later rounds from the previous
solution and its multipliers (planner/methods/nlp/twins.py). Per move, both on the same
minimum-time result, interleaved; the judge of the energy is ``evaluate()`` (the quasi-static
model), the seconds are the whole ``energy_optimal`` call.

    python benchmarks/bench_energy_rounds.py [--moves 36]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from planner import Crane
from planner.io import atomic_write_text
from planner.library.build import ENERGY_BUDGET
from planner.methods.nlp.energy import energy_optimal
from planner.methods.nlp.move import MoveNLP
from planner.tasks.suites import load_suite
from planner.trajectory import evaluate

ENV = "CRANE_PLANNER_NLP_WARM_ROUNDS"


def run(moves: int) -> dict:
    crane = Crane.from_id("s100f")
    meta, suite = load_suite("forwarder-cycle")
    obst = tuple(meta["obstacles"])
    sel = [suite[i] for i in np.unique(np.linspace(0, len(suite) - 1, moves).round().astype(int))]
    tn = MoveNLP(crane, "time", "free", N=40, obstacles=obst)
    en = MoveNLP(crane, "energy", "free", N=40, obstacles=obst)
    en.build_twins()
    rows = []
    for k, m in enumerate(sel):
        rt = tn.solve(m.start, m.goal)
        T = ENERGY_BUDGET * rt.duration_s
        row = dict(move=m.id, T_min=rt.duration_s)
        for mode in (("cold", "warm") if k % 2 == 0 else ("warm", "cold")):
            os.environ[ENV] = "1" if mode == "warm" else "0"
            t0 = time.perf_counter()
            r, info = energy_optimal(crane, m.start, m.goal, T, time_result=rt, time_nlp=tn,
                                     energy_nlp=en)
            dt = time.perf_counter() - t0
            ev = evaluate(crane, r.trajectory)
            row[mode] = dict(s=dt, energy_J=ev.energy_J, winner=info["winner"],
                             iterations=r.stats.get("iterations", 0),
                             violation=ev.max_limit_violation)
        print(m.id, {k2: (round(v["s"], 2), round(v["energy_J"] / 1e3, 2), v["winner"])
                     for k2, v in row.items() if k2 in ("cold", "warm")}, flush=True)
        rows.append(row)
    os.environ.pop(ENV, None)
    return dict(rows=rows)


def history(md: Path) -> str:
    """The hand-kept "History …" paragraph of an earlier report (earlier runs and what changed
    in between), so that a re-run keeps it; "" when there is none."""
    if not md.exists():
        return ""
    paras = md.read_text(encoding="utf-8").split("\n\n")
    return next((p.strip() for p in paras if p.startswith("History")), "")


def report(res: dict, header: str, hist: str = "") -> str:
    rows = res["rows"]
    s = {m: np.array([r[m]["s"] for r in rows]) for m in ("cold", "warm")}
    E = {m: np.array([r[m]["energy_J"] for r in rows]) for m in ("cold", "warm")}
    dE = E["warm"] / E["cold"] - 1
    viol = max(r[m]["violation"] for r in rows for m in ("cold", "warm"))
    out = [header, "",
           "| measure | cold rounds | warm rounds |", "| --- | ---: | ---: |",
           f"| seconds, sum over {len(rows)} moves | {s['cold'].sum():.1f} | "
           f"{s['warm'].sum():.1f} ({s['warm'].sum() / s['cold'].sum() - 1:+.0%}) |",
           f"| pump energy (evaluate), sum [kJ] | {E['cold'].sum() / 1e3:.1f} | "
           f"{E['warm'].sum() / 1e3:.1f} ({E['warm'].sum() / E['cold'].sum() - 1:+.2%}) |",
           f"| energy warm vs cold per move: median / min / max | | {np.median(dE):+.2%} / "
           f"{dE.min():+.2%} / {dE.max():+.2%} |",
           f"| NLP won against the incumbents | "
           f"{sum(r['cold']['winner'] == 'nlp' for r in rows)} | "
           f"{sum(r['warm']['winner'] == 'nlp' for r in rows)} |",
           f"| worst evaluate() violation | | {viol:.4%} (both) |", ""]
    if hist:
        out += [hist, ""]
    out += ["| move | T_min s | cold s | cold kJ | cold it. | warm s | warm kJ | warm it. | "
           "winner (cold / warm) |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        c, w = r["cold"], r["warm"]
        out.append(f"| {r['move']} | {r['T_min']:.3f} | {c['s']:.2f} | {c['energy_J'] / 1e3:.2f} | "
                   f"{c['iterations']} | {w['s']:.2f} | {w['energy_J'] / 1e3:.2f} | "
                   f"{w['iterations']} | {c['winner']} / {w['winner']} |")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--moves", type=int, default=36)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args()
    t0 = time.time()
    res = run(a.moves)
    load = os.getloadavg()
    header = ("# Energy NLP: activity rounds warm vs cold (issue 15)\n\n"
              f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, "
              f"{platform.platform()}, {os.cpu_count()} CPUs, load {load[0]:.1f} {load[1]:.1f} "
              f"{load[2]:.1f}, {time.time() - t0:.0f} s. `python benchmarks/bench_energy_rounds.py "
              f"--moves {a.moves}`. s100f forwarder-cycle moves spread over the suite, energy "
              "entry as the library plans it (1.2 × T_min, headboard obstacle); cold and warm "
              "interleaved per move on the same minimum-time result; energy judged by evaluate().")
    out = Path(a.out)
    atomic_write_text(out / "energy_rounds.json", json.dumps(dict(res, moves=a.moves), indent=1))
    atomic_write_text(out / "energy_rounds.md",
                      report(res, header, history(out / "energy_rounds.md")))


if __name__ == "__main__":
    main()
