"""What every command module of the CLI shares: the user-error type, ``--json`` handling,
argument types (tip points, method names) and reading a trajectory named on the command line.

Building the parser needs none of the package's numerical parts: planner.io (numpy), the method
registry's methods and the trajectory type are imported where an argument is checked or a
command runs."""
from __future__ import annotations

from typing import TYPE_CHECKING

import argparse
import os
import sys

from planner.version import __version__
from planner.units import checked_trajectory, parse_point

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.trajectory import Trajectory


class CLIError(Exception):
    """A user error: printed as one line, exit status 2."""


def point_arg(text: str) -> tuple[float, float, float]:
    """argparse type of ``--start`` / ``--goal``: :func:`planner.units.parse_point`, its errors
    as usage errors."""
    try:
        return parse_point(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def method_arg(text: str) -> str:
    """argparse type of ``--method``: a name of the method registry (looking it up imports
    that method's module; every method's only when the name is unknown, to list them)."""
    from planner.methods import available, get
    try:
        get(text)
        return text
    except KeyError:
        names = available()
    raise argparse.ArgumentTypeError(f"unknown method {text!r}; available: {', '.join(names)}")


class LazyChoices:
    """argparse ``choices`` that the package supplies (``load()`` -> the allowed names), read
    when first needed: when a value is checked or the command's own help is printed, not when
    the parser is built (so ``crane-planner --help`` imports none of the module that knows
    them)."""

    def __init__(self, load):
        self.load = load
        self.names = None

    def resolved(self) -> list:
        if self.names is None:
            self.names = list(self.load())
        return self.names

    def __contains__(self, value) -> bool:
        return value in self.resolved()

    def __iter__(self):
        return iter(self.resolved())

    def __len__(self) -> int:
        return len(self.resolved())


def package_version() -> str:
    """The installed distribution's version (package metadata); the source tree's
    ``planner.__version__`` when the package is not installed."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("crane-planner")
    except PackageNotFoundError:
        return __version__


class VersionAction(argparse.Action):
    """``--version``: print ``crane-planner VERSION`` (:func:`package_version`, read from the
    package metadata when asked, not when the parser is built) and exit 0."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="show program's version number and exit"):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0,
                         help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        sys.stdout.write(f"crane-planner {package_version()}\n")
        parser.exit()


def output_arg(text: str) -> str:
    """argparse type of an output FILE (``--json``, ``--out``): checked before any work is done
    (:func:`planner.io.check_output`: not a directory, its folder writable); '-' is stdout."""
    from planner.io import OutputError, check_output
    try:
        check_output(text)
    except OutputError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


def note_created(dirs) -> None:
    """Say on stderr which output folders a command created (they are never created silently)."""
    for d in dirs:
        print(f"crane-planner: note: created directory {d}", file=sys.stderr)


def add_json_arg(p: argparse.ArgumentParser) -> None:
    """``--json [FILE]`` on a sub-command (the path is checked when the arguments are read)."""
    p.add_argument("--json", nargs="?", const="-", metavar="FILE", type=output_arg,
                   help="write a JSON result to FILE ('-' or no value: stdout)")


def emit(args, obj) -> None:
    """Write ``obj`` as the command's JSON result when ``--json`` was given (and say which
    folders that created)."""
    target = getattr(args, "json", None)
    if target:
        from planner.io import missing_dirs, write_json
        created = [] if target == "-" else missing_dirs(target)
        write_json(target, obj)
        note_created(created)


def split_ref(ref: str) -> tuple[str, str]:
    """``FILE#ID`` -> (FILE, ID). A file name may itself contain '#': the whole string is a
    file when such a file exists (``run#1.h5``); else the first split at a '#' whose left part
    is an existing file (``run#1.h5#plan:time``); else at the first '#'."""
    if "#" not in ref or os.path.isfile(ref):
        return ref, ""
    cuts = [i for i, c in enumerate(ref) if c == "#"]
    for i in cuts:
        if os.path.isfile(ref[:i]):
            return ref[:i], ref[i + 1:]
    return ref[:cuts[0]], ref[cuts[0] + 1:]


# the arguments that name files, by their argparse dest: read by a command, or written by it
# (how the one-line refusal names them); every command is checked by :func:`check_distinct`
INPUT_DESTS = dict(crane="CRANE", trajectory="--trajectory", measured="MEASURED.csv",
                   library="LIB.h5", tasks="--tasks", from_result="--from", results="--results",
                   entry="LIB.h5#ID", map="--map", model="--model")
OUTPUT_DESTS = dict(out="--out", json="--json", plot="--plot", save_model="--save-model",
                    report="--report", animate="--animate")


def _identity(path: str) -> set:
    """What makes two paths the same file: the resolved path, and the device and inode of an
    existing file (hard links)."""
    keys = {("path", os.path.realpath(path))}
    try:
        st = os.stat(path)
        keys.add(("inode", st.st_dev, st.st_ino))
    except OSError:
        pass   # not there yet: its resolved path is what it will be
    return keys


def check_distinct(args) -> None:
    """Refuse, before any work, an output path that is one of the command's inputs or another
    of its outputs (by resolved path: ``simulate --trajectory m.csv --out m.csv`` would replace
    the plan, ``--out x.csv --json x.csv`` leave JSON in the trajectory file). Inputs count when
    they are existing files (a machine id is not); outputs written in place (stdout, devices)
    do not count. Called by :func:`planner.cli.main` for every command."""
    from planner.io import OutputError, output_target
    files = []
    for dest, label in INPUT_DESTS.items():
        vals = getattr(args, dest, None)
        for v in (vals if isinstance(vals, list) else [vals]):   # a repeated option: a list
            path = (split_ref(v)[0] if dest in ("trajectory", "entry") and isinstance(v, str)
                    else v)
            if isinstance(path, str) and path and os.path.isfile(path):
                files.append((label, v, path))
    for dest, label in OUTPUT_DESTS.items():
        v = getattr(args, dest, None)
        if not isinstance(v, str) or not v or v == "-":
            continue
        try:
            if output_target(v)[1]:
                continue   # a stream or device: appended to, never replaced
        except OutputError:
            pass   # a folder: its own check refuses it where a file is expected
        files.append((label, v, v))
    seen: list = []
    for label, v, path in files:
        keys = _identity(path)
        for first, fv, other in seen:
            if keys & other:
                raise CLIError(f"{label} {v}: the same file as {first} {fv}; an output may "
                               "not replace an input or another output of the same command: "
                               "choose another file name")
        seen.append((label, v, keys))


def entry_of(db, path: str, entry: str) -> str:
    """The entry a ``FILE.h5#ID`` names in the open library ``db``: ``entry``, or the only one
    when it is left out; one-line CLIError when it is ambiguous or unknown (with the first
    few ids)."""
    ids = db.ids()
    if not entry:
        if len(ids) != 1:
            raise CLIError(f"{path} holds {len(ids)} entries: name one as {path}#ID")
        return ids[0]
    if entry not in ids:
        near = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
        raise CLIError(f"{path}: no entry {entry!r}; its entries: {near or 'none'}")
    return entry


def read_trajectory(crane: Crane, ref: str) -> Trajectory:
    """A trajectory named on the command line: FILE.csv, or FILE.h5#ID (an entry of a library
    database; the ID may be left out when the file holds one entry; :func:`split_ref` for a
    '#' in the file name), checked against ``crane`` (:func:`planner.units.checked_trajectory`:
    the library's crane id, the joints, the ranges)."""
    from planner.trajectory import Trajectory
    path, entry = split_ref(ref)
    if path.endswith(".h5"):
        from planner.library.store import LibraryStore  # h5py: only when a database is read
        with LibraryStore.open(path, "r") as db:
            entry = entry or entry_of(db, path, entry)
            return checked_trajectory(crane, db.trajectory(entry), f"{path}#{entry}",
                                      crane_id=db.crane_id)
    try:
        traj = Trajectory.from_csv(path)   # the file's own joints, checked against the machine's
        if sorted(traj.joint_names) == sorted(crane.names) != list(traj.joint_names):
            traj = Trajectory.from_csv(path, joint_names=crane.names)
        return checked_trajectory(crane, traj, path)
    except OSError as e:
        raise CLIError(f"cannot read trajectory {path}: {e.strerror}") from None


def replay_commands(crane: Crane, ref: str, traj: Trajectory, which: str = "auto"):
    """(trajectory to replay, which commands) for ``ref`` read as ``traj``: a library entry's
    refined commands (``library refine``) when present and ``which`` is "auto", or as asked
    ("nominal" | "refined"); the trajectory's own otherwise ("nominal"). One-line CLIError
    when refined commands are asked of a CSV or of an entry without them."""
    from planner.library.refined import COMMAND_CHOICES
    if which not in COMMAND_CHOICES:
        raise CLIError(f"--commands {which}: allowed {', '.join(COMMAND_CHOICES)}")
    path, entry = split_ref(ref)
    if not path.endswith(".h5"):
        if which == "refined":
            raise CLIError(f"--commands refined: {path} is a trajectory file; refined commands "
                           "live in a library entry (FILE.h5#ID after `library refine`)")
        return traj, "nominal"
    from planner.feedforward import on_command_grid
    from planner.library.refined import entry_commands
    from planner.library.store import LibraryStore, StoreError
    with LibraryStore.open(path, "r") as db:
        entry = entry or entry_of(db, path, entry)
        try:
            t_u, u, used, _ = entry_commands(db, entry, traj, which)
        except StoreError as e:
            raise CLIError(str(e)) from None
    if used == "refined":
        return on_command_grid(traj, t_u, u), used
    return traj, used


def add_animate_args(p, shows: str) -> None:
    """``--animate FILE`` and ``--fps`` of a command that draws a move; ``shows``: what the
    drawing shows besides the crane and the tip path (the walls, the suite's obstacles)."""
    p.add_argument("--animate", metavar="FILE.gif|.mp4|.html", type=output_arg,
                   help="animate the move: the crane in a side and a top view, the tip path, "
                        f"{shows} (.mp4 needs ffmpeg; .html is self-contained)")
    p.add_argument("--fps", type=float, default=20.0,
                   help="--animate frames per second of the move (20; at most 30, and at most "
                        "600 frames: longer moves play faster)")
