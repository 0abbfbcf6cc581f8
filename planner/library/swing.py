"""The grapple in a library build: the link the load hangs on, and the swing each entry leaves.

A build with a grapple (``library build --grapple LENGTH``, or the spec's
``[dynamics.grapple]``) hands the link to the methods that plan with it (``nlp-sway``, ``zv``,
``zvd``: :meth:`~planner.methods.base.Planner.library_request`) and stores with every planned
entry what the model predicts the load does along the plan (:func:`swing_attrs`): the load is a
compound pendulum on a two-pin link driven by the tip's acceleration
(:mod:`planner.model.pendulum`), integrated from hanging at rest. The residual swing is the
amplitude the free, undamped swing reaches with the energy it holds when the tip stops; the
load's clearance is the swinging load's centre of mass (tip + link vector) against the suite's
obstacles on a 1 kHz resampling, beside the tip's (``clearance_m``).

The build's setting is a plain pair (length [m] or None for the spec's link, pin damping as a
share of critical or None), picklable for the workers; :func:`pendulum_of` turns it into the
model's :class:`~planner.model.pendulum.Pendulum` where it is used. A library remembers its link
in every entry (``grapple_m``): a resumed build must name the same one (:func:`same_grapple`).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.model.pendulum import Pendulum

__all__ = ["grapple_setting", "pendulum_of", "same_grapple", "swing_attrs", "SWING_ATTRS",
           "GrappleError"]

#: the attributes :func:`swing_attrs` stores per entry (load_clearance_m: with obstacles)
SWING_ATTRS = ("grapple_m", "grapple_zeta", "pendulum_hz", "swing_residual_m", "swing_peak_m",
               "load_clearance_m")


class GrappleError(ValueError):
    """A grapple setting that cannot be used (one line naming the option)."""


def pendulum_of(crane: Crane, grapple: tuple | None) -> Pendulum | None:
    """The model's pendulum of a build's ``grapple`` setting; None without one."""
    if grapple is None:
        return None
    from planner.model.pendulum import Pendulum
    return Pendulum.of(crane, grapple[0], zeta=grapple[1])


def grapple_setting(crane: Crane, grapple, zeta) -> tuple | None:
    """The build's setting of ``grapple`` (a link length [m]; True: the spec's
    ``[dynamics.grapple]``; None or False: none) and ``zeta`` (share of critical damping at
    the pins, or None), checked: :class:`GrappleError` (one line, naming the option)."""
    if grapple is None or grapple is False:
        if zeta is not None:
            raise GrappleError(f"`grapple_zeta` {zeta!r}: needs a grapple (`grapple` a link "
                               "length [m], or True for the spec's [dynamics.grapple])")
        return None
    length = None if grapple is True else grapple
    from planner.model.pendulum import Pendulum
    try:
        Pendulum.of(crane, length, zeta=zeta)
    except (TypeError, ValueError) as e:
        raise GrappleError(str(e).replace("pendulum `length`", "`grapple`")
                           .replace("pendulum `zeta`", "`grapple_zeta`")) from None
    return (None if length is None else float(length), None if zeta is None else float(zeta))


def same_grapple(db, out, pend: Pendulum | None) -> None:
    """Refuse (:class:`GrappleError`, one line) to resume the library ``db`` (at ``out``) when
    its entries were planned for another grapple link, or none, than ``pend``."""
    ids = db.ids()
    if not ids:
        return
    had = db.entry_attrs(ids[0]).get("grapple_m")
    now = None if pend is None else pend.length
    if (had is None) != (now is None) or (had is not None and abs(had - now) > 1e-9):
        def say(v):
            return "no grapple link" if v is None else f"a {v:g} m grapple link"
        raise GrappleError(f"`grapple`: {out} holds entries planned with {say(had)}, this "
                           f"build asks for {say(now)}; allowed: the same link to resume, or "
                           "another library file")


def swing_attrs(crane: Crane, grapple: tuple | None, obstacles, traj) -> dict | None:
    """What an entry of a build with a ``grapple`` stores (None without one): ``grapple_m``
    [m], ``grapple_zeta``, ``pendulum_hz`` of the link; the model's swing along the plan
    ``traj`` (:func:`~planner.model.pendulum.predict_swing`, 200 Hz, from hanging at rest):
    ``swing_residual_m`` (the free swing's amplitude after arrival) and ``swing_peak_m`` (the
    largest offset from under the tip during the move) [m]; with ``obstacles``
    ``load_clearance_m``: the swinging load's least distance to them on a 1 kHz resampling [m]
    (:func:`~planner.methods.shaping.load_clearance`)."""
    pend = pendulum_of(crane, grapple)
    if pend is None:
        return None
    from planner.model.pendulum import predict_swing
    pred = predict_swing(crane, traj, pend)
    out = dict(grapple_m=pend.length, grapple_zeta=pend.zeta,
               pendulum_hz=pend.omega / (2 * math.pi), swing_residual_m=pred.residual_m,
               swing_peak_m=pred.peak_during_m)
    if obstacles:
        from planner.methods.shaping import load_clearance
        out["load_clearance_m"] = load_clearance(crane, traj, pend, obstacles)
    return out
