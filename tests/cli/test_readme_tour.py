"""The README's tour, run as written: every command in its ``## Tour`` block exits 0 and writes
the files it names (the tour is what a new user types first; this keeps it from drifting away
from the CLI). Slow: the tour builds the full 400-entry forwarder library (about 4 minutes on
2 cores); ``make bench`` runs it."""
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def tour_commands() -> list:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"^## Tour\n.*?^```sh\n(.*?)^```", text, re.S | re.M)
    assert block, "README.md has no ```sh block under '## Tour'"
    cmds = []
    for line in block.group(1).replace("\\\n", " ").splitlines():
        line = re.split(r"\s#\s", line)[0].strip()
        if line.startswith("crane-planner "):
            cmds.append(shlex.split(line)[1:])
    return cmds


def written_files(argv: list) -> list:
    """The paths a command names after --out/--plot (a folder for export)."""
    return [argv[i + 1] for i, a in enumerate(argv[:-1]) if a in ("--out", "--plot")
            and argv[i + 1] != "-"]


def test_the_tour_block_is_found_and_names_its_outputs():
    cmds = tour_commands()
    assert len(cmds) >= 15
    assert any(c[:2] == ["library", "build"] for c in cmds)
    # every file a later command reads was written by an earlier one
    made = set()
    for c in cmds:
        for flag in ("--trajectory", ):
            if flag in c:
                assert c[c.index(flag) + 1] in made, c
        if c[:2] in (["library", "query"], ["library", "export"]):
            assert c[2] in made, c
        made.update(written_files(c))


@pytest.mark.slow
def test_the_readme_tour_runs_as_written(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    for argv in tour_commands():
        r = subprocess.run([sys.executable, "-m", "planner", *argv], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, (argv, r.stderr[-2000:])
        for f in written_files(argv):
            p = tmp_path / f
            assert p.exists(), (argv, f)
            assert p.is_dir() and any(p.iterdir()) or p.stat().st_size > 0, (argv, f)
