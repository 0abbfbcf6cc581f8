"""Matplotlib figures. Every function returns a :class:`matplotlib.figure.Figure` and, given a
path, also writes it there (the format from the suffix: .png, .pdf or .svg — real vector PDF
and SVG) atomically.

No backend is selected on import: the figures are plain ``Figure`` objects (not registered with
pyplot), so they save without any display and show inline in Jupyter when returned. ``plt`` is
re-exported for the benchmark scripts that draw with pyplot; pyplot itself picks Agg when there
is no display.

matplotlib is imported when a figure is made, not with this module: checking a figure path
(:func:`figure_format`, before a command's work) costs nothing, and pyplot is loaded only for
``plt``."""
from __future__ import annotations

from typing import TYPE_CHECKING

import io
import math
import sys
from pathlib import Path

import numpy as np

from planner.io import atomic_write_bytes

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from planner.model import Crane

__all__ = ["FIGURE_FORMATS", "FigureFormatError", "figure_format", "new_figure", "save", "plt",
           "workspace_extent", "reachable_region", "workspace_figure", "trajectory_figure",
           "discrepancy_residual_figure", "discrepancy_overlay_figure",
           "discrepancy_ranking_figure", "PUMP_FLOW_COLOUR", "PUMP_POWER_COLOUR"]

FIGURE_FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
# no date stamps: the same figure gives the same bytes (deterministic outputs)
_METADATA = {"png": {}, "pdf": {"CreationDate": None, "ModDate": None}, "svg": {"Date": None}}
# the pump panel's colours: outside the joints' colour cycle (C0, C1, ... per joint)
PUMP_FLOW_COLOUR = "black"
PUMP_POWER_COLOUR = "darkgoldenrod"


class FigureFormatError(ValueError):
    """A figure path whose suffix is not one of :data:`FIGURE_FORMATS`."""


def figure_format(path) -> str:
    """The matplotlib format name for a figure ``path`` from its suffix (case-insensitive):
    'png', 'pdf' or 'svg'; any other suffix raises :class:`FigureFormatError`."""
    suffix = Path(str(path)).suffix
    fmt = FIGURE_FORMATS.get(suffix.lower())
    if fmt is None:
        raise FigureFormatError(f"figure file {path}: unknown format {suffix or '(no suffix)'!r};"
                                f" allowed: {', '.join(FIGURE_FORMATS)}")
    return fmt


def new_figure(**kw) -> Figure:
    """A Figure outside pyplot (no backend, no global state); ``kw`` go to ``Figure``."""
    from matplotlib.figure import Figure
    return Figure(**kw)


def __getattr__(name):
    # ``plt``: pyplot, imported when a script asks for it (it is never needed to draw here)
    if name == "plt":
        import matplotlib.pyplot as plt
        return plt
    raise AttributeError(f"module 'planner.plots' has no attribute {name!r}")


def save(fig, path, dpi: int = 110) -> None:
    """Write ``fig`` to ``path`` (format from the suffix, see :func:`figure_format`; tight
    bounding box, ``dpi`` for raster output) atomically, and release it from pyplot if it was
    made there."""
    import matplotlib
    fmt = figure_format(path)
    buf = io.BytesIO()
    with matplotlib.rc_context({"svg.hashsalt": "crane-planner"}):  # stable SVG element ids
        fig.savefig(buf, format=fmt, dpi=dpi, bbox_inches="tight", metadata=_METADATA[fmt])
    if "matplotlib.pyplot" in sys.modules:   # a figure made with pyplot: release it there
        sys.modules["matplotlib.pyplot"].close(fig)
    atomic_write_bytes(path, buf.getvalue())


def _finish(fig, path):
    if path is not None:
        save(fig, path)
    return fig


def _planar(crane: Crane, q):
    """(ρ, z) of points given as (x, y, z) at slew 0: ρ along the boom plane."""
    o = crane.frame_origins(q)
    h = np.array([math.cos(crane.chain.psi_h), math.sin(crane.chain.psi_h), 0.0])
    return o @ h, o[:, 2]


def workspace_extent(crane: Crane, n: int = 90) -> dict:
    """Largest reach r_max and the tip height range z_min … z_max [m] at slew 0, from an
    n × n × 6 grid of (boom, jib, telescope) over the joint ranges."""
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
    return dict(r_max=float(np.max(tip[:, 0])), z_min=float(np.min(tip[:, 1])),
                z_max=float(np.max(tip[:, 1])))


def reachable_region(crane: Crane, n: int = 48) -> np.ndarray:
    """The reachable tip region at slew 0 as quadrilaterals in (r, z) [m], shape (M, 4, 2).

    The (boom, jib[, telescope]) box maps onto the plane; a point's preimage is a curve that
    ends on the box's faces, so the images of the faces (each an n × n grid of cells) cover
    the region without gaps — unlike a scatter or histogram of interior samples."""
    L = crane.limit_arrays()
    pc = crane.chain
    axes = [pc.boom, pc.jib] + ([pc.tele] if pc.tele is not None else [])
    lo, hi = L["q_min"], L["q_max"]
    faces = []
    if len(axes) == 2:
        faces.append((pc.boom, pc.jib, None, None))
    else:
        for fixed in axes:
            u, v = [a for a in axes if a != fixed]
            faces += [(u, v, fixed, lo[fixed]), (u, v, fixed, hi[fixed])]
    quads = []
    for u, v, fixed, value in faces:
        U, V = np.meshgrid(np.linspace(lo[u], hi[u], n), np.linspace(lo[v], hi[v], n),
                           indexing="ij")
        Q = np.zeros((U.size, crane.n))
        Q[:, u], Q[:, v] = U.ravel(), V.ravel()
        if fixed is not None:
            Q[:, fixed] = value
        P = crane.tip(Q)[:, :2].reshape(n, n, 2)
        quads.append(np.stack([P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]],
                              axis=2).reshape(-1, 4, 2))
    return np.concatenate(quads)


REGION_COLOUR = "#cfe8c9"  # the reachable region's fill (light green)


def workspace_figure(crane: Crane, path=None, n: int = 90) -> Figure:
    """Reachable r–z region at slew 0 (filled, all telescope values: :func:`reachable_region`),
    its joint-limit boundaries, and the crane drawn at mid-range. Written to ``path`` if given
    (:func:`save`); the extent numbers are :func:`workspace_extent`."""
    spec = crane.spec
    L = crane.limit_arrays()
    pc = crane.chain
    from matplotlib.collections import PolyCollection
    fig = new_figure(figsize=(7, 6))
    ax = fig.subplots()
    # opaque cells with matching edges: no seams; rasterised in PDF / SVG (thousands of cells)
    ax.add_collection(PolyCollection(reachable_region(crane), facecolors=REGION_COLOUR,
                                     edgecolors=REGION_COLOUR, linewidths=0.6, zorder=0,
                                     rasterized=True, label="reachable region"))
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
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("r [m] (horizontal distance from the slew axis)")
    ax.set_ylabel("z [m] (height in frame 0)")
    tl = ("; dotted: telescope retracted" if pc.tele is not None else "")
    ax.set_title(f"{spec.name}\nreachable tip region at slew 0 (green){tl}", fontsize=10)
    ax.legend(fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    return _finish(fig, path)


def _joint_panel(ax, crane: Crane, ev):
    """Joint positions: revolute in degrees on ``ax``, prismatic (telescope) in metres on a
    twin axis of their own (dashed). Joint i is drawn in colour C{i}."""
    prismatic = [i for i, j in enumerate(crane.spec.joints) if not j.revolute]
    axm = ax.twinx() if prismatic else None
    for i, name in enumerate(crane.names):
        if i in prismatic:
            axm.plot(ev.t, ev.q[:, i], "--", color=f"C{i}", label=f"{name} [m] (right)")
        else:
            ax.plot(ev.t, np.degrees(ev.q[:, i]), color=f"C{i}", label=f"{name} [°]")
    ax.set_ylabel("angle [°]")
    handles, labels = ax.get_legend_handles_labels()
    if axm is not None:
        axm.set_ylabel("telescope [m]" if len(prismatic) == 1 else "prismatic joints [m]")
        h2, l2 = axm.get_legend_handles_labels()
        handles, labels = handles + h2, labels + l2
    ax.legend(handles, labels, fontsize=8)
    ax.set_title("joint positions")
    return axm


def _pump_panel(ax, crane: Crane, ev):
    """Pump flow [L/min] (left axis, with its limit) and power [kW] (right axis) in colours
    outside the joints' cycle, one legend for both."""
    ax.plot(ev.t, ev.hyd["q_pump"] * 6e4, color=PUMP_FLOW_COLOUR, label="pump flow [L/min]")
    ax.axhline(crane.spec.pump.max_flow * 6e4, color=PUMP_FLOW_COLOUR, ls=":", lw=0.9,
               label="max pump flow [L/min]")
    axp = ax.twinx()
    axp.plot(ev.t, ev.hyd["power"] / 1e3, "-.", color=PUMP_POWER_COLOUR,
             label="pump power [kW] (right)")
    axp.set_ylabel("power [kW]", color=PUMP_POWER_COLOUR)
    ax.set_ylabel("flow [L/min]")
    ax.set_title(f"pump: {ev.energy_J / 1e3:.2f} kJ")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = axp.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper right")
    return axp


def trajectory_figure(crane: Crane, ev, path=None, title: str = "", walls=()) -> Figure:
    """Joint positions (telescope metres on their own axis), rates relative to their limits,
    the tip path in r–z, and pump flow / power of an evaluated trajectory (an
    :class:`~planner.trajectory.Evaluation`). Written to ``path`` if given."""
    L = crane.limit_arrays()
    from matplotlib.patches import Rectangle
    fig = new_figure(figsize=(11, 7), layout="tight")
    ax = fig.subplots(2, 2)
    _joint_panel(ax[0, 0], crane, ev)
    for i, name in enumerate(crane.names):
        lim = np.where(ev.qd[:, i] >= 0, L["qd_max"][i], -L["qd_min"][i])
        ax[0, 1].plot(ev.t, ev.qd[:, i] / lim, color=f"C{i}", label=name)
    ax[0, 1].axhline(1, color="k", lw=0.8, ls="--")
    ax[0, 1].axhline(-1, color="k", lw=0.8, ls="--")
    ax[0, 1].set_title("joint rate / limit in the direction of motion")
    ax[1, 0].plot(ev.tip[:, 0], ev.tip[:, 1], "k-")
    ax[1, 0].plot(ev.tip[[0, -1], 0], ev.tip[[0, -1], 1], "ro")
    for w in walls:  # obstacles (e.g. the headboard) with their clearance band
        ax[1, 0].plot([w.r, w.r], [w.z_bottom, w.z_top], color="saddlebrown", lw=4)
        ax[1, 0].add_patch(Rectangle((w.r - w.clearance, w.z_bottom - w.clearance),
                                     2 * w.clearance, w.z_top - w.z_bottom + 2 * w.clearance,
                                     color="saddlebrown", alpha=0.15))
    ax[1, 0].set_aspect("equal", adjustable="datalim")
    ax[1, 0].ticklabel_format(useOffset=False)
    ax[1, 0].margins(0.15)
    ax[1, 0].set_xlabel("r [m]")
    ax[1, 0].set_ylabel("z [m]")
    ax[1, 0].set_title("tip path")
    _pump_panel(ax[1, 1], crane, ev)
    for a in (ax[0, 0], ax[0, 1], ax[1, 1]):
        a.set_xlabel("t [s]")
        a.grid(alpha=0.3)
    ax[0, 1].legend(fontsize=8)
    fig.suptitle(title or f"{crane.spec.id}: {ev.duration:.3f} s", fontsize=11)
    return _finish(fig, path)


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
    fig = new_figure(figsize=(9, row_height * len(chans) + extra))
    axes = fig.subplots(len(chans), 1, sharex=True, squeeze=False)
    return fig, axes, s["t"] - s["t"][0], [(c, cols.index(c)) for c in chans]


def discrepancy_residual_figure(res, path=None, k: int = 4) -> Figure:
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
    return _finish(fig, path)


def discrepancy_overlay_figure(res, path=None, k: int = 2) -> Figure:
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
    return _finish(fig, path)


def discrepancy_ranking_figure(res, path=None, k: int = 12) -> Figure:
    """Held-out score of the best k candidate effects (threshold dashed)."""
    rows = res.ranking[:k]
    fig = new_figure(figsize=(7, 0.3 * len(rows) + 1.2))
    ax = fig.subplots()
    names = [r["model"] for r in rows][::-1]
    sc = [r["score"] for r in rows][::-1]
    ax.barh(names, sc, color=["tab:blue" if v > 0 else "0.6" for v in sc])
    ax.set_xscale("symlog", linthresh=10)
    thr = res.series.get("threshold")
    if thr is not None:
        ax.axvline(thr, ls="--", color="k", lw=0.8)
    ax.set_xlabel("held-out score ΔJ − k·ln n (symlog)")
    ax.tick_params(axis="y", labelsize=7)
    return _finish(fig, path)
