"""The crane model: one CasADi definition, numeric and symbolic faces.

>>> crane = Crane.from_id("umea-lab")
>>> crane.tip([0, 0.5, -1.2, 0.3])          # (r, z, slew)
>>> q = crane.ik((3.0, 2.5, 0.0), tele=0.5)  # joint configuration
>>> crane.f_hyd                              # casadi.Function, callable on SX/MX for the NLP
>>> Crane.from_id("s100f", pricing="seed")   # the seeds' pump pricing (planner.model.pricing)

Numeric methods accept one configuration (shape (n,)) or a batch (shape (N, n)) and return
arrays with the same leading shape; batches are evaluated by CasADi in one call (no Python loop).
"""
from __future__ import annotations

import math
from functools import lru_cache

import casadi as ca
import numpy as np

from planner.model.spec import CraneSpec, SpecError, load_spec
from planner.model.actuators import lever_pin, stroke_expr, stroke_range
from planner.model.dynamics import lumped_links, potential_energy, rnea
from planner.model.hydraulics import OUTPUTS, hydraulics
from planner.model.pricing import meter_in_pressures, pricing_of
from planner.model.numeric import Batched
from planner.model.kinematics import (UnreachableError, cylindrical, ik_planar, joint_transforms,
                         planar_chain, tip_position)
from planner.problems import crane_file

__all__ = ["Crane", "UnreachableError", "load_crane"]


def _batch(a, n):
    a = np.asarray(a, dtype=float)
    single = a.ndim == 1
    a2 = np.atleast_2d(a)
    if a2.shape[-1] != n:
        raise ValueError(f"expected {n} joint values per configuration, got shape {a.shape}")
    return a2, single


class Crane:
    """Numeric and symbolic model of one machine spec (build once, evaluate many times).

    ``f_fk``, ``f_kin``, ``f_stroke``, ``f_id``, ``f_hyd`` are the symbolic CasADi functions
    (call them on SX/MX in an NLP); the numeric methods use compiled copies of the same
    functions (see :mod:`planner.model.numeric`). ``pricing`` ("seed" | "machine"; default:
    machine where the spec has ``[dynamics]``) is how the pump work is priced
    (:mod:`planner.model.pricing`); ``f_pin`` gives the energy NLP the meter-in pressures.
    """

    def __init__(self, spec: CraneSpec, pricing: str | None = None):
        self.spec = spec
        self.prices = pr = pricing_of(spec, pricing)
        self.pricing = pr.mode
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
        hy = hydraulics(spec, x, xd, force, pr)
        self.f_hyd = ca.Function("hydraulics", [q, qd, qdd, m], [hy[k] for k in OUTPUTS],
                                 ["q", "qd", "qdd", "payload"], list(OUTPUTS))
        Fs, vs = ca.SX.sym("force", n), ca.SX.sym("xd", n)
        pins = [meter_in_pressures(pr, j.actuator.area_a, j.actuator.area_b,
                                   spec.pump.tank_pressure, i, Fs[i], vs[i])
                for i, j in enumerate(spec.joints)]
        self.f_pin = ca.Function("meter_in_pressure", [Fs, vs],
                                 [ca.vertcat(*[p[0] for p in pins]),
                                  ca.vertcat(*[p[1] for p in pins])],
                                 ["force", "xd"], ["p_extend", "p_retract"])
        self._batched: dict[str, Batched] = {}
        self._check_actuators()
        self._stroke_tables = self._make_stroke_tables()

    def _eval(self, name: str, *args):
        """Numeric face of ``self.f_<name>`` on N samples (compiled on first use): args are
        (N, size) arrays or broadcastable; returns a list of (N, size_out) arrays."""
        b = self._batched.get(name)
        if b is None:
            b = self._batched[name] = Batched(getattr(self, f"f_{name}"))
        return b(*args)

    def numeric_status(self) -> dict[str, bool]:
        """Which numeric functions have been built so far, and whether each is compiled."""
        return {k: b.compiled for k, b in sorted(self._batched.items())}

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def from_id(cls, crane_id: str, pricing: str | None = None) -> "Crane":
        """Model of a shipped machine (see ``crane-planner problems list``) or a TOML path,
        with the pump ``pricing`` ("seed" | "machine"; default: the spec's)."""
        return _cached_crane(_resolve(crane_id), pricing)

    @classmethod
    def from_file(cls, path, pricing: str | None = None) -> "Crane":
        return cls(load_spec(path), pricing)

    def _check_actuators(self):
        """Cylinder strokes must cover the joint range; linkages must close; no dead point."""
        spec = self.spec
        grid = np.linspace(0, 1, 401)
        lims = np.array([j.limits.q for j in spec.joints])
        qs = lims[:, 0] + grid[:, None] * (lims[:, 1] - lims[:, 0])
        x, dxdq = self._eval("stroke", qs)
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
        return qs, self._eval("stroke", qs)[0]

    # ------------------------------------------------------------------ numeric faces
    def _q(self, q):
        """(N, n) array and whether the input was a single configuration."""
        return _batch(q, self.n)

    @staticmethod
    def _out(a, single):
        return a[0] if single else a

    def fk(self, q):
        """Tip position (x, y, z) [m] in frame 0."""
        qb, single = self._q(q)
        return self._out(self._eval("fk", qb)[0], single)

    def frame_origins(self, q):
        """Origins of DH frames 0..n [m], shape (n+1, 3) — for drawing the crane."""
        o = self._eval("origins", self._q(q)[0][:1])[0][0]
        return o.reshape(self.n + 1, 3)

    def tip(self, q):
        """Tip (r, z, slew) [m, m, rad] — the CONTRACT coordinates."""
        qb, single = self._q(q)
        return self._out(self._eval("fk", qb)[1], single)

    def jacobian(self, q, coords: str = "cyl"):
        """∂tip/∂q, shape (3, n) (or (N, 3, n)); coords 'cyl' = (r, z, slew), 'xyz'."""
        qb, single = self._q(q)
        if coords == "cyl":
            J = self._eval("kin", qb)[1]
        elif coords == "xyz":
            J = self._eval("jac_xyz", qb)[0]
        else:
            raise ValueError(f"coords must be 'cyl' or 'xyz', not {coords!r}")
        J = J.reshape(-1, self.n, 3).transpose(0, 2, 1)  # column-major vec -> (N, 3, n)
        return self._out(J, single)

    def kinematics(self, q):
        """FK + Jacobian + stroke map in one call: (tip (r, z, slew) [3], ∂tip/∂q [3×n],
        strokes x [n], dx/dq [n]); a batch (N, n) gives arrays with a leading N."""
        qb, single = self._q(q)
        cyl, J, x, d = self._eval("kin", qb)
        J = J.reshape(-1, self.n, 3).transpose(0, 2, 1)
        return tuple(self._out(a, single) for a in (cyl, J, x, d))

    def stroke(self, q):
        """Actuator strokes x [m | rad] and dx/dq, each shaped like q."""
        qb, single = self._q(q)
        x, d = self._eval("stroke", qb)
        return self._out(x, single), self._out(d, single)

    def joint_from_stroke(self, x):
        """Inverse stroke map x -> q (table look-up + Newton polish), shaped like x."""
        xb, single = _batch(x, self.n)
        qs, xs = self._stroke_tables
        q = np.empty_like(xb)
        for i in range(self.n):
            order = np.argsort(xs[:, i])
            q[:, i] = np.interp(xb[:, i], xs[order, i], qs[order, i])
        for _ in range(3):
            xq, d = self._eval("stroke", q)
            q = q - (xq - xb) / d
        return self._out(q, single)

    def _payload(self, payload):
        return self.spec.payload.total if payload is None else payload

    def inverse_dynamics(self, q, qd, qdd, payload=None):
        """Joint torques/forces [N·m | N] that realise (q, qd, qdd) with the given payload [kg]
        (default: the spec's load + tool)."""
        qb, single = self._q(q)
        t = self._eval("id", qb, self._q(qd)[0], self._q(qdd)[0], self._payload(payload))[0]
        return self._out(t, single)

    def potential_energy(self, q, payload=None):
        """Gravitational potential energy [J] of links, actuators and payload (z = 0 at frame 0)."""
        qb, single = self._q(q)
        e = self._eval("pe", qb, self._payload(payload))[0][:, 0]
        return self._out(e, single)

    def hydraulics(self, q, qd, qdd, payload=None) -> dict:
        """Strokes, rates, forces, chamber pressures [Pa], flows [m³/s], pump pressure, flow,
        power [W] and throttling loss [W] for every sample (dict of arrays)."""
        qb, single = self._q(q)
        res = self._eval("hyd", qb, self._q(qd)[0], self._q(qdd)[0], self._payload(payload))
        out = {}
        for k, a in zip(OUTPUTS, res):
            if a.shape[1] == 1:
                a = a[:, 0]
            out[k] = self._out(a, single)
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

    def ik_batch(self, tips, tele=None, explain: bool = True):
        """Vectorised IK over tips (N, 3) and/or telescope values (N,). Returns (q[N, n],
        reasons[N]); rows that fail are NaN with a non-empty reason (a short constant text
        when ``explain`` is False — faster on large grids)."""
        tips = np.atleast_2d(np.asarray(tips, float))
        t = self._tele_default(tele)
        return ik_planar(self.spec, self.chain, tips[:, 0], tips[:, 1], tips[:, 2], t,
                         explain=explain)

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
        """Dict of arrays: q_min, q_max, qd_min, qd_max, qdd_max, qddd_max (inf if none).
        The arrays are built once per crane and read-only (copy one before changing it)."""
        cached = self.__dict__.get("_limits")
        if cached is None:
            J = self.spec.joints
            cached = dict(q_min=[j.limits.q[0] for j in J], q_max=[j.limits.q[1] for j in J],
                          qd_min=[j.limits.qd[0] for j in J], qd_max=[j.limits.qd[1] for j in J],
                          qdd_max=[j.limits.qdd for j in J],
                          qddd_max=[j.limits.qddd if j.limits.qddd else np.inf for j in J])
            for k, v in cached.items():
                cached[k] = a = np.array(v, dtype=float)
                a.flags.writeable = False
            self._limits = cached
        return dict(cached)

    def __repr__(self):
        return f"Crane({self.spec.id!r}, joints={self.names}, pricing={self.pricing!r})"


def load_crane(crane_id: str) -> CraneSpec:
    """Validated :class:`~planner.model.spec.CraneSpec` of a shipped machine id (see
    :func:`planner.problems.crane_ids`) or of a path to a TOML file; KeyError for an unknown id,
    SpecError for a malformed file."""
    return load_spec(crane_file(crane_id))


def _resolve(crane_id: str) -> str:
    return str(crane_file(crane_id).resolve())


@lru_cache(maxsize=16)
def _cached_crane(path: str, pricing: str | None = None) -> Crane:
    if pricing is not None and pricing == _cached_crane(path, None).pricing:
        return _cached_crane(path, None)  # one object whether or not the pricing was named
    return Crane(load_spec(path), pricing)
