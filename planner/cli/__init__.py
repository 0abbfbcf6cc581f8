"""``crane-planner`` command line (also ``python -m planner``).

Every sub-command has ``--help``; ``--json FILE`` (``-`` or no value: stdout) writes a
machine-readable result. Plain numbers are SI; angles may be written ``30deg``.

One thin module per command group registers its sub-parsers (``add_parsers``) and holds only
argument parsing, a call into the package and the printing: :mod:`~planner.cli.problems`
(problems, bound), :mod:`~planner.cli.plan`, :mod:`~planner.cli.library`,
:mod:`~planner.cli.simulate` (simulate, effects), :mod:`~planner.cli.discrepancy`,
:mod:`~planner.cli.studies` (bench, demo); :mod:`~planner.cli.common` has what they share.
"""
from __future__ import annotations

import argparse
import sys

from planner.cli import (discrepancy, excite, library, plan, problems, resample, simulate,
                         studies)
from planner.cli.common import CLIError
from planner.model import UnreachableError
from planner.model.spec import SpecError

__all__ = ["CLIError", "build_parser", "main"]

# the order of the sub-commands in --help
COMMAND_GROUPS = (problems, plan, library, simulate, discrepancy, resample, excite, studies)


def build_parser() -> argparse.ArgumentParser:
    """The `crane-planner` parser: every command group's sub-commands, in COMMAND_GROUPS order."""
    ap = argparse.ArgumentParser(prog="crane-planner",
                                 description="Trajectory planning for hydraulic knuckle-boom "
                                             "cranes (SI units; angles may be written 30deg).")
    sub = ap.add_subparsers(dest="command", required=True)
    for group in COMMAND_GROUPS:
        group.add_parsers(sub)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        rc = args.func(args)
    except (SpecError, UnreachableError, CLIError, ValueError, OSError) as e:
        print(f"crane-planner: error: {e}", file=sys.stderr)
        return 2
    except KeyError as e:
        print(f"crane-planner: error: {e.args[0]}", file=sys.stderr)
        return 2
    return rc or 0


if __name__ == "__main__":
    raise SystemExit(main())
