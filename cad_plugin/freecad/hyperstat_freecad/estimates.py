"""How long a run of the command line will take: the last runs' durations, remembered per command and template.

Units: seconds.

A job's progress shows its stage and an estimate ("tolerance values (hyperstat report):
4 s of about 9 s").  The estimate of a command for a template is the mean of its last runs
on this machine, kept in FreeCAD's parameters (``Mod/Hyperstat/Durations``, so it survives a
restart); before the first run, a typical duration of the command measured on a 2-core
machine (:data:`TYPICAL_S`).  Pure Python apart from the parameter store, which falls back to
memory outside FreeCAD.
"""

from __future__ import annotations

__all__ = ["TYPICAL_S", "expected", "record", "progress_text", "STORE"]

#: typical seconds per command (cold start of the command line included), measured on a 2-core machine
TYPICAL_S = {"parameters": 3.0, "build": 6.0, "analyze": 4.0, "report": 8.0, "identify": 8.0, "diagnose": 15.0,
             "export-controller": 20.0}
#: the parameter group that remembers the durations
STORE = "User parameter:BaseApp/Preferences/Mod/Hyperstat/Durations"
_MEMORY: dict = {}
_WEIGHT = 0.5  # weight of the newest run in the remembered mean


def _key(command: str, subject: str) -> str:
    return f"{command}:{subject}" if subject else command


def _group():
    try:
        import FreeCAD
    except ImportError:  # the project's tests, outside FreeCAD
        return None
    return FreeCAD.ParamGet(STORE)


def expected(command: str, subject: str = "") -> tuple[float, bool]:
    """(seconds, measured): the remembered duration of ``command`` for ``subject``, else the typical one.

    >>> expected("nonexistent-command")
    (5.0, False)
    """
    key = _key(command, subject)
    group = _group()
    value = group.GetFloat(key, 0.0) if group is not None else _MEMORY.get(key, 0.0)
    if value > 0:
        return value, True
    return TYPICAL_S.get(command, 5.0), False


def record(command: str, subject: str, seconds: float) -> None:
    """Remember a run's duration (a running mean that follows the machine's load)."""
    if not seconds > 0:
        return
    key = _key(command, subject)
    old, measured = expected(command, subject)
    value = _WEIGHT * seconds + (1 - _WEIGHT) * old if measured else seconds
    group = _group()
    if group is not None:
        group.SetFloat(key, float(value))
    else:
        _MEMORY[key] = float(value)


def progress_text(title: str, stage: str, step: int, elapsed: float, estimate: float, measured: bool) -> str:
    """The progress line of a job.

    >>> progress_text("Analyse", "tolerance values (hyperstat report)", 2, 4.2, 9.0, True)
    'Analyse, step 2: tolerance values (hyperstat report), 4 s of about 9 s (last runs)'
    >>> progress_text("Analyse", "building", 1, 12.0, 6.0, False)
    'Analyse, step 1: building, 12 s (typically 6 s: it takes longer this time)'
    """
    basis = "last runs" if measured else "typical"
    if elapsed <= 1.2 * estimate:
        return f"{title}, step {step}: {stage}, {elapsed:.0f} s of about {estimate:.0f} s ({basis})"
    word = "usually" if measured else "typically"
    return f"{title}, step {step}: {stage}, {elapsed:.0f} s ({word} {estimate:.0f} s: it takes longer this time)"
