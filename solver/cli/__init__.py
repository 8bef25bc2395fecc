"""The ``hyperstat`` command line, solver side: one module per pipeline stage.

Units: lengths in mm, angles in rad.

The solver knows model files (``*.json``).  The CAD side (:mod:`hyperstat.cad_plugin.cli`)
registers more source kinds (templates ``*.py``, STEP files) and commands (``build``,
``view``, ``report``, ...) and is what the ``hyperstat`` console script runs, so that the
solver never imports CAD code.  Every user error is one sentence on stderr and exit code
2; outputs are written atomically.
"""

from __future__ import annotations

import argparse
import sys

from hyperstat.solver.cli import analysis, calibration, diagnosis, export, tolerances
from hyperstat.solver.cli.common import (
    analysis_of,
    jsonable,
    load_source,
    register_name_resolver,
    register_plotter,
    register_source,
    stages,
)
from hyperstat.solver.cli.outputs import command_outputs
from hyperstat.solver.cli.suggest import SuggestingParser
from hyperstat.solver.errors import HyperstatError

__all__ = ["main", "build_parser", "register_source", "register_plotter", "register_name_resolver", "load_source",
           "jsonable", "analysis_of", "stages"]


def _installed_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("hyperstat")
    except PackageNotFoundError:  # pragma: no cover - a source tree that was never installed
        return "0+unknown"


def build_parser() -> argparse.ArgumentParser:
    """Argument parser with the solver's commands."""
    parser = SuggestingParser(
        prog="hyperstat",
        description="Geometric defects of over-constrained mechanisms: stationarity analysis, accuracy, "
        "identification, diagnosis (lengths in mm, angles in rad).",
    )
    parser.add_argument("--version", action="version", version=f"hyperstat {_installed_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for stage in (analysis, tolerances, calibration, diagnosis, export):
        stage.add_commands(sub)
    return parser


_LINE_BREAKS = {c: c.encode("unicode_escape").decode("ascii") for c in "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"}


def one_line(message: str) -> str:
    """``message`` on one line: line breaks that came from an input (a name with a newline) are escaped.

    >>> print(one_line("field 'a' names 'x" + chr(10) + "y'."))
    field 'a' names 'x\\ny'.
    """
    return message.translate(str.maketrans(_LINE_BREAKS))


class Terminated(BaseException):
    """Raised by the SIGTERM handler so that pending atomic writes clean up their temporary files."""


def _on_sigterm(signum, frame):  # noqa: ARG001 - signal handler signature
    raise Terminated()


def main(argv: list[str] | None = None, parser: argparse.ArgumentParser | None = None) -> int:
    """Run the command line; returns the exit code (2 for a user error, 143 when terminated)."""
    import signal
    import threading

    from hyperstat.solver.allocator import keep_freed_memory

    parser = parser or build_parser()
    args = parser.parse_args(argv)
    if argv is None:  # the process's own command line (not the Python API's call): large arrays reuse freed pages
        keep_freed_memory()  # less system CPU (hyperstat.solver.allocator)
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        with command_outputs(parser, args):  # outputs checked first, written together at the end
            code = int(args.func(args) or 0)
        return code
    except Terminated:
        sys.stderr.write("hyperstat: terminated; no output was left half-written\n")
        return 143
    except HyperstatError as exc:
        sys.stderr.write(f"hyperstat: error: {one_line(str(exc))}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("hyperstat: interrupted\n")
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
