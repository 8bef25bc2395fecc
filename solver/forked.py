"""A stage computed by a forked child while the caller goes on with the next (the machine's second core).

Units: none.

The values stage of a report runs on one core for seconds while the second core has little to do
(``hyperstat report``'s own children, the diagnosis and the part pages, wait for most of it).  A
stage that does not depend on what the caller computes next is started with :class:`Forked`: the
child sees a snapshot of the caller's memory, computes ``fn(*args)`` and hands the result back through
a pipe as JSON (:func:`hyperstat.solver.cache.encode`: floats and arrays bit for bit, never a pickle,
whose loading runs code).  The child's arithmetic is the caller's, so the result is the one the
caller would have computed.  Without a child (``fork=False``, ``HYPERSTAT_NO_FORK``, off Linux: fork
without exec is unsafe with macOS' system libraries, Windows has none) or when the child fails,
:meth:`Forked.result` computes ``fn(*args)`` in-process, so an error is raised exactly as without it.

(The report's pictures use :mod:`hyperstat.cad_plugin.background`; this module is the solver's own,
which never imports the CAD side.)

:func:`beside` splits one stage in two when a core is idle at that moment (:func:`idle_core`): the second half
by a child, the first here. Whether it forks depends on the machine's load, never the result: the child's
arithmetic is the same, and its result comes back bit for bit.
"""

from __future__ import annotations

import gc
import json
import os
import sys
from typing import Any, Callable

__all__ = ["Forked", "HUNG_AFTER", "beside", "idle_core", "when_idle"]

HUNG_AFTER = 600.0  #: seconds without a byte from the child after which :meth:`Forked.result` kills it (s)


def _after_fork() -> None:
    """In the child: the parent's thread pools have no threads here; new ones are made on first use."""
    from hyperstat.solver.kinematics import continuation, fastfk

    fastfk._POOL = None  # noqa: SLF001
    continuation._BLOCK_POOL = None  # noqa: SLF001


class Forked:
    """``fn(*args)`` started in a forked child now; :meth:`result` waits for it (or computes it in-process).

    Parameters
    ----------
    fn : callable
        A function of the state at the time of the call; its result made of what
        :func:`hyperstat.solver.cache.encode` carries (numbers, str, None, lists, tuples, dicts, arrays).
    *args
        Its arguments.
    fork : bool
        ``False``: no child, :meth:`result` computes in-process.

    Examples
    --------
    >>> Forked(sum, [1, 2, 3.5]).result()
    6.5
    >>> Forked(lambda: {"a": (1, None)}, fork=False).result()
    {'a': (1, None)}
    """

    def __init__(self, fn: Callable, *args: Any, fork: bool = True) -> None:
        self._fn, self._args = fn, args
        self._pid = self._read = None
        self._owner = os.getpid()
        if not fork or os.environ.get("HYPERSTAT_NO_FORK") or not sys.platform.startswith("linux"):
            return
        for stream in (sys.stdout, sys.stderr):  # nothing buffered may be written twice
            try:
                stream.flush()
            except (AttributeError, ValueError):
                pass
        read, write = os.pipe()
        gc.freeze()  # the heap so far out of the child's collector's reach: its collections skip what it inherits
        try:
            pid = os.fork()
        except OSError:  # no process left: computed in-process later
            gc.unfreeze()
            os.close(read)
            os.close(write)
            return
        if pid == 0:  # the child: compute, write, leave without running the parent's exit handlers
            code = 1
            try:
                os.close(read)
                from hyperstat.solver.cache import encode

                _after_fork()
                data = json.dumps(encode(fn(*args))).encode()
                view = memoryview(data)
                while view:
                    view = view[os.write(write, view):]
                code = 0
            except BaseException:  # noqa: BLE001 - the parent computes it again and raises there
                pass
            finally:
                os._exit(code)
        gc.unfreeze()  # this process' collector gets its heap back (a long-lived caller keeps collecting it)
        os.close(write)
        self._pid, self._read = pid, read

    def result(self, timeout: float = HUNG_AFTER) -> Any:
        """The child's result; ``fn(*args)`` computed here if there is no child, it failed, or it sent nothing for
        ``timeout`` seconds (a hung child is killed: the caller never waits forever)."""
        if self._pid is not None:
            import select
            import signal

            chunks, hung = [], False
            try:
                while True:  # read all before waiting: a full pipe would block the child
                    if not select.select([self._read], [], [], timeout)[0]:
                        hung = True
                        os.kill(self._pid, signal.SIGKILL)
                        break
                    chunk = os.read(self._read, 1 << 20)
                    if not chunk:
                        break
                    chunks.append(chunk)
            finally:
                os.close(self._read)
                _, status = os.waitpid(self._pid, 0)
                self._pid = self._read = None
            if not hung and os.waitstatus_to_exitcode(status) == 0 and chunks:
                from hyperstat.solver.cache import decode

                try:
                    return decode(json.loads(b"".join(chunks)))
                except ValueError:
                    pass
        return self._fn(*self._args)

    def __del__(self) -> None:
        # a child whose result nobody asked for (the caller raised in between): stopped and reaped, never a zombie
        if getattr(self, "_pid", None) is not None and os.getpid() == getattr(self, "_owner", None):
            try:
                self.cancel()
            except Exception:  # noqa: BLE001 - at interpreter exit, os may be half torn down
                pass

    def cancel(self) -> None:
        """Stop the child (the caller failed and will not ask for the result)."""
        if self._pid is not None:
            import signal

            try:
                os.kill(self._pid, signal.SIGKILL)
            except OSError:
                pass
            os.close(self._read)
            os.waitpid(self._pid, 0)
            self._pid = self._read = None


def idle_core() -> bool:
    """True when this process may run on two cores or more and another one is idle now.

    Linux only (elsewhere, or with ``HYPERSTAT_NO_FORK`` set: False): the count of tasks running at this
    instant (``/proc/loadavg``, this one included) is below the number of cores this process may use.  A
    snapshot, so a decision of *where* to compute (:func:`beside`), never of *what*.

    Examples
    --------
    >>> isinstance(idle_core(), bool)
    True
    """
    if os.environ.get("HYPERSTAT_NO_FORK") or not sys.platform.startswith("linux"):
        return False
    try:
        cores = len(os.sched_getaffinity(0))
        with open("/proc/loadavg", encoding="ascii") as fh:
            running = int(fh.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError, AttributeError):
        return False
    return cores >= 2 and running < cores


def beside(first: Callable[[], Any], second: Callable[[], Any]) -> tuple[Any, Any]:
    """``(first(), second())``: ``second`` computed by a forked child meanwhile when a core is idle
    (:func:`idle_core`), else here after ``first``.

    For a stage whose two halves are independent and each costs well over a fork (about 5-10 ms from a
    process of 300 MB): the same results either way (:class:`Forked`: the same arithmetic, handed back bit
    for bit), so the choice depends only on the load.  ``second``'s result must be what
    :func:`hyperstat.solver.cache.encode` carries, and it must not change this process' state (a child's
    changes stay in the child).

    Examples
    --------
    >>> beside(lambda: [1.5], lambda: (2, None))
    ([1.5], (2, None))
    """
    import threading

    if threading.current_thread() is not threading.main_thread() or not idle_core():  # fork from the main thread only
        return first(), second()
    child = Forked(second)
    try:
        head = first()
    except BaseException:
        child.cancel()
        raise
    return head, child.result()


class _Done:
    """A result computed at once, with :class:`Forked`'s interface (:func:`when_idle`)."""

    def __init__(self, value: Any) -> None:
        self._value = value

    def result(self, timeout: float = HUNG_AFTER) -> Any:
        return self._value

    def cancel(self) -> None:
        pass


def when_idle(fn: Callable, *args: Any) -> "Forked | _Done":
    """``fn(*args)`` started in a forked child when a core is idle now (:func:`idle_core`), else computed here at
    once; its ``result()`` either way (and ``cancel()``, which stops a child).

    For a stage the caller does not need before its next one: the same result wherever it is computed
    (:class:`Forked`), so the choice depends only on the load.  ``fn`` must not change this process' state.

    Examples
    --------
    >>> when_idle(sum, [1, 2, 3.5]).result()
    6.5
    """
    import threading

    if threading.current_thread() is threading.main_thread() and idle_core():
        return Forked(fn, *args)
    return _Done(fn(*args))
