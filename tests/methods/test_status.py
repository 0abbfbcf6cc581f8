"""The result codes of the planning methods (planner.methods.base.PlanStatus): one documented
enum, refused when unknown, written to JSON as the plain code."""
import ast
import json
import re
from pathlib import Path

import pytest

import planner
import planner.methods.base as base
from planner.io import write_json
from planner.methods import PlanResult, PlanStatus

ROOT = Path(__file__).resolve().parents[2]


def test_every_code_is_documented_in_the_module_doc_and_the_json_keys():
    doc = base.__doc__
    in_doc = set(re.findall(r"^- ``([a-z_]+)``:", doc, re.M))
    keys = (ROOT / "docs" / "json-keys.md").read_text(encoding="utf-8")
    table = keys.split("## Result codes\n", 1)[1].split("\n## ", 1)[0]
    in_table = set(re.findall(r"^\| `([a-z_]+)` \| ", table, re.M))
    codes = {m.value for m in PlanStatus}
    assert len(codes) == len(PlanStatus) >= 12
    assert in_doc == codes, f"module doc lists {sorted(in_doc ^ codes)} differently"
    assert in_table == codes, f"docs/json-keys.md lists {sorted(in_table ^ codes)} differently"
    for m in PlanStatus:
        assert m.meaning and "\n" not in m.meaning, m


def test_an_unknown_code_is_refused_naming_it_and_the_allowed_ones():
    with pytest.raises(ValueError) as e:
        PlanResult("unreachabel", "typo")
    msg = str(e.value)
    assert "'unreachabel'" in msg and all(m.value in msg for m in PlanStatus)
    res = PlanResult("ok")
    with pytest.raises(ValueError, match="'done'"):
        res.status = "done"
    assert res.status is PlanStatus.OK


def test_a_status_compares_and_serialises_as_its_plain_code(tmp_path):
    res = PlanResult("infeasible", "no timing")
    assert res.status is PlanStatus.INFEASIBLE and res.status == "infeasible" and not res.ok
    assert PlanResult(PlanStatus.OK).ok and PlanResult("ok").status == "ok"
    assert {"infeasible": 1}[res.status] == 1 and f"{res.status}" == "infeasible"
    assert json.dumps({"status": res.status}) == '{"status": "infeasible"}'
    out = tmp_path / "r.json"
    write_json(str(out), dict(status=res.status, reason=res.reason))   # the CLI's writer
    assert json.loads(out.read_text()) == {"status": "infeasible", "reason": "no timing"}
    assert planner.PlanStatus is PlanStatus and "PlanStatus" in planner.__all__


def test_the_methods_use_the_members_not_string_literals():
    makers = {"PlanResult", "nlp_result", "_result", "TimedPath", "Outcome"}
    found = []
    for p in sorted((ROOT / "planner").rglob("*.py")):
        if p.parts[-2] == "cli":
            continue
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and node.args and \
                    getattr(node.func, "id", getattr(node.func, "attr", None)) in makers and \
                    isinstance(node.args[0], ast.Constant) and \
                    isinstance(node.args[0].value, str):
                found.append(f"{p.relative_to(ROOT)}:{node.lineno}: {node.args[0].value!r}")
    assert not found, "status string literals: " + "; ".join(found)
