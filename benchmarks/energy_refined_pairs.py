"""Energy entries against time entries on Exudyn, with the nominal and the refined commands
(issues 27 and 30).

Reads results of ``bench_refine.py`` (parts or a merged run) and pairs each move's energy entry
with its time entry (same move id, both in the files). Judge: the Exudyn plant with the spec's
parameters; the figure is its pump work at the shaft (``pump_J``) over the replay, the valves
closed ``settle`` s after the last command. Per pair the saving 1 − E_energy / E_time, for the
nominal commands (inverted from the quasi-static model) and for the commands refined on the
twin (what the library replays once refined); the median and the saving over the sum, how many
energy entries cost more than their time entry, and the refined / nominal pump work ratio per
objective.

    python benchmarks/energy_refined_pairs.py refine_s100f-400-p0-v3.json \
        refine_s100f-400-p1.json [--tag s100f-400-p01]
"""
from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_refine import landed as _landed  # noqa: E402  (its landing rule)
from planner.io import atomic_write_text  # noqa: E402


def _rows(files: list) -> dict:
    """{(commands, entry id): row} over the files (a later file's row replaces an earlier)."""
    out = {}
    for f in files:
        d = json.loads(Path(f).read_text())
        for which, run in d["runs"].items():
            for r in run["rows"]:
                out[which, r["id"]] = r
    return out


def pairs(rows: dict) -> list:
    """One dict per move with both entries replayed with both commands: pump work [J]."""
    moves = sorted({i.rsplit(":", 1)[0] for _, i in rows})
    out = []
    for m in moves:
        keys = [(w, f"{m}:{o}") for w in ("nominal", "refined") for o in ("energy", "time")]
        if not all(k in rows and rows[k].get("status") == "ok"
                   and (rows[k].get("exudyn") or {}).get("pump_J") for k in keys):
            continue
        J = {f"{w}_{k.rsplit(':', 1)[1]}": rows[w, k]["exudyn"]["pump_J"] for w, k in keys}
        J["move"] = m
        J["landed_energy"] = _landed(rows["refined", f"{m}:energy"])
        J["landed_time"] = _landed(rows["refined", f"{m}:time"])
        out.append(J)
    return out


def summary(P: list) -> dict:
    s = {}
    for w in ("nominal", "refined"):
        e = np.array([p[f"{w}_energy"] for p in P])
        t = np.array([p[f"{w}_time"] for p in P])
        save = 1.0 - e / t
        s[w] = dict(median_saving=float(np.median(save)), sum_saving=float(1 - e.sum() / t.sum()),
                    p10_saving=float(np.percentile(save, 10)),
                    costlier=int(np.sum(e > t)), worst=float(save.min()))
    for o in ("energy", "time"):
        r = np.array([p[f"refined_{o}"] / p[f"nominal_{o}"] for p in P])
        s[f"refined_over_nominal_{o}"] = dict(median=float(np.median(r)),
                                              p90=float(np.percentile(r, 90)),
                                              max=float(r.max()),
                                              above_1_35=int(np.sum(r > 1.35)))
    both = [p for p in P if p["landed_energy"] and p["landed_time"]]
    if both:
        e = np.array([p["refined_energy"] for p in both])
        t = np.array([p["refined_time"] for p in both])
        s["refined_both_landed"] = dict(pairs=len(both),
                                        median_saving=float(np.median(1 - e / t)),
                                        sum_saving=float(1 - e.sum() / t.sum()),
                                        costlier=int(np.sum(e > t)))
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+", help="bench_refine.py results (JSON)")
    ap.add_argument("--tag", default="s100f")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    a = ap.parse_args()
    P = pairs(_rows(a.files))
    if not P:
        sys.exit("energy_refined_pairs: no move has both its energy and its time entry "
                 "replayed with both commands in these files")
    S = summary(P)
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    L = [f"# Energy entries against time entries on Exudyn, nominal and refined commands "
         f"({a.tag})", "",
         f"{date}. `python benchmarks/energy_refined_pairs.py "
         f"{' '.join(Path(f).name for f in a.files)} --tag {a.tag}`. Judge: the Exudyn plant "
         f"with the spec's parameters, its pump work at the shaft over each replay (the valves "
         f"closed after the last command, as `bench_refine.py` replays). {len(P)} moves with "
         f"both entries.", "",
         "| commands | median saving of the energy entry | saving over the sum | p10 | "
         "worst | energy entries costlier than their time entry |",
         "| --- | ---: | ---: | ---: | ---: | ---: |"]
    for w in ("nominal", "refined"):
        r = S[w]
        L.append(f"| {w} | {100 * r['median_saving']:.1f} % | {100 * r['sum_saving']:.1f} % | "
                 f"{100 * r['p10_saving']:.1f} % | {100 * r['worst']:.1f} % | "
                 f"{r['costlier']} of {len(P)} |")
    L += ["", "Refined / nominal pump work (Exudyn), per objective:", "",
          "| entries | median | p90 | max | above 1.35 × |", "| --- | ---: | ---: | ---: | ---: |"]
    for o in ("energy", "time"):
        r = S[f"refined_over_nominal_{o}"]
        L.append(f"| {o} | {r['median']:.2f} | {r['p90']:.2f} | {r['max']:.2f} | "
                 f"{r['above_1_35']} of {len(P)} |")
    if "refined_both_landed" in S:
        r = S["refined_both_landed"]
        L += ["", f"Over the {r['pairs']} moves whose two refined entries both land (≤ 5 mm at "
              f"rest, < 5 mm ringing): median saving {100 * r['median_saving']:.1f} %, over the "
              f"sum {100 * r['sum_saving']:.1f} %, {r['costlier']} energy entries costlier."]
    L += ["", "| move | nominal energy / time [kJ] | refined energy / time [kJ] | "
          "refined saving | landed (energy, time) |", "| --- | --- | --- | ---: | --- |"]
    for p in P:
        L.append(f"| {p['move']} | {p['nominal_energy'] / 1e3:.0f} / {p['nominal_time'] / 1e3:.0f}"
                 f" | {p['refined_energy'] / 1e3:.0f} / {p['refined_time'] / 1e3:.0f} | "
                 f"{100 * (1 - p['refined_energy'] / p['refined_time']):.1f} % | "
                 f"{'yes' if p['landed_energy'] else 'no'}, "
                 f"{'yes' if p['landed_time'] else 'no'} |")
    out = Path(a.out)
    atomic_write_text(out / f"energy_refined_pairs_{a.tag}.json",
                      json.dumps(dict(date=date, files=[str(f) for f in a.files], summary=S,
                                      pairs=P), indent=1))
    atomic_write_text(out / f"energy_refined_pairs_{a.tag}.md", "\n".join(L) + "\n")
    print("\n".join(L[:12]))


if __name__ == "__main__":
    main()
