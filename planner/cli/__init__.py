"""``crane-planner`` command line (also ``python -m planner``).

Every sub-command has ``--help``; ``--json FILE`` (``-`` or no value: stdout) writes a
machine-readable result. Plain numbers are SI; angles may be written ``30deg``.

One thin module per command group registers its sub-parsers (``add_parsers``) and holds only
argument parsing, a call into the package and the printing: :mod:`~planner.cli.problems`
(problems, bound), :mod:`~planner.cli.plan`, :mod:`~planner.cli.library`,
:mod:`~planner.cli.simulate` (simulate, effects), :mod:`~planner.cli.discrepancy`,
:mod:`~planner.cli.calibrate` (the dynamic twin fitted to logs),
:mod:`~planner.cli.studies` (bench, demo); :mod:`~planner.cli.common` has what they share.
The package's messages name fields (`tip_speed`); :mod:`~planner.cli.wording` prints them as
the flags that set them (--tip-speed).

Building the parser imports nothing heavy: each command module imports the package parts it
calls (numpy, CasADi, scipy, matplotlib, h5py, Exudyn, Dask) inside its command, so
``crane-planner --help`` and a command's start-up pay only for what that command uses
(tests/test_startup.py holds the list of what ``--help`` must not load).
"""
from __future__ import annotations

import argparse
import re
import sys

from planner.cli import (calibrate, discrepancy, excite, library, plan, problems, resample,
                         simulate, studies)
from planner.cli.common import CLIError, VersionAction, check_distinct
from planner.cli.wording import cli_text

__all__ = ["CLIError", "build_parser", "join_negative_values", "main"]

# the order of the sub-commands in --help
COMMAND_GROUPS = (problems, plan, library, simulate, discrepancy, calibrate, resample, excite,
                  studies)


def build_parser() -> argparse.ArgumentParser:
    """The `crane-planner` parser: every command group's sub-commands, in COMMAND_GROUPS order."""
    ap = argparse.ArgumentParser(prog="crane-planner",
                                 description="Trajectory planning for hydraulic knuckle-boom "
                                             "cranes (SI units; angles may be written 30deg).")
    ap.add_argument("--version", action=VersionAction)
    sub = ap.add_subparsers(dest="command", required=True)
    for group in COMMAND_GROUPS:
        group.add_parsers(sub)
    return ap


# a value that starts with "-" and is a number (or a comma list starting with one): -50,1,0
# -0.5 -.5 -1e4,0,30deg -inf (argparse alone takes "-50,1,0" for an option and fails with
# "expected one argument")
NEGATIVE_VALUE = re.compile(r"-(\d|\.\d|inf\b|nan\b)", re.IGNORECASE)


def join_negative_values(argv: list[str]) -> list[str]:
    """``--opt -50,1,0`` -> ``--opt=-50,1,0`` for every long option followed by a value that
    starts with a minus sign and a digit (or ``.5``, ``inf``, ``nan``), so negative numbers and
    points need no ``=``. Tokens after ``--`` and options already written ``--opt=value`` are
    left alone; no option of this CLI is a negative number, so nothing else can match."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        tok = argv[i]
        if tok == "--":
            return out + argv[i:]
        nxt = argv[i + 1] if i + 1 < len(argv) else None
        if tok.startswith("--") and "=" not in tok and nxt is not None and \
                NEGATIVE_VALUE.match(nxt):
            out.append(f"{tok}={nxt}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser().parse_args(join_negative_values(argv))
    try:
        check_distinct(args)   # no output replaces an input or another output
        rc = args.func(args)
    except KeyboardInterrupt:   # Ctrl-C: one line, the shell's 128 + SIGINT; outputs are atomic
        print(f"crane-planner: interrupted (SIGINT) during {args.command}; nothing was written "
              "that was not complete", file=sys.stderr)
        return 130
    except (CLIError, ValueError, OSError) as e:
        # a bad machine spec (SpecError) and an unreachable point (UnreachableError) are
        # ValueErrors too: the model need not be imported to catch them
        print(f"crane-planner: error: {cli_text(e, args.command)}", file=sys.stderr)
        return 2
    except KeyError as e:
        print(f"crane-planner: error: {cli_text(e.args[0], args.command)}", file=sys.stderr)
        return 2
    return rc or 0


if __name__ == "__main__":
    raise SystemExit(main())
