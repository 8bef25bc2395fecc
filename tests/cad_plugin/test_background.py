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
