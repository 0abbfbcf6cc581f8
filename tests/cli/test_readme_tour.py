"""The README, run as written: every ```sh block's ``crane-planner`` commands, in the order the
README gives them, in one folder (a later block reads what an earlier one wrote: the
discrepancy block replays the tour's ``move.csv``), each exiting 0 and writing the files it
names; then every ```python block. The tour is what a new user types first; this keeps it from
drifting away from the CLI.

Not run: ``make`` (it runs this suite) and the Dask block (``dask scheduler`` / ``dask worker``
and a build pointed at ``tcp://HOST:8786`` need a cluster; tests/library covers Dask).
Slow: the tour builds the full 400-entry forwarder library and runs the Exudyn plant, the
discrepancy workflow and two excitation designs — measured 29.5 min on 2 shared cores at load
10-13 (the library build 17 min, ``excite --from`` 5.4 min); ``make bench`` runs it, or
``pytest -m slow tests/cli/test_readme_tour.py``."""
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

NEEDS_A_CLUSTER = "tcp://HOST:"


def blocks(lang: str) -> list:
    """The README's fenced ```lang blocks, in order."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return re.findall(rf"^```{lang}\n(.*?)^```", text, re.S | re.M)


def commands() -> list:
    """Every ``crane-planner`` command of the ```sh blocks, in order (continuation lines
    joined, comments dropped), as argv lists without the program name."""
    cmds = []
    for block in blocks("sh"):
        for line in block.replace("\\\n", " ").splitlines():
            line = re.split(r"(?:^|\s)#(?:\s|$)", line)[0].strip()
            if line.startswith("crane-planner ") and NEEDS_A_CLUSTER not in line:
                cmds.append(shlex.split(line)[1:])
    return cmds


def written_files(argv: list) -> list:
    """The paths a command names after --out/--plot/--json/--report/--save-model (a folder for
    export and report)."""
    return [argv[i + 1] for i, a in enumerate(argv[:-1])
            if a in ("--out", "--plot", "--json", "--report", "--save-model")
            and argv[i + 1] != "-"]


def read_files(argv: list) -> list:
    """The paths a command reads: --trajectory (FILE.h5#ID: the file), --measured, --from,
    the library of ``library query/export`` and the recording of ``resample``."""
    out = [argv[i + 1].partition("#")[0] for i, a in enumerate(argv[:-1])
           if a in ("--trajectory", "--measured", "--from")]
    if argv[:2] in (["library", "query"], ["library", "export"], ["library", "info"]):
        out.append(argv[2])
    if argv[:1] == ["resample"]:
        out.append(argv[1])
    return out


def test_the_readme_commands_read_only_what_an_earlier_one_wrote():
    """The order as written: no command reads a file that no earlier command has made (the
    discrepancy block once used exc.csv before any command made it)."""
    cmds = commands()
    assert len(cmds) >= 25
    assert any(c[:2] == ["library", "build"] for c in cmds)
    assert any(c[0] == "discrepancy" for c in cmds) and any(c[0] == "excite" for c in cmds)
    made = set()
    for c in cmds:
        for f in read_files(c):
            # a file made by an earlier command, or one inside a folder an earlier one filled
            assert f in made or any(d.endswith("/") and f.startswith(d) for d in made), (c, f)
        made.update(written_files(c))


def test_the_readme_python_blocks_define_what_they_use():
    """Every name a ```python block loads is imported or assigned in it (or a builtin)."""
    import ast
    import builtins
    for code in blocks("python"):
        tree = ast.parse(code)
        bound = set(dir(builtins))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                bound.update((a.asname or a.name).split(".")[0] for a in node.names)
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                bound.add(node.id)
        used = {n.id for n in ast.walk(tree)
                if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}
        assert used <= bound, sorted(used - bound)


@pytest.mark.slow
def test_the_readme_runs_as_written(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT))
    times = []
    for argv in commands():
        t0 = time.monotonic()
        r = subprocess.run([sys.executable, "-m", "planner", *argv], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=1800)
        times.append((time.monotonic() - t0, " ".join(argv[:2])))
        assert r.returncode == 0, (argv, r.stderr[-2000:])
        for f in written_files(argv):
            p = tmp_path / f
            assert p.exists(), (argv, f)
            assert p.is_dir() and any(p.iterdir()) or p.stat().st_size > 0, (argv, f)
    for code in blocks("python"):
        r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, (code, r.stderr[-2000:])
    print("\n".join(f"{s:7.1f} s  {what}" for s, what in times))
