"""The calibrated model as a file: the crane spec's TOML with the identified effects appended
as ``[[effects]]`` tables (what ``discrepancy --save-model`` writes; the spec reader loads it
as the machine with those effects, :mod:`planner.model.effects`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from planner.model import Crane


def calibrated_spec_text(crane: Crane, effects, source: str = "") -> str:
    """The crane's TOML spec with the effects appended as ``[[effects]]`` tables."""
    if not crane.spec.text:
        raise ValueError(f"crane '{crane.spec.id}': the spec's TOML text is not available")
    lines = [crane.spec.text.rstrip(), "",
             f"# calibrated: effects identified by crane-planner discrepancy {source}".rstrip()]
    for e in effects:
        lines.append("[[effects]]")
        lines.append(f'name = "{e.name}"')
        if e.joint:
            lines.append(f'joint = "{e.joint}"')
        for k, v in e.values.items():
            lines.append(f"{k} = {v!r}")
    return "\n".join(lines) + "\n"
