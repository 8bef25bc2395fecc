"""The outputs of a command: checked before the work starts, written all together or not at all.

Units: none (paths only).

A command's outputs are its options with the destinations below (``--out``, ``--json``,
``--hal``, ...); an option whose metavar is ``DIR`` is a directory, and the names a command
declares with ``set_defaults(known_outputs=(...))`` are files it writes there (checked too).  Before the command runs,
:func:`hyperstat.solver.atomic.check_writable` refuses a location that cannot be written;
while it runs, every file it writes there is staged beside its target
(:func:`hyperstat.solver.atomic.all_or_nothing`), and moved in when it ends without an
error.  What the command prints goes to the terminal after its files are in place, so that
no ``wrote ...`` line announces a file that was not written.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
from pathlib import Path
from typing import Iterator

from hyperstat.solver.atomic import all_or_nothing, check_writable

__all__ = ["OUTPUT_OPTIONS", "declared_outputs", "command_outputs"]

#: destinations of the options that name an output (a file, or a directory when the metavar is DIR)
OUTPUT_OPTIONS = ("out", "validation_out", "truth", "residuals", "json", "markdown", "hal", "ini", "step", "model",
                  "png", "map_png", "plots")


def _subparser(parser: argparse.ArgumentParser, command: str | None) -> argparse.ArgumentParser | None:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            return action.choices[command]
    return None


def declared_outputs(parser: argparse.ArgumentParser, args: argparse.Namespace) -> tuple[list[Path], list[Path]]:
    """Output files and directories that ``args`` name, from the command's options."""
    sub = _subparser(parser, getattr(args, "command", None)) or parser
    files: list[Path] = []
    dirs: list[Path] = []
    for action in sub._actions:
        if action.dest not in OUTPUT_OPTIONS or not action.option_strings:
            continue
        value = getattr(args, action.dest, None)
        if not isinstance(value, str) or not value:
            continue
        if action.dest == "map_png" and not getattr(args, "map", None):
            continue  # the accuracy map is drawn only with --map
        if action.metavar == "DIR":
            dirs.append(Path(value))
            files += [Path(value) / name for name in getattr(args, "known_outputs", ())]
        else:
            files.append(Path(value))
    return files, dirs


@contextlib.contextmanager
def command_outputs(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Iterator[None]:
    """Check the outputs of ``args``, run the block with them staged, move them in at its end."""
    files, dirs = declared_outputs(parser, args)
    if not files and not dirs:
        yield
        return
    check_writable(files, dirs)
    terminal = sys.stdout
    held = io.StringIO()
    sys.stdout = held
    try:
        with all_or_nothing(files, dirs, only_declared=True):
            yield
    finally:
        sys.stdout = terminal
    terminal.write(held.getvalue())
