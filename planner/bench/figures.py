"""The benchmark's figures (PNG, Agg backend): per suite the time–energy scatter of every
move with the Pareto front of its points, per-move bars per method (duration; pump energy on
timed cycles, whose durations are equal), and the joint and actuator-stroke profiles of one move
per method. Units: s, kJ, rad or m."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.bench.methods import method_names
from planner.bench.rows import by_move, succeeded

if TYPE_CHECKING:
    from planner.model import Crane


def _colour(m, methods=None):
    """The method's colour: its place in the bench's method list (the variants first, so
    their colours never depend on what else is registered)."""
    import matplotlib
    methods = list(methods or method_names())
    if m not in methods:
        methods.append(m)
    return matplotlib.colormaps["tab20"](methods.index(m) % 20)


def pareto(points):
    """Indices of the non-dominated (duration, energy) points, by duration."""
    idx = sorted(range(len(points)), key=lambda i: points[i])
    front, best = [], np.inf
    for i in idx:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _grid(n):
    c = min(n, 4)
    return (n + c - 1) // c, c


def fig_time_energy(name, sres, path):
    from planner.plots import plt, save
    R = by_move(sres)
    rows, cols = _grid(len(R))
    fig, axs = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows), squeeze=False)
    seen = {}
    for ax, (mv, rr) in zip(axs.flat, R.items()):
        pts = [(r["duration_s"], r["energy_J"] / 1e3, m) for m, r in rr.items() if succeeded(r)]
        for t, e, m in pts:
            seen[m] = ax.scatter(t, e, color=_colour(m), s=36, edgecolor="k", lw=0.4, zorder=3)
        f = pareto([(t, e) for t, e, _ in pts])
        if f:
            ax.step([pts[i][0] for i in f], [pts[i][1] for i in f], where="post", color="k",
                    lw=1, ls="--", zorder=2)
        ax.set_title(mv, fontsize=9)
        ax.set_xlabel("duration [s]")
        ax.set_ylabel("pump energy [kJ]")
        ax.grid(alpha=0.3)
    for ax in list(axs.flat)[len(R):]:
        ax.axis("off")
    fig.suptitle(f"{name}: time vs pump energy of the successful runs (dashed: Pareto front)")
    fig.tight_layout()
    fig.legend(list(seen.values()), list(seen), loc="center left", fontsize=8,
               bbox_to_anchor=(1.0, 0.5))
    save(fig, path)


def fig_bars(name, sres, path):
    from planner.plots import plt, save
    R = by_move(sres)
    energy = sres["kind"] == "cycle"   # every method runs a cycle's clock: compare energies
    meths = [m for m, s in sres["summary"].items() if s["applicable"]]
    fig, ax = plt.subplots(figsize=(max(7, 1.2 * len(R) * len(meths) / 4), 4.5))
    w = 0.8 / max(1, len(meths))
    for j, m in enumerate(meths):
        for i, (mv, rr) in enumerate(R.items()):
            r = rr.get(m)
            x = i + (j - (len(meths) - 1) / 2) * w
            if succeeded(r):
                ax.bar(x, r["energy_J"] / 1e3 if energy else r["duration_s"], w,
                       color=_colour(m), label=m if i == 0 else None)
            else:
                ax.plot(x, 0, "x", color=_colour(m), label=m if i == 0 else None)
    ax.set_xticks(range(len(R)), list(R))
    ax.set_ylabel("pump energy [kJ]" if energy else "duration [s]")
    what = "pump energy (timed cycles: equal durations)" if energy else "duration"
    ax.set_title(f"{name}: per-move {what} per method (x: failed)")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    save(fig, path)


def fig_profiles(name, keep, crane: Crane, move_id, path):
    """Joint positions (left) and cylinder strokes (right) of one move, one line per method."""
    from planner.plots import plt, save
    n = crane.n
    fig, axs = plt.subplots(n, 2, figsize=(12, 2.2 * n), sharex=True, squeeze=False)
    for m, out in keep.items():
        for k, (t0, tr) in enumerate(out.pieces):
            t = np.linspace(tr.t[0], tr.t[-1], max(50, int(tr.duration * 100)))
            q = tr.sample(t)[0]
            x, _ = crane.stroke(q)
            for i in range(n):
                axs[i, 0].plot(t0 + t, q[:, i], color=_colour(m), lw=1,
                               label=m if (i == 0 and k == 0) else None)
                axs[i, 1].plot(t0 + t, x[:, i], color=_colour(m), lw=1)
    for i, jn in enumerate(crane.names):
        unit = "m" if crane.spec.joints[i].type == "prismatic" else "rad"
        axs[i, 0].set_ylabel(f"{jn} [{unit}]")
        axs[i, 1].set_ylabel(f"{jn} actuator [m]")
        for a in axs[i]:
            a.grid(alpha=0.3)
            lo, hi = a.get_ylim()
            if hi - lo < 1e-6:  # a joint that does not move: no round-off noise scale
                a.set_ylim(lo - 0.05, hi + 0.05)
    axs[-1, 0].set_xlabel("t [s]")
    axs[-1, 1].set_xlabel("t [s]")
    axs[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"{name}, move {move_id}: joints (left) and actuator strokes (right)")
    fig.tight_layout()
    save(fig, path)


__all__ = ["pareto", "fig_time_energy", "fig_bars", "fig_profiles"]
