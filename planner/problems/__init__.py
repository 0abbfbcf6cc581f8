"""Where the shipped machines and task suites live: package data, located and never parsed here.

``cranes/<id>.toml`` holds one machine specification, ``tasks/<name>.toml`` one task suite; both
ship inside the package (``[tool.setuptools.package-data]``), so an installed copy finds them next
to this file. This module only maps ids to paths: it imports nothing from the rest of
:mod:`planner`, so every layer may use it. Reading a file is the model's business
(:func:`planner.model.load_crane`, :func:`planner.model.spec.load_spec`) and the task layer's
(:func:`planner.tasks.suites.load_suite`).

An id that is not shipped gives a :class:`KeyError` that lists the known ids; a path to an
existing ``.toml`` file is accepted wherever an id is.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["HERE", "CRANES", "TASKS", "crane_ids", "crane_path", "crane_file", "task_ids",
           "task_path"]

HERE = Path(__file__).resolve().parent
CRANES = HERE / "cranes"
TASKS = HERE / "tasks"


def _ids(folder: Path) -> list[str]:
    return sorted(p.stem for p in folder.glob("*.toml"))


def _given_file(name) -> Path | None:
    """``name`` as a path (as given) when it names an existing ``.toml`` file, else None."""
    p = Path(name)
    return p if p.suffix == ".toml" and p.is_file() else None


def crane_ids() -> list[str]:
    """Ids of the shipped machines (file stems of ``planner/problems/cranes/*.toml``)."""
    return _ids(CRANES)


def crane_path(crane_id: str) -> Path:
    """Path of a shipped machine spec; a KeyError lists the known ids."""
    p = CRANES / f"{crane_id}.toml"
    if not p.is_file():
        raise KeyError(f"unknown crane '{crane_id}'; known: {', '.join(crane_ids())} "
                       "(or give a path to a .toml file)")
    return p


def crane_file(crane_id_or_path) -> Path:
    """The spec file of a shipped machine id, or the path given when it names a ``.toml``
    file; a KeyError lists the known ids otherwise."""
    given = _given_file(crane_id_or_path)
    return given if given is not None else crane_path(str(crane_id_or_path))


def task_ids() -> list[str]:
    """Names of the shipped task suites (file stems of ``planner/problems/tasks/*.toml``)."""
    return _ids(TASKS)


def task_path(name) -> Path:
    """The file of a shipped task suite (by name) or of a path to a ``.toml`` file; a KeyError
    lists the known suites."""
    given = _given_file(name)
    if given is not None:
        return given
    p = TASKS / f"{name}.toml"
    if not p.is_file():
        raise KeyError(f"unknown task suite '{name}'; known: {', '.join(task_ids())} "
                       "(or a path to a .toml)")
    return p
