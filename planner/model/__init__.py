"""The crane model: one CasADi definition, numeric and symbolic faces.

>>> crane = Crane.from_id("umea-lab")
>>> crane.tip([0, 0.5, -1.2, 0.3])          # (r, z, slew)
>>> q = crane.ik((3.0, 2.5, 0.0), tele=0.5)  # joint configuration
>>> crane.f_hyd                              # casadi.Function, callable on SX/MX for the NLP

Numeric methods accept one configuration (shape (n,)) or a batch (shape (N, n)) and return
arrays with the same leading shape; batches are evaluated by CasADi in one call (no Python loop).
"""
from __future__ import annotations

import math
import os
import warnings
from functools import lru_cache
from pathlib import Path

import casadi as ca
import numpy as np

from ..spec import CraneSpec, SpecError, load_spec
from .actuators import lever_pin, stroke_expr, stroke_range
from .dynamics import lumped_links, potential_energy, rnea
from .hydraulics import OUTPUTS, hydraulics
from .kinematics import (UnreachableError, cylindrical, ik_planar, joint_transforms,
                         planar_chain, tip_position)

__all__ = ["Crane", "UnreachableError"]


def _batch(a, n):
    a = np.asarray(a, dtype=float)
    single = a.ndim == 1
    a2 = np.atleast_2d(a)
    if a2.shape[-1] != n:
        raise ValueError(f"expected {n} joint values per configuration, got shape {a.shape}")
    return a2, single


def _jit(f: ca.Function) -> ca.Function:
    """Compile a CasADi function to machine code with the system C compiler (≈4× faster batched
    evaluation); fall back to CasADi's virtual machine when no compiler is available or when
    CRANE_PLANNER_JIT=0. Both give identical results."""
    if os.environ.get("CRANE_PLANNER_JIT", "1") == "0":
        return f
    try:
        ins = f.sx_in()
        return ca.Function(f.name(), ins, f.call(ins), f.name_in(), f.name_out(),
                           {"jit": True, "compiler": "shell",
                            "jit_options": {"flags": ["-O2"], "verbose": False}})
    except Exception as e:  # no compiler: the interpreted function is exact, only slower
        warnings.warn(f"CasADi JIT unavailable ({type(e).__name__}); using the interpreter",
                      RuntimeWarning, stacklevel=3)
        return f


class Crane:
    """Numeric and symbolic model of one machine spec (build once, evaluate many times).

    ``f_fk``, ``f_kin``, ``f_stroke``, ``f_id``, ``f_hyd`` are the symbolic CasADi functions
    (call them on SX/MX in an NLP); the numeric methods use compiled copies of the same
    functions (see :func:`_jit`).
    """

    def __init__(self, spec: CraneSpec):
        self.spec = spec
        self.n = n = spec.n
        self.names = spec.joint_names
        self.chain = planar_chain(spec)
        self.bodies = lumped_links(spec)
        q = ca.SX.sym("q", n)
        qd = ca.SX.sym("qd", n)
        qdd = ca.SX.sym("qdd", n)
        m = ca.SX.sym("payload")
        p = tip_position(spec, q)
        cyl = cylindrical(p)
        x = ca.vertcat(*[stroke_expr(j, q[i]) for i, j in enumerate(spec.joints)])
        dxdq = ca.vertcat(*[ca.jacobian(x[i], q[i]) for i in range(n)])
        # symbolic building blocks
        self.f_fk = ca.Function("fk", [q], [p, cyl], ["q"], ["xyz", "cyl"])
        T = ca.SX.eye(4)
        origins = [T[:3, 3]]
        for A in joint_transforms(spec, q):
            T = T @ A
            origins.append(T[:3, 3])
        self.f_origins = ca.Function("origins", [q], [ca.horzcat(*origins)], ["q"], ["o"])
        self.f_kin = ca.Function("kin", [q], [cyl, ca.jacobian(cyl, q), x, dxdq],
                                 ["q"], ["cyl", "J", "x", "dxdq"])
        self.f_jac_xyz = ca.Function("jac_xyz", [q], [ca.jacobian(p, q)], ["q"], ["J"])
        self.f_stroke = ca.Function("stroke", [q], [x, dxdq], ["q"], ["x", "dxdq"])
        self.f_pe = ca.Function("potential_energy", [q, m],
                                [potential_energy(spec, q, m, self.bodies)],
                                ["q", "payload"], ["E"])
        tau = rnea(spec, q, qd, qdd, m, self.bodies)
        self.f_id = ca.Function("inverse_dynamics", [q, qd, qdd, m], [tau],
                                ["q", "qd", "qdd", "payload"], ["tau"])
        xd = dxdq * qd
        force = tau / dxdq
        hy = hydraulics(spec, x, xd, force)
        self.f_hyd = ca.Function("hydraulics", [q, qd, qdd, m], [hy[k] for k in OUTPUTS],
                                 ["q", "qd", "qdd", "payload"], list(OUTPUTS))
        self._compiled: dict[str, ca.Function] = {}
        self._check_actuators()
        self._stroke_tables = self._make_stroke_tables()

    def _num(self, name: str) -> ca.Function:
        """Compiled numeric face of ``self.f_<name>`` (compiled once, on first use)."""
        f = self._compiled.get(name)
        if f is None:
            f = self._compiled[name] = _jit(getattr(self, f"f_{name}"))
        return f

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def from_id(cls, crane_id: str) -> "Crane":
        """Model of a shipped machine (see ``crane-planner problems list``) or a TOML path."""
        return _cached_crane(_resolve(crane_id))

    @classmethod
    def from_file(cls, path) -> "Crane":
        return cls(load_spec(path))

    def _check_actuators(self):
        """Cylinder strokes must cover the joint range; linkages must close; no dead point."""
        spec = self.spec
        grid = np.linspace(0, 1, 401)
        qs = np.array([[lo + s * (hi - lo) for (lo, hi) in (j.limits.q for j in spec.joints)]
                       for s in grid])
        x, dxdq = (np.array(a).T for a in self._num("stroke")(qs.T))
        for i, j in enumerate(spec.joints):
            act = j.actuator
            where = f"joint[{i}]({j.name}).actuator"
            if act.kind == "lever":
                qq = ca.SX.sym("qq")
                _, h2 = lever_pin(act, j.dh.theta + qq)
                h2v = np.array(ca.Function("h2", [qq], [h2])(qs[:, i][None, :])).ravel()
                if np.min(h2v) <= 0:
                    k = int(np.argmin(h2v))
                    raise SpecError(spec.path, where + ".lever_lengths", act.lever_lengths,
                                    f"the lever linkage cannot close at {j.name} = "
                                    f"{math.degrees(qs[k, i]):.1f}°")
            lo, hi = stroke_range(act)
            tol = 1e-3
            if np.min(x[:, i]) < lo - tol or np.max(x[:, i]) > hi + tol:
                k = int(np.argmin(x[:, i])) if np.min(x[:, i]) < lo - tol else int(np.argmax(x[:, i]))
                at = f"{math.degrees(qs[k, i]):.1f}°" if j.revolute else f"{qs[k, i]:.3f} m"
                raise SpecError(spec.path, where + ".stroke", act.stroke,
                                f"the joint range needs strokes {np.min(x[:, i]):.3f} .. "
                                f"{np.max(x[:, i]):.3f} m (worst at {j.name} = {at}), "
                                f"outside the cylinder's 0 .. {act.stroke} m")
            s = np.sign(dxdq[:, i])
            if np.any(np.abs(dxdq[:, i]) < 1e-4) or np.any(s != s[0]):
                raise SpecError(spec.path, where, act.kind,
                                f"the stroke map has a dead point inside the range of {j.name} "
                                "(dx/dq changes sign or vanishes): the cylinder cannot drive it")

    def _make_stroke_tables(self):
        lims = np.array([j.limits.q for j in self.spec.joints])
        grid = np.linspace(0, 1, 2001)
        qs = lims[:, 0][None, :] + grid[:, None] * (lims[:, 1] - lims[:, 0])[None, :]
        x, _ = self._num("stroke")(qs.T)
        return qs, np.array(x).T

    # ------------------------------------------------------------------ numeric faces
    def fk(self, q):
        """Tip position (x, y, z) [m] in frame 0."""
        qb, single = _batch(q, self.n)
        out = np.array(self._num("fk")(qb.T)[0]).T
        return out[0] if single else out

    def frame_origins(self, q):
        """Origins of DH frames 0..n [m], shape (n+1, 3) — for drawing the crane."""
        return np.array(self.f_origins(np.asarray(q, float))).T

    def tip(self, q):
        """Tip (r, z, slew) [m, m, rad] — the CONTRACT coordinates."""
        qb, single = _batch(q, self.n)
        out = np.array(self._num("fk")(qb.T)[1]).T
        return out[0] if single else out

    def jacobian(self, q, coords: str = "cyl"):
        """∂tip/∂q, shape (3, n) (or (N, 3, n)); coords 'cyl' = (r, z, slew), 'xyz'."""
        qb, single = _batch(q, self.n)
        if coords == "cyl":
            J = np.array(self._num("kin")(qb.T)[1])
        elif coords == "xyz":
            J = np.array(self._num("jac_xyz")(qb.T))
        else:
            raise ValueError(f"coords must be 'cyl' or 'xyz', not {coords!r}")
        J = J.reshape(3, qb.shape[0], self.n).transpose(1, 0, 2)
        return J[0] if single else J

    def kinematics(self, q):
        """One call: (tip cyl [3], Jacobian [3×n], strokes x [n], dx/dq [n])."""
        r = self._num("kin")(np.asarray(q, float))
        return (np.array(r[0]).ravel(), np.array(r[1]), np.array(r[2]).ravel(),
                np.array(r[3]).ravel())

    def stroke(self, q):
        """Actuator strokes x [m | rad] and dx/dq, each shaped like q."""
        qb, single = _batch(q, self.n)
        x, d = (np.array(a).T for a in self._num("stroke")(qb.T))
        return (x[0], d[0]) if single else (x, d)

    def joint_from_stroke(self, x):
        """Inverse stroke map x -> q (table look-up + Newton polish), shaped like x."""
        xb, single = _batch(x, self.n)
        qs, xs = self._stroke_tables
        q = np.empty_like(xb)
        for i in range(self.n):
            xi, qi = xs[:, i], qs[:, i]
            order = np.argsort(xi)
            q[:, i] = np.interp(xb[:, i], xi[order], qi[order])
        for _ in range(3):
            xq, d = (np.array(a).T for a in self._num("stroke")(q.T))
            q = q - (xq - xb) / d
        return q[0] if single else q

    def inverse_dynamics(self, q, qd, qdd, payload=None):
        """Joint torques/forces [N·m | N] that realise (q, qd, qdd) with the given payload [kg]
        (default: the spec's load + tool)."""
        qb, single = _batch(q, self.n)
        m = self.spec.payload.total if payload is None else payload
        t = np.array(self._num("id")(qb.T, _batch(qd, self.n)[0].T, _batch(qdd, self.n)[0].T, m)).T
        return t[0] if single else t

    def potential_energy(self, q, payload=None):
        """Gravitational potential energy [J] of links, actuators and payload (z = 0 at frame 0)."""
        qb, single = _batch(q, self.n)
        m = self.spec.payload.total if payload is None else payload
        e = np.array(self._num("pe")(qb.T, m)).ravel()
        return e[0] if single else e

    def hydraulics(self, q, qd, qdd, payload=None) -> dict:
        """Strokes, rates, forces, chamber pressures [Pa], flows [m³/s], pump pressure, flow,
        power [W] and throttling loss [W] for every sample (dict of arrays)."""
        qb, single = _batch(q, self.n)
        m = self.spec.payload.total if payload is None else payload
        res = self._num("hyd")(qb.T, _batch(qd, self.n)[0].T, _batch(qdd, self.n)[0].T, m)
        out = {}
        for k, v in zip(OUTPUTS, res):
            a = np.array(v).T
            if a.shape[1] == 1:
                a = a[:, 0]
            out[k] = a[0] if single else a
        return out

    # ------------------------------------------------------------------ inverse kinematics
    def ik(self, tip, tele=None):
        """Joint configuration for a tip (r, z, slew) and a telescope value [m].

        ``tele`` defaults to the middle of the telescope range. Raises :class:`UnreachableError`
        naming the point and the reason (out of reach, or which joint limit)."""
        q, reason = self.ik_batch(np.atleast_2d(np.asarray(tip, float)), tele)
        if reason[0]:
            r, z, s = np.asarray(tip, float)
            raise UnreachableError(f"{self.spec.id}: tip (r={r:.3f} m, z={z:.3f} m, slew="
                                   f"{math.degrees(s):.1f}°) with telescope "
                                   f"{self._tele_default(tele):.3f} m is unreachable: {reason[0]}")
        return q[0]

    def ik_batch(self, tips, tele=None):
        """Vectorised IK over tips (N, 3) and/or telescope values (N,). Returns (q[N, n],
        reasons[N]); rows that fail are NaN with a non-empty reason."""
        tips = np.atleast_2d(np.asarray(tips, float))
        t = self._tele_default(tele)
        return ik_planar(self.spec, self.chain, tips[:, 0], tips[:, 1], tips[:, 2], t)

    def _tele_default(self, tele):
        if self.chain.tele is None:
            return 0.0 if tele is None else tele
        if tele is None:
            lo, hi = self.spec.joints[self.chain.tele].limits.q
            return 0.5 * (lo + hi)
        return tele

    @property
    def tele_range(self) -> tuple[float, float] | None:
        if self.chain.tele is None:
            return None
        return self.spec.joints[self.chain.tele].limits.q

    # ------------------------------------------------------------------ limits as arrays
    def limit_arrays(self):
        """Dict of arrays: q_min, q_max, qd_min, qd_max, qdd_max, qddd_max (inf if none)."""
        J = self.spec.joints
        return dict(q_min=np.array([j.limits.q[0] for j in J]),
                    q_max=np.array([j.limits.q[1] for j in J]),
                    qd_min=np.array([j.limits.qd[0] for j in J]),
                    qd_max=np.array([j.limits.qd[1] for j in J]),
                    qdd_max=np.array([j.limits.qdd for j in J]),
                    qddd_max=np.array([j.limits.qddd if j.limits.qddd else np.inf for j in J]))

    def __repr__(self):
        return f"Crane({self.spec.id!r}, joints={self.names})"


def _resolve(crane_id: str) -> str:
    from problems import crane_path
    p = Path(crane_id)
    if p.suffix == ".toml" and p.exists():
        return str(p.resolve())
    return str(crane_path(crane_id))


@lru_cache(maxsize=16)
def _cached_crane(path: str) -> Crane:
    return Crane(load_spec(path))
