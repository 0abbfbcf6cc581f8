"""Spec validation: every kind of mistake in a crane TOML raises a SpecError that names the file,
the field and what is allowed (planner/spec.py), including the geometric checks done when the
model is built (planner.model.Crane._check_actuators, planner.model.kinematics.planar_chain).

All cases start from the valid planner/problems/cranes/umea-lab.toml (joints: 0 slew/rotary,
1 boom/triangle, 2 jib/lever, 3 tele/telescope) and change one thing.
"""
from __future__ import annotations

import copy
import math
import tomllib

import pytest

from planner.model import Crane
from planner.model.spec import SpecError, load_spec, parse_spec
from planner.problems import crane_path
from planner.units import parse_angle

UMEA = crane_path("umea-lab")
FILE = "x.toml"
JOINT_KEYS = ["actuator", "com", "dh", "inertia", "limits", "mass", "name", "source", "type"]


@pytest.fixture(scope="module")
def base() -> dict:
    return tomllib.loads(UMEA.read_text(encoding="utf-8"))


def _set(path, value):
    """Mutation that sets data[path[0]][path[1]]... = value."""
    def mut(d):
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value
    return mut


def _pop(path):
    def mut(d):
        for k in path[:-1]:
            d = d[k]
        del d[path[-1]]
    return mut


def _add_transformer(**kw):
    def mut(d):
        d["transformer"] = {"source_joint": "boom", "target_joint": "jib", "source": "test", **kw}
    return mut


def _spec_error(base, mutate, build=False) -> SpecError:
    data = copy.deepcopy(base)
    mutate(data)
    with pytest.raises(SpecError) as ei:
        spec = parse_spec(data, file=FILE)
        if build:
            Crane(spec)
    return ei.value


# (id, kind of mistake, mutation, build model?, exact field, substrings of `expected`)
CASES = [
    ("q-reversed", "q-order", _set(["joint", 1, "limits", "q"], [1.0, 0.5]), False,
     "joint[1](boom).limits.q", ["q_min must be < q_max"]),
    ("q-empty", "q-order", _set(["joint", 1, "limits", "q"], [0.5, 0.5]), False,
     "joint[1](boom).limits.q", ["q_min must be < q_max"]),
    ("q-over-2pi", "q-span", _set(["joint", 0, "limits", "q"], ["-200deg", "200deg"]), False,
     "joint[0](slew).limits.q", ["at most 2π"]),
    ("area-negative", "not-positive", _set(["joint", 1, "actuator", "area_a"], -0.001), False,
     "joint[1](boom).actuator.area_a", ["must be > 0"]),
    ("area-zero", "not-positive", _set(["joint", 1, "actuator", "area_a"], 0.0), False,
     "joint[1](boom).actuator.area_a", ["must be > 0"]),
    ("annulus>piston", "annulus", _set(["joint", 1, "actuator", "area_b"], 0.002), False,
     "joint[1](boom).actuator.area_b", ["annulus area must not exceed the piston area",
                                        "0.0012566"]),
    ("joint-unknown-key", "unknown-joint-key", _set(["joint", 1, "masss"], 45.0), False,
     "joint[1].masss", ["unknown key; allowed: " + ", ".join(JOINT_KEYS)]),
    ("dh-unknown-key", "unknown-dh-key", _set(["joint", 1, "dh", "beta"], 0.1), False,
     "joint[1](boom).dh.beta", ["unknown key; allowed: a, alpha, d, theta"]),
    ("actuator-unknown-key", "unknown-actuator-key",
     _set(["joint", 1, "actuator", "bore"], 0.04), False,
     "joint[1](boom).actuator.bore", ["unknown key; allowed:", "area_a", "lever_lengths"]),
    ("top-unknown-table", "unknown-table", _set(["pumps"], {"max_flow": 1e-3}), False,
     "pumps", ["unknown key; allowed: crane, dynamics, effects, joint, laws, payload, pump, transformer"]),
    ("missing-max-flow", "missing-number", _pop(["pump", "max_flow"]), False,
     "pump.max_flow", ["missing (required number)"]),
    ("missing-source", "missing-string", _pop(["joint", 1, "actuator", "source"]), False,
     "joint[1](boom).actuator.source", ["missing (required string)"]),
    ("missing-dh-table", "missing-table", _pop(["joint", 2, "dh"]), False,
     "joint[2](jib).dh", ["missing table"]),
    ("string-for-number", "type-number", _set(["pump", "max_flow"], "lots"), False,
     "pump.max_flow", ["expected a number"]),
    ("bool-for-number", "type-number", _set(["joint", 1, "mass"], True), False,
     "joint[1](boom).mass", ["expected a number"]),
    ("bad-angle-string", "type-angle", _set(["joint", 1, "dh", "theta"], "ten degrees"), False,
     "joint[1](boom).dh.theta", ["expected a number or an angle like '30deg'"]),
    ("number-for-string", "type-string", _set(["joint", 1, "name"], 5), False,
     "joint[1].name", ["expected a string"]),
    ("short-list", "list-length", _set(["joint", 1, "com"], [1.0, 2.0]), False,
     "joint[1](boom).com", ["expected a list of 3 numbers"]),
    ("nan-in-list", "non-finite", _set(["joint", 1, "limits", "q"], [float("nan"), 1.0]), False,
     "joint[1](boom).limits.q", ["expected finite numbers"]),
    ("qd-both-positive", "qd-signs", _set(["joint", 1, "limits", "qd"], [0.1, 0.2]), False,
     "joint[1](boom).limits.qd", ["qd_min < 0 < qd_max"]),
    ("qd-both-negative", "qd-signs", _set(["joint", 3, "limits", "qd"], [-0.5, -0.1]), False,
     "joint[3](tele).limits.qd", ["qd_min < 0 < qd_max"]),
    ("qddd-negative", "qddd", _set(["joint", 1, "limits", "qddd"], -2.0), False,
     "joint[1](boom).limits.qddd", ["must be > 0 (omit for no jerk limit)"]),
    ("actuator-kind", "choice-kind", _set(["joint", 1, "actuator", "kind"], "piston"), False,
     "joint[1](boom).actuator.kind", ["allowed: triangle, lever, telescope, rotary, rack"]),
    ("prismatic-triangle", "prismatic-kind", _set(["joint", 3, "actuator", "kind"], "triangle"),
     False, "joint[3](tele).actuator.kind", ["a prismatic joint needs kind = 'telescope'"]),
    ("revolute-telescope", "revolute-kind", _set(["joint", 1, "actuator", "kind"], "telescope"),
     False, "joint[1](boom).actuator.kind",
     ["a revolute joint needs triangle, lever, rotary or rack"]),
    ("single-telescope", "single-acting", _set(["joint", 3, "actuator", "acting"], "single"),
     False, "joint[3](tele).actuator.acting",
     ["single-acting is only allowed for cylinders (kind triangle or lever)"]),
    ("acting-choice", "choice-acting", _set(["joint", 1, "actuator", "acting"], "triple"), False,
     "joint[1](boom).actuator.acting", ["allowed: double, single"]),
    ("pump-efficiency>1", "above-max", _set(["pump", "efficiency"], 1.2), False,
     "pump.efficiency", ["must be <= 1.0"]),
    ("transformer-efficiency>1", "above-max", _add_transformer(efficiency=1.5), False,
     "transformer.efficiency", ["must be <= 1.0"]),
    ("deadband>0.5", "above-deadband", _set(["joint", 3, "actuator", "deadband"], 0.6), False,
     "joint[3](tele).actuator.deadband", ["must be <= 0.5"]),
    ("negative-payload", "negative", _set(["payload", "mass"], -1.0), False,
     "payload.mass", ["must be >= 0.0"]),
    ("duplicate-name", "duplicate", _set(["joint", 2, "name"], "boom"), False,
     "joint[2].name", ["joint names must be unique"]),
    ("name-not-identifier", "identifier", _set(["joint", 1, "name"], "inner boom"), False,
     "joint[1].name", ["must be an identifier"]),
    ("redundancy-missing-joint", "dangling-joint", _set(["crane", "redundancy"], "telescope"),
     False, "crane.redundancy", ["must name a joint: slew, boom, jib, tele"]),
    ("transformer-unknown-joint", "dangling-joint", _add_transformer(target_joint="stick"),
     False, "transformer.target_joint", ["must name a joint: slew, boom, jib, tele"]),
    ("transformer-same-joint", "transformer-same", _add_transformer(target_joint="boom"), False,
     "transformer.target_joint", ["must differ from source_joint"]),
    ("redundancy-revolute", "redundancy-type", _set(["crane", "redundancy"], "jib"), False,
     "crane.redundancy", ["must be a prismatic (telescope) joint"]),
    ("redundancy-omitted", "redundancy-required", _pop(["crane", "redundancy"]), False,
     "crane.redundancy", ["required: name the telescope joint (tele)"]),
    ("inertia-triangle", "inertia-triangle", _set(["joint", 1, "inertia"], [0.5, 7.4, 100.0]),
     False, "joint[1](boom).inertia", ["triangle inequality"]),
    ("inertia-negative", "inertia-negative", _set(["joint", 1, "inertia"], [-0.5, 7.4, 7.4]),
     False, "joint[1](boom).inertia", ["principal inertias must be >= 0"]),
    ("too-few-joints", "joint-count", lambda d: d.__setitem__("joint", d["joint"][:2]), False,
     "joint", ["expected at least three [[joint]] tables"]),
    ("elbow-choice", "choice-elbow", _set(["crane", "elbow"], "sideways"), False,
     "crane.elbow", ["allowed: up, down"]),
    ("constant-pressure-no-pressure", "missing-number",
     _set(["pump", "kind"], "constant_pressure"), False,
     "pump.pressure", ["missing (required number)"]),
    # --- geometric consistency, checked when the model is built
    ("stroke-too-short", "stroke", _set(["joint", 1, "actuator", "stroke"], 0.2), True,
     "joint[1](boom).actuator.stroke", ["the joint range needs strokes",
                                        "outside the cylinder's 0 .. 0.2 m"]),
    ("telescope-stroke-too-short", "stroke", _set(["joint", 3, "actuator", "stroke"], 1.0), True,
     "joint[3](tele).actuator.stroke", ["needs strokes 0.000 .. 1.550 m",
                                        "outside the cylinder's 0 .. 1.0 m"]),
    ("lever-cannot-close", "lever", _set(["joint", 2, "actuator", "lever_lengths"], [0.1, 0.1]),
     True, "joint[2](jib).actuator.lever_lengths", ["the lever linkage cannot close at jib ="]),
    ("slew-alpha", "dh-boom-axis", _set(["joint", 0, "dh", "alpha"], 0.0), True,
     "joint[0](slew).dh.alpha", ["the boom axis must be horizontal"]),
]


@pytest.mark.parametrize("cid,kind,mutate,build,fld,parts", CASES, ids=[c[0] for c in CASES])
def test_spec_error_names_field_and_rule(base, cid, kind, mutate, build, fld, parts):
    e = _spec_error(base, mutate, build=build)
    assert e.file == FILE
    assert e.field == fld
    for p in parts:
        assert p in e.expected
    msg = str(e)
    assert msg.startswith(f"{FILE}: field '{fld}' = ")
    assert msg.endswith(e.expected)


def test_unmodified_spec_is_valid(base):
    """Sanity check of the starting point: every failure above comes from the mutation."""
    spec = parse_spec(copy.deepcopy(base), file=FILE)
    assert spec.joint_names == ["slew", "boom", "jib", "tele"]
    assert Crane(spec).n == 4


def test_error_values_are_the_offending_input(base):
    e = _spec_error(base, _set(["joint", 1, "limits", "q"], [1.0, 0.5]))
    assert e.value == [1.0, 0.5]
    e = _spec_error(base, _set(["pump", "max_flow"], "lots"))
    assert e.value == "lots"
    e = _spec_error(base, _pop(["pump", "max_flow"]))
    assert e.value is None
    assert isinstance(e, ValueError)  # callers may catch it as a ValueError


def test_unknown_key_message_lists_every_allowed_actuator_key(base):
    e = _spec_error(base, _set(["joint", 1, "actuator", "bore"], 0.04))
    allowed = e.expected.split("allowed: ", 1)[1].split(", ")
    assert allowed == sorted(allowed)
    assert set(allowed) == {"kind", "area_a", "area_b", "acting", "stroke", "closed_length",
                            "base", "rod", "lever_pivot", "lever_link", "lever_lengths",
                            "lever_branch", "ratio", "q_ref", "radius", "flow_gain", "deadband",
                            "max_speed", "mass", "source"}


def test_each_kind_of_mistake_has_its_own_expected_text(base):
    """Different kinds of mistake never share an ``expected`` text (cases of the same kind —
    e.g. a zero and a negative area — state the same rule)."""
    by_kind: dict[str, set[str]] = {}
    for cid, kind, mutate, build, fld, parts in CASES:
        by_kind.setdefault(kind, set()).add(_spec_error(base, mutate, build=build).expected)
    seen: dict[str, str] = {}
    for kind, texts in by_kind.items():
        for t in texts:
            assert t not in seen, f"{kind!r} and {seen[t]!r} both say {t!r}"
            seen[t] = kind
    # and the full messages of all cases are pairwise distinct
    msgs = [str(_spec_error(base, c[2], build=c[3])) for c in CASES]
    assert len(set(msgs)) == len(msgs)


# ----------------------------------------------------------------------------- geometry
def test_non_knuckle_boom_dh_is_rejected(base):
    """Twisting the boom row (alpha != 0) makes the jib axis non-parallel to the boom axis."""
    data = copy.deepcopy(base)
    data["joint"][1]["dh"]["alpha"] = 0.5
    spec = parse_spec(data, file=FILE)          # each row is valid on its own ...
    with pytest.raises(SpecError) as ei:        # ... but the chain is not a knuckle boom
        Crane(spec)
    e = ei.value
    assert e.file == FILE
    assert e.field == "joint[1](boom).dh.alpha"  # the offending (boom) row's twist
    assert "the jib axis must be parallel to the boom axis" in e.expected
    assert e.value == 0.5


def test_tilted_jib_row_is_rejected(base):
    data = copy.deepcopy(base)
    data["joint"][2]["dh"]["alpha"] = 0.0   # telescope axis no longer in the boom plane
    with pytest.raises(SpecError) as ei:
        Crane(parse_spec(data, file=FILE))
    assert "the telescope must slide in the plane of boom and jib" in ei.value.expected
    assert ei.value.field == "joint[2](jib).dh.alpha"


def test_stroke_error_reports_the_needed_range(base):
    e = _spec_error(base, _set(["joint", 1, "actuator", "stroke"], 0.2), build=True)
    assert e.value == 0.2
    lo, hi = (float(v) for v in
              e.expected.split("needs strokes ", 1)[1].split(" m", 1)[0].split(" .. "))
    assert 0.0 <= lo < 0.2 < hi <= 0.5647 + 1e-3   # the shipped stroke covers the range


# ----------------------------------------------------------------------------- angles
@pytest.mark.parametrize("text,deg", [("30deg", 30.0), (" 30 DEG ", 30.0), ("-45deg", -45.0),
                                      ("90°", 90.0), ("1.5e1deg", 15.0)])
def test_parse_angle_degrees(text, deg):
    assert parse_angle(text) == pytest.approx(math.radians(deg))


@pytest.mark.parametrize("value,rad", [("0.5rad", 0.5), ("0.5", 0.5), (2, 2.0), (0.25, 0.25)])
def test_parse_angle_radians(value, rad):
    assert parse_angle(value) == pytest.approx(rad)


@pytest.mark.parametrize("value", ["thirty deg", "30 degrees", "deg", "", "30grad", "1,5deg",
                                   True, None, [30]])
def test_parse_angle_rejects(value):
    with pytest.raises(ValueError):
        parse_angle(value)


def test_angle_strings_accepted_in_spec(base):
    data = copy.deepcopy(base)
    data["joint"][1]["limits"]["q"] = ["-20deg", "70deg"]
    data["joint"][1]["limits"]["qd"] = "10deg"         # one number: symmetric limit
    data["joint"][1]["dh"]["theta"] = "0.1192rad"
    spec = parse_spec(data, file=FILE)
    b = spec.joints[1]
    assert b.limits.q == pytest.approx((math.radians(-20), math.radians(70)))
    assert b.limits.qd == pytest.approx((-math.radians(10), math.radians(10)))
    assert b.dh.theta == pytest.approx(0.1192)


def test_angle_strings_rejected_for_prismatic_joint(base):
    e = _spec_error(base, _set(["joint", 3, "limits", "q"], ["0deg", "1.5deg"]))
    assert e.field == "joint[3](tele).limits.q"
    assert e.expected == "expected a list of 2 numbers"


# ----------------------------------------------------------------------------- files
def test_load_spec_valid_file_with_angle_strings(tmp_path):
    text = UMEA.read_text(encoding="utf-8").replace(
        "limits = { q = [-1.0, 0.5],", 'limits = { q = ["-60deg", "30deg"],', 1)
    p = tmp_path / "lab.toml"
    p.write_text(text, encoding="utf-8")
    spec = load_spec(p)
    assert spec.path == str(p)
    assert spec.text == text
    assert spec.joints[0].limits.q == pytest.approx((math.radians(-60), math.radians(30)))


def test_load_spec_invalid_toml(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text(UMEA.read_text(encoding="utf-8") + "\n[pump\nmax_flow = 1\n", encoding="utf-8")
    with pytest.raises(SpecError) as ei:
        load_spec(p)
    e = ei.value
    assert e.file == str(p)
    assert e.field == "<toml>"
    assert e.expected.startswith("not valid TOML")
    assert str(p) in str(e)


def test_load_spec_missing_file(tmp_path):
    p = tmp_path / "does-not-exist.toml"
    with pytest.raises(SpecError) as ei:
        load_spec(p)
    e = ei.value
    assert e.file == str(p)
    assert e.field == "<file>"
    assert e.expected.startswith("cannot read file")
    assert "No such file" in e.expected


def test_load_spec_reports_field_errors_with_the_path(tmp_path):
    text = UMEA.read_text(encoding="utf-8").replace("efficiency = 0.8", "efficiency = 1.8", 1)
    p = tmp_path / "eff.toml"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(SpecError) as ei:
        load_spec(p)
    assert ei.value.file == str(p)
    assert ei.value.field == "pump.efficiency"
    assert str(ei.value) == f"{p}: field 'pump.efficiency' = 1.8: must be <= 1.0"


# ----------------------------------------------------------------------------- sentinels
def test_max_speed_minus_one_rejected(base):
    e = _spec_error(base, _set(["joint", 1, "actuator", "max_speed"], -1.0))
    assert e.field == "joint[1](boom).actuator.max_speed"


def test_qddd_minus_one_rejected(base):
    e = _spec_error(base, _set(["joint", 1, "limits", "qddd"], -1.0))
    assert e.field == "joint[1](boom).limits.qddd"


def test_lever_branch_bool_rejected(base):
    e = _spec_error(base, _set(["joint", 2, "actuator", "lever_branch"], True))
    assert e.field == "joint[2](jib).actuator.lever_branch"


def test_max_speed_other_negative_rejected(base):
    e = _spec_error(base, _set(["joint", 1, "actuator", "max_speed"], -2.0))
    assert e.field == "joint[1](boom).actuator.max_speed"
    assert e.expected == "must be > 0"
