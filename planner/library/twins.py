"""The twins ``library refine`` works on, built once per process (:func:`spec_twin`) from a
spec's TOML text (the library's stored spec or a ``--model`` file), and what a refinement task
takes of an entry (:func:`entry_arrays`, :func:`entry_grapple`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["model_crane", "spec_twin", "entry_grapple", "entry_arrays"]

_TWINS: dict = {}   # per process: (spec text, options) -> (crane, twin)


def model_crane(spec_text: str, where: str):
    """The crane of a spec TOML text (a library's stored spec, or a ``--model`` file)."""
    import tomllib

    from planner.model import Crane
    from planner.model.spec import parse_spec
    return Crane(parse_spec(tomllib.loads(spec_text), where, spec_text))


def spec_twin(spec_text: str, where: str, step: float, grapple: tuple | None = None):
    """(crane, twin) of a spec TOML text at the twin ``step`` [s], built once per process;
    ``grapple`` (link length [m], pin damping as a share of critical or None): the twin that
    carries the load on that link (:mod:`planner.model.twin.coupled`)."""
    from planner.simulation.twin_plant import twin_of
    key = (spec_text, step, grapple)
    if key not in _TWINS:
        crane = model_crane(spec_text, where)
        if grapple is None:
            _TWINS[key] = (crane, twin_of(crane, step=step))
        else:
            from planner.model.pendulum import Pendulum
            from planner.model.twin import Twin
            if crane.spec.effects:
                raise ValueError(f"model {where}: [[effects]] with a grapple entry: the swing "
                                 "is refined on the bare twin with its link; allowed: a model "
                                 "without effects, or swing_weight 0")
            pend = Pendulum.of(crane, grapple[0], zeta=grapple[1])
            _TWINS[key] = (crane, Twin(crane, step=step, grapple=pend))
    return _TWINS[key]


def entry_grapple(attrs: dict) -> tuple | None:
    """The link an entry was planned with (``library build --grapple``: its ``grapple_m`` and
    ``grapple_zeta``), or None."""
    g = attrs.get("grapple_m")
    if g is None or not np.isfinite(g) or g <= 0:
        return None
    z = attrs.get("grapple_zeta")
    return float(g), (None if z is None or not np.isfinite(z) else float(z))


def entry_arrays(crane: Crane, tr, rate: float) -> dict:
    """An entry's trajectory and nominal commands, as a refinement task takes them."""
    from planner.feedforward import commands, fills_oil, stored_commands
    cmd = stored_commands(tr, rate)
    if cmd is None:
        ff = commands(crane, tr, rate, oil=fills_oil(crane))
        cmd = (ff.t, ff.u)
    return dict(t=tr.t, q=tr.q, qd=tr.qd, qdd=tr.qdd, joint_names=list(tr.joint_names),
                t_u=cmd[0], u=cmd[1])
