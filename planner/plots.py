"""Matplotlib figures (Agg backend: works without a display)."""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .io import atomic_write_bytes  # noqa: E402


def _save(fig, path):
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
    tl = (f"; dotted: telescope retracted" if pc.tele is not None else "")
    ax.set_title(f"{spec.name}\nreachable tip region at slew 0 (green){tl}", fontsize=10)
    ax.legend(fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    _save(fig, path)
    return dict(r_max=float(np.max(tip[:, 0])), z_min=float(np.min(tip[:, 1])),
                z_max=float(np.max(tip[:, 1])))
