"""The bookkeeping of a transcribed NLP: decision variables, constraints and parameters in
named blocks, and IPOPT's return status as a result code.

A :class:`Layout` collects the pieces of an NLP in the order they are added, so the
formulation reads as the formulation::

    lay = Layout()
    X = lay.add_var("X", (6, N + 1), lo, hi)     # a new CasADi symbol, bounds broadcast
    lay.add_con("dynamics", X[:, 1:] - ..., 0.0, 0.0)
    lay.add_con("dynamics", ...)                 # a block may grow: rows are kept per name
    ...
    w, g = lay.w, lay.g                          # vertcat of the blocks, in order
    w_opt[lay.slice("X")].reshape(lay.shape("X"), order="F")

Variables are stacked column by column (CasADi's ``vec``), bounds likewise. Parameters are
declared once (:meth:`Layout.parameters`) and packed by name (:meth:`Layout.pack`).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from planner.methods.base import PlanResult, PlanStatus

__all__ = ["Layout", "STATUS_OK", "IPOPT_CODES", "ipopt_code", "nlp_result"]

STATUS_OK = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
IPOPT_CODES = {"Infeasible_Problem_Detected": PlanStatus.INFEASIBLE,
               "Maximum_Iterations_Exceeded": PlanStatus.MAX_ITER,
               "Restoration_Failed": PlanStatus.RESTORATION_FAILED,
               "Maximum_WallTime_Exceeded": PlanStatus.TIMEOUT}


def ipopt_code(status: str) -> PlanStatus:
    """The result code of an IPOPT return status (``failed`` for the unnamed ones)."""
    return IPOPT_CODES.get(status, PlanStatus.FAILED)


def nlp_result(status: PlanStatus | str, reason: str = "", **kw) -> PlanResult:
    """An NLP's result: status "ok" or a short code ("infeasible", "max_iter", "error",
    "unreachable", "obstacle", …); stats ``energy_model_J`` (the NLP's own conservative energy
    estimate, NaN when not computed), ``iterations``, ``ipopt_status`` and the solver
    details."""
    kw.setdefault("energy_model_J", float("nan"))
    kw.setdefault("iterations", 0)
    kw.setdefault("ipopt_status", "")
    return PlanResult(status, reason, **kw)


class Layout:
    """Decision variables and constraints of an NLP in named blocks, in the order added.

    Variable names are unique; a constraint name may be used again (its rows accumulate, e.g.
    one dynamics block per interval). Offsets are looked up, never kept by hand."""

    def __init__(self):
        self._w, self._lbw, self._ubw = [], [], []
        self._g, self._lbg, self._ubg = [], [], []
        self._vars: dict[str, tuple[int, tuple]] = {}   # name -> (offset, shape)
        self._cons: dict[str, list[range]] = {}
        self._nw = self._ng = 0
        self._wstage, self._gstage = [], []   # per entry: (stage, kind) or None (no stage)
        self._pars: dict[str, slice] = {}
        self.P = None

    # ------------------------------------------------------------------ variables
    def __getstate__(self):
        # the numeric bookkeeping only (offsets, bounds, parameter blocks): a layout loaded from
        # the NLP cache serves unpack/pack/slice/rows/param_vector, not the symbols
        state = dict(self.__dict__)
        state.update(_w=None, _g=None, P=None)
        return state

    def add_var(self, name: str, var, lo, hi, stage: int | None = None) -> ca.SX:
        """Add a variable block: ``var`` a shape (int or (rows, cols): a new SX symbol named
        ``name``) or an existing SX symbol; ``lo``/``hi`` broadcast to its shape. ``stage``
        (optimal-control structure, :meth:`stage_order`): 0 — column k is a state of stage k,
        1 — column k is a control of stage k. Returns the symbol."""
        if name in self._vars:
            raise ValueError(f"variable block {name!r} exists already")
        if not isinstance(var, ca.SX):
            var = ca.SX.sym(name, *((var,) if np.isscalar(var) else tuple(var)))
        shape = var.shape
        self._w.append(ca.vec(var))
        self._lbw.extend(np.broadcast_to(lo, shape).ravel(order="F").tolist())
        self._ubw.extend(np.broadcast_to(hi, shape).ravel(order="F").tolist())
        self._vars[name] = (self._nw, shape)
        self._wstage.extend([None] * (shape[0] * shape[1]) if stage is None else
                            [(k, stage) for k in range(shape[1]) for _ in range(shape[0])])
        self._nw += shape[0] * shape[1]
        return var

    def has(self, name: str) -> bool:
        """Whether the layout has a variable block ``name``."""
        return name in self._vars

    def slice(self, name: str) -> slice:
        """Where variable block ``name`` sits in the decision vector."""
        off, shape = self._var(name)
        return slice(off, off + shape[0] * shape[1])

    def shape(self, name: str) -> tuple:
        """The (rows, cols) of variable block ``name``."""
        return self._var(name)[1]

    def unpack(self, w, name: str) -> np.ndarray:
        """Variable block ``name`` of a decision vector ``w``, in its shape (a copy)."""
        return np.asarray(w)[self.slice(name)].reshape(self.shape(name), order="F").copy()

    def pack(self, w, name: str, value) -> None:
        """Write ``value`` (the block's shape, or flat) into block ``name`` of ``w``."""
        sl = self.slice(name)   # a scalar fills the whole block
        w[sl] = np.broadcast_to(np.asarray(value, float).ravel(order="F"), (sl.stop - sl.start,))

    def _var(self, name):
        try:
            return self._vars[name]
        except KeyError:
            raise KeyError(f"no variable block {name!r}: known "
                           f"{', '.join(self._vars) or 'none'}") from None

    # ------------------------------------------------------------------ constraints
    def add_con(self, name: str, expr, lo, hi, stage: tuple | None = None) -> None:
        """Add constraint rows lo ≤ vec(expr) ≤ hi (``lo``/``hi`` broadcast) under ``name``;
        ``stage`` = (k, kind) orders them for :meth:`stage_order` (kind 0: the dynamics of
        stage k, 1: its path constraints)."""
        e = ca.vec(expr)
        m = e.shape[0]
        self._gstage.extend([stage] * m)
        self._g.append(e)
        self._lbg.extend(np.broadcast_to(lo, (m,)).tolist())
        self._ubg.extend(np.broadcast_to(hi, (m,)).tolist())
        self._cons.setdefault(name, []).append(range(self._ng, self._ng + m))
        self._ng += m

    def rows(self, name: str) -> np.ndarray:
        """Indices of every constraint row added under ``name``, in order."""
        if name not in self._cons:
            raise KeyError(f"no constraint block {name!r}: known {', '.join(self._cons)}")
        return np.concatenate([np.arange(r.start, r.stop) for r in self._cons[name]])

    def stage_order(self) -> tuple:
        """(variable permutation, constraint permutation) that order the NLP stage by stage —
        per stage its states, then its controls; its dynamics, then its path constraints — as
        a structure-exploiting solver (FATROP) needs; ValueError when an entry has no stage."""
        if None in self._wstage or None in self._gstage:
            raise ValueError("every variable and constraint needs a stage for stage_order()")
        order = lambda keys: np.array(sorted(range(len(keys)), key=lambda i: keys[i]),  # noqa
                                      dtype=int)
        return order(self._wstage), order(self._gstage)

    # ------------------------------------------------------------------ parameters
    def parameters(self, **sizes: int) -> dict:
        """Declare the parameter vector once, blocks in keyword order (name=size); returns
        name -> its symbolic slice (size-1 blocks as scalars). The whole vector is ``P``."""
        if self.P is not None:
            raise ValueError("parameters are declared once")
        self.P = ca.SX.sym("P", sum(sizes.values()))
        out, off = {}, 0
        for name, n in sizes.items():
            self._pars[name] = slice(off, off + n)
            out[name] = self.P[off] if n == 1 else self.P[off:off + n]
            off += n
        return out

    def param_vector(self, **values) -> np.ndarray:
        """The numeric parameter vector from every declared block by name."""
        missing = set(self._pars) - set(values)
        extra = set(values) - set(self._pars)
        if missing or extra:
            raise ValueError(f"parameters: missing {sorted(missing)}, unknown {sorted(extra)}")
        return np.concatenate([np.atleast_1d(np.asarray(values[k], float)).ravel()
                               for k in self._pars])

    # ------------------------------------------------------------------ the NLP
    @property
    def var_names(self) -> list:
        """Variable block names in the order added."""
        return list(self._vars)

    @property
    def con_names(self) -> list:
        """Constraint block names in the order first used."""
        return list(self._cons)

    @property
    def nw(self) -> int:
        return self._nw

    @property
    def ng(self) -> int:
        return self._ng

    @property
    def w(self) -> ca.SX:
        """All decision variables, stacked in the order added."""
        return ca.vertcat(*self._w)

    @property
    def g(self) -> ca.SX:
        """All constraints, stacked in the order added."""
        return ca.vertcat(*self._g)

    def bounds(self) -> tuple:
        """(lbw, ubw, lbg, ubg) as arrays."""
        return (np.array(self._lbw), np.array(self._ubw), np.array(self._lbg),
                np.array(self._ubg))
