"""Machine specifications: TOML -> validated, immutable dataclasses.

A crane file (planner/problems/cranes/*.toml) holds a ``[crane]`` table, one ``[[joint]]`` table
per joint in chain order (DH row, limits, link inertia, actuator), ``[payload]``, ``[pump]`` and an
optional ``[transformer]``. Every table carries a ``source`` string (provenance of its numbers).
Units are SI; angles may also be written as strings such as ``"123deg"``.

Loading validates everything and raises :class:`SpecError` naming the file, the field, the value
and what is allowed. Unknown keys are errors (a typo must not silently fall back to a default).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from planner.model.dynamics_spec import DynamicsSpec, parse_dynamics
from planner.model.effects import effect_from_dict
from planner.model.reader import SpecError, TableReader, read_toml_text
from planner.units import parse_angle

__all__ = ["SpecError", "DH", "Limits", "Actuator", "Joint", "Payload", "Pump", "Transformer",
           "LawParams", "CraneSpec", "load_spec", "parse_spec", "parse_angle"]


# ----------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True)
class DH:
    """One standard DH row, A = Rot_z(theta)·Trans_z(d)·Trans_x(a)·Rot_x(alpha).

    For a revolute joint ``theta`` is the offset added to q; for a prismatic one ``d`` is.
    """
    theta: float
    d: float
    a: float
    alpha: float


@dataclass(frozen=True)
class Limits:
    """Joint limits. q: (min, max) [rad|m]; qd: (min, max) with min < 0 < max [rad/s|m/s];
    qdd, qddd: symmetric magnitudes [rad/s², rad/s³] (qddd None = no jerk limit)."""
    q: tuple[float, float]
    qd: tuple[float, float]
    qdd: float
    qddd: float | None


@dataclass(frozen=True)
class Actuator:
    """Hydraulic actuator of one joint; maps joint position q <-> stroke x.

    kinds: ``triangle`` (cylinder between a pin on the parent link and one on the child link),
    ``lever`` (cylinder pushing a two-lever linkage to the child link), ``telescope`` (x = (q -
    q_ref)/ratio: chain-coupled sections), ``rotary`` (motor through a gear: x = ratio·q, motor
    angle), ``rack`` (rack-and-pinion: x = radius·q).

    Pins are 2-D points [m] in the plane of rotation of the joint, expressed in the parent's DH
    frame (``base``, ``lever_pivot``) or in the child's frame before the DH twist, i.e. rotated
    with the full DH angle (``rod``, ``lever_link``). area_a / area_b: piston and annulus areas
    [m²] (or motor displacement [m³/rad] for rotary). flow_gain: valve flow at full command
    [m³/s]; deadband: fraction of the command range with no flow.
    """
    kind: str
    area_a: float
    area_b: float
    acting: str = "double"
    stroke: float = math.inf
    closed_length: float = 0.0
    base: tuple[float, float] | None = None
    rod: tuple[float, float] | None = None
    lever_pivot: tuple[float, float] | None = None
    lever_link: tuple[float, float] | None = None
    lever_lengths: tuple[float, float] | None = None
    lever_branch: int = 1
    ratio: float = 1.0
    q_ref: float = 0.0
    radius: float = 0.0
    flow_gain: float = math.inf
    deadband: float = 0.0
    max_speed: float | None = None
    mass: float = 0.0
    source: str = ""


@dataclass(frozen=True)
class Joint:
    name: str
    type: str                       # "revolute" | "prismatic"
    dh: DH
    limits: Limits
    mass: float                     # link mass [kg]
    com: tuple[float, float, float]  # centre of mass in the DH frame of this link [m]
    inertia: tuple[float, float, float]  # principal inertia about the COM, frame axes [kg m²]
    actuator: Actuator
    source: str = ""

    @property
    def revolute(self) -> bool:
        return self.type == "revolute"


@dataclass(frozen=True)
class Payload:
    mass: float        # load in the grapple [kg]
    tool_mass: float   # grapple + rotator, always carried [kg]
    source: str = ""

    @property
    def total(self) -> float:
        return self.mass + self.tool_mass


@dataclass(frozen=True)
class Pump:
    """kind ``load_sensing``: p_pump = max(active load pressures) + margin (>= standby);
    ``constant_pressure``: p_pump = pressure. Pressures [Pa], max_flow [m³/s]."""
    kind: str
    max_flow: float
    efficiency: float
    margin: float = 0.0
    pressure: float = 0.0
    standby: float = 0.0
    max_pressure: float = math.inf
    tank_pressure: float = 0.0
    source: str = ""


@dataclass(frozen=True)
class Transformer:
    """Hydraulic transformer: the rod side of ``source_joint``'s cylinder feeds the piston side
    of ``target_joint``'s cylinder (seed 002). ratio = displacement ratio (1 = equal units)."""
    source_joint: str
    target_joint: str
    ratio: float = 1.0
    efficiency: float = 1.0
    enabled: bool = True
    source: str = ""


@dataclass(frozen=True)
class LawParams:
    """Parameters of the local control laws (optional ``[laws]`` table).

    weights: joint name -> weight of the max-velocity law's pseudo-inverse (seed 000:
    w·θ̇max² roughly equal per joint); max_lift: the telescope-by-position circle (rc, zc [m],
    rho_min, rho_max [m]) of seed 000's maximum-lifting-capacity law."""
    weights: dict = field(default_factory=dict)
    max_lift: dict = field(default_factory=dict)
    source: str = ""


@dataclass(frozen=True)
class CraneSpec:
    id: str
    name: str
    description: str
    source: str
    elbow: str                     # "up" | "down": IK branch, see model.kinematics
    redundancy: str | None         # joint name used as the IK redundancy parameter
    joints: tuple[Joint, ...]
    payload: Payload
    pump: Pump
    transformer: Transformer | None
    laws: LawParams = field(default_factory=LawParams)
    effects: tuple = ()            # calibrated effects (dicts, planner.model.effects), see plant.py
    dynamics: DynamicsSpec | None = None  # [dynamics] (planner.model.dynamics_spec), dynamic plant
    gravity: float = 9.81
    path: str = "<memory>"
    raw: dict = field(default_factory=dict, repr=False, compare=False)
    text: str = field(default="", repr=False, compare=False)

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def joint_names(self) -> list[str]:
        return [j.name for j in self.joints]

    def joint_index(self, name: str) -> int:
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"crane '{self.id}' has no joint '{name}' "
                           f"(joints: {', '.join(self.joint_names)})") from None


# ----------------------------------------------------------------------------- parsing
_JOINT_KEYS = {"name", "type", "dh", "limits", "mass", "com", "inertia", "actuator", "source"}
_DH_KEYS = {"theta", "d", "a", "alpha"}
_LIMIT_KEYS = {"q", "qd", "qdd", "qddd"}
_ACT_KEYS = {"kind", "area_a", "area_b", "acting", "stroke", "closed_length", "base", "rod",
             "lever_pivot", "lever_link", "lever_lengths", "lever_branch", "ratio", "q_ref",
             "radius", "flow_gain", "deadband", "max_speed", "mass", "source"}
_ACT_KINDS = ("triangle", "lever", "telescope", "rotary", "rack")
# [m³/s] the largest plausible flow of one pump or valve (3000 L/min; crane pumps deliver
# 20–600 L/min): a larger number is almost surely L/min written where m³/s is expected
MAX_FLOW = 0.05


def _flow(R: TableReader, tbl: dict, key: str, where: str) -> float:
    """A flow [m³/s] > 0, refused as "looks like L/min" above :data:`MAX_FLOW`."""
    v = R.num(tbl, key, where, lo=0, lo_open=True)
    if v > MAX_FLOW:
        R.fail(f"{where}{key}", tbl[key], f"implausible for m³/s (allowed up to {MAX_FLOW} "
                                          f"m³/s = {MAX_FLOW * 6e4:.0f} L/min): looks like L/min; "
                                          f"{v:g} L/min is {v / 6e4:.4g} m³/s")
    return v


def _parse_actuator(R: TableReader, tbl: dict, where: str, jtype: str) -> Actuator:
    R.keys(tbl, _ACT_KEYS, where)
    kind = R.text(tbl, "kind", where, choices=_ACT_KINDS)
    if jtype == "prismatic" and kind != "telescope":
        R.fail(f"{where}kind", kind, "a prismatic joint needs kind = 'telescope'")
    if jtype == "revolute" and kind == "telescope":
        R.fail(f"{where}kind", kind, "a revolute joint needs triangle, lever, rotary or rack")
    acting = R.text(tbl, "acting", where, default="double", choices=("double", "single"))
    area_a = R.num(tbl, "area_a", where, lo=0, lo_open=True)
    area_b = R.num(tbl, "area_b", where, default=area_a if kind in ("rotary", "rack") else None,
                   lo=0, lo_open=True)
    if kind in ("triangle", "lever", "telescope") and area_b > area_a:
        R.fail(f"{where}area_b", tbl.get("area_b"),
               f"annulus area must not exceed the piston area area_a = {area_a}")
    kw: dict[str, Any] = dict(kind=kind, area_a=area_a, area_b=area_b, acting=acting)
    if kind in ("triangle", "lever"):
        kw["base"] = R.vec(tbl, "base", where, 2)
        kw["stroke"] = R.num(tbl, "stroke", where, lo=0, lo_open=True)
        kw["closed_length"] = R.num(tbl, "closed_length", where, lo=0, lo_open=True)
    if kind == "triangle":
        kw["rod"] = R.vec(tbl, "rod", where, 2)
    if kind == "lever":
        kw["lever_pivot"] = R.vec(tbl, "lever_pivot", where, 2)
        kw["lever_link"] = R.vec(tbl, "lever_link", where, 2)
        kw["lever_lengths"] = R.vec(tbl, "lever_lengths", where, 2)
        if min(kw["lever_lengths"]) <= 0:
            R.fail(f"{where}lever_lengths", tbl["lever_lengths"], "lengths must be > 0")
        br = tbl.get("lever_branch", 1)
        if isinstance(br, bool) or br not in (1, -1):
            R.fail(f"{where}lever_branch", br, "allowed: 1 or -1")
        kw["lever_branch"] = int(br)
    if kind == "telescope":
        kw["ratio"] = R.num(tbl, "ratio", where, default=1.0, lo=0, lo_open=True)
        kw["q_ref"] = R.num(tbl, "q_ref", where, default=0.0)
        kw["stroke"] = R.num(tbl, "stroke", where, lo=0, lo_open=True)
    if kind == "rotary":
        kw["ratio"] = R.num(tbl, "ratio", where, lo=0, lo_open=True)
    if kind == "rack":
        kw["radius"] = R.num(tbl, "radius", where, lo=0, lo_open=True)
    if acting == "single" and kind not in ("triangle", "lever"):
        R.fail(f"{where}acting", acting, "single-acting is only allowed for cylinders "
                                          "(kind triangle or lever)")
    kw["flow_gain"] = _flow(R, tbl, "flow_gain", where)
    kw["deadband"] = R.num(tbl, "deadband", where, default=0.0, lo=0.0, hi=0.5)
    kw["max_speed"] = (R.num(tbl, "max_speed", where, lo=0, lo_open=True)
                       if "max_speed" in tbl else None)
    kw["mass"] = R.num(tbl, "mass", where, default=0.0, lo=0.0)
    kw["source"] = R.text(tbl, "source", where)
    return Actuator(**kw)


def _parse_joint(R: TableReader, tbl: dict, i: int) -> Joint:
    where = f"joint[{i}]."
    if not isinstance(tbl, dict):
        R.fail(f"joint[{i}]", tbl, "expected a table")
    R.keys(tbl, _JOINT_KEYS, where)
    name = R.text(tbl, "name", where)
    if not name.isidentifier():
        R.fail(f"{where}name", name, "a joint name must be an identifier (letters, digits, _)")
    where = f"joint[{i}]({name})."
    jtype = R.text(tbl, "type", where, choices=("revolute", "prismatic"))
    dh_t = R.table(tbl, "dh", where)
    R.keys(dh_t, _DH_KEYS, where + "dh.")
    dh = DH(theta=R.num(dh_t, "theta", where + "dh.", default=0.0, angle=True),
            d=R.num(dh_t, "d", where + "dh.", default=0.0),
            a=R.num(dh_t, "a", where + "dh.", default=0.0),
            alpha=R.num(dh_t, "alpha", where + "dh.", default=0.0, angle=True))
    lt = R.table(tbl, "limits", where)
    lw = where + "limits."
    R.keys(lt, _LIMIT_KEYS, lw)
    q = R.vec(lt, "q", lw, 2, angle=jtype == "revolute")
    if not q[0] < q[1]:
        R.fail(lw + "q", lt["q"], "q_min must be < q_max")
    if jtype == "revolute" and q[1] - q[0] > 2 * math.pi + 1e-9:
        R.fail(lw + "q", lt["q"], "a revolute range may span at most 2π")
    qd_raw = lt.get("qd")
    if isinstance(qd_raw, (int, float, str)) and not isinstance(qd_raw, bool):
        v = R.num(lt, "qd", lw, lo=0, lo_open=True, angle=jtype == "revolute")
        qd = (-v, v)
    else:
        qd = R.vec(lt, "qd", lw, 2, angle=jtype == "revolute")
        if not (qd[0] < 0 < qd[1]):
            R.fail(lw + "qd", lt["qd"], "expected [qd_min, qd_max] with qd_min < 0 < qd_max "
                                          "(or one positive number for symmetric limits)")
    qdd = R.num(lt, "qdd", lw, lo=0, lo_open=True, angle=jtype == "revolute")
    qddd = R.num(lt, "qddd", lw, angle=jtype == "revolute") if "qddd" in lt else None
    if qddd is not None and qddd <= 0:  # omitted: no jerk limit
        R.fail(lw + "qddd", lt["qddd"], "must be > 0 (omit for no jerk limit)")
    limits = Limits(q=q, qd=qd, qdd=qdd, qddd=qddd)
    mass = R.num(tbl, "mass", where, lo=0.0)
    com = R.vec(tbl, "com", where, 3)
    inertia = R.vec(tbl, "inertia", where, 3)
    if min(inertia) < 0:
        R.fail(where + "inertia", tbl["inertia"], "principal inertias must be >= 0")
    ix, iy, iz = inertia
    if ix > iy + iz + 1e-9 or iy > ix + iz + 1e-9 or iz > ix + iy + 1e-9:
        R.fail(where + "inertia", tbl["inertia"], "violates the triangle inequality of a rigid "
                                                 "body (each principal inertia <= sum of the others)")
    at = R.table(tbl, "actuator", where)
    act = _parse_actuator(R, at, where + "actuator.", jtype)
    return Joint(name=name, type=jtype, dh=dh, limits=limits, mass=mass, com=com,
                 inertia=inertia, actuator=act, source=R.text(tbl, "source", where))


def parse_spec(data: dict, file: str = "<memory>", text: str = "") -> CraneSpec:
    """Validate a parsed TOML dict and build a :class:`CraneSpec`."""
    R = TableReader(file)
    R.keys(data, {"crane", "joint", "payload", "pump", "transformer", "laws", "effects",
                  "dynamics"}, "")
    ct = R.table(data, "crane", "")
    R.keys(ct, {"id", "name", "description", "source", "elbow", "redundancy", "gravity"}, "crane.")
    cid = R.text(ct, "id", "crane.")
    joints_raw = data.get("joint")
    if not isinstance(joints_raw, list) or len(joints_raw) < 3:
        R.fail("joint", joints_raw, "expected at least three [[joint]] tables "
                                    "(slew + two boom joints)")
    joints = tuple(_parse_joint(R, jt, i) for i, jt in enumerate(joints_raw))
    names = [j.name for j in joints]
    for i, nm in enumerate(names):
        if names.index(nm) != i:
            R.fail(f"joint[{i}].name", nm, "joint names must be unique")
    if joints[0].type != "revolute":
        R.fail("joint[0].type", joints[0].type, "the first joint must be the revolute slew")
    red = ct.get("redundancy")
    if red is not None:
        if red not in names:
            R.fail("crane.redundancy", red, f"must name a joint: {', '.join(names)}")
        if joints[names.index(red)].type != "prismatic":
            R.fail("crane.redundancy", red, "the redundancy parameter must be a prismatic "
                                            "(telescope) joint")
    prism = [j.name for j in joints if j.type == "prismatic"]
    if prism and red is None:
        R.fail("crane.redundancy", None, f"required: name the telescope joint ({prism[0]})")
    pt = R.table(data, "payload", "")
    R.keys(pt, {"mass", "tool_mass", "source"}, "payload.")
    payload = Payload(mass=R.num(pt, "mass", "payload.", lo=0.0),
                      tool_mass=R.num(pt, "tool_mass", "payload.", default=0.0, lo=0.0),
                      source=R.text(pt, "source", "payload."))
    pu = R.table(data, "pump", "")
    pw = "pump."
    R.keys(pu, {"kind", "max_flow", "efficiency", "margin", "pressure", "standby",
                "max_pressure", "tank_pressure", "source"}, pw)
    kind = R.text(pu, "kind", pw, choices=("load_sensing", "constant_pressure"))
    pump = Pump(kind=kind,
                max_flow=_flow(R, pu, "max_flow", pw),
                efficiency=R.num(pu, "efficiency", pw, lo=0, lo_open=True, hi=1.0),
                margin=R.num(pu, "margin", pw, default=None if kind == "load_sensing" else 0.0,
                             lo=0.0),
                pressure=R.num(pu, "pressure", pw,
                               default=None if kind == "constant_pressure" else 0.0, lo=0.0),
                standby=R.num(pu, "standby", pw, default=0.0, lo=0.0),
                max_pressure=R.num(pu, "max_pressure", pw, default=math.inf, lo=0, lo_open=True),
                tank_pressure=R.num(pu, "tank_pressure", pw, default=0.0, lo=0.0),
                source=R.text(pu, "source", pw))
    if kind == "constant_pressure" and pump.pressure <= 0:
        R.fail(pw + "pressure", pu.get("pressure"), "a constant-pressure pump needs pressure > 0")
    transformer = None
    tt = R.table(data, "transformer", "", required=False)
    if tt is not None:
        tw = "transformer."
        R.keys(tt, {"source_joint", "target_joint", "ratio", "efficiency", "enabled", "source"}, tw)
        sj = R.text(tt, "source_joint", tw)
        tj = R.text(tt, "target_joint", tw)
        for k, v in (("source_joint", sj), ("target_joint", tj)):
            if v not in names:
                R.fail(tw + k, v, f"must name a joint: {', '.join(names)}")
        if sj == tj:
            R.fail(tw + "target_joint", tj, "must differ from source_joint")
        en = tt.get("enabled", True)
        if not isinstance(en, bool):
            R.fail(tw + "enabled", en, "expected true or false")
        transformer = Transformer(source_joint=sj, target_joint=tj,
                                  ratio=R.num(tt, "ratio", tw, default=1.0, lo=0, lo_open=True),
                                  efficiency=R.num(tt, "efficiency", tw, default=1.0, lo=0,
                                                   lo_open=True, hi=1.0),
                                  enabled=en, source=R.text(tt, "source", tw))
    laws = LawParams()
    lt = R.table(data, "laws", "", required=False)
    if lt is not None:
        R.keys(lt, {"weights", "max_lift", "source"}, "laws.")
        wt = R.table(lt, "weights", "laws.", required=False) or {}
        weights = {}
        for k in wt:
            if k not in names:
                R.fail(f"laws.weights.{k}", wt[k], f"must name a joint: {', '.join(names)}")
            weights[k] = R.num(wt, k, "laws.weights.", lo=0, lo_open=True)
        ml = R.table(lt, "max_lift", "laws.", required=False) or {}
        R.keys(ml, {"rc", "zc", "rho_min", "rho_max"}, "laws.max_lift.")
        max_lift = {k: R.num(ml, k, "laws.max_lift.") for k in ml}
        if max_lift:
            for k in ("rc", "zc", "rho_min", "rho_max"):
                if k not in max_lift:
                    R.fail(f"laws.max_lift.{k}", None, "missing (rc, zc, rho_min, rho_max)")
            if not 0 <= max_lift["rho_min"] < max_lift["rho_max"]:
                R.fail("laws.max_lift.rho_max", max_lift["rho_max"],
                       "need 0 <= rho_min < rho_max")
        laws = LawParams(weights=weights, max_lift=max_lift,
                         source=R.text(lt, "source", "laws."))
    effects = []
    er = data.get("effects", [])
    if not isinstance(er, list):
        R.fail("effects", er, "expected [[effects]] tables (name, joint, parameters)")
    for i, et in enumerate(er):
        if not isinstance(et, dict):
            R.fail(f"effects[{i}]", et, "expected a table")
        if et.get("joint") is not None and et.get("joint") not in names:
            R.fail(f"effects[{i}].joint", et.get("joint"), f"must name a joint: {', '.join(names)}")
        try:
            effects.append(effect_from_dict(et).to_dict())
        except ValueError as e:
            R.fail(f"effects[{i}]", et, str(e))
    spec = CraneSpec(
        id=cid, name=R.text(ct, "name", "crane."),
        description=R.text(ct, "description", "crane.", default=""),
        source=R.text(ct, "source", "crane."),
        elbow=R.text(ct, "elbow", "crane.", choices=("up", "down")),
        redundancy=red, joints=joints, payload=payload, pump=pump, transformer=transformer,
        laws=laws, effects=tuple(effects), dynamics=parse_dynamics(R, data, names),
        gravity=R.num(ct, "gravity", "crane.", default=9.81, lo=0.0),
        path=file, raw=data, text=text)
    return spec


def load_spec(path: str | Path) -> CraneSpec:
    """Read and validate a crane TOML file. Raises :class:`SpecError` on any problem.

    Geometric consistency (knuckle-boom structure, cylinder strokes covering the joint range)
    is checked when the model is built: see :func:`planner.model.Crane`.
    """
    path = Path(path)
    text = read_toml_text(path)       # UTF-8 (a byte-order mark dropped), or SpecError
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SpecError(str(path), "<toml>", None, f"not valid TOML: {e}") from None
    return parse_spec(data, str(path), text)
