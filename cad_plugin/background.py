"""Work done in a forked process while the command goes on (pictures of a report).

Units: none (PNG bytes).

A report spends a good part of its time drawing: the skeleton views (pyvista / VTK) and the
diagnosis plots (matplotlib), each with its library's import.  Neither depends on what the
command computes next, so on a machine with a free core they are drawn by a forked child
while the parent verifies, diagnoses and allocates.  The result is the same bytes as drawing
in-process: off Linux (fork without exec is unsafe with macOS' system libraries, Windows has
no fork), with ``HYPERSTAT_NO_FORK`` set, or when the child fails or hangs,
:meth:`Background.result` draws in-process, so an error is raised exactly as without the child.
"""

from __future__ import annotations

import os
import pickle
import sys
import tempfile
from typing import Any, Callable

__all__ = ["Background"]


def _child(fn: Callable, args: tuple, path: str) -> None:
    """Body of the forked process: the result pickled to ``path``; no traceback, no flush of inherited buffers."""
    try:
        result = fn(*args)
        with open(path + ".part", "wb") as fh:
            pickle.dump(result, fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(path + ".part", path)
    except BaseException:  # noqa: BLE001 - the parent redoes the work in-process and raises there
        os._exit(1)
    os._exit(0)


class Background:
    """``fn(*args)`` started in a forked child; :meth:`result` waits for it (or runs it in-process).

    Parameters
    ----------
    fn : callable
        A function of what exists at the time of the call (the child sees a snapshot of
        the parent's memory); its result must pickle.
    *args
        Its arguments.

    Examples
    --------
    >>> Background(sum, [1, 2, 3]).result()
    6
    """

    def __init__(self, fn: Callable, *args: Any) -> None:
        self._fn, self._args = fn, args
        self._proc = None
        self._path = None
        if os.environ.get("HYPERSTAT_NO_FORK") or not sys.platform.startswith("linux"):
            return  # fork without exec is not safe with macOS' system libraries; Windows has none
        import multiprocessing

        try:
            ctx = multiprocessing.get_context("fork")
        except ValueError:  # pragma: no cover - platforms without fork
            return
        fd, self._path = tempfile.mkstemp(prefix="hyperstat-", suffix=".pickle")
        os.close(fd)
        os.unlink(self._path)
        for stream in (sys.stdout, sys.stderr):  # nothing buffered may be written twice
            try:
                stream.flush()
            except (AttributeError, ValueError):
                pass
        try:
            self._proc = ctx.Process(target=_child, args=(fn, args, self._path), daemon=True)
            self._proc.start()
        except OSError:  # pragma: no cover - no process left: do it in-process later
            self._proc = None

    def result(self, timeout: float = 180.0) -> Any:
        """The child's result; ``fn(*args)`` in-process if there is no child, it failed, or it ran past ``timeout`` s."""
        if self._proc is not None:
            self._proc.join(timeout)
            if self._proc.is_alive():  # pragma: no cover - a hung child: kill it and do the work here
                self._proc.kill()
                self._proc.join()
            ok = self._proc.exitcode == 0
            self._proc = None
            try:
                if ok:
                    with open(self._path, "rb") as fh:
                        return pickle.load(fh)
            except (OSError, pickle.UnpicklingError, EOFError):
                pass
            finally:
                for p in (self._path, self._path + ".part"):
                    if os.path.exists(p):
                        os.unlink(p)
        return self._fn(*self._args)
