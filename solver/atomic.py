"""Atomic file output: write to a temporary file in the same folder, then rename.

A reader never sees a half-written file, and a previous file survives a crash or a
kill in the middle of writing.
"""

from __future__ import annotations

import glob
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

__all__ = ["write_text", "write_bytes", "write_json", "dumps_json"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + ``os.replace``).

    The temporary file is ``.NAME.XXXX.part`` next to ``path``; it is removed if the
    write fails or the process is interrupted (``SIGINT``, or ``SIGTERM`` under the
    command line).  A ``SIGKILL`` cannot be caught: it may leave that hidden ``.part``
    file, never a partial ``path``; the next successful write of ``path`` removes it.
    The environment variable ``HYPERSTAT_TEST_WRITE_DELAY`` (seconds) pauses half-way
    through each write, so that tests can kill a process in the middle of one.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    started = time.time()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
        with os.fdopen(fd, "wb") as fh:
            delay = float(os.environ.get("HYPERSTAT_TEST_WRITE_DELAY", "0") or 0)
            if delay > 0:
                fh.write(data[: len(data) // 2])
                fh.flush()
                time.sleep(delay)
                fh.write(data[len(data) // 2:])
            else:
                fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    for stale in path.parent.glob(f".{glob.escape(path.name)}.*.part"):  # left by a killed writer
        try:
            if stale.stat().st_mtime < started:
                stale.unlink()
        except FileNotFoundError:
            pass
    return path


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def dumps_json(obj: Any, sort_keys: bool = True) -> str:
    """Deterministic JSON text: two-space indent, final newline, no NaN or infinity."""
    return json.dumps(obj, indent=2, sort_keys=sort_keys, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike, obj: Any, sort_keys: bool = True) -> Path:
    """Write ``obj`` as deterministic JSON to ``path`` atomically."""
    return write_text(path, dumps_json(obj, sort_keys=sort_keys))
