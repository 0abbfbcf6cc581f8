"""Issue 32, faults-b's classes (defects 5-8, 11, 13, 15): each bad input or fault run as a
user would, through the CLI in a fresh process; measured, not asserted (the tests in
tests/cli/test_faults_b.py assert). Each row: exit code, seconds, the last stderr line.

Run: ``python benchmarks/bench_faults.py --issue32b`` -> the "Issue 32 (faults-b)" section of
benchmarks/results/faults.md and the ``issue32_b`` key of faults.json.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "planner"]
ENV = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")


def cli(argv, cwd, timeout=600) -> dict:
    t0 = time.monotonic()
    r = subprocess.run(CLI + [str(a) for a in argv], cwd=cwd, env=ENV, capture_output=True,
                       text=True, timeout=timeout)
    lines = [ln for ln in r.stderr.strip().splitlines() if not ln.startswith(("usage:", " "))
             and "fit/s" not in ln]
    return dict(rc=r.returncode, s=round(time.monotonic() - t0, 2),
                line=lines[-1] if lines else r.stdout.strip().splitlines()[-1],
                traceback="Traceback" in r.stderr, stdout=r.stdout)


def children(pid) -> list[int]:
    out = []
    for d in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{d}/stat") as fh:
                st = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(st[1]) == pid and st[0] not in "ZX":
            out.append(int(d))
    return out


def default_sigint():
    """In the child before exec: SIGINT back to its default (a job started in the background
    of a non-interactive shell inherits SIGINT ignored, and Python then keeps ignoring it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def interrupted(argv, cwd, ready, after=0.3) -> dict:
    """SIGINT to the process group once ``ready(pid)`` holds; exit code, seconds to exit, the
    most processes it had, the stderr lines and stdout."""
    p = subprocess.Popen(CLI + [str(a) for a in argv], cwd=cwd, env=ENV, text=True,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         start_new_session=True, preexec_fn=default_sigint)
    most, t0 = 0, time.monotonic()
    while p.poll() is None and not ready(p.pid) and time.monotonic() - t0 < 300:
        most = max(most, len(children(p.pid)))
        time.sleep(0.02)
    time.sleep(after)
    most = max(most, len(children(p.pid)))
    kids = children(p.pid)
    t1 = time.monotonic()
    os.killpg(p.pid, signal.SIGINT)
    out, err = p.communicate(timeout=300)
    return dict(rc=p.returncode, exit_s=round(time.monotonic() - t1, 2), processes=most,
                left=sum(os.path.exists(f"/proc/{k}") for k in kids),
                lines=err.strip().splitlines(), stdout=out.strip())


def run() -> dict:
    from planner import Crane
    from planner.feedforward import commands
    from planner.library.store import LibraryStore
    from planner.methods.ruckig import rest_to_rest
    from planner.problems import crane_path
    from planner.simulation.dynamic.simulate import slowed
    from dataclasses import replace
    w = Path(tempfile.mkdtemp(prefix="faults-b-"))
    s100f = Crane.from_id("s100f")
    tr = rest_to_rest(s100f, s100f.ik((6.0, -1.0, 0.0), tele=2.2),
                      s100f.ik((5.0, 0.5, 0.3), tele=2.2)).trajectory
    tr.to_csv(w / "s100f-move.csv")
    with LibraryStore.create(w / "s100f.h5", s100f.spec) as db:
        db.add("m0", tr, start=(6, -1, 0), goal=(5, 0.5, 0.3), objective="time",
               method="ruckig", status="ok")
    slowed(tr, 8.0).to_csv(w / "slow.csv")
    ff = commands(s100f, tr, 50.0)
    q, qd, qdd, _ = tr.sample(ff.t)
    replace(tr, t=ff.t, q=q, qd=qd, qdd=qdd, u=ff.u).to_csv(w / "exc.csv")
    res = {}
    res["5 csv"] = cli(["simulate", "umea-lab", "--trajectory", "s100f-move.csv",
                        "--out", "m.csv"], w)
    res["5 h5"] = cli(["simulate", "umea-lab", "--trajectory", "s100f.h5#m0", "--out", "m.csv"],
                      w)
    # the Exudyn run: Ctrl-C 8 s after the start (imports and set-up take a few; the solve of
    # the 16 s move far longer)
    t_start = time.monotonic()
    res["6"] = interrupted(["simulate", "s100f", "--trajectory", "slow.csv", "--plant",
                            "exudyn", "--out", "dyn.csv"], w,
                           lambda pid: time.monotonic() - t_start > 8.0, after=0.0)
    res["6"]["out_written"] = (w / "dyn.csv").exists()
    r = cli(["simulate", "s100f", "--trajectory", "exc.csv", "--out", "m100.csv", "--rate",
             "100"], w)
    with open(w / "m100.csv") as fh:
        fh.readline()
        t = [float(fh.readline().split(",")[0]) for _ in range(3)]
    r["step_s"] = round(t[1] - t[0], 6)
    res["7"] = r
    res["8"] = cli(["library", "build", "cranab850", "--tasks", "forwarder-cycle", "--out",
                    "c.h5"], w)
    res["11"] = interrupted(["library", "build", "s100f", "--tasks", "forwarder-cycle",
                             "--workers", "1000", "--limit", "2", "--out", "w.h5"], w,
                            lambda pid: len(children(pid)) >= 2)
    # 13: epoch stamps on a recording of the move
    cli(["simulate", "s100f", "--trajectory", "slow.csv", "--out", "meas.csv", "--noise"], w)
    lines = (w / "meas.csv").read_text().splitlines()
    body = [f"{1764130000 + float(ln.split(',', 1)[0]):.2f}," + ln.split(",", 1)[1]
            for ln in lines[1:]]
    (w / "epoch.csv").write_text("\n".join([lines[0]] + body) + "\n")
    r = cli(["discrepancy", "s100f", "--measured", "epoch.csv", "--trajectory", "slow.csv",
             "--json", "r.json"], w)
    r["line"] = next((ln for ln in r.pop("stdout").splitlines() if ln.startswith("verdict")),
                     r["line"])
    res["13"] = r
    raw = crane_path("umea-lab").read_bytes()
    (w / "bom.toml").write_bytes(b"\xef\xbb\xbf" + raw)
    (w / "latin1.toml").write_bytes(raw.replace(b"assumed", b"assum\xe9d", 1))
    (w / "empty.toml").write_text('[suite]\nid = "empty-grid"\ncrane = "s100f"\n[pickups]\n'
                                  'r = []\nslew = ["0deg"]\nz = -1.0\n[drops]\nr = [3.0]\n'
                                  'slew = ["60deg"]\nz = 1.5\n')
    r = cli(["problems", "show", "bom.toml"], w)
    r["line"] = r["stdout"].splitlines()[0]
    res["15 bom"] = r
    res["15 latin-1"] = cli(["problems", "show", "latin1.toml"], w)
    res["15 720deg"] = cli(["bound", "s100f", "--start", "6,-1,0", "--goal", "4,0,720deg"], w)
    res["15 empty grid"] = cli(["library", "build", "s100f", "--tasks", "empty.toml",
                                "--out", "e.h5"], w)
    for v in res.values():
        if "exit_s" not in v:          # a command's stdout: only its last line was kept
            v.pop("stdout", None)
    return res


CASES = {
    "5 csv": "`simulate umea-lab --trajectory s100f-move.csv` (telescope 2.2 m; umea-lab's "
             "ends at 1.55 m)",
    "5 h5": "`simulate umea-lab --trajectory s100f.h5#m0` (crane_id s100f)",
    "6": "Ctrl-C 8 s into `simulate s100f --plant exudyn` (a 16 s move)",
    "7": "`simulate s100f --trajectory exc.csv --rate 100` (commands u_* at 50 Hz)",
    "8": "`library build cranab850 --tasks forwarder-cycle` (declared for s100f)",
    "11": "`library build … --workers 1000 --limit 2`, Ctrl-C while the workers start",
    "13": "`discrepancy s100f --measured epoch.csv` (t = 1764130000.00, .02, …)",
    "15 bom": "`problems show bom.toml` (UTF-8 with a byte-order mark)",
    "15 latin-1": "`problems show latin1.toml` (one Latin-1 byte in a comment)",
    "15 720deg": "`bound s100f … --goal 4,0,720deg`",
    "15 empty grid": "`library build s100f --tasks empty.toml` (pickups.r = [])",
}


def markdown(res) -> str:
    import datetime
    import platform
    L = [MARK, "", "## Issue 32 (faults-b): silently wrong results and misleading messages", "",
         f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.platform()}, "
         f"{os.cpu_count()} CPUs (shared, load {os.getloadavg()[0]:.1f}). Measured by "
         "`python benchmarks/bench_faults.py "
         "--issue32b`, each case a fresh process; `before`: what issue 32 reported.", "",
         "| case | before | exit | s | what it says |", "| --- | --- | ---: | ---: | --- |"]
    before = {"5 csv": "exit 0, replayed", "5 h5": "exit 0, replayed",
              "6": "exit 3 `diverged` on stdout (here: exit 0, ran to the end)",
              "7": "exit 0, --rate ignored", "8": "exit 0, built", "11": "~300 processes, "
              "Ctrl-C ignored 30 s", "13": "exit 2 \"not uniform\"",
              "15 bom": "exit 2, no BOM named", "15 latin-1": "exit 2, no file name",
              "15 720deg": "hint: write 12.5664deg", "15 empty grid": "exit 0, empty library"}
    for k, what in CASES.items():
        r = res[k]
        if "exit_s" in r:
            extra = (f"{r['processes']} process(es) at most, {r['left']} left; "
                     if k == "11" else "")
            line = extra + " / ".join(r["lines"]) + (f"; stdout: {r['stdout']!r}"
                                                      if r["stdout"] else "")
            L.append(f"| {what} | {before[k]} | {r['rc']} | {r['exit_s']} | {line} |")
        else:
            extra = f"step {r['step_s']} s; " if "step_s" in r else ""
            L.append(f"| {what} | {before[k]} | {r['rc']} | {r['s']} | {extra}"
                     f"{r['line'].replace('|', '/')} |")
    L += ["", "`s`: wall seconds of the command (6, 11: from SIGINT to exit).", "", MARK_END, ""]
    return "\n".join(L)


MARK, MARK_END = "<!-- faults-b -->", "<!-- /faults-b -->"


def write(res, results: Path) -> str:
    """faults.json's ``issue32_b`` key and faults.md's faults-b section (between its markers;
    the rest of both files is kept)."""
    import json
    import re
    js, md = results / "faults.json", results / "faults.md"
    data = json.loads(js.read_text()) if js.exists() else {}
    data["issue32_b"] = res
    js.write_text(json.dumps(data, indent=2) + "\n")
    section = markdown(res)
    text = md.read_text() if md.exists() else ""
    pat = re.compile(re.escape(MARK) + ".*?" + re.escape(MARK_END) + "\n?", re.S)
    text = pat.sub(lambda m: section, text) if pat.search(text) else \
        text.rstrip("\n") + "\n\n" + section
    md.write_text(text)
    return section
