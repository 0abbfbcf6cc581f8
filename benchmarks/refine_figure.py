"""The residual figure with the refined commands beside the nominal ones (issue 27): library
entries replayed open loop on the Exudyn plant (the judge) with their nominal and their
twin-refined commands; per entry the tip's distance from the plan during the move and from
the goal after it, one panel each.

    python benchmarks/refine_figure.py --library SEL.h5 --entries ID[,ID…]
                                       [--out benchmarks/results/refine_residual.png]

``SEL.h5``: a library whose entries carry refined commands (``library refine``, e.g. the
``--work`` folder of ``bench_refine.py`` / ``bench_refine_robust.py``).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from planner.library.refined import entry_commands  # noqa: E402
from planner.library.store import LibraryStore  # noqa: E402
from planner.simulation.dynamic.claims import replay_move  # noqa: E402

SETTLE = 3.0
TOL = 0.005


def runs(path: Path, entry: str):
    """(crane, plan, {commands: (measures, Exudyn run)}) of one entry."""
    from planner.library.query import library_crane
    with LibraryStore.open(path) as db:
        crane = library_crane(db.spec_toml)
        traj = db.trajectory(entry)
        cmds = {w: entry_commands(db, entry, traj, w)[:2] for w in ("nominal", "refined")}
    out = {}
    for w, (t_u, u) in cmds.items():
        m, run, _ = replay_move(crane, traj, t_u=t_u, u=u, settle=SETTLE, tol=TOL,
                                keep_runs=True)
        out[w] = (m, run)
    return crane, traj, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--library", required=True)
    ap.add_argument("--entries", required=True, help="comma list of entry ids")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"
                                         / "refine_residual.png"))
    a = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ids = a.entries.split(",")
    fig, axs = plt.subplots(len(ids), 2, figsize=(10, 3.2 * len(ids)), squeeze=False)
    for row, eid in zip(axs, ids):
        crane, traj, rr = runs(Path(a.library), eid)
        goal = crane.fk(traj.q[-1:])[0]
        for w, style in (("nominal", "C3-"), ("refined", "C0-")):
            m, run = rr[w]
            tip = crane.fk(run.q)
            ref = crane.fk(traj.sample(np.clip(run.t, traj.t[0], traj.t[-1]))[0])
            during = run.t <= traj.t[-1]
            row[0].plot(run.t[during], 1e3 * np.linalg.norm(tip - ref, axis=1)[during], style,
                        lw=1.2, label=f"{w}: max {1e3 * m.exudyn['max_track_m']:.0f} mm")
            after = run.t >= traj.t[-1] - 0.5
            row[1].plot(run.t[after] - traj.t[-1],
                        1e3 * np.linalg.norm(tip[after] - goal, axis=1), style, lw=1.2,
                        label=f"{w}: rest {1e3 * m.exudyn['offset_m']:.1f} mm, ringing "
                              f"{1e3 * m.exudyn['peak_osc_m']:.1f} mm")
        row[0].set_xlabel("time [s]")
        row[0].set_ylabel("tip distance from the plan [mm]")
        row[0].set_title(f"{eid}: during the move ({traj.duration:.1f} s)", fontsize=9)
        row[1].axvline(0, color="k", lw=0.8)
        row[1].axhline(1e3 * TOL, color="k", lw=0.6, ls=":")
        row[1].set_yscale("symlog", linthresh=1.0)
        row[1].set_ylim(bottom=0.0)
        row[1].set_xlabel("time after the planned arrival [s]")
        row[1].set_ylabel("tip distance from the goal [mm]")
        row[1].set_title(f"{eid}: arrival and rest (valves closed after the last command)",
                         fontsize=9)
        for ax in row:
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    fig.suptitle("s100f forwarder moves replayed open loop on the Exudyn plant: nominal "
                 "feed-forward vs commands refined on the dynamic twin", fontsize=10)
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)
    plt.close(fig)
    print(a.out)


if __name__ == "__main__":
    main()
