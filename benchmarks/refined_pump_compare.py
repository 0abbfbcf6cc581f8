"""Refined commands' pump work on Exudyn, one refinement against another (issue 30).

Reads ``bench_refine.py`` results: the *base* files (a run's parts, e.g. the 400-entry s100f
run) and a *new* run over some of the same entries (refined with other options), and for
each entry of the new run sets its Exudyn pump work and landing beside the base's; with
``--pairs`` (``energy_refined_pairs.py``'s JSON of the base run) also each move's energy
entry (from the base) against the new time entry: what the energy entry saves once its time
entry is refined the new way. Judge: the Exudyn plant with the spec's parameters, pump work
at the shaft, valves closed ``settle`` s after the last command (as ``bench_refine.py``).

    python benchmarks/refined_pump_compare.py --new refine_s100f-t16-p10f.json \
        --base refine_s100f-400-p1.json refine_s100f-400-p3.json … \
        --pairs energy_refined_pairs_s100f-400.json --tag time_priced_t16
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_refine import landed  # noqa: E402
from planner.io import atomic_write_text  # noqa: E402

RESULTS = Path(__file__).parent / "results"


def _rows(files, which):
    out = {}
    for f in files:
        for r in json.loads(Path(f).read_text())["runs"][which]["rows"]:
            out[r["id"]] = r
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--new", required=True)
    ap.add_argument("--base", nargs="+", required=True)
    ap.add_argument("--pairs")
    ap.add_argument("--tag", required=True)
    a = ap.parse_args()
    new = json.loads(Path(a.new).read_text())
    nrow = {r["id"]: r for r in new["runs"]["refined"]["rows"]}
    nom = {r["id"]: r for r in new["runs"]["nominal"]["rows"]}
    base = _rows(a.base, "refined")
    opts = {k: v for k, v in new["options"].items() if k in ("energy_weight", "keep_direction")}
    lines = [f"# Refined commands' pump work on Exudyn: {Path(a.new).name} against the base run",
             "", f"`python benchmarks/refined_pump_compare.py --new {Path(a.new).name} --base "
             f"{' '.join(Path(b).name for b in a.base)}"
             + (f" --pairs {Path(a.pairs).name}" if a.pairs else "") + f" --tag {a.tag}`. "
             "Judge: the Exudyn plant with the spec's parameters, pump work at the shaft over "
             "each replay (valves closed 3 s after the last command). The new run's options "
             f"differ from the base's in {opts} (`{Path(a.new).name}`).", "",
             "| entry | nominal [kJ] | base refined [kJ] | new refined [kJ] | landed base / new "
             "| tip error during the move base / new [mm] |", "| --- | ---: | ---: | ---: | --- | --- |"]
    rb, rn = [], []
    for i in sorted(nrow):
        r, b, n = nrow[i], base[i], nom[i]
        e, eb = r["exudyn"], b["exudyn"]
        rb.append(eb["pump_J"] / n["exudyn"]["pump_J"])
        rn.append(e["pump_J"] / n["exudyn"]["pump_J"])
        lines.append(f"| {i} | {n['exudyn']['pump_J'] / 1e3:.0f} | {eb['pump_J'] / 1e3:.0f} | "
                     f"{e['pump_J'] / 1e3:.0f} | {'yes' if landed(b) else 'no'} / "
                     f"{'yes' if landed(r) else 'no'} | {1e3 * eb['max_track_m']:.0f} / "
                     f"{1e3 * e['max_track_m']:.0f} |")
    sb = sum(base[i]["exudyn"]["pump_J"] for i in nrow)
    sn = sum(r["exudyn"]["pump_J"] for r in nrow.values())
    lines += ["", f"Summed: base {sb / 1e3:.0f} kJ, new {sn / 1e3:.0f} kJ ({100 * (sn / sb - 1):+.1f} %); "
              f"refined / nominal median base {np.median(rb):.2f}, new {np.median(rn):.2f}; "
              f"landed base {sum(landed(base[i]) for i in nrow)} of {len(nrow)}, new "
              f"{sum(landed(r) for r in nrow.values())} of {len(nrow)}."]
    if a.pairs:
        pairs = {x["move"]: x for x in json.loads(Path(a.pairs).read_text())["pairs"]}
        lines += ["", "Each move's energy entry (the base run's refinement) against its time "
                  "entry refined the new way:", "",
                  "| move | energy [kJ] | time base / new [kJ] | saving base / new | nominal "
                  "saving |", "| --- | ---: | --- | --- | ---: |"]
        sv_b, sv_n, sv_0 = [], [], []
        for i in sorted(nrow):
            m = i.rsplit(":", 1)[0]
            if not i.endswith(":time") or m not in pairs:
                continue
            x = pairs[m]
            tn = nrow[i]["exudyn"]["pump_J"]
            sv_b.append(1 - x["refined_energy"] / x["refined_time"])
            sv_n.append(1 - x["refined_energy"] / tn)
            sv_0.append(1 - x["nominal_energy"] / x["nominal_time"])
            lines.append(f"| {m} | {x['refined_energy'] / 1e3:.0f} | "
                         f"{x['refined_time'] / 1e3:.0f} / {tn / 1e3:.0f} | "
                         f"{100 * sv_b[-1]:.1f} % / {100 * sv_n[-1]:.1f} % | {100 * sv_0[-1]:.1f} % |")
        if sv_n:
            lines += ["", f"Median saving of the energy entry: base {100 * np.median(sv_b):.1f} %, "
                      f"new {100 * np.median(sv_n):.1f} % (nominal commands "
                      f"{100 * np.median(sv_0):.1f} %); energy entries dearer than their time "
                      f"entry: base {sum(s < 0 for s in sv_b)}, new {sum(s < 0 for s in sv_n)} "
                      f"of {len(sv_n)}."]
    atomic_write_text(RESULTS / f"{a.tag}.md", "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
