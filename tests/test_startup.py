"""Start-up cost: ``import planner`` and ``crane-planner --help`` load none of the heavy
libraries, and a command loads only what it uses (issue 31).

The judge is the interpreter itself, in a fresh process: ``python -X importtime`` logs every
module it imports (one line each, on stderr), and the probes below print ``sys.modules``. Each
check is paired with a control that must see a heavy module where one is used, so a probe that
sees nothing cannot pass by accident.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: the libraries that cost start-up time (each 0.05 ... 1 s to import); none of them may load
#: for ``import planner`` or ``crane-planner --help`` (top-level package names)
HEAVY = ("numpy", "scipy", "casadi", "matplotlib", "mpl_toolkits", "exudyn", "dask",
         "distributed", "toppra", "ruckig", "h5py", "tqdm", "pandas", "rosbags", "PIL")


def _run(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env,
                          cwd=ROOT, timeout=300)


def imported(*args: str) -> set[str]:
    """The top-level names of every module ``python -X importtime ARGS`` imported (its log
    lines: ``import time: self | cumulative | name``); the process must succeed."""
    r = _run("-X", "importtime", *args)
    assert r.returncode == 0, r.stderr[-2000:]
    names = {line.rsplit("|", 1)[1].strip() for line in r.stderr.splitlines()
             if line.startswith("import time:") and line.count("|") == 2}
    assert "encodings" in names or "planner" in names   # the log was read
    return {n.split(".")[0] for n in names} | names


def probe(code: str) -> set[str]:
    """``sys.modules`` (full dotted names) after running ``code`` in a fresh interpreter."""
    r = _run("-c", code + "\nimport sys; print('\\n'.join(sorted(sys.modules)))")
    assert r.returncode == 0, r.stderr[-2000:]
    return set(r.stdout.split())


def test_the_import_log_sees_a_heavy_import():
    # the control of the checks below: the same reader sees numpy where it is imported
    assert "numpy" in imported("-c", "import numpy")


def test_import_planner_loads_nothing_heavy():
    got = imported("-c", "import planner")
    assert "planner" in got
    assert sorted(got & set(HEAVY)) == []


def test_the_public_names_still_load_on_use():
    # lazily loaded, the public API is the same objects as the modules' own
    mods = probe("import planner\nfrom planner import Crane, plan, Trajectory, SpecError\n"
                 "from planner.model import Crane as C\nassert Crane is C\n"
                 "assert sorted(planner.__all__) == sorted(n for n in planner.__all__ "
                 "if n in dir(planner))")
    assert {"casadi", "planner.model", "planner.methods", "planner.trajectory"} <= mods


def test_help_and_version_load_nothing_heavy():
    for args in (["--help"], ["--version"]):
        got = imported("-m", "planner", *args)
        assert "planner.cli" in got
        assert sorted(got & set(HEAVY)) == [], args


# every command's own --help (simulate's names the plants, which their module knows: it may load
# numpy and CasADi, nothing else heavy)
COMMAND_HELPS = [["problems", "list"], ["problems", "show"], ["problems", "urdf"], ["bound"],
                 ["plan"], ["library", "build"], ["library", "info"], ["library", "show"],
                 ["library", "query"], ["library", "export"], ["effects", "list"],
                 ["discrepancy"], ["resample"], ["excite"], ["bench"], ["demo"]]


def test_every_command_help_loads_nothing_heavy():
    code = ("import contextlib, io\nfrom planner.cli import main\n"
            f"for argv in {COMMAND_HELPS!r}:\n"
            "    with contextlib.redirect_stdout(io.StringIO()) as out:\n"
            "        try:\n            main(argv + ['--help'])\n"
            "        except SystemExit as e:\n            assert e.code == 0, argv\n"
            "    assert 'usage: crane-planner ' + argv[0] in out.getvalue(), argv")
    mods = probe(code)
    assert "planner.cli.plan" in mods
    assert sorted({m.split(".")[0] for m in mods} & set(HEAVY)) == []
    mods = probe(code.replace(repr(COMMAND_HELPS), "[['simulate']]"))
    assert sorted({m.split(".")[0] for m in mods} & set(HEAVY)) == ["casadi", "numpy"]


def test_simulate_help_names_every_registered_plant():
    # --plant's choices are read when used: the help shows the plant module's own list
    from planner.simulation.plants import PLANTS
    r = _run("-m", "planner", "simulate", "--help")
    assert r.returncode == 0
    assert "--plant {" + ",".join(sorted(PLANTS)) + "}" in r.stdout


def test_naming_one_method_loads_only_its_module():
    # an NLP plan needs CasADi and Ruckig (its first guess), never toppra (which imports
    # matplotlib); a law's name finds it in its family's modules; an unknown name (in a known
    # family) loads every method, toppra included, to list them all
    r = _run("-c", "import sys\nfrom planner.methods import get\n"
                   "assert get('nlp').name == 'nlp'\n"
                   "assert get('law:p_optimal').name == 'law:p_optimal'\n"
                   "print(' '.join(sorted(sys.modules)))\n"
                   "try:\n    get('law:nope')\nexcept KeyError as e:\n    print(e.args[0])\n"
                   "print('toppra' in sys.modules)")
    assert r.returncode == 0, r.stderr[-2000:]
    mods, unknown, toppra = r.stdout.splitlines()
    mods = set(mods.split())
    assert {"casadi", "ruckig", "planner.methods.nlp", "planner.methods.laws_energy"} <= mods
    assert sorted(m for m in mods if m.split(".")[0] in ("toppra", "matplotlib", "h5py")
                  or m == "planner.methods.topp") == []
    assert unknown.startswith("unknown method 'law:nope'")
    assert all(m in unknown for m in ("dp", "nlp", "topp", "ruckig", "law:jla",
                                      "law:least_norm"))
    assert toppra == "True"


PLUGIN = '''from planner.methods import Planner, register
from planner.methods.ruckig import RuckigPlanner


class Mine(RuckigPlanner):
    name = "test:plugged"


class Impostor(RuckigPlanner):
    name = "nlp"


register(Mine())
register(Impostor())
'''


def test_a_plugin_is_found_by_name_and_cannot_take_a_builtin_name(tmp_path):
    """An installed plug-in (a distribution with a ``crane_planner.methods`` entry point, made
    here on sys.path) is found by its own name and listed; one that registers a built-in's name
    is ignored with a warning, whether the built-in was looked up before or after. (A name
    outside the built-ins loads the plug-ins: test_naming_one_method_loads_only_its_module.)"""
    (tmp_path / "plug_mod.py").write_text(PLUGIN, encoding="utf-8")
    info = tmp_path / "crane_plug-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: crane-plug\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[crane_planner.methods]\nplug = plug_mod\n")
    head = f"import sys, warnings\nsys.path.insert(0, {str(tmp_path)!r})\n" \
           "from planner.methods import available, get\n"
    # a built-in name first (its module alone), then the whole list (the plug-in too)
    r = _run("-c", head + "print(type(get('nlp')).__module__)\n"
                          "with warnings.catch_warnings(record=True) as w:\n"
                          "    warnings.simplefilter('always')\n"
                          "    names = available()\n"
                          "print('test:plugged' in names, type(get('nlp')).__module__, "
                          "type(get('test:plugged')).__name__)\n"
                          "print(' | '.join(str(x.message) for x in w))")
    assert r.returncode == 0, r.stderr[-2000:]
    first, listed, warned = r.stdout.splitlines()
    assert first == "planner.methods.nlp"
    assert listed == "True planner.methods.nlp Mine"
    assert "'nlp'" in warned and "plug-in ignored" in warned
