"""The residual distributions of a library replayed open loop, nominal vs refined commands
(issue 27): from a ``bench_refine.py`` results file (a part or the merged run), the empirical
distribution over the entries of the rest offset from the goal, the ringing after the plan's
end and the tip error during the move, one panel each, the nominal commands (inverted from the
quasi-static model) beside the commands refined on the dynamic twin. Judge: whatever replayed
the results — ``bench_refine.py`` replays on the Exudyn plant; the title says which machine.

    python benchmarks/refine_distribution.py benchmarks/results/refine_s100f-400.json \
        [--out benchmarks/results/refine_s100f-400.png]

Draws from the results alone (no simulation): an entry whose replay failed is drawn at the
right edge of each panel (it did not land) and counted in the legend.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

#: (field of the Exudyn measures, panel title, issue 27's line [mm]: 5 mm at rest and ringing,
#: a 20 mm median during the move)
PANELS = (("offset_m", "rest offset from the goal", 5.0),
          ("peak_osc_m", "ringing after the plan's end", 5.0),
          ("max_track_m", "tip error during the move", 20.0))


def values(rows: list, field: str) -> tuple:
    """(sorted values [mm] of the ok rows, number of rows that failed)."""
    v = [1e3 * r["exudyn"][field] for r in rows
         if r.get("status") == "ok" and r.get("exudyn") and r["exudyn"].get(field) is not None]
    return np.sort(np.asarray(v, float)), len(rows) - len(v)


def draw(rep: dict, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(1, len(PANELS), figsize=(13, 3.8))
    for ax, (field, title, line) in zip(axs, PANELS):
        for which, style in (("nominal", "C3-"), ("refined", "C0-")):
            rows = rep["runs"][which]["rows"]
            v, failed = values(rows, field)
            n = len(rows)
            if not n:
                continue
            share = np.arange(1, v.size + 1) / n
            med = f"{np.median(v):.1f}" if v.size else "–"
            label = f"{which} (median {med} mm" + (f", {failed} failed)" if failed else ")")
            ax.step(np.maximum(v, 1e-2), share, style, where="post", label=label)
        if line is not None:
            ax.axvline(line, color="0.4", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel(f"{title} [mm]")
        ax.set_ylim(0, 1.0)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    axs[0].set_ylabel("share of entries at or below")
    fig.suptitle(f"{rep['crane']}: {rep['selected']} library entries open loop on the Exudyn "
                 "plant (the spec's parameters), nominal vs refined on the twin", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".part" + out.suffix)
    fig.savefig(tmp, dpi=110)
    tmp.replace(out)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", help="a bench_refine.py results file (JSON)")
    ap.add_argument("--out", help="the figure (PNG; default: beside the results, same stem)")
    a = ap.parse_args(argv)
    try:
        rep = json.loads(Path(a.results).read_text())
        rep["runs"]["nominal"]["rows"], rep["runs"]["refined"]["rows"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        print(f"results: {a.results!r} is not a bench_refine.py results file ({e}); expected "
              "the JSON that bench_refine.py writes", file=sys.stderr)
        return 2
    out = Path(a.out) if a.out else Path(a.results).with_suffix(".png")
    draw(rep, out)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
