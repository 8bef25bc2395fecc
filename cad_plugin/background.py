"""Work done in a forked process while the command goes on (pictures of a report).

Units: none (PNG bytes).

A report spends a good part of its time drawing: the skeleton views (pyvista / VTK) and the
diagnosis plots (matplotlib), each with its library's import.  Neither depends on what the
command computes next, so on a machine with a free core they are drawn by a forked child
while the parent verifies, diagnoses and allocates.  The result is the same bytes as drawing
in-process: off Linux (fork without exec is unsafe with macOS' system libraries, Windows has
no fork), with ``HYPERSTAT_NO_FORK`` set, or when the child fails or hangs,
:meth:`Background.result` draws in-process, so an error is raised exactly as without the child.

The child hands its result back as JSON (bytes as base64) in a directory only this user can
enter: never as a pickle, whose loading runs code (the trust boundary of the README).
"""

from __future__ import annotations

import base64
import gc
import json
import os
import shutil
import sys
import tempfile
from typing import Any, Callable

__all__ = ["Background", "Deferred", "PICTURES_NICE", "PAGES_NICE"]

#: niceness of a report's picture children (skeleton views, diagnosis) when the machine is idle as the report starts:
#: the report's own line of work (the values, then the Monte Carlo and the document) is its critical path, and the
#: pictures are wanted at its end only; with equal shares the children took the cores from it, and its last second
#: ran on one core (Tripteor report with data, alternated: 6.28-6.46 s, 5.65-5.80 s with these values).  On a machine
#: busy with other work the children keep the caller's priority: niced, they lost to the other processes (the same
#: report beside two busy loops: 9.5 s at equal priority, 12.0-12.4 s niced)
PICTURES_NICE = 6
#: niceness of the part pages' child (the longest of them, whose last drawing follows the values)
PAGES_NICE = 3


def _encode(value: Any) -> Any:
    """JSON-ready form of a result made of bytes, str, numbers, lists, tuples and str-keyed dicts."""
    if isinstance(value, (bytes, bytearray)):
        return {"bytes": base64.b64encode(bytes(value)).decode("ascii")}
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError("a background result's dict keys must be strings")
        return {"dict": {k: _encode(v) for k, v in value.items()}}
    if isinstance(value, (list, tuple)):
        return {"list": [_encode(v) for v in value]}
    if value is None or isinstance(value, (str, bool, int, float)):
        return {"value": value}
    raise TypeError(f"a background result cannot hold a {type(value).__name__}")


def _decode(doc: Any) -> Any:
    (kind, value), = doc.items()
    if kind == "bytes":
        return base64.b64decode(value)
    if kind == "dict":
        return {k: _decode(v) for k, v in value.items()}
    if kind == "list":
        return [_decode(v) for v in value]
    return value


def _child(fn: Callable, args: tuple, path: str, nice: int = 0) -> None:
    """Body of the forked process: the result written to ``path`` as JSON; no traceback, no flush of inherited buffers."""
    try:
        if nice > 0:
            try:
                os.nice(nice)
            except OSError:  # pragma: no cover - a system that refuses: the child runs at the caller's priority
                pass
        result = fn(*args)
        with open(path + ".part", "w", encoding="utf-8") as fh:
            json.dump(_encode(result), fh)
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
        the parent's memory); its result is made of bytes, str, numbers, lists, tuples
        (given back as lists) and str-keyed dicts.
    *args
        Its arguments.
    fork : bool
        ``False``: no child, :meth:`result` runs ``fn`` in-process.
    nice : int
        Added to the child's niceness (0: none), so that the caller's own work keeps the cores first
        (:data:`PICTURES_NICE`).

    Examples
    --------
    >>> Background(sum, [1, 2, 3]).result()
    6
    >>> Background(lambda: {"views.png": b"PNG"}).result()
    {'views.png': b'PNG'}
    """

    def __init__(self, fn: Callable, *args: Any, fork: bool = True, nice: int = 0) -> None:
        self._fn, self._args = fn, args
        self._proc = None
        self._path = self._dir = None
        if not fork or os.environ.get("HYPERSTAT_NO_FORK") or not sys.platform.startswith("linux"):
            return  # fork without exec is not safe with macOS' system libraries; Windows has none
        import multiprocessing

        try:
            ctx = multiprocessing.get_context("fork")
        except ValueError:  # pragma: no cover - platforms without fork
            return
        self._dir = tempfile.mkdtemp(prefix="hyperstat-")  # mode 0700: no other user can put a file there
        self._path = os.path.join(self._dir, "result.json")
        for stream in (sys.stdout, sys.stderr):  # nothing buffered may be written twice
            try:
                stream.flush()
            except (AttributeError, ValueError):
                pass
        # the heap so far out of the child's collector's reach: its collections do not go over the objects it
        # inherits (modules, data); given back to this process' collector once the child is started, so that a
        # long-lived caller (a notebook, a workbench) keeps collecting what was garbage at the fork
        gc.freeze()
        try:
            self._proc = ctx.Process(target=_child, args=(fn, args, self._path, nice), daemon=True)
            self._proc.start()
        except OSError:  # pragma: no cover - no process left: do it in-process later
            self._proc = None
        finally:
            gc.unfreeze()

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
                    with open(self._path, encoding="utf-8") as fh:
                        return _decode(json.load(fh))
            except (OSError, ValueError, TypeError, AttributeError):
                pass
            finally:
                shutil.rmtree(self._dir, ignore_errors=True)
        return self._fn(*self._args)

    def cancel(self) -> None:
        """Stop the child, if any, and remove its directory (its result will not be asked for)."""
        if self._proc is not None:
            self._proc.kill()
            self._proc.join()
            self._proc = None
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)


def _deferred_child(fn: Callable, prepare: Callable | None, fd: int, path: str) -> Any:
    """Body of a :class:`Deferred` child: ``prepare()``, then ``fn`` of the input the parent wrote to ``path`` (one
    byte on ``fd`` says it is there)."""
    if prepare is not None:
        prepare()
    _read_exactly(fd, 1)
    with open(path, encoding="utf-8") as fh:
        return fn(_decode(json.load(fh)))


def _read_exactly(fd: int, n: int) -> bytes:
    chunks, left = [], n
    while left:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            raise EOFError("the parent sent no input")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


class Deferred:
    """``fn(value)`` in a forked child started now, whose input ``value`` is given later (:meth:`result`).

    The child runs ``prepare()`` at once (imports, fonts: what does not depend on the input), then waits for
    the input, so that the preparation overlaps the parent's work.  The input and the result travel as JSON
    (bytes as base64: :class:`Background`'s encoding, never a pickle); the input through a file in a directory only
    this user can enter, so that :meth:`send` never waits for a child still preparing (through the pipe, an input
    over its 64 kB buffer held the report's process until the child had read it).  Without a child
    (``fork=False``, off Linux, ``HYPERSTAT_NO_FORK``, a failed or hung child) :meth:`result` computes ``fn(value)``
    in-process.

    Examples
    --------
    >>> Deferred(lambda v: v["a"] * 2).result({"a": 21})
    42
    """

    def __init__(self, fn: Callable, prepare: Callable | None = None, fork: bool = True, nice: int = 0) -> None:
        self._fn = fn
        self._write = None
        self._sent = False
        self._dir = tempfile.mkdtemp(prefix="hyperstat-")  # mode 0700: no other user can put a file there
        self._input = os.path.join(self._dir, "input.json")
        read, write = os.pipe()
        self._background = Background(_deferred_child, fn, prepare, read, self._input, fork=fork, nice=nice)
        os.close(read)  # the child has its copy
        if self._background._proc is None:
            os.close(write)
            shutil.rmtree(self._dir, ignore_errors=True)
        else:
            self._write = write

    def send(self, value: Any) -> None:
        """Give the child its input (once); it computes while the caller goes on."""
        self._sent = True
        if self._write is not None:
            try:
                with open(self._input + ".part", "w", encoding="utf-8") as fh:
                    json.dump(_encode(value), fh)
                os.replace(self._input + ".part", self._input)
                os.write(self._write, b"\1")  # one byte: the pipe's buffer takes it at once
            except (OSError, TypeError):  # a dead child (broken pipe) or an input JSON cannot carry
                if self._background._proc is not None:
                    self._background._proc.kill()
            finally:
                os.close(self._write)
                self._write = None
        self._background._fn, self._background._args = self._fn, (value,)  # the in-process fallback

    def result(self, *value: Any, timeout: float = 180.0) -> Any:
        """``fn(value)``: the child's result, or computed here; ``value`` is sent first when given."""
        try:
            if value:
                self.send(*value)
            if not self._sent:
                if self._write is not None:
                    os.close(self._write)
                    self._write = None
                self._background.cancel()  # the child waits for an input that will not come
                raise ValueError("Deferred.result: no input was sent")
            return self._background.result(timeout)
        finally:
            shutil.rmtree(self._dir, ignore_errors=True)
