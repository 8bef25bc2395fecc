"""Pictures drawn by a forked child (``cad_plugin/background.py``): the same result as in-process, or in-process."""

from __future__ import annotations

import os

import pytest

from hyperstat.cad_plugin.background import Background


def _pid_and_square(x: int) -> tuple[int, int]:
    return os.getpid(), x * x


def _fails(x: int) -> int:
    raise ValueError(f"no picture for {x}")


def test_the_child_computes_the_same_result_in_another_process():
    pid, value = Background(_pid_and_square, 7).result()
    assert value == 49 and pid != os.getpid()


def test_without_fork_the_work_is_done_in_process(monkeypatch):
    monkeypatch.setenv("HYPERSTAT_NO_FORK", "1")
    pid, value = Background(_pid_and_square, 5).result()
    assert value == 25 and pid == os.getpid()


def test_a_failing_child_leaves_no_file_and_the_error_is_raised_in_process():
    job = Background(_fails, 3)
    path = job._path  # noqa: SLF001 - the temporary file of the child's result
    with pytest.raises(ValueError, match="no picture for 3"):
        job.result()
    assert path is not None and not os.path.exists(path) and not os.path.exists(path + ".part")


def test_a_deferred_child_prepares_at_once_and_computes_the_input_sent_later():
    from hyperstat.cad_plugin.background import Deferred

    ready = {}

    def prepare():
        ready["pid"] = os.getpid()

    def fn(value):
        return {"prepared_in": ready.get("pid"), "ran_in": os.getpid(), "twice": [2 * v for v in value["x"]]}

    got = Deferred(fn, prepare).result({"x": [1, 2.5]})
    assert got["twice"] == [2, 5.0]
    assert got["ran_in"] == got["prepared_in"] != os.getpid()  # prepared, then computed, in the child


def test_a_deferred_child_that_fails_or_cannot_fork_leaves_the_work_to_this_process(monkeypatch):
    from hyperstat.cad_plugin.background import Deferred

    job = Deferred(_fails)
    with pytest.raises(ValueError, match="no picture for 4"):
        job.result(4)
    waiting = Deferred(_pid_and_square)
    with pytest.raises(ValueError, match="no input was sent"):
        waiting.result()
    # the child that waited for the input is stopped, and neither its directory nor the input's is left behind
    assert waiting._background._proc is None  # noqa: SLF001
    assert not os.path.exists(waiting._dir) and not os.path.exists(waiting._background._dir)  # noqa: SLF001
    monkeypatch.setenv("HYPERSTAT_NO_FORK", "1")
    pid, value = Deferred(_pid_and_square).result(6)
    assert value == 36 and pid == os.getpid()


def _frozen_in_the_child() -> tuple[int, int]:
    import gc

    return os.getpid(), gc.get_freeze_count()


def test_the_child_skips_the_inherited_heap_and_the_caller_keeps_collecting_its_own():
    """gc.freeze before the fork: the child's collections leave out what it inherits; the caller's heap is given back
    to its collector once the child is started (a workbench or a notebook keeps collecting the garbage of that moment)."""
    import gc

    assert gc.get_freeze_count() == 0
    job = Background(_frozen_in_the_child)
    assert gc.get_freeze_count() == 0
    pid, frozen = job.result()
    assert pid != os.getpid() and frozen > 1000


def _pid_and_niceness() -> tuple[int, int]:
    return os.getpid(), os.nice(0)


def test_a_niced_child_runs_below_its_caller_and_the_caller_keeps_its_priority():
    base = os.nice(0)
    pid, niceness = Background(_pid_and_niceness, nice=4).result()
    assert pid != os.getpid() and niceness == min(base + 4, 19)
    assert os.nice(0) == base  # only the child's
    assert Background(_pid_and_niceness).result()[1] == base  # none unless asked


def test_a_large_input_is_sent_while_the_child_is_still_preparing():
    """The input (over a pipe's 64 kB) travels through a file: ``send`` returns while the child prepares (the report's
    process was held there until the part pages' child had imported OCCT).  The child's preparation waits for a word
    sent after ``send`` returns: a ``send`` that waited for the child would never return (a thread, joined with a
    timeout, tells)."""
    import threading

    from hyperstat.cad_plugin.background import Deferred

    go_read, go_write = os.pipe()

    def prepare():
        os.read(go_read, 1)  # until the caller has sent the input

    job = Deferred(lambda value: sum(value["x"]), prepare)
    big = {"x": [float(i) for i in range(200_000)]}  # about 2 MB of JSON
    sender = threading.Thread(target=job.send, args=(big,), daemon=True)
    sender.start()
    sender.join(timeout=120.0)
    returned = not sender.is_alive()
    os.write(go_write, b"1")  # the child may go on either way (never a hung test)
    assert returned, "send waited for the child"
    assert job.result() == sum(big["x"])
    assert job._background._proc is None and not os.path.exists(job._dir)  # noqa: SLF001 - its input file removed
