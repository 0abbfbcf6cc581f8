"""A picture of the move: the crane drawn frame by frame in a side view (r–z) and a top view
(x–y), with the tip path, the obstacles and the load, written as an animated GIF, an MP4 or a
self-contained HTML page (``plan --animate``, ``library show --animate``).

Geometry comes from the model: every frame draws the DH frame origins of
:meth:`planner.model.Crane.frame_origins` (the same chain as ``crane.fk``). The side view is
the vertical plane through the slew axis and the tip: a point (x, y, z) is drawn at the signed
distance x·cos φ + y·sin φ along the tip's slew direction φ, so the tip sits at its cylindrical
(r, z). Obstacles: a :class:`~planner.geometry.obstacles.Wall` is a vertical segment at its r
(side) and a circle (top); a :class:`~planner.geometry.obstacles.Plate` (the forwarder's
headboard) a segment across the machine (top) and, in the side view, its cut by the frame's
vertical plane where the plane crosses it — each with its clearance band. The load hangs from
the tip on a link of ``traj.meta["grapple"]["length"]`` [m] at swing angles
``traj.meta["grapple"]["angles"]`` ((N, 2) [rad] about x and y, on the trajectory's samples) when
the trajectory carries them (a simulated grapple); otherwise it is a point at the tip.

Bounded: at most :data:`MAX_FPS` frames per second of the move and :data:`MAX_FRAMES`
frames. A move of duration T at ``fps`` has ``frame_count(T, fps)`` = min(MAX_FRAMES,
max(2, ceil(T·fps) + 1)) frames at equal steps from its first to its last sample (both
included); longer moves play faster than real time (``speedup`` in the result).

matplotlib is imported only here, and this module only by the commands that draw.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import html
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner.geometry.obstacles import Plate, Wall
from planner.io import atomic_write_bytes, atomic_write_text

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["ANIMATION_FORMATS", "MAX_FPS", "MAX_FRAMES", "DEFAULT_FPS", "AnimationError",
           "animation_format", "check_fps", "frame_count", "MoveAnimation", "animate"]

ANIMATION_FORMATS = {".gif": "gif", ".mp4": "mp4", ".html": "html"}
MAX_FPS = 30.0
MAX_FRAMES = 600
DEFAULT_FPS = 20.0
HTML_EMBED_MB = 200.0  # to_jshtml drops frames past matplotlib's embed limit (20 MB): raised


class AnimationError(ValueError):
    """An animation that cannot be written as asked (suffix, writer, frame rate)."""


def animation_format(path) -> str:
    """'gif' | 'mp4' | 'html' from the suffix of ``path`` (case-insensitive); an mp4 only
    when ffmpeg is installed. Anything else raises :class:`AnimationError` (one line)."""
    suffix = Path(str(path)).suffix
    fmt = ANIMATION_FORMATS.get(suffix.lower())
    if fmt is None:
        raise AnimationError(f"animation file {path}: unknown format "
                             f"{suffix or '(no suffix)'!r}; allowed: "
                             f"{', '.join(ANIMATION_FORMATS)}")
    if fmt == "mp4":
        from matplotlib import animation
        if not animation.writers.is_available("ffmpeg"):
            raise AnimationError(f"animation file {path}: .mp4 needs ffmpeg, which is not "
                                 "installed; write .gif or .html instead")
    return fmt


# matplotlib's player loads its button icons (Font Awesome) from a CDN: the buttons get
# text symbols instead, so the page needs nothing from the network
_ICONS = {"minus": "&minus;", "fast-backward": "&#9198;", "step-backward": "&#9664;|",
          "play fa-flip-horizontal": "&#9664;", "pause": "&#9208;", "play": "&#9654;",
          "step-forward": "|&#9654;", "fast-forward": "&#9197;", "plus": "+"}


def self_contained(player: str) -> str:
    """``to_jshtml``'s player without its external stylesheet: each icon a text symbol."""
    out = re.sub(r"<link[^>]*https?://[^>]*>", "", player)
    return re.sub(r'<i class="fa fa-([a-z -]+)"></i>',
                  lambda m: _ICONS.get(m.group(1), m.group(1)), out)


def frame_count(duration: float, fps: float) -> int:
    """Frames of a move of ``duration`` [s] at ``fps`` (module docstring)."""
    return int(min(MAX_FRAMES, max(2, math.ceil(duration * fps - 1e-9) + 1)))


def check_fps(fps) -> float:
    """``fps`` as a float when 0 < fps <= MAX_FPS, else :class:`AnimationError` (one line)."""
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise AnimationError(f"fps = {fps!r}; allowed: 0 < fps <= {MAX_FPS:g}")
    return float(fps)


@dataclass
class MoveAnimation:
    """The figure and its artists, ready to draw frame k (:meth:`draw`); ``times`` [s] of the
    frames, ``fps``, ``speedup`` (move time per second of playback / 1)."""
    fig: object
    times: np.ndarray
    fps: float
    speedup: float
    artists: dict
    _frames: list = field(repr=False, default_factory=list)

    def draw(self, k: int):
        """Set every moving artist to frame k; returns them (FuncAnimation's blit list)."""
        f = self._frames[k]
        a = self.artists
        a["side_crane"].set_data(f["side"][:, 0], f["side"][:, 1])
        a["top_crane"].set_data(f["origins"][:, 0], f["origins"][:, 1])
        a["side_tip"].set_data([f["tip_side"][0]], [f["tip_side"][1]])
        a["top_tip"].set_data([f["tip"][0]], [f["tip"][1]])
        a["side_load"].set_data([f["tip_side"][0], f["load_side"][0]],
                                [f["tip_side"][1], f["load_side"][1]])
        a["top_load"].set_data([f["tip"][0], f["load"][0]], [f["tip"][1], f["load"][1]])
        cut = f["plate_cuts"]
        a["side_plate"].set_data(cut[:, 0], cut[:, 1]) if len(cut) else \
            a["side_plate"].set_data([], [])
        a["clock"].set_text(f"t = {self.times[k]:.2f} s")
        return list(a.values())


def _load_points(traj, times, tip_xyz):
    """The load (x, y, z) at the frame times: on the grapple link when the trajectory carries
    its swing angles, else the tip itself."""
    g = (traj.meta or {}).get("grapple")
    if not g:
        return tip_xyz.copy()
    ang = np.asarray(g["angles"], float)
    L = float(g["length"])
    if ang.shape != (len(traj.t), 2):
        raise AnimationError(f"grapple angles shape {ang.shape}; expected ({len(traj.t)}, 2)")
    ax = np.interp(times, traj.t, ang[:, 0])
    ay = np.interp(times, traj.t, ang[:, 1])
    # hanging straight down, rotated by ax about x, then ay about y
    d = np.column_stack([np.cos(ax) * np.sin(ay), -np.sin(ax), -np.cos(ax) * np.cos(ay)])
    return tip_xyz + L * d


def _plate_cut(p: Plate, phi: float):
    """(r, z) segment where the vertical plane at slew φ crosses the plate, or empty."""
    c, s = math.cos(phi), math.sin(phi)
    if abs(c) < 1e-9:
        return np.zeros((0, 2))
    r = p.x / c
    if not (p.y_min <= r * s <= p.y_max):
        return np.zeros((0, 2))
    return np.array([[r, p.z_bottom], [r, p.z_top]])


def build_animation(crane: Crane, traj, obstacles=(), fps: float = DEFAULT_FPS,
                    title: str = "") -> MoveAnimation:
    """The figure, its artists and every frame's geometry (nothing written)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Rectangle
    fps = check_fps(fps)
    duration = float(traj.t[-1] - traj.t[0])
    n = frame_count(duration, fps)
    times = np.linspace(traj.t[0], traj.t[-1], n)
    q = traj.sample(times)[0]
    q[-1] = traj.q[-1]  # the last frame is the last sample exactly
    q[0] = traj.q[0]
    tip_xyz = np.asarray(crane.fk(q), float).reshape(n, 3)
    load_xyz = _load_points(traj, times, tip_xyz)
    path_xyz = np.asarray(crane.fk(traj.q), float).reshape(-1, 3)
    plates = [o for o in obstacles if isinstance(o, Plate)]
    frames = []
    for k in range(n):
        o = np.asarray(crane.frame_origins(q[k]), float)
        phi = math.atan2(tip_xyz[k, 1], tip_xyz[k, 0])
        h = np.array([math.cos(phi), math.sin(phi)])
        cuts = [_plate_cut(p, phi) for p in plates]
        frames.append(dict(origins=o, side=np.column_stack([o[:, :2] @ h, o[:, 2]]),
                           tip=tip_xyz[k], tip_side=(float(tip_xyz[k, :2] @ h), tip_xyz[k, 2]),
                           load=load_xyz[k], load_side=(float(load_xyz[k, :2] @ h),
                                                        load_xyz[k, 2]),
                           plate_cuts=(np.vstack(cuts) if cuts else np.zeros((0, 2)))))
    fig = Figure(figsize=(10, 4.8), layout="constrained")
    canvas = FigureCanvasAgg(fig)
    # headless: the writers draw every frame when they grab it; the animation's extra
    # draw_idle after each frame would draw it a second time for nothing
    canvas.draw_idle = lambda *args, **kwargs: None
    side, top = fig.subplots(1, 2)
    path_r = np.hypot(path_xyz[:, 0], path_xyz[:, 1])
    side.plot(path_r, path_xyz[:, 2], color="0.55", lw=1, ls="--", label="tip path")
    top.plot(path_xyz[:, 0], path_xyz[:, 1], color="0.55", lw=1, ls="--")
    for ob in obstacles:
        if isinstance(ob, Wall):
            side.plot([ob.r, ob.r], [ob.z_bottom, ob.z_top], color="saddlebrown", lw=4)
            side.add_patch(Rectangle((ob.r - ob.clearance, ob.z_bottom - ob.clearance),
                                     2 * ob.clearance, ob.z_top - ob.z_bottom + 2 * ob.clearance,
                                     color="saddlebrown", alpha=0.15))
            top.add_patch(Circle((0, 0), ob.r, fill=False, color="saddlebrown", lw=3))
        elif isinstance(ob, Plate):
            top.plot([ob.x, ob.x], [ob.y_min, ob.y_max], color="saddlebrown", lw=4)
            top.add_patch(Rectangle((ob.x - ob.clearance, ob.y_min - ob.clearance),
                                    2 * ob.clearance, ob.y_max - ob.y_min + 2 * ob.clearance,
                                    color="saddlebrown", alpha=0.15))
    top.plot([0], [0], "k+", ms=10)
    art = dict(
        side_crane=side.plot([], [], "o-", color="tab:orange", lw=3, ms=4, label="crane")[0],
        top_crane=top.plot([], [], "o-", color="tab:orange", lw=3, ms=4)[0],
        side_plate=side.plot([], [], color="saddlebrown", lw=4, label="obstacle")[0],
        side_load=side.plot([], [], "-s", color="tab:blue", lw=1, ms=7, markevery=[1],
                            label="load")[0],
        top_load=top.plot([], [], "-s", color="tab:blue", lw=1, ms=7, markevery=[1])[0],
        side_tip=side.plot([], [], "o", color="k", ms=5, label="tip")[0],
        top_tip=top.plot([], [], "o", color="k", ms=5)[0],
        clock=side.text(0.02, 0.96, "", transform=side.transAxes, va="top"))
    pts = np.vstack([np.vstack([f["side"] for f in frames]),
                     np.column_stack([path_r, path_xyz[:, 2]])])
    xy = np.vstack([np.vstack([f["origins"][:, :2] for f in frames]), path_xyz[:, :2],
                    load_xyz[:, :2]])
    for ob in obstacles:
        if isinstance(ob, Wall):
            pts = np.vstack([pts, [[ob.r, ob.z_bottom], [ob.r, ob.z_top]]])
            xy = np.vstack([xy, [[ob.r, 0], [-ob.r, 0], [0, ob.r], [0, -ob.r]]])
        elif isinstance(ob, Plate):
            xy = np.vstack([xy, [[ob.x, ob.y_min], [ob.x, ob.y_max]]])
            pts = np.vstack([pts, [[ob.x, ob.z_bottom], [ob.x, ob.z_top]]])
    pts = np.vstack([pts, np.column_stack([[f["load_side"][0] for f in frames],
                                           [f["load_side"][1] for f in frames]])])
    for axis, P, labels, name in ((side, pts, ("r [m] (in the tip's vertical plane)", "z [m]"),
                                   "side view"),
                                  (top, xy, ("x [m]", "y [m]"), "top view")):
        lo, hi = P.min(axis=0), P.max(axis=0)
        pad = 0.08 * float(max(hi - lo)) + 0.2
        axis.set_xlim(lo[0] - pad, hi[0] + pad)
        axis.set_ylim(lo[1] - pad, hi[1] + pad)
        axis.set_aspect("equal", adjustable="box")
        axis.set_xlabel(labels[0])
        axis.set_ylabel(labels[1])
        axis.set_title(name)
        axis.grid(alpha=0.3)
    fig.legend(handles=[h for h in side.lines if not h.get_label().startswith("_")],
               loc="outside lower center", ncol=5, fontsize=8, frameon=False)
    speedup = max(1.0, (duration * fps) / max(1, n - 1)) if duration > 0 else 1.0
    fig.suptitle(title + (f" (played {speedup:.1f}x)" if speedup > 1.0 + 1e-9 else ""))
    anim = MoveAnimation(fig, times, fps, speedup, art, frames)
    anim.draw(0)
    fig.canvas.draw()               # the layout once; per frame it would cost 2-3x the drawing
    fig.set_layout_engine("none")
    return anim


def animate(crane: Crane, traj, path, obstacles=(), fps: float = DEFAULT_FPS, title: str = "",
            dpi: int = 80) -> dict:
    """Write the animation of ``traj`` to ``path`` (format from the suffix,
    :func:`animation_format`), atomically. Returns dict file, format, frames, fps, speedup."""
    from matplotlib import animation, rc_context
    fmt = animation_format(path)
    a = build_animation(crane, traj, obstacles, fps, title)
    fa = animation.FuncAnimation(a.fig, a.draw, frames=len(a.times), interval=1000 / a.fps,
                                 blit=False, repeat=True)
    path = Path(path)
    if fmt == "html":
        with rc_context({"animation.embed_limit": HTML_EMBED_MB, "savefig.dpi": dpi}):
            body = self_contained(fa.to_jshtml(fps=a.fps, default_mode="loop"))
        atomic_write_text(path, "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
                                f"<title>{html.escape(path.stem)}</title></head>\n<body>\n"
                                f"{body}\n</body></html>\n")
    else:
        import tempfile
        writer = (animation.PillowWriter(fps=a.fps) if fmt == "gif"
                  else animation.FFMpegWriter(fps=a.fps))
        with tempfile.TemporaryDirectory(dir=path.parent) as d:
            tmp = Path(d) / f"move.{fmt}"
            fa.save(str(tmp), writer=writer, dpi=dpi)
            atomic_write_bytes(path, tmp.read_bytes())
    return dict(file=str(path), format=fmt, frames=len(a.times), fps=a.fps,
                speedup=a.speedup)
