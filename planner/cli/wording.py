"""Command-line wording of the package's messages: fields become flags.

The layers below the CLI speak Python: an error or a reason names the *field* it is about in
backticks, as the caller wrote it (``PlanRequest(tip_speed=-1)`` is refused with "`tip_speed`
= -1 m/s: allowed a finite number > 0"). The command line has flags instead, so before the CLI
prints such a text it passes it through :func:`cli_text`, which writes each named field as the
flag that sets it ("--tip-speed -1 m/s: allowed a finite number > 0"); a ``name = value``
becomes ``--flag value``. The mapping is :data:`FLAGS` (every command) and
:data:`COMMAND_FLAGS` (one command's own names, first); a field without a flag is left as
written. tests/cli/test_wording.py checks that every flag named here exists on its command
and that no module outside ``planner/cli/`` writes a flag into a message.
"""
from __future__ import annotations

import re

__all__ = ["FLAGS", "COMMAND_FLAGS", "cli_text"]

# field (as the Python API names it) -> the flag that sets it, on every command that has it
FLAGS = {
    "tip_speed": "--tip-speed",
    "duration": "--duration",
    "objective": "--objective",
    "path": "--path",
    "method": "--method",
    "intervals": "--intervals",
    "rate": "--rate",
    "step": "--step",
    "tele_step": "--tele-step",
    "window": "--window",
    "tele0": "--tele0",
    "grapple": "--grapple",
    "grapple_zeta": "--grapple-zeta",
    "scheduler": "--scheduler",
    "out": "--out",
    "units_row": "--units-row",
    "plant": "--plant",
    "joint": "--joint",
    "map": "--map",
}

# a command's own names for a field (checked before FLAGS)
COMMAND_FLAGS = {
    "excite": {"text": "--separate"},                    # parse_candidates(crane, text, joint)
    "discrepancy": {"plan": "--trajectory"},             # Recording.from_csv(path, crane, plan)
}

_FIELD = re.compile(r"`([A-Za-z_]\w*)`( = )?")


def flag_of(field: str, command: str | None = None) -> str | None:
    """The flag that sets ``field`` on ``command`` (None: no flag)."""
    return COMMAND_FLAGS.get(command or "", {}).get(field) or FLAGS.get(field)


def cli_text(text: str, command: str | None = None) -> str:
    """``text`` (a message of the package) in the command line's words: every backticked field
    that has a flag on ``command`` written as that flag (```x` = v`` -> ``--x v``)."""
    def flag(m: re.Match) -> str:
        f = flag_of(m.group(1), command)
        if f is None:
            return m.group(0)
        return f + (" " if m.group(2) else "")
    return _FIELD.sub(flag, str(text))
