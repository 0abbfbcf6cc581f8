"""Issue 32 defects 2 and 14: no command's output replaces one of its inputs or another of its
outputs (it used to, with exit 0: ``simulate --trajectory m.csv --out m.csv`` replaced the
plan), and a '#' in a file name (``run#1.h5``) is a file name, not FILE#ID."""
import argparse
import os
import shutil
from pathlib import Path

import pytest

from planner.cli import build_parser, main
from planner.cli.common import INPUT_DESTS, OUTPUT_DESTS, output_arg, split_ref

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "planner" / "problems" / "cranes" / "s100f.toml"
SUITE = ROOT / "planner" / "problems" / "tasks" / "forwarder-cycle.toml"
S, G = "3,1,0", "5,2,30deg"

# every sub-command with an output, each with a collision (the argv, the file the refusal names;
# the inputs are made in tmp_path; "spec.toml", "suite.toml" are copies of shipped files)
CASES = {
    "simulate (output = input)": (["simulate", "s100f", "--trajectory", "m.csv", "--out",
                                   "m.csv"], "m.csv"),
    "simulate (output = output)": (["simulate", "s100f", "--trajectory", "m.csv", "--out",
                                    "o.csv", "--json", "o.csv"], "o.csv"),
    "simulate (h5#ID input)": (["simulate", "s100f", "--trajectory", "lib.h5#plan:time",
                                "--out", "lib.h5"], "lib.h5"),
    "plan (output = output)": (["plan", "s100f", "--start", S, "--goal", G, "--out", "x.csv",
                                "--json", "x.csv"], "x.csv"),
    "plan (spec = plot)": (["plan", "spec.toml", "--start", S, "--goal", G, "--plot",
                            "spec.toml"], "spec.toml"),
    "library query (json = library)": (["library", "query", "lib.h5", "--start", S, "--goal", G,
                                        "--json", "lib.h5"], "lib.h5"),
    "library query (out = json)": (["library", "query", "lib.h5", "--start", S, "--goal", G,
                                    "--out", "q.csv", "--json", "q.csv"], "q.csv"),
    "library info": (["library", "info", "lib.h5", "--json", "lib.h5"], "lib.h5"),
    "library build (json = tasks)": (["library", "build", "s100f", "--tasks", "suite.toml",
                                      "--out", "new.h5", "--json", "suite.toml"], "suite.toml"),
    "library build (json = out)": (["library", "build", "s100f", "--tasks", "forwarder-cycle",
                                    "--out", "lib.h5", "--json", "lib.h5"], "lib.h5"),
    "library export": (["library", "export", "lib.h5", "--format", "json", "--out", "exp",
                        "--json", "lib.h5"], "lib.h5"),
    "discrepancy (json = measured)": (["discrepancy", "s100f", "--measured", "m.csv", "--json",
                                       "m.csv"], "m.csv"),
    "discrepancy (model = trajectory)": (["discrepancy", "s100f", "--measured", "m.csv",
                                          "--trajectory", "t.csv", "--save-model", "t.csv"],
                                         "t.csv"),
    "discrepancy (report = crane spec)": (["discrepancy", "spec.toml", "--measured", "m.csv",
                                           "--report", "spec.toml"], "spec.toml"),
    "resample": (["resample", "m.csv", "--rate", "50", "--out", "m.csv"], "m.csv"),
    "calibrate (out = second log)": (["calibrate", "s100f", "--measured", "t.csv",
                                      "--measured", "m.csv", "--out", "m.csv"], "m.csv"),
    "excite": (["excite", "s100f", "--from", "r.json", "--out", "e.csv", "--json", "r.json"],
               "r.json"),
    "problems urdf": (["problems", "urdf", "spec.toml", "--out", "spec.toml"], "spec.toml"),
    "problems show": (["problems", "show", "spec.toml", "--plot", "spec.toml"], "spec.toml"),
    "bound": (["bound", "spec.toml", "--start", S, "--goal", G, "--json", "spec.toml"],
              "spec.toml"),
    "library show": (["library", "show", "lib.h5", "--json", "lib.h5"], "lib.h5"),
    "library refine": (["library", "refine", "lib.h5", "--json", "spec.toml", "--model",
                        "spec.toml"], "spec.toml"),
}
# sub-commands whose outputs cannot collide with anything: no file input, one output (or
# output folders)
NO_COLLISION = {"problems list", "effects list", "bench", "demo"}


@pytest.fixture
def files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "m.csv").write_text("t,q_slew\n0,0\n")
    (tmp_path / "t.csv").write_text("t,q_slew\n0,0\n")
    (tmp_path / "r.json").write_text("{}\n")
    (tmp_path / "lib.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(100))
    shutil.copy(SPEC, tmp_path / "spec.toml")
    shutil.copy(SUITE, tmp_path / "suite.toml")
    return tmp_path


@pytest.mark.parametrize("case", sorted(CASES))
def test_an_output_never_replaces_an_input_or_another_output(files, capsys, case):
    argv, keep = CASES[case]
    before = {p.name: p.read_bytes() for p in files.iterdir() if p.is_file()}
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("crane-planner: error: "), err
    assert "the same file as" in err[0] and "choose another file name" in err[0], err
    after = {p.name: p.read_bytes() for p in files.iterdir() if p.is_file()}
    assert after == before                           # nothing written, nothing replaced
    assert f" {keep}: the same file as " in err[0]


def test_links_to_an_input_are_the_input(files, capsys):
    os.symlink("m.csv", files / "soft.csv")
    os.link(files / "m.csv", files / "hard.csv")
    for out in ("soft.csv", "hard.csv", "./sub/../m.csv"):
        assert main(["simulate", "s100f", "--trajectory", "m.csv", "--out", out]) == 2
        assert f"--out {out}: the same file as --trajectory m.csv" in capsys.readouterr().err
    assert (files / "m.csv").read_text() == "t,q_slew\n0,0\n"


def _leaves(parser, prefix=()):
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                yield from _leaves(sub, prefix + (name,))
            return
    yield " ".join(prefix), parser


def test_every_sub_command_with_an_output_is_covered():
    """The table of file arguments knows every output and input of every sub-command, and the
    cases above cover every sub-command that writes a file."""
    covered = {" ".join(w for w in argv[:2] if not w.startswith("-") and w not in
                        ("s100f", "spec.toml", "lib.h5", "m.csv")) for argv, _ in CASES.values()}
    for name, p in _leaves(build_parser()):
        dests = {a.dest: a for a in p._actions if a.option_strings or a.dest != "help"}
        outs = [d for d, a in dests.items() if a.type is output_arg or d in OUTPUT_DESTS]
        for d, a in dests.items():
            meta = str(a.metavar or "")
            if a.type is output_arg or any(k in meta for k in ("FILE", ".csv", ".h5", ".json",
                                                                ".toml", "DIR")):
                assert d in INPUT_DESTS or d in OUTPUT_DESTS, (name, d)
        if outs:
            assert name in covered or name in NO_COLLISION, name


def test_a_hash_in_a_file_name(tmp_path, monkeypatch, capsys):
    """Defect 14: `plan --out 'run#1.h5'` wrote it, `simulate --trajectory 'run#1.h5'` looked
    for a file 'run'."""
    monkeypatch.chdir(tmp_path)
    assert main(["plan", "s100f", "--start", S, "--goal", G, "--method", "ruckig", "--out",
                 "run#1.h5"]) == 0
    assert main(["simulate", "s100f", "--trajectory", "run#1.h5", "--out", "a.csv"]) == 0
    assert main(["simulate", "s100f", "--trajectory", "run#1.h5#plan:time", "--out",
                 "b.csv"]) == 0
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert main(["simulate", "s100f", "--trajectory", "run#1.h5#nope", "--out", "c.csv"]) == 2
    assert "run#1.h5: no entry 'nope'" in capsys.readouterr().err
    assert split_ref("none#x") == ("none", "x") and split_ref("run#1.h5") == ("run#1.h5", "")
