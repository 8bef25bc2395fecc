"""Find the ``hyperstat`` command line and run it; turn its failures into one clear sentence.

Units: the command line works in mm and rad.

Why a command line and not an import: FreeCAD runs its own Python (Debian's 3.11 with
numpy 1.24 for FreeCAD 0.20) while the solver lives in the project's virtual
environment (scipy, sympy, CadQuery/OCP, newer numpy).  Mixing the two in one process
means putting the venv's site-packages on FreeCAD's ``sys.path``, where two builds of
numpy and two builds of OpenCASCADE (FreeCAD's and CadQuery's OCP) collide.  Running
``hyperstat`` as a subprocess and exchanging files (STEP + sidecar, model files, JSON)
keeps each side in its own interpreter; the files are the documented contract.

Where the executable is looked for, first hit wins:

1. the environment variable ``HYPERSTAT_CLI``;
2. the preference ``Mod/Hyperstat/CliPath`` (Edit > Preferences > Hyperstat);
3. the path recorded by ``make freecad-install`` in ``install.json`` next to this file;
4. ``hyperstat`` on the ``PATH``.

This module does not import FreeCAD at module level: the preference is read only when
FreeCAD is there, so the project's own tests can import it.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "HyperstatWorkbenchError",
    "CommandMissing",
    "CliResult",
    "PREFERENCES",
    "install_record",
    "find_cli",
    "templates_dir",
    "list_templates",
    "run_cli",
    "run_together",
    "available_commands",
    "OPTIONAL_COMMANDS",
    "prepare_command",
    "interpret",
    "DEFAULT_TIMEOUT_S",
]

PREFERENCES = "User parameter:BaseApp/Preferences/Mod/Hyperstat"
INSTALL_RECORD = Path(__file__).resolve().parent / "install.json"
DEFAULT_TIMEOUT_S = 900.0
#: sub-commands built by other parts of the project; an older command line may lack them
OPTIONAL_COMMANDS = ("diagnose", "report", "export-controller")
_COMMANDS_CACHE: dict[tuple[str, float], frozenset[str]] = {}


class HyperstatWorkbenchError(Exception):
    """A user-facing error of the workbench: the message is one sentence to show as is."""


class CommandMissing(HyperstatWorkbenchError):
    """The ``hyperstat`` executable found has no such sub-command (an older checkout)."""


@dataclass
class CliResult:
    """What a successful ``hyperstat`` run printed."""

    command: list[str]
    stdout: str
    stderr: str


def install_record() -> dict:
    """``install.json`` written by ``make freecad-install`` (empty when absent or unreadable)."""
    try:
        data = json.loads(INSTALL_RECORD.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _preference(name: str) -> str:
    try:
        import FreeCAD
    except ImportError:
        return ""
    return FreeCAD.ParamGet(PREFERENCES).GetString(name, "").strip()


def find_cli() -> str:
    """Absolute path of the ``hyperstat`` executable (see the module docstring for the order).

    Raises
    ------
    HyperstatWorkbenchError
        If no candidate exists, or the one configured is not an executable file.
    """
    candidates = [
        ("the environment variable HYPERSTAT_CLI", os.environ.get("HYPERSTAT_CLI", "").strip()),
        ("the preference Hyperstat > command line", _preference("CliPath")),
        (f"the install record {INSTALL_RECORD}", str(install_record().get("cli", "")).strip()),
    ]
    for origin, value in candidates:
        if not value:
            continue
        path = Path(value).expanduser()
        if path.is_file() and os.access(path, os.X_OK):
            return str(path)
        raise HyperstatWorkbenchError(
            f"{origin} names '{value}', which is not an executable file: point it at the 'hyperstat' "
            "command of a hyperstat checkout (.venv/bin/hyperstat) or run 'make freecad-install' again."
        )
    found = shutil.which("hyperstat")
    if found:
        return found
    raise HyperstatWorkbenchError(
        "The hyperstat command line was not found: set HYPERSTAT_CLI, or the preference "
        "Edit > Preferences > Hyperstat, or run 'make freecad-install' in a hyperstat checkout."
    )


def templates_dir() -> Path | None:
    """Folder of the shipped templates: preference ``TemplatesDir``, else the install record."""
    for value in (_preference("TemplatesDir"), str(install_record().get("templates", ""))):
        if value and Path(value).is_dir():
            return Path(value)
    return None


def list_templates() -> list[Path]:
    """Template files (``*.py``) of :func:`templates_dir`, sorted, then those of its ``corpus`` folder (the
    mechanisms with their theory, docs/authoring.md); empty if there is none."""
    folder = templates_dir()
    if folder is None:
        return []
    return [p for sub in (folder, folder / "corpus")
            for p in sorted(sub.glob("*.py")) if not p.name.startswith("_")]


def _log(text: str) -> None:
    try:
        import FreeCAD
    except ImportError:
        return
    FreeCAD.Console.PrintLog(text)


def _clean_environment() -> dict[str, str]:
    """The environment without FreeCAD's Python settings, which would confuse the venv's Python."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env.setdefault("MPLBACKEND", "Agg")
    return env


def _error_line(stderr: str) -> str:
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    if not lines:
        return "no message on stderr"
    last = lines[-1]
    for prefix in ("hyperstat: error: ", "error: "):
        if last.startswith(prefix):
            return last[len(prefix):]
    return last


def available_commands(cli: str | None = None) -> frozenset[str]:
    """Sub-commands that ``hyperstat --help`` lists (cached per executable and modification time)."""
    cli = cli or find_cli()
    key = (cli, os.stat(cli).st_mtime)
    if key not in _COMMANDS_CACHE:
        try:
            proc = subprocess.run([cli, "--help"], capture_output=True, text=True, env=_clean_environment(), timeout=120)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise HyperstatWorkbenchError(f"{cli} could not be started ({exc}).") from None
        match = re.search(r"\{([A-Za-z0-9_,-]+)\}", proc.stdout)
        _COMMANDS_CACHE[key] = frozenset(match.group(1).split(",")) if match else frozenset()
    return _COMMANDS_CACHE[key]


def _missing(cli: str, sub: str) -> CommandMissing:
    return CommandMissing(
        f"This hyperstat command line ({cli}) has no '{sub}' command yet: update the hyperstat checkout "
        "and run 'make freecad-install' again."
    )


def prepare_command(arguments: list[str], check_optional: bool = True) -> tuple[list[str], dict[str, str]]:
    """The full command line and environment of ``hyperstat ARGUMENTS`` (for a synchronous or a Qt run).

    With ``check_optional``, a sub-command of :data:`OPTIONAL_COMMANDS` is first looked up in
    ``hyperstat --help`` (a blocking call, cached); without it, a missing sub-command is still
    recognised afterwards by :func:`interpret` from argparse's "invalid choice" message.

    Raises
    ------
    CommandMissing, HyperstatWorkbenchError
        As :func:`run_cli`.
    """
    cli = find_cli()
    sub = str(arguments[0]) if arguments else ""
    if check_optional and sub in OPTIONAL_COMMANDS and sub not in available_commands(cli):
        raise _missing(cli, sub)
    return [cli, *map(str, arguments)], _clean_environment()


def interpret(command: list[str], returncode: int, stdout: str, stderr: str) -> CliResult:
    """A finished run's output, or its failure as one sentence (see :func:`run_cli`)."""
    cli, sub = command[0], (command[1] if len(command) > 1 else "")
    if returncode == 0:
        return CliResult(command, stdout, stderr)
    message = _error_line(stderr)
    if "invalid choice" in message and f"'{sub}'" in message:
        raise _missing(cli, sub)
    if returncode == 2:
        raise HyperstatWorkbenchError(message[:1].upper() + message[1:])
    raise HyperstatWorkbenchError(f"'hyperstat {sub}' failed with exit code {returncode}: {message}")


def run_cli(arguments: list[str], timeout: float = DEFAULT_TIMEOUT_S, cwd: str | os.PathLike | None = None) -> CliResult:
    """Run ``hyperstat ARGUMENTS`` and return its output (blocking; the GUI uses :mod:`.jobs`).

    Raises
    ------
    CommandMissing
        If the executable does not know the sub-command ``arguments[0]``.
    HyperstatWorkbenchError
        On any other failure: the executable's own one-line message, or a sentence
        naming the command, its exit code and the last line it printed.
    """
    command, env = prepare_command(arguments)
    sub = str(arguments[0]) if arguments else ""
    started = time.monotonic()
    try:
        proc = subprocess.run(command, capture_output=True, text=True, env=env, timeout=timeout, cwd=cwd)
    except subprocess.TimeoutExpired:
        raise HyperstatWorkbenchError(f"'hyperstat {sub}' did not finish within {timeout:g} s and was stopped.") from None
    except OSError as exc:
        raise HyperstatWorkbenchError(f"{command[0]} could not be started ({exc.strerror or exc}).") from None
    _log(f"hyperstat: '{' '.join(command)}' exit {proc.returncode} in {time.monotonic() - started:.1f} s\n")
    return interpret(command, proc.returncode, proc.stdout, proc.stderr)


def run_together(arguments_list: list[list[str]], timeout: float = DEFAULT_TIMEOUT_S) -> tuple[CliResult, ...]:
    """Run several ``hyperstat`` commands that do not depend on each other at once, one process each (on as many
    cores), and return their outputs in order (blocking; the GUI uses :mod:`.jobs`).

    Every process is waited for; then the first failure in the order given is raised, as :func:`run_cli` raises it.
    As in the GUI (:mod:`.jobs`), an optional sub-command is not first looked up in ``hyperstat --help`` (a process
    start before the runs): a command line without it is named by :func:`interpret` from argparse's answer.
    """
    prepared = [prepare_command(arguments, check_optional=False) for arguments in arguments_list]
    started = time.monotonic()
    procs = []
    try:
        for command, env in prepared:
            procs.append(subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env))
    except OSError as exc:
        for proc in procs:
            proc.kill()
            proc.wait()
        raise HyperstatWorkbenchError(f"{prepared[len(procs)][0][0]} could not be started ({exc.strerror or exc}).") \
            from None

    def wait(proc):
        try:
            return proc.communicate(timeout=max(1.0, timeout - (time.monotonic() - started)))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            return None

    with ThreadPoolExecutor(len(procs)) as pool:  # each process' pipes read as it writes them
        outputs = list(pool.map(wait, procs))
    results, failure = [], None
    for (command, _), proc, out in zip(prepared, procs, outputs):
        sub = command[1] if len(command) > 1 else ""
        _log(f"hyperstat: '{' '.join(command)}' exit {proc.returncode} in {time.monotonic() - started:.1f} s\n")
        try:
            if out is None:
                raise HyperstatWorkbenchError(f"'hyperstat {sub}' did not finish within {timeout:g} s and was stopped.")
            results.append(interpret(command, proc.returncode, *out))
        except HyperstatWorkbenchError as exc:
            failure = failure or exc
    if failure is not None:
        raise failure
    return tuple(results)
