"""What every command module of the CLI shares: the user-error type, ``--json`` handling,
argument types (tip points, method names) and reading a trajectory named on the command line."""
from __future__ import annotations

import argparse
import sys
from importlib.metadata import PackageNotFoundError, version

from planner.version import __version__
from planner.io import OutputError, check_output, missing_dirs, write_json
from planner.methods import available
from planner.trajectory import Trajectory
from planner.units import checked_trajectory, parse_point


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
    """argparse type of ``--method``: a name of the method registry."""
    names = available()
    if text in names:
        return text
    raise argparse.ArgumentTypeError(f"unknown method {text!r}; available: {', '.join(names)}")


def package_version() -> str:
    """The installed distribution's version (package metadata); the source tree's
    ``planner.__version__`` when the package is not installed."""
    try:
        return version("crane-planner")
    except PackageNotFoundError:
        return __version__


def output_arg(text: str) -> str:
    """argparse type of an output FILE (``--json``, ``--out``): checked before any work is done
    (:func:`planner.io.check_output`: not a directory, its folder writable); '-' is stdout."""
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
        created = [] if target == "-" else missing_dirs(target)
        write_json(target, obj)
        note_created(created)


def read_trajectory(crane, ref: str) -> Trajectory:
    """A trajectory named on the command line: FILE.csv, or FILE.h5#ID (an entry of a library
    database; the ID may be left out when the file holds one entry), checked against ``crane``
    (:func:`planner.units.checked_trajectory`: the library's crane id, the joints, the ranges)."""
    path, _, entry = ref.partition("#")
    if path.endswith(".h5"):
        from planner.library.store import LibraryStore  # h5py: only when a database is read
        with LibraryStore.open(path, "r") as db:
            ids = db.ids()
            if not entry:
                if len(ids) != 1:
                    raise CLIError(f"{path} holds {len(ids)} entries: name one as {path}#ID")
                entry = ids[0]
            return checked_trajectory(crane, db.trajectory(entry), f"{path}#{entry}",
                                      crane_id=db.crane_id)
    try:
        traj = Trajectory.from_csv(path)   # the file's own joints, checked against the machine's
        if sorted(traj.joint_names) == sorted(crane.names) != list(traj.joint_names):
            traj = Trajectory.from_csv(path, joint_names=crane.names)
        return checked_trajectory(crane, traj, path)
    except OSError as e:
        raise CLIError(f"cannot read trajectory {path}: {e.strerror}") from None
