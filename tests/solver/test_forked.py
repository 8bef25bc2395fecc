"""A stage computed by a forked child (:mod:`hyperstat.solver.forked`): the caller's result, or the caller computes it.

Units: none.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from hyperstat.solver.forked import Forked


def _state(x: np.ndarray) -> dict:
    return {"sum": float(np.sum(x)), "array": x * np.pi, (1, "a"): (None, [np.float64(0.1)]), "pid": os.getpid()}


def test_the_child_computes_the_callers_result_bit_for_bit():
    x = np.random.default_rng(3).normal(size=(7, 5))
    job = Forked(_state, x)
    assert job._pid is not None  # a child was started (Linux, HYPERSTAT_NO_FORK unset)
    got = job.result()
    want = _state(x)
    assert got["pid"] != want["pid"]  # computed in the child
    assert got["sum"] == want["sum"] and got[(1, "a")] == want[(1, "a")]
    assert got["array"].tobytes() == want["array"].tobytes() and got["array"].shape == (7, 5)


def _fails_in_the_child(parent: int) -> int:
    if os.getpid() != parent:
        raise RuntimeError("child")
    return 42


def test_a_failed_child_leaves_the_work_to_the_caller():
    assert Forked(_fails_in_the_child, os.getpid()).result() == 42


def test_an_error_is_raised_by_the_caller_as_without_a_child():
    with pytest.raises(ZeroDivisionError):
        Forked(lambda: 1 / 0).result()


def test_without_fork_the_caller_computes(monkeypatch):
    monkeypatch.setenv("HYPERSTAT_NO_FORK", "1")
    job = Forked(os.getpid)
    assert job._pid is None and job.result() == os.getpid()


def test_a_cancelled_child_is_reaped():
    job = Forked(lambda: [0] * 10)
    pid = job._pid
    job.cancel()
    assert job._pid is None
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)


def _hangs_in_the_child(parent: int) -> int:
    if os.getpid() != parent:
        import time

        time.sleep(60)
        return -1  # what a child that is waited for (not killed) would hand back
    return 7


def test_a_hung_child_is_killed_and_the_caller_computes():
    job = Forked(_hangs_in_the_child, os.getpid())
    pid = job._pid
    assert job.result(timeout=0.5) == 7
    with pytest.raises(ChildProcessError):  # killed and reaped, not left running
        os.waitpid(pid, os.WNOHANG)


def _frozen_in_the_child() -> dict:
    import gc

    return {"pid": os.getpid(), "frozen": gc.get_freeze_count()}


def test_the_child_skips_the_inherited_heap_and_the_caller_keeps_collecting_its_own():
    """The child's collector leaves out what it inherits (gc.freeze before the fork); the caller's heap is given back
    to its collector at once (a long-lived caller must not keep the garbage of the moment of a fork for good)."""
    import gc

    assert gc.get_freeze_count() == 0
    job = Forked(_frozen_in_the_child)
    assert gc.get_freeze_count() == 0  # given back in the caller, right after the fork
    got = job.result()
    assert got["pid"] != os.getpid() and got["frozen"] > 1000  # the interpreter's and the modules' objects at least


def _pid_and(x: np.ndarray) -> tuple:
    return os.getpid(), x @ x.T


def test_beside_gives_the_second_half_to_a_child_when_a_core_is_idle(monkeypatch):
    from hyperstat.solver import forked

    x = np.random.default_rng(5).normal(size=(9, 4))
    monkeypatch.setattr(forked, "idle_core", lambda: True)
    (p1, a1), (p2, a2) = forked.beside(lambda: _pid_and(x), lambda: _pid_and(x))
    assert p1 == os.getpid() != p2  # the second computed by a child
    assert a1.tobytes() == a2.tobytes()  # the same arithmetic, handed back bit for bit
    monkeypatch.setattr(forked, "idle_core", lambda: False)
    (p1, _), (p2, _) = forked.beside(lambda: _pid_and(x), lambda: _pid_and(x))
    assert p1 == p2 == os.getpid()  # no idle core: both here


def test_beside_stops_its_child_when_the_first_half_fails(monkeypatch):
    from hyperstat.solver import forked

    started = []

    class Recorded(forked.Forked):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            started.append((self, self._pid))
    monkeypatch.setattr(forked, "idle_core", lambda: True)
    monkeypatch.setattr(forked, "Forked", Recorded)
    with pytest.raises(ZeroDivisionError):
        forked.beside(lambda: 1 / 0, lambda: 2)
    (job, pid), = started
    assert pid is not None and job._pid is None  # a child was started, then killed
    with pytest.raises(ChildProcessError):  # and reaped
        os.waitpid(pid, os.WNOHANG)


def test_idle_core_reads_the_running_tasks(monkeypatch, tmp_path):
    from hyperstat.solver import forked

    monkeypatch.setenv("HYPERSTAT_NO_FORK", "1")
    assert forked.idle_core() is False
    monkeypatch.delenv("HYPERSTAT_NO_FORK")
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    real_open = open

    def loadavg(running: int):
        def fake(path, *a, **k):
            if path == "/proc/loadavg":
                p = tmp_path / "loadavg"
                p.write_text(f"0.50 0.40 0.30 {running}/120 4242\n")
                return real_open(p, *a, **k)
            return real_open(path, *a, **k)
        return fake
    monkeypatch.setattr("builtins.open", loadavg(1))
    assert forked.idle_core() is True  # only this task runs on two cores
    monkeypatch.setattr("builtins.open", loadavg(2))
    assert forked.idle_core() is False
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    monkeypatch.setattr("builtins.open", loadavg(1))
    assert forked.idle_core() is False  # one core: nothing beside


def test_when_idle_forks_on_an_idle_core_and_otherwise_computes_at_once(monkeypatch):
    from hyperstat.solver import forked

    calls = []

    def job(x):
        calls.append(x)
        return os.getpid(), x * 2.5
    monkeypatch.setattr(forked, "idle_core", lambda: True)
    started = forked.when_idle(job, 3)
    assert calls == []  # in the child: nothing ran here
    pid, value = started.result()
    assert pid != os.getpid() and value == 7.5
    monkeypatch.setattr(forked, "idle_core", lambda: False)
    done = forked.when_idle(job, 4)
    assert calls == [4]  # computed here, at once (the order of the work without a child)
    assert done.result() == (os.getpid(), 10.0)
    done.cancel()  # nothing to stop


def test_a_child_whose_result_nobody_asks_for_is_reaped_when_its_job_is_dropped():
    import gc

    job = Forked(lambda: [1.0] * 5)
    pid = job._pid
    assert pid is not None
    del job  # the caller raised before asking (calibrated_values' dead centres)
    gc.collect()
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)
