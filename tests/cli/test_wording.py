"""Command-line wording stays in planner/cli/: the layers below name fields, the CLI prints
flags (planner/cli/wording.py).

The scan reads every module outside planner/cli/ with ``ast``: no string of the code (its
docstrings and comments aside) may name a command-line flag, unless it spells out a whole
``crane-planner …`` command (a suggestion the user can copy). The mapping is checked against
the parser itself: every flag it prints exists on the command it is printed for.
"""
import ast
import json
import re
from pathlib import Path

import pytest

from planner.cli import build_parser, main
from planner.cli.wording import COMMAND_FLAGS, FLAGS, cli_text
from planner.methods import PlanRequest, UnsupportedRequest

PKG = Path(__file__).resolve().parents[2] / "planner"
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def _docstrings(tree) -> set:
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                out.add(id(body[0].value))
    return out


def _texts(tree):
    """(line, text) of every string of the code: an f-string as one text ({} for its values),
    docstrings left out."""
    skip = _docstrings(tree)
    inner = {id(v) for n in ast.walk(tree) if isinstance(n, ast.JoinedStr) for v in n.values}
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            yield node.lineno, "".join(v.value if isinstance(v, ast.Constant) else "{}"
                                       for v in node.values)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and \
                id(node) not in skip and id(node) not in inner:
            yield node.lineno, node.value


def _flags_outside_commands(text: str) -> list:
    """The flags of ``text`` that are not part of a spelled-out ``crane-planner`` command."""
    cmd = text.find("crane-planner ")
    return [m.group(0) for m in FLAG.finditer(text) if cmd < 0 or m.start() < cmd]


def test_no_module_below_the_cli_writes_a_flag_into_a_message():
    found = []
    for p in sorted(PKG.rglob("*.py")):
        if p.relative_to(PKG).parts[0] == "cli":
            continue
        for line, text in _texts(ast.parse(p.read_text(encoding="utf-8"))):
            flags = _flags_outside_commands(text)
            if flags:
                found.append(f"{p.relative_to(PKG.parent)}:{line}: {flags} in {text[:60]!r}")
    assert not found, "name the field (`tip_speed`), not the flag:\n" + "\n".join(found)


def test_the_scan_finds_a_flag_and_spares_a_command():
    tree = ast.parse('def f(x):\n    """--doc is fine"""\n'
                     '    raise ValueError(f"--tip-speed {x}: allowed > 0")\n'
                     'HINT = "resample first: crane-planner resample FILE --rate HZ"\n')
    texts = dict(_texts(tree))
    assert _flags_outside_commands(texts[3]) == ["--tip-speed"]
    assert _flags_outside_commands(texts[4]) == []
    assert 2 not in texts


def _parser_flags() -> dict:
    """command -> every option string of it and of its sub-commands."""
    out = {}
    sub = next(a for a in build_parser()._actions if a.choices and a.dest == "command")

    def walk(parser, into):
        for a in parser._actions:
            into.update(s for s in a.option_strings if s.startswith("--"))
            if a.choices and isinstance(a.choices, dict):
                for child in a.choices.values():
                    walk(child, into)
    for name, parser in sub.choices.items():
        walk(parser, out.setdefault(name, set()))
    return out


def test_every_flag_of_the_mapping_exists_on_its_command():
    flags = _parser_flags()
    everywhere = set().union(*flags.values())
    assert not [f for f in FLAGS.values() if f not in everywhere]
    for command, table in COMMAND_FLAGS.items():
        assert command in flags, command
        assert not [f for f in table.values() if f not in flags[command]], command


def test_fields_become_flags_when_the_cli_prints():
    assert cli_text("`tip_speed` = -1.0 m/s: allowed a finite number > 0", "plan") == \
        "--tip-speed -1.0 m/s: allowed a finite number > 0"
    assert cli_text("use a larger `step` or `tele_step`, a smaller `window`") == \
        "use a larger --step or --tele-step, a smaller --window"
    # a command's own name first; a field without a flag is left as written
    assert cli_text("`text` 'a': name at least two effects", "excite") == \
        "--separate 'a': name at least two effects"
    assert cli_text("`text` 'a'", "plan") == "`text` 'a'"
    assert cli_text("`q_start` = [1, 2]: outside the limits") == \
        "`q_start` = [1, 2]: outside the limits"
    with pytest.raises(UnsupportedRequest) as e:
        PlanRequest((5, 1, 0), (4, 2, 0), tip_speed=-1)
    assert str(e.value).startswith("`tip_speed` = -1 m/s")   # the Python caller: the field


def _err(capsys, *argv) -> tuple:
    rc = main(list(argv))
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_a_plan_reason_names_the_flags(capsys):
    """The DP's "too fast" reason (a result, not an error) reaches the user with flags, on
    stderr and in the JSON."""
    rc, out, err = _err(capsys, "plan", "cranab850", "--start", "1.5,1.0,0",
                        "--goal", "5.5,-3.0,0", "--method", "dp", "--objective", "energy",
                        "--duration", "0.5", "--step", "0.05", "--tele-step", "0.05",
                        "--window", "2", "--json", "-")
    assert rc == 3
    reason = json.loads(out)["reason"]
    assert "--duration >= " in reason and "--tip-speed <= " in reason and "`" not in reason
    assert reason in err


def test_lower_layer_errors_reach_the_user_with_flags(capsys, tmp_path):
    rc, _, err = _err(capsys, "plan", "cranab850", "--start", "1.5,1.0,0", "--goal",
                      "5.5,-3.0,0", "--method", "ruckig", "--objective", "energy")
    assert rc == 2 and "--objective energy: ruckig plans time" in err
    rc, _, err = _err(capsys, "plan", "cranab850", "--start", "1.5,1.0,0", "--goal",
                      "5.5,-3.0,0", "--method", "dp", "--objective", "energy")
    assert rc == 2 and "--method dp with --objective energy needs exactly one of " \
        "--tip-speed [m/s] or --duration [s]" in err
    rc, _, err = _err(capsys, "excite", "cat215b", "--separate", "leakage@boom", "--out",
                      str(tmp_path / "x.csv"))
    assert rc == 2 and "--separate 'leakage@boom': name at least two effects" in err
    assert not (tmp_path / "x.csv").exists()
