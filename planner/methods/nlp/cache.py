"""Built move NLPs kept on disk: compiled once per machine and formulation, loaded in milliseconds.

Building a :class:`~planner.methods.nlp.move.MoveNLP` means writing its expressions and letting
CasADi derive the exact Jacobian and Hessian (0.3–0.7 s for N = 40); every new process paid it.
With the cache, the NLP's functions are generated as C (CasADi code generation), compiled into a
shared library with the system C compiler, and stored with the numeric rest of the structure
(bounds, block offsets, the energy function) under a key of everything that determines them.
A later process loads the library (a few ms) and solves the same problem with the same numbers.

Entry layout (one folder per key under :func:`cache_root`/nlp/)::

    <key>/meta.json        what the key was made of (versions, formulation), compile seconds
         /nlp.so           the solver's functions (f, g, their derivatives, the Hessian)
         /energy.casadi    the NLP's own energy estimate (serialised casadi.Function)
         /structure.pkl    bounds, block offsets and the other numeric state of the MoveNLP

The key hashes the machine spec (every field), the formulation (objective, path, N, pump,
regularisation, pump margin, obstacles, IPOPT options), the CasADi and package versions and the
source of the modules that write the expressions, so an entry can never be used for anything it
was not built from. An entry is written into a private temporary folder and renamed into place:
concurrent builders (library workers, Dask) each build; the first rename wins and the others use
it. An entry that fails to load (truncated, corrupt, a library for another machine) is removed
and rebuilt, never trusted. Without a C compiler the interpreted NLP is used, as before.

Modes (``MoveNLP(cache=...)``, ``CRANE_PLANNER_NLP_CACHE``): ``off`` — never read or write;
``use`` (default) — load an entry when there is one, else build in memory; ``build`` — load, or
build, compile and store (the compile takes ~1–2 min for N = 40, once per machine and
formulation: ``crane-planner plan … --compile``, ``library build … --compile``).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca

from planner.methods.nlp.stagewise import StagewiseSolver, fatrop_options
from planner.model.numeric import cache_root, compiler, file_digest

__all__ = ["MODES", "cache_root", "entry_key", "load_entry", "store_entry", "build_or_load",
           "mode_from_env", "compiler"]

MODES = ("off", "use", "build")
ENV_MODE = "CRANE_PLANNER_NLP_CACHE"
FORMAT = 1
# the modules whose source writes the NLP's expressions: a change to any invalidates every key
_SOURCES = ("methods/nlp/move.py", "methods/nlp/transcription.py", "methods/nlp/limits.py",
            "methods/nlp/tip.py", "methods/nlp/stagewise.py", "methods/nlp/pump.py",
            "methods/nlp/activity.py", "methods/nlp/hessian.py",
            "model/__init__.py",
            "model/kinematics.py", "model/actuators.py", "model/dynamics.py",
            "model/hydraulics.py", "model/pricing.py", "model/valve_physics.py",
            "model/spec.py", "geometry/obstacles.py")


def mode_from_env(default: str = "use") -> str:
    """The cache mode of ``CRANE_PLANNER_NLP_CACHE`` (off | use | build), else ``default``."""
    m = os.environ.get(ENV_MODE, default).strip().lower()
    if m not in MODES:
        raise ValueError(f"{ENV_MODE}={m!r}: allowed {', '.join(MODES)}")
    return m


def _source_digest() -> str:
    pkg = Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for rel in _SOURCES:
        h.update(rel.encode())
        h.update((pkg / rel).read_bytes())
    return h.hexdigest()


def entry_key(spec, **formulation) -> tuple[str, dict]:
    """(hex key, the description it hashes) of a spec and a formulation."""
    from planner.version import __version__
    desc = dict(format=FORMAT, casadi=ca.__version__, planner=__version__,
                python=f"{sys.version_info[0]}.{sys.version_info[1]}", sources=_source_digest(),
                spec=repr(dataclasses.asdict(spec)),
                formulation={k: repr(v) for k, v in sorted(formulation.items())})
    key = hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:32]
    return key, desc


def _folder(key: str) -> Path:
    return cache_root() / "nlp" / key


def load_entry(key: str, ipopt_opts: dict):
    """(solver, energy function, structure dict) of a stored entry, or None when there is none
    or it does not load (a broken entry is removed so that it is rebuilt). A FATROP entry
    (structure "stages": its permutations and equality rows) comes back wrapped as a
    :class:`~planner.methods.nlp.stagewise.StagewiseSolver`."""
    d = _folder(key)
    if not (d / "meta.json").exists():
        return None
    try:
        meta = json.loads((d / "meta.json").read_text())
        if meta.get("key") != key:
            raise ValueError("key mismatch")
        for name, digest in meta["files"].items():   # a truncated library must never be
            if file_digest(d / name) != digest:          # mapped: that crashes the process
                raise ValueError(f"{name}: checksum mismatch")
        energy = ca.Function.load(str(d / "energy.casadi"))
        with open(d / "structure.pkl", "rb") as f:
            structure = pickle.load(f)
        stages = structure.get("stages")
        if stages is None:
            solver = ca.nlpsol("move", "ipopt", str(d / "nlp.so"),
                               {"print_time": False, "ipopt": dict(ipopt_opts)})
        else:
            solver = StagewiseSolver(ca.nlpsol("move_fatrop", "fatrop", str(d / "nlp.so"),
                                               fatrop_options(stages["equality"], ipopt_opts)),
                                     stages["wperm"], stages["gperm"])
        return solver, energy, structure
    except Exception:   # truncated, corrupt or foreign: never trusted, rebuilt by the caller
        shutil.rmtree(d, ignore_errors=True)
        return None


def store_entry(key: str, desc: dict, solver: ca.Function, energy: ca.Function,
                structure: dict, flags: tuple = ("-O0",)) -> float:
    """Generate, compile and store an entry; returns the seconds it took. Raises RuntimeError
    when no C compiler is available or compilation fails (the caller keeps its in-memory NLP)."""
    cc = compiler()
    if cc is None:
        raise RuntimeError("no C compiler (set CC or install cc/gcc)")
    t0 = time.perf_counter()
    final = _folder(key)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{key}-", dir=final.parent))
    try:
        # the oracle "nlp" (x, p -> f, g) and the derivatives IPOPT calls, as one C file
        cg = ca.CodeGenerator("nlp.c", {"with_header": False})
        inner = getattr(solver, "solver", solver)   # a StagewiseSolver wraps its FATROP solver
        cg.add(inner.oracle())
        for name in inner.get_function():
            cg.add(inner.get_function(name))
        cg.generate(str(tmp) + os.sep)
        r = subprocess.run([cc, "-fPIC", "-shared", *flags, "nlp.c", "-o", "nlp.so", "-lm"],
                           cwd=tmp, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"{cc} failed: {r.stderr.strip()[-400:]}")
        (tmp / "nlp.c").unlink()
        energy.save(str(tmp / "energy.casadi"))
        with open(tmp / "structure.pkl", "wb") as f:
            pickle.dump(structure, f)
        seconds = time.perf_counter() - t0
        files = {n: file_digest(tmp / n) for n in ("nlp.so", "energy.casadi", "structure.pkl")}
        (tmp / "meta.json").write_text(json.dumps(dict(desc, key=key, compile_s=seconds,
                                                       compiler=cc, flags=list(flags),
                                                       files=files), indent=1))
        try:
            os.rename(tmp, final)   # atomic; fails when another builder was first
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
        return seconds
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def build_or_load(nlp, mode: str | None, formulation: dict, build) -> str:
    """Give ``nlp`` (a MoveNLP being constructed) its solver, energy function, layout and bounds:
    from a stored entry when there is one (mode use/build), else by calling ``build()`` and, in
    mode build, storing the result. Returns the cache status: "off", "hit", "miss" (built in
    memory), "stored" (built and stored now) or "no-compiler"/"compile-failed" (built in memory;
    the reason is in ``nlp.cache_error``)."""
    mode = mode_from_env() if mode is None else mode
    if mode not in MODES:
        raise ValueError(f"cache {mode!r}: allowed {', '.join(MODES)}")
    nlp.cache_error = ""
    if mode == "off":
        build()
        return "off"
    key, desc = entry_key(nlp.crane.spec, pricing=nlp.crane.pricing, **formulation)
    got = load_entry(key, formulation["ipopt"])
    if got is not None:
        nlp.solver, nlp.energy_fn, s = got
        nlp.layout, nlp.lbw, nlp.ubw, nlp.lbg, nlp.ubg = (s["layout"], s["lbw"], s["ubw"],
                                                         s["lbg"], s["ubg"])
        nlp.nw = nlp.layout.nw
        return "hit"
    build()
    if mode == "use":
        return "miss"
    structure = dict(layout=nlp.layout, lbw=nlp.lbw, ubw=nlp.ubw, lbg=nlp.lbg, ubg=nlp.ubg)
    if isinstance(nlp.solver, StagewiseSolver):
        structure["stages"] = dict(wperm=nlp.solver.wperm, gperm=nlp.solver.gperm,
                                   equality=nlp.solver.equality)
    try:
        store_entry(key, desc, nlp.solver, nlp.energy_fn, structure)
    except RuntimeError as e:
        nlp.cache_error = str(e)
        return "no-compiler" if compiler() is None else "compile-failed"
    return "stored"
