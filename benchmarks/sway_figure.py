#!/usr/bin/env python3
"""The README figure of issue 29: the load's swing on one s100f forwarder move, judged on the
Exudyn plant with the grapple on its link — the sway-blind minimum-time plan (``nlp``), its ZVD
shaping (``zvd``) and the sway-free plan (``nlp-sway``) with its valve commands refined on the
dynamic twin that carries the load on its link, with the swing term (``+ffs``, as
``benchmarks/bench_sway.py``).

    python benchmarks/sway_figure.py [--move p05-d00] [--length 1.5] [--zeta 0.05]
                                     [--settle 6] [--ff-iterations 80] [--swing-weight 10]
                                     [--out benchmarks/results/sway_figure]
    python benchmarks/sway_figure.py --draw-only     # the figure again from the saved series

Each plan's 50 Hz commands (nominal for ``nlp`` and ``zvd``, refined for ``nlp-sway+ffs``) are
replayed open loop on the plant, then ``--settle`` s with the valves closed. Plotted: the
horizontal distance of the load's centre of mass from under the tip
(:func:`planner.simulation.plants.load_swing`, the plant's own tree) against time, each plan's
arrival marked. The series go to ``OUT.json`` (with the command line, date and the numbers
quoted in the caption), the figure to ``OUT.png``. matplotlib is imported only to draw.
"""
from __future__ import annotations

import argparse
import json
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

LABELS = {"nlp": "sway-blind (nlp)", "zvd": "ZVD shaping (zvd)",
          "nlp-sway+ffs": "sway-free (nlp-sway, twin-refined)"}
COLOURS = {"nlp": "tab:red", "zvd": "tab:blue", "nlp-sway+ffs": "tab:green"}


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def measure(args) -> dict:
    """Plan, refine and replay the three on the plant: the series and their numbers."""
    from bench_exudyn_claims import subset_suite
    from planner import Crane
    from planner.bench.context import Settings
    from planner.bench.suites import build_suite
    from bench_sway_robust import move_commands
    from planner.methods import PlanRequest, plan
    from planner.model.effects import make
    from planner.model.pendulum import Pendulum
    from planner.simulation.plants import load_swing, make_plant
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    t_start = time.perf_counter()
    crane = Crane.from_id("s100f")
    pend = Pendulum.of(crane, args.length, zeta=args.zeta)
    plant = make_plant("exudyn", crane, [make("grapple_swing", length=args.length,
                                              damping=round(pend.damping, 1))])
    work = Path(os.environ.get("TMPDIR", "/tmp")) / "crane-sway-figure"
    work.mkdir(parents=True, exist_ok=True)
    suite = build_suite(str(subset_suite(work / "forwarder-cycle-claims.toml")),
                        Settings(forwarder_moves=10 ** 6))
    mv = next((m for m in suite.moves if m.id == args.move), None)
    if mv is None:
        raise SystemExit(f"--move {args.move}: not a move of the suite; allowed: "
                         + ", ".join(m.id for m in suite.moves))
    obstacles = tuple(suite.obstacles)
    opts = {"grapple": args.length, "grapple_zeta": args.zeta}
    series = {}
    for name in ("nlp", "zvd", "nlp-sway+ffs"):
        method = name.split("+")[0]
        res = plan(crane, PlanRequest(mv.start, mv.goal, obstacles=obstacles,
                                      options={} if method == "nlp" else opts), method)
        if not res.ok:
            raise SystemExit(f"{name} on {mv.id}: {res.status}: {res.reason}")
        tr = res.trajectory
        t_u, u = move_commands(crane, tr, name, pend, args)
        rec = plant.run(t_u, u, tr.q[0], t_end=float(t_u[-1]), rate=50.0)
        if not rec.ok:
            raise SystemExit(f"{name} on {mv.id}: the plant run stopped: {rec.status}")
        ts, sw = load_swing(plant, rec)
        r = np.linalg.norm(sw, axis=1)
        T = float(tr.duration)
        keep = np.unique(np.searchsorted(ts, np.arange(0.0, ts[-1], 0.01)))   # 100 Hz
        series[name] = dict(t=ts[keep].tolist(), swing_m=r[keep].tolist(), duration_s=T,
                            residual_m=float(r[ts >= T].max()),
                            during_m=float(r[ts <= T].max()))
        s = series[name]
        log(f"{mv.id} {name:13s} T = {T:.2f} s, swing after arrival "
            f"{s['residual_m'] * 1e3:.0f} mm, during {s['during_m'] * 1e3:.0f} mm")
    return dict(date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                             load=list(os.getloadavg())),
                command="python benchmarks/sway_figure.py " + " ".join(sys.argv[1:]),
                move=mv.id, start=list(mv.start), goal=list(mv.goal), length_m=args.length,
                zeta=args.zeta, pendulum_hz=pend.omega / (2 * np.pi), settle_s=args.settle,
                judge="Exudyn plant (grapple_swing effect on its link)",
                series=series, wall_s=time.perf_counter() - t_start)


def draw(res: dict, path: Path) -> None:
    """The figure: the swing against time, one line per plan, its arrival dashed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8.0, 3.6), dpi=150)
    blind = res["series"]["nlp"]["duration_s"]
    for name, s in res["series"].items():
        c = COLOURS[name]
        ax.plot(s["t"], np.asarray(s["swing_m"]) * 1e3, color=c, lw=1.4,
                label=f"{LABELS[name]}: {s['duration_s']:.2f} s "
                      f"({s['duration_s'] / blind:.2f}×), {s['residual_m'] * 1e3:.0f} mm after")
        ax.axvline(s["duration_s"], color=c, ls="--", lw=0.9)
    ax.set_xlabel("time [s] (dashed: arrival; valves closed afterwards)")
    ax.set_ylabel("load offset from under the tip [mm]")
    ax.set_title(f"s100f forwarder move {res['move']}, {res['length_m']:g} m grapple link "
                 f"({res['pendulum_hz']:.2f} Hz), judged on the Exudyn plant", fontsize=9)
    ax.set_xlim(0, max(s["t"][-1] for s in res["series"].values()))
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7.5, loc="upper right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--move", default="p05-d00", help="a move of the bench's forwarder subset")
    ap.add_argument("--length", type=float, default=1.5, help="link length [m]")
    ap.add_argument("--zeta", type=float, default=0.05, help="pin damping, share of critical")
    ap.add_argument("--settle", type=float, default=6.0, help="valves closed after arrival [s]")
    ap.add_argument("--ff-iterations", type=int, default=80)
    ap.add_argument("--swing-weight", type=float, default=10.0)
    ap.add_argument("--out", type=Path, default=HERE / "results" / "sway_figure",
                    help="stem of OUT.json (the series) and OUT.png (the figure)")
    ap.add_argument("--draw-only", action="store_true",
                    help="draw OUT.png from the saved OUT.json without running anything")
    args = ap.parse_args(argv)
    js, png = args.out.with_suffix(".json"), args.out.with_suffix(".png")
    if args.draw_only:
        res = json.loads(js.read_text())
    else:
        res = measure(args)
        js.parent.mkdir(parents=True, exist_ok=True)
        js.write_text(json.dumps(res) + "\n")
    draw(res, png)
    log(f"wrote {png}")


if __name__ == "__main__":
    main()
