"""Outputs whole or absent: one file, a set of files, and the check of output locations before the work.

Units: none (files only).
"""

from __future__ import annotations

import os
import subprocess

import pytest

from hyperstat.solver import atomic
from hyperstat.solver.atomic import all_or_nothing, check_writable, write_text
from hyperstat.solver.errors import HyperstatError


def _visible(d):
    return sorted(p.name for p in d.iterdir())


def test_a_set_of_files_appears_at_the_end_of_the_block(tmp_path):
    (tmp_path / "b.txt").write_text("old b")
    with all_or_nothing():
        write_text(tmp_path / "a.txt", "new a")
        write_text(tmp_path / "sub" / "c.txt", "new c")  # a folder that does not exist yet
        write_text(tmp_path / "b.txt", "new b")
        assert (tmp_path / "b.txt").read_text() == "old b" and not (tmp_path / "a.txt").exists()
        assert not (tmp_path / "sub").exists()
    assert _visible(tmp_path) == ["a.txt", "b.txt", "sub"]
    assert [(tmp_path / n).read_text() for n in ("a.txt", "b.txt", "sub/c.txt")] == ["new a", "new b", "new c"]


def test_an_error_in_the_block_writes_nothing(tmp_path):
    (tmp_path / "b.txt").write_text("old b")
    with pytest.raises(RuntimeError):
        with all_or_nothing():
            write_text(tmp_path / "a.txt", "new a")
            write_text(tmp_path / "b.txt", "new b")
            raise RuntimeError("the work failed")
    assert _visible(tmp_path) == ["b.txt"] and (tmp_path / "b.txt").read_text() == "old b"


def test_a_failed_move_takes_the_others_back(tmp_path, monkeypatch):
    """The third of three renames fails (fault injected): the first two targets get their previous content back,
    the new file is removed, no staging directory remains."""
    for n in ("a", "b"):
        (tmp_path / f"{n}.txt").write_text(f"old {n}")
    real = os.rename
    moved = []

    def rename(src, dst):
        if str(dst).endswith("c.txt"):
            raise OSError(5, "Input/output error")
        moved.append(dst)
        return real(src, dst)

    with pytest.raises(HyperstatError, match=r"c\.txt: cannot be replaced \(Input/output error\); no output was written"):
        with all_or_nothing():
            for n in ("a", "b", "c"):
                write_text(tmp_path / f"{n}.txt", f"new {n}")
            monkeypatch.setattr(atomic.os, "rename", rename)
    monkeypatch.undo()
    assert len(moved) >= 2  # a and b were moved in before c failed
    assert _visible(tmp_path) == ["a.txt", "b.txt"]
    assert [(tmp_path / f"{n}.txt").read_text() for n in "ab"] == ["old a", "old b"]


def test_nested_blocks_join_the_outer_one(tmp_path):
    with all_or_nothing():
        with all_or_nothing():
            write_text(tmp_path / "a.txt", "a")
        assert not (tmp_path / "a.txt").exists()  # the inner block ended, the outer one has not
    assert (tmp_path / "a.txt").read_text() == "a"


def test_undeclared_writes_go_straight_to_disk(tmp_path):
    """With declared outputs (the command line's), a scratch file elsewhere is written at once (a rendering
    that reads back what it wrote must find it); the declared output waits for the end."""
    out, scratch = tmp_path / "out", tmp_path / "scratch"
    with all_or_nothing(directories=[out], only_declared=True):
        write_text(scratch / "views.png", "x")
        assert (scratch / "views.png").read_text() == "x"
        write_text(out / "report.md", "r")
        assert not out.exists()
    assert (out / "report.md").read_text() == "r"


def test_a_forked_child_writes_its_own_files(tmp_path):
    with all_or_nothing():
        pid = os.fork()
        if pid == 0:  # the child: its writes are not part of the parent's set
            try:
                write_text(tmp_path / "child.txt", "c")
            finally:
                os._exit(0)
        os.waitpid(pid, 0)
        assert (tmp_path / "child.txt").read_text() == "c"


def _immutable(path):
    """Make ``path`` unwritable even for root (``chattr +i``); False where that is not possible."""
    if os.geteuid() != 0:
        os.chmod(path, 0o555 if path.is_dir() else 0o444)
        return True
    return subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode == 0


def _mutable(path):
    if os.geteuid() == 0:
        subprocess.run(["chattr", "-i", str(path)], capture_output=True)
    os.chmod(path, 0o755 if path.is_dir() else 0o644)


def test_output_locations_are_checked_before_the_work(tmp_path):
    (tmp_path / "a_dir").mkdir()
    (tmp_path / "a_file").write_text("x")
    cases = [(dict(files=[tmp_path / "a_dir"]), "is a directory; give a file name"),
             (dict(files=[tmp_path / "a_file" / "out.json"]), "is a file, not a directory"),
             (dict(directories=[tmp_path / "a_file"]), "is a file; this output is a directory")]
    for kwargs, message in cases:
        with pytest.raises(HyperstatError, match=message):
            check_writable(**kwargs)
    locked = tmp_path / "locked"
    locked.mkdir()
    kept = tmp_path / "kept.json"
    kept.write_text("{}")
    assert _immutable(locked) and _immutable(kept)
    try:
        with pytest.raises(HyperstatError, match="locked: the directory cannot be written"):
            check_writable(files=[locked / "new" / "out.json"])
        with pytest.raises(HyperstatError, match="kept.json: exists and cannot be replaced"):
            check_writable(files=[kept])
    finally:
        _mutable(locked)
        _mutable(kept)
    check_writable(files=[tmp_path / "new" / "deeper" / "out.json"], directories=[tmp_path / "report"])
    assert _visible(tmp_path) == ["a_dir", "a_file", "kept.json", "locked"]  # nothing created by the check


class _Interrupted(BaseException):
    """What the command line's SIGTERM handler raises (a BaseException, as a signal's exception is)."""


def _interrupt_right_after(monkeypatch, name: str, created: list) -> None:
    """``os.<name>`` (mkdir or open) does its work, then is interrupted before it returns: a signal landing there."""
    real = getattr(os, name)

    def interrupted(path, *args, **kwargs):
        result = real(path, *args, **kwargs)
        if str(os.fspath(path)).endswith(".part"):
            created.append(os.fspath(path))
            if name == "open":
                os.close(result)
            raise _Interrupted
        return result

    monkeypatch.setattr(os, name, interrupted)


def test_an_interrupt_right_after_the_staging_directory_is_made_leaves_nothing(tmp_path, monkeypatch):
    created: list = []
    _interrupt_right_after(monkeypatch, "mkdir", created)
    with pytest.raises(_Interrupted):
        with all_or_nothing():
            write_text(tmp_path / "a.txt", "a")
    monkeypatch.undo()
    assert created and list(tmp_path.iterdir()) == []  # made, then removed by the block's discard


def test_an_interrupt_right_after_the_temporary_file_is_made_leaves_nothing(tmp_path, monkeypatch):
    created: list = []
    _interrupt_right_after(monkeypatch, "open", created)
    with pytest.raises(_Interrupted):
        write_text(tmp_path / "a.txt", "a")
    monkeypatch.undo()
    assert created and list(tmp_path.iterdir()) == []
