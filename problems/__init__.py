"""Machine and task specifications shipped with the package (TOML) and their loader."""
from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
CRANES = HERE / "cranes"
TASKS = HERE / "tasks"


def crane_ids() -> list[str]:
    """Ids of the shipped machines (file stems of problems/cranes/*.toml)."""
    return sorted(p.stem for p in CRANES.glob("*.toml"))


def crane_path(crane_id: str) -> Path:
    """Path of a shipped machine spec; a clear error lists the known ids."""
    p = CRANES / f"{crane_id}.toml"
    if not p.exists():
        raise KeyError(f"unknown crane '{crane_id}'; known: {', '.join(crane_ids())} "
                       "(or give a path to a .toml file)")
    return p


def load_crane(crane_id: str):
    """Validated :class:`planner.model.spec.CraneSpec` of a shipped machine or a TOML path."""
    from planner.model.spec import load_spec
    p = Path(crane_id)
    if p.suffix == ".toml" and p.exists():
        return load_spec(p)
    return load_spec(crane_path(crane_id))
