"""The method registry: every planning method registered once, found by name everywhere.

``crane-planner plan --method NAME``, the benchmark and ``library build --method NAME`` look
methods up here. The built-in methods register themselves when their module is imported; the
registry imports those modules (and any ``crane_planner.methods`` entry point of an installed
plug-in package) the first time a name is looked up, so importing the registry stays cheap.
Looking up one built-in name (:func:`get`) imports its own module only (``BUILTIN_HOMES``: an
NLP plan loads no toppra, and through it no matplotlib, and no package metadata is scanned);
:func:`available` and any other name import them all, the plug-ins included. The names the
built-in modules register belong to them: a plug-in that registers one of them is ignored with
a warning (so a name means the same method however it was looked up).

Adding a method is one module: subclass :class:`~planner.methods.base.Planner` and call
:func:`register` on an instance at import time (or decorate the class with it).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import importlib
import time
import warnings

from planner.methods.base import Planner, PlanRequest, PlanResult

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["register", "unregister", "get", "available", "plan", "BUILTIN_MODULES"]

BUILTIN_MODULES = ("planner.methods.laws", "planner.methods.laws_energy", "planner.methods.dp",
                   "planner.methods.topp", "planner.methods.ruckig", "planner.methods.nlp",
                   "planner.methods.shaping", "planner.methods.sway")
#: the module that registers a built-in name ("law:" for every name of the family); only a
#: shortcut: a name not registered where it is said to be loads every module
BUILTIN_HOMES = {"nlp": ("planner.methods.nlp",), "dp": ("planner.methods.dp",),
                 "topp": ("planner.methods.topp",), "ruckig": ("planner.methods.ruckig",),
                 "zv": ("planner.methods.shaping",), "zvd": ("planner.methods.shaping",),
                 "nlp-sway": ("planner.methods.sway",),
                 "law:": ("planner.methods.laws", "planner.methods.laws_energy")}
ENTRY_POINT_GROUP = "crane_planner.methods"

_REGISTRY: dict[str, Planner] = {}
_loaded = False


def register(planner):
    """Register a :class:`Planner` instance (or class: it is instantiated without arguments)
    under its ``name``; returns what it was given, so it also works as a class decorator. A
    second registration under the same name replaces the first."""
    inst = planner() if isinstance(planner, type) else planner
    if not isinstance(inst, Planner):
        raise TypeError(f"register() takes a Planner, got {type(inst).__name__}")
    if not inst.name or any(c.isspace() for c in inst.name):
        raise ValueError(f"planner name {inst.name!r}: expected a non-empty name without spaces")
    _REGISTRY[inst.name] = inst
    return planner


def unregister(name: str) -> None:
    """Remove ``name`` from the registry (tests that register a temporary method)."""
    _REGISTRY.pop(name, None)


def _load() -> None:
    """Import every built-in module, then the plug-ins' entry points (once)."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    for mod in BUILTIN_MODULES:
        importlib.import_module(mod)
    builtin = dict(_REGISTRY)
    from importlib.metadata import entry_points   # the package metadata: only here
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        ep.load()
    for name, p in builtin.items():
        if _REGISTRY.get(name) is not p:
            warnings.warn(f"method {name!r} of a plug-in ignored: the name is taken by "
                          f"{type(p).__module__}", stacklevel=3)
            _REGISTRY[name] = p


def _load_for(name: str) -> None:
    """Import what registers ``name``: its built-in module(s) when ``BUILTIN_HOMES`` names
    them, everything when it does not or the name is not registered there."""
    if _loaded:
        return
    homes = [m for key, mods in BUILTIN_HOMES.items()
             if name == key or (key.endswith(":") and name.startswith(key)) for m in mods]
    for mod in homes:
        importlib.import_module(mod)
    if name not in _REGISTRY:
        _load()


def available() -> list[str]:
    """Every registered method name, sorted (built-ins: ``dp``, ``law:NAME``, ``nlp``,
    ``ruckig``, ``topp``)."""
    _load()
    return sorted(_REGISTRY)


def get(name: str) -> Planner:
    """The planner registered as ``name``; KeyError naming the known methods otherwise."""
    _load_for(name)
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown method {name!r}: known {', '.join(sorted(_REGISTRY))}") from None


def plan(crane: Crane, request: PlanRequest, method: str = "nlp") -> PlanResult:
    """Plan ``request`` on ``crane`` with the registered ``method``. Raises
    :class:`~planner.methods.base.UnsupportedRequest` for a request the method does not plan;
    every other failure is a result status. Sets ``method`` and (when the method left it at 0)
    ``solve_time_s`` of the result."""
    p = get(method)
    p.check(request)
    t0 = time.perf_counter()
    res = p.plan(crane, request)
    res.method = res.method or p.name
    if not res.solve_time_s:
        res.solve_time_s = time.perf_counter() - t0
    return res
