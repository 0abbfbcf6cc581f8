"""A whole library replayed open loop on the Exudyn plant, on the build's executors (issue 13,
item 5: "the library replay of 400 entries runs on the existing process pool / Dask executors").

Every ok entry's stored 50 Hz commands drive the Exudyn plant and the fast replay plant
(:func:`planner.library.dynamic.replay_library`), valves closed for ``--settle`` s after the
plan's end. Reported: throughput (entries per minute, CPU per entry) per executor, and the
measures over all entries (judge: Exudyn; the fast plant beside it). A library is built first
(forwarder cycle on s100f, the default build) unless ``--library`` names one.

    python benchmarks/bench_exudyn_library.py --library lib.h5 [--executors processes:2,local:2]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from planner.io import atomic_write_text
from planner.library.dynamic import replay_library


def run(lib: Path, executor: str, limit, settle: float) -> dict:
    kw = (dict(workers=int(executor.split(":")[1])) if executor.startswith("processes:")
          else dict(scheduler=executor))
    done = [0]

    def tick(r):
        done[0] += 1
        if done[0] % 25 == 0:
            print(f"  {executor}: {done[0]} entries", flush=True)
    res = replay_library(lib, limit=limit, settle=settle, on_result=tick, **kw)
    return res


def stats(rows) -> dict:
    ok = [r for r in rows if r.get("status") == "ok"]

    def col(plant, key):
        return np.array([r[plant][key] for r in ok if r[plant].get(key) is not None], float)
    out = dict(ok=len(ok), failed={})
    for r in rows:
        if r.get("status") != "ok":
            out["failed"][r.get("status")] = out["failed"].get(r.get("status"), 0) + 1
    for plant in ("exudyn", "fast"):
        d = {}
        for key in ("max_track_m", "arrival_m", "offset_m", "peak_osc_m"):
            v = col(plant, key)
            if v.size:
                d[key] = dict(median=float(np.median(v)), p90=float(np.percentile(v, 90)),
                              max=float(v.max()))
        st = col(plant, "settle_rest_s")
        d["settled"] = int(np.isfinite(st).sum())
        out[plant] = d
    cpu = np.array([r.get("cpu_s", np.nan) for r in ok], float)
    out["cpu_per_entry_s"] = float(np.nanmedian(cpu)) if cpu.size else float("nan")
    return out


def markdown(rep) -> str:
    L = ["# A library replayed on the Exudyn plant, on the build's executors (issue 13)", "",
         f"{rep['date']}, {rep['platform']}, {rep['cpus']} CPUs, load {rep['load'][0]:.1f} "
         f"{rep['load'][1]:.1f} {rep['load'][2]:.1f}. `python benchmarks/bench_exudyn_library.py "
         f"{rep['argv']}`. Library: {rep['library_desc']}; every ok entry's stored 50 Hz "
         f"commands replayed open loop, valves closed {rep['settle']:g} s after the plan's end "
         "(judge: Exudyn; the fast replay plant beside it).", "",
         "| executor | entries | wall s | entries / min | CPU per entry (median) s | failed |",
         "| --- | ---: | ---: | ---: | ---: | --- |"]
    for e in rep["runs"]:
        s = e["stats"]
        L.append(f"| {e['executor']} | {e['entries']} | {e['seconds']:.0f} | "
                 f"{60 * e['entries'] / e['seconds']:.1f} | {s['cpu_per_entry_s']:.2f} | "
                 f"{s['failed'] or 'none'} |")
    s = rep["runs"][0]["stats"]
    L += ["", f"Measures over the {s['ok']} entries replayed ({rep['runs'][0]['executor']}; "
          "every executor gives the same numbers: `tests/library/test_dynamic_replay.py`):", "",
          "| measure [mm] | Exudyn median / p90 / max | fast plant median / p90 / max |",
          "| --- | --- | --- |"]
    names = dict(max_track_m="tip error during the move", arrival_m="tip error at arrival",
                 offset_m="rest offset from the goal",
                 peak_osc_m="residual oscillation (peak from the rest point)")
    for k, label in names.items():
        cells = []
        for plant in ("exudyn", "fast"):
            d = s[plant].get(k)
            cells.append("–" if d is None else
                         f"{1e3 * d['median']:.1f} / {1e3 * d['p90']:.1f} / {1e3 * d['max']:.1f}")
        L.append(f"| {label} | {cells[0]} | {cells[1]} |")
    L.append(f"| settled within 5 mm of the rest point (count) | {s['exudyn']['settled']} | "
             f"{s['fast']['settled']} |")
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--library", help="an existing library (default: build the forwarder cycle)")
    ap.add_argument("--executors", default="processes:2",
                    help="comma-separated: processes:N, local:N or a scheduler address")
    ap.add_argument("--limit", type=int)
    ap.add_argument("--settle", type=float, default=3.0)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args()
    tmp = None
    if a.library:
        lib, desc = Path(a.library), f"`{Path(a.library).name}` (given)"
    else:
        from planner.library.build import build
        tmp = tempfile.TemporaryDirectory()
        lib = Path(tmp.name) / "lib.h5"
        build("s100f", "forwarder-cycle", lib, objectives=("time", "energy"), workers=2,
              progress=False)
        desc = "the default forwarder-cycle build on s100f (time and energy, built here)"
    runs = []
    for ex in a.executors.split(","):
        t0 = time.perf_counter()
        res = run(lib, ex, a.limit, a.settle)
        runs.append(dict(executor=ex, entries=res["entries"], seconds=time.perf_counter() - t0,
                         stats=stats(res["rows"]), rows=res["rows"]))
        print(ex, res["entries"], f"{runs[-1]['seconds']:.0f} s", flush=True)
    argv = " ".join(x for x in (f"--executors {a.executors}",
                                f"--limit {a.limit}" if a.limit else "",
                                "--library LIB.h5" if a.library else "") if x)
    rep = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
               platform=platform.platform(), cpus=os.cpu_count(), load=os.getloadavg(),
               argv=argv, library_desc=desc, settle=a.settle, runs=runs)
    out = Path(a.out)
    atomic_write_text(out / "exudyn_library.json", json.dumps(rep, indent=1, default=str))
    atomic_write_text(out / "exudyn_library.md", markdown(rep))
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
