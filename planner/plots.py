"""Matplotlib figures (Agg backend: works without a display)."""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from planner.io import atomic_write_bytes  # noqa: E402


def save(fig, path):
    """Write ``fig`` as a PNG (110 dpi, tight) to ``path`` atomically and close it."""
    import io
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def _planar(crane, q):
    """(ρ, z) of points given as (x, y, z) at slew 0: ρ along the boom plane."""
    o = crane.frame_origins(q)
    h = np.array([math.cos(crane.chain.psi_h), math.sin(crane.chain.psi_h), 0.0])
    return o @ h, o[:, 2]


def workspace_figure(crane, path, n: int = 90):
    """Reachable r–z region at slew 0 (all telescope values), its joint-limit boundaries, and
    the crane drawn at mid-range. Writes a PNG to ``path``."""
    spec = crane.spec
    L = crane.limit_arrays()
    pc = crane.chain
    b = np.linspace(L["q_min"][pc.boom], L["q_max"][pc.boom], n)
    j = np.linspace(L["q_min"][pc.jib], L["q_max"][pc.jib], n)
    teles = (np.linspace(L["q_min"][pc.tele], L["q_max"][pc.tele], 6) if pc.tele is not None
             else np.zeros(1))
    B, J, T = np.meshgrid(b, j, teles, indexing="ij")
    Q = np.zeros((B.size, crane.n))
    Q[:, pc.boom], Q[:, pc.jib] = B.ravel(), J.ravel()
    if pc.tele is not None:
        Q[:, pc.tele] = T.ravel()
    tip = crane.tip(Q)
    fig, ax = plt.subplots(figsize=(7, 6))
    ax.hist2d(tip[:, 0], tip[:, 1], bins=120, cmin=1, cmap="Greens", alpha=0.6)
    tele_hi = L["q_max"][pc.tele] if pc.tele is not None else 0.0
    tele_lo = L["q_min"][pc.tele] if pc.tele is not None else 0.0
    s = np.linspace(0, 1, 200)
    curves = [
        (pc.boom, "q_min", pc.jib, "C0"), (pc.boom, "q_max", pc.jib, "C1"),
        (pc.jib, "q_min", pc.boom, "C2"), (pc.jib, "q_max", pc.boom, "C3"),
    ]
    for fixed, side, sweep, col in curves:
        for tv, ls in ((tele_hi, "-"), (tele_lo, ":")):
            Qc = np.zeros((len(s), crane.n))
            Qc[:, fixed] = L[side][fixed]
            Qc[:, sweep] = L["q_min"][sweep] + s * (L["q_max"][sweep] - L["q_min"][sweep])
            if pc.tele is not None:
                Qc[:, pc.tele] = tv
            tc = crane.tip(Qc)
            lim = math.degrees(L[side][fixed])
            lab = (f"{spec.joints[fixed].name} at {side[2:]} ({lim:.0f}°)" if ls == "-" else None)
            ax.plot(tc[:, 0], tc[:, 1], ls, color=col, lw=1.4, label=lab)
    qm = 0.5 * (L["q_min"] + L["q_max"])
    qm[pc.slew] = 0.0
    r, z = _planar(crane, qm)
    ax.plot(r, z, "o-", color="k", lw=3, ms=5, label="crane at mid-range")
    ax.axvline(0, color="grey", lw=0.8)
    ax.axhline(0, color="grey", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("r [m] (horizontal distance from the slew axis)")
    ax.set_ylabel("z [m] (height in frame 0)")
    tl = ("; dotted: telescope retracted" if pc.tele is not None else "")
    ax.set_title(f"{spec.name}\nreachable tip region at slew 0 (green){tl}", fontsize=10)
    ax.legend(fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    save(fig, path)
    return dict(r_max=float(np.max(tip[:, 0])), z_min=float(np.min(tip[:, 1])),
                z_max=float(np.max(tip[:, 1])))


def trajectory_figure(crane, ev, path, title: str = "", walls=()):
    """Joint positions, rates relative to their limits, the tip path in r–z, and pump flow /
    power of an evaluated trajectory (an :class:`~planner.trajectory.Evaluation`)."""
    L = crane.limit_arrays()
    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    for i, name in enumerate(crane.names):
        scale, unit = (180 / math.pi, "°") if crane.spec.joints[i].revolute else (1.0, " m")
        ax[0, 0].plot(ev.t, ev.q[:, i] * scale, label=f"{name} [{unit.strip()}]")
        lim = np.where(ev.qd[:, i] >= 0, L["qd_max"][i], -L["qd_min"][i])
        ax[0, 1].plot(ev.t, ev.qd[:, i] / lim, label=name)
    ax[0, 0].set_title("joint positions")
    ax[0, 1].axhline(1, color="k", lw=0.8, ls="--")
    ax[0, 1].axhline(-1, color="k", lw=0.8, ls="--")
    ax[0, 1].set_title("joint rate / limit in the direction of motion")
    ax[1, 0].plot(ev.tip[:, 0], ev.tip[:, 1], "k-")
    ax[1, 0].plot(ev.tip[[0, -1], 0], ev.tip[[0, -1], 1], "ro")
    for w in walls:  # obstacles (e.g. the headboard) with their clearance band
        ax[1, 0].plot([w.r, w.r], [w.z_bottom, w.z_top], color="saddlebrown", lw=4)
        ax[1, 0].add_patch(plt.Rectangle((w.r - w.clearance, w.z_bottom - w.clearance),
                                         2 * w.clearance, w.z_top - w.z_bottom + 2 * w.clearance,
                                         color="saddlebrown", alpha=0.15))
    ax[1, 0].set_aspect("equal", adjustable="datalim")
    ax[1, 0].ticklabel_format(useOffset=False)
    ax[1, 0].margins(0.15)
    ax[1, 0].set_xlabel("r [m]")
    ax[1, 0].set_ylabel("z [m]")
    ax[1, 0].set_title("tip path")
    ax[1, 1].plot(ev.t, ev.hyd["q_pump"] * 6e4, label="pump flow [L/min]")
    ax[1, 1].axhline(crane.spec.pump.max_flow * 6e4, color="C0", ls="--", lw=0.8)
    ax2 = ax[1, 1].twinx()
    ax2.plot(ev.t, ev.hyd["power"] / 1e3, "C1", label="pump power [kW]")
    ax2.set_ylabel("kW")
    ax[1, 1].set_ylabel("L/min")
    ax[1, 1].set_title(f"pump: {ev.energy_J / 1e3:.2f} kJ")
    for a in (ax[0, 0], ax[0, 1], ax[1, 1]):
        a.set_xlabel("t [s]")
        a.grid(alpha=0.3)
    ax[0, 0].legend(fontsize=8)
    ax[0, 1].legend(fontsize=8)
    fig.suptitle(title or f"{crane.spec.id}: {ev.duration:.3f} s", fontsize=11)
    fig.tight_layout()
    save(fig, path)


# ----------------------------------------------------------------------------- discrepancy
def _top_channels(res, k):
    ranked = [c["channel"] for c in res.where["channels"]]
    return ranked[:k]


def _channel_axes(res, k, row_height, extra):
    """One shared-time axis per channel that disagrees most: (fig, axes, t from 0 [s],
    [(channel, its column)])."""
    s = res.series
    cols = list(s["columns"])
    chans = _top_channels(res, k)
    fig, axes = plt.subplots(len(chans), 1, figsize=(9, row_height * len(chans) + extra),
                             sharex=True, squeeze=False)
    return fig, axes, s["t"] - s["t"][0], [(c, cols.index(c)) for c in chans]


def discrepancy_residual_figure(res, path, k: int = 4):
    """Residuals (measured − model) over time, in units of the noise floor, for the k channels
    that disagree most: nominal model and calibrated model; held-out blocks shaded."""
    s = res.series
    fig, axes, t, rows = _channel_axes(res, k, 1.9, 0.6)
    for ax, (c, i) in zip(axes[:, 0], rows):
        sig = s["sigma"][i]
        ax.plot(t, (s["Y"][:, i] - s["Y0"][:, i]) / sig, lw=0.6, color="tab:red",
                label="nominal model")
        ax.plot(t, (s["Y"][:, i] - s["Yf"][:, i]) / sig, lw=0.6, color="tab:blue",
                label="calibrated model")
        ax.axhspan(-1, 1, color="0.85", zorder=0)
        te = s["test"]
        edges = np.flatnonzero(np.diff(np.r_[0, te.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            ax.axvspan(t[a], t[min(b, len(t) - 1)], color="0.95", zorder=-1)
        ax.set_ylabel(f"{c}\n[σ]", fontsize=8)
    axes[0, 0].legend(loc="upper right", fontsize=7, ncol=2)
    axes[-1, 0].set_xlabel("t [s] (light bands: held-out blocks; grey: ±1 σ noise floor)")
    fig.suptitle(f"Residuals — {res.message[:90]}", fontsize=9)
    save(fig, path)


def discrepancy_overlay_figure(res, path, k: int = 2):
    """Measured, nominal and calibrated signals of the k channels that disagree most."""
    s = res.series
    fig, axes, t, rows = _channel_axes(res, k, 2.4, 0.4)
    for ax, (c, i) in zip(axes[:, 0], rows):
        scale, unit = (1e-6, "MPa") if c.startswith("p_") else (1.0, "rad | m")
        ax.plot(t, s["Y"][:, i] * scale, lw=0.5, color="0.5", label="measured")
        ax.plot(t, s["Y0"][:, i] * scale, lw=1.0, color="tab:red", label="nominal model")
        ax.plot(t, s["Yf"][:, i] * scale, lw=1.0, ls="--", color="tab:blue",
                label="calibrated model")
        ax.set_ylabel(f"{c} [{unit}]", fontsize=8)
    axes[0, 0].legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1, 0].set_xlabel("t [s]")
    save(fig, path)


def discrepancy_ranking_figure(res, path, k: int = 12):
    """Held-out score of the best k candidate effects (threshold dashed)."""
    rows = res.ranking[:k]
    fig, ax = plt.subplots(figsize=(7, 0.3 * len(rows) + 1.2))
    names = [r["model"] for r in rows][::-1]
    sc = [r["score"] for r in rows][::-1]
    ax.barh(names, sc, color=["tab:blue" if v > 0 else "0.6" for v in sc])
    ax.set_xscale("symlog", linthresh=10)
    thr = res.series.get("threshold")
    if thr is not None:
        ax.axvline(thr, ls="--", color="k", lw=0.8)
    ax.set_xlabel("held-out score ΔJ − k·ln n (symlog)")
    ax.tick_params(axis="y", labelsize=7)
    save(fig, path)
