"""The twin's pump work of each library entry's replayed commands against Exudyn's (issue 30):
may the pair check of ``library refine`` (:mod:`planner.library.refine_pairs`) decide on the
twin which of a move's two entries is dearer?

Reads the libraries of ``bench_refine.py`` parts (a later library's entry replaces an
earlier's) and ``energy_refined_pairs.py``'s JSON (Exudyn's pump work of each move's refined
energy and time entries, the spec's parameters); runs each entry's refined commands on the
spec's twin (:func:`planner.library.refine_pairs.pump_work`, the valves closed 3 s after the
last command, as the bench's replay) and writes the ratio Exudyn / twin and whether the two
agree on which entry is dearer.

    python benchmarks/twin_pump_check.py --pairs energy_refined_pairs_s100f-400.json \
        --libraries P0.h5 P1.h5 … --tag twin_exudyn_pump_s100f-400
"""
from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from planner.io import atomic_write_text  # noqa: E402
from planner.library.refine_pairs import pump_work  # noqa: E402
from planner.library.refined import entry_commands  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.library.twins import spec_twin  # noqa: E402

RESULTS = Path(__file__).parent / "results"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", required=True)
    ap.add_argument("--libraries", nargs="+", required=True)
    ap.add_argument("--tag", required=True)
    a = ap.parse_args()
    where = {}
    for p in a.libraries:
        with LibraryStore.open(p, "r") as db:
            for r in db.index_rows():
                where[r["id"]] = p
    pairs = json.loads(Path(a.pairs).read_text())["pairs"]
    out = []
    for x in sorted(pairs, key=lambda x: x["move"]):
        J = {}
        for obj in ("time", "energy"):
            i = f"{x['move']}:{obj}"
            with LibraryStore.open(where[i], "r") as db:
                _, twin = spec_twin(db.spec_toml, "<library spec>", 0.002)
                tr = db.trajectory(i)
                t_u, u, _, _ = entry_commands(db, i, tr, "auto")
            J[obj] = pump_work(twin, tr.q[0], t_u, u)
        out.append(dict(move=x["move"], twin_time=J["time"], twin_energy=J["energy"],
                        exudyn_time=x["refined_time"], exudyn_energy=x["refined_energy"]))
    r = np.array([o[f"exudyn_{k}"] / o[f"twin_{k}"] for o in out for k in ("time", "energy")])
    tw = np.array([o["twin_energy"] > o["twin_time"] for o in out])
    ex = np.array([o["exudyn_energy"] > o["exudyn_time"] for o in out])
    md = [f"# The twin's pump work against Exudyn's, {len(out)} moves × 2 entries", "",
          f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M UTC}. `python "
          f"benchmarks/twin_pump_check.py --pairs {Path(a.pairs).name} --libraries "
          f"{' '.join(Path(p).name for p in a.libraries)} --tag {a.tag}`. Each entry's "
          "refined commands (what the library replays) on the spec's twin and on Exudyn "
          "(the spec's parameters: the pairs file's replay), pump work at the shaft, the "
          "valves closed 3 s after the last command.", "",
          f"Exudyn / twin per entry: median {np.median(r):.4f}, min {r.min():.4f}, max "
          f"{r.max():.4f}. Energy entry dearer than its time entry: twin {tw.sum()}, Exudyn "
          f"{ex.sum()}, both {(tw & ex).sum()}, twin only {(tw & ~ex).sum()}, Exudyn only "
          f"{(~tw & ex).sum()} of {len(out)} moves."]
    atomic_write_text(RESULTS / f"{a.tag}.md", "\n".join(md) + "\n")
    atomic_write_text(RESULTS / f"{a.tag}.json", json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
