"""Atomic file output: one file is written whole or not at all, and so is a set of files.

* One file (:func:`write_bytes`): written to a temporary file in the same folder, then renamed.
  A reader never sees a half-written file, and a previous file survives a crash or a kill in
  the middle of writing.
* Several files (:func:`all_or_nothing`): inside the block, every file is written into a
  hidden temporary directory beside its target (``.hyperstat-<pid>-XXXX.part``) and nothing
  reaches the targets until the block ends; then the files are moved in (a new output
  directory in one rename), each previous file kept aside until all are in.  If a file cannot
  be moved in, the ones already moved are taken back and the previous files restored: the
  command leaves its outputs as they were.  The command line wraps every command in such a
  block, after :func:`check_writable` has checked every output location before the work starts.

What remains: a ``SIGKILL`` (which cannot be caught) in the middle of moving the files in,
a window of a few renames, may leave some new and some previous files; it may also leave a
hidden ``.part`` file or directory, which the next write into that folder removes.
"""

from __future__ import annotations

import contextlib
import glob
import json
import os
import secrets
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Iterable, Iterator

from hyperstat.solver.errors import HyperstatError

__all__ = ["write_text", "write_bytes", "write_json", "dumps_json", "all_or_nothing", "check_writable",
           "OutputSet"]

_STAGING_PREFIX = ".hyperstat-"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _write_file(fd: int, data: bytes) -> None:
    """Write ``data`` to an open descriptor and flush it to disk (the test hook pauses half-way)."""
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


def _absolute(path: str | os.PathLike) -> Path:
    return Path(os.path.abspath(os.fspath(path)))


def _anchor(directory: Path) -> Path:
    """The nearest existing ancestor of ``directory`` (itself if it exists); refuses a file on the way."""
    d = directory
    while not d.exists():
        d = d.parent
    if not d.is_dir():
        raise HyperstatError(f"{d}: is a file, not a directory, so {directory} cannot be created.")
    return d


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_stale_staging(directory: Path) -> None:
    """Remove staging directories left in ``directory`` by a killed hyperstat process (its pid is gone)."""
    for stale in directory.glob(f"{_STAGING_PREFIX}*.part"):
        try:
            pid = int(stale.name[len(_STAGING_PREFIX):].split("-", 1)[0])
        except ValueError:
            continue
        if pid != os.getpid() and not _pid_alive(pid):
            shutil.rmtree(stale, ignore_errors=True)


class OutputSet:
    """Files staged beside their targets and moved in together (see :func:`all_or_nothing`).

    Parameters
    ----------
    files, directories : iterable of path-like
        Declared outputs.  With ``only_declared``, only writes to a declared file, into a
        declared directory or beside a declared file are staged; other writes (scratch files
        of a rendering, a forked child's) go straight to disk.
    only_declared : bool
        See above; False stages every write made in this process while the set is open.
    """

    def __init__(self, files: Iterable = (), directories: Iterable = (), only_declared: bool = False) -> None:
        self.pid = os.getpid()
        files = [_absolute(f) for f in files]
        self.folders = {f.parent for f in files} | {_absolute(d) for d in directories}
        self.only_declared = only_declared
        self.forced = 0
        self._staging: dict[Path, Path] = {}  # anchor folder -> its staging directory
        self._entries: dict[Path, tuple[Path, Path]] = {}  # target -> (anchor, path relative to the anchor)

    def covers(self, path: str | os.PathLike) -> bool:
        """Whether a write to ``path`` belongs to this set."""
        if os.getpid() != self.pid:
            return False  # a forked child writes its own files
        return self.forced > 0 or not self.only_declared or _absolute(path).parent in self.folders

    def stage(self, path: str | os.PathLike, data: bytes) -> Path:
        """Write ``data`` into the staging directory beside ``path``; returns ``path`` (not written yet)."""
        target = _absolute(path)
        anchor = _anchor(target.parent)
        staging = self._staging.get(anchor)
        try:
            if staging is None:
                _remove_stale_staging(anchor)
                staging = self._new_staging(anchor)
            rel = target.relative_to(anchor)
            staged = staging / "new" / rel
            staged.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".w", dir=staged.parent)
            _write_file(fd, data)
            os.replace(tmp, staged)
        except OSError as exc:
            raise HyperstatError(f"{target}: cannot be written ({exc.strerror or exc.__class__.__name__}); "
                                 f"no output was written.") from None
        self._entries[target] = (anchor, rel)
        return Path(path)

    def _new_staging(self, anchor: Path) -> Path:
        """A new staging directory in ``anchor``, known to :meth:`discard` before it exists: a ``SIGTERM`` that
        lands right after its creation (before ``tempfile.mkdtemp`` would have returned it) still has it removed."""
        for _ in range(100):
            staging = anchor / f"{_STAGING_PREFIX}{self.pid}-{secrets.token_hex(6)}.part"
            self._staging[anchor] = staging
            try:
                staging.mkdir(mode=0o700)  # as mkdtemp: no other user can put a file there
                return staging
            except FileExistsError:  # another directory's name: not ours to remove
                del self._staging[anchor]
            except OSError:
                del self._staging[anchor]
                raise
        raise FileExistsError(f"no free name for a staging directory in {anchor}")

    def discard(self) -> None:
        """Remove every staged file: nothing was written."""
        for staging in self._staging.values():
            shutil.rmtree(staging, ignore_errors=True)
        self._staging.clear()
        self._entries.clear()

    def commit(self) -> list[Path]:
        """Move every staged file to its target, all or none.

        Raises
        ------
        HyperstatError
            Naming the target that could not be replaced; the targets are then as before.
        """
        undo: list = []
        moved_dirs: set[tuple[Path, str]] = set()
        try:
            plan = []
            for target, (anchor, rel) in self._entries.items():
                top = rel.parts[0]
                if len(rel.parts) > 1:  # its folder did not exist: the new folder moves in whole
                    if (anchor, top) not in moved_dirs:
                        moved_dirs.add((anchor, top))
                        if (anchor / top).exists():
                            raise HyperstatError(f"{anchor / top}: appeared while the outputs were computed; "
                                                 f"no output was written.")
                        plan.append(("dir", anchor / top, self._staging[anchor] / "new" / top))
                    continue
                if target.exists() and (not target.is_file() or not os.access(target, os.W_OK)):
                    what = ("is a directory" if target.is_dir() else "is not a regular file" if not target.is_file()
                            else "cannot be replaced (read-only or immutable)")
                    raise HyperstatError(f"{target}: {what}; no output was written.")
                plan.append(("file", target, self._staging[anchor] / "new" / rel))
            for kind, target, staged in plan:
                try:
                    if kind == "file" and target.exists():
                        backup = Path(tempfile.mkdtemp(prefix="old", dir=staged.parent.parent)) / target.name
                        os.rename(target, backup)
                        undo.append((backup, target))
                    os.rename(staged, target)
                    undo.append((target, staged))
                except OSError as exc:
                    raise HyperstatError(f"{target}: cannot be replaced ({exc.strerror or exc.__class__.__name__}); "
                                         f"no output was written.") from None
            undo.clear()
            return list(self._entries)
        finally:
            for src, dst in reversed(undo):  # a failure: take the new files back, put the previous ones back
                with contextlib.suppress(OSError):
                    os.rename(src, dst)
            self.discard()


_ACTIVE: OutputSet | None = None


@contextlib.contextmanager
def all_or_nothing(files: Iterable = (), directories: Iterable = (), only_declared: bool = False) -> Iterator[OutputSet]:
    """Write every file of the block whole, together, at its end; or none of them.

    Inside an open set (the command line's), a nested block joins it: its files are moved in
    when the outer block ends.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with all_or_nothing():
    ...     _ = write_text(d / "a.txt", "a")
    ...     _ = write_text(d / "b.txt", "b")
    ...     print(sorted(p.name for p in d.iterdir() if not p.name.startswith(".")))
    []
    >>> sorted(p.name for p in d.iterdir())
    ['a.txt', 'b.txt']
    """
    global _ACTIVE
    if _ACTIVE is not None and _ACTIVE.pid == os.getpid():
        _ACTIVE.forced += 1
        try:
            yield _ACTIVE
        finally:
            _ACTIVE.forced -= 1
        return
    outputs = OutputSet(files, directories, only_declared)
    _ACTIVE = outputs
    try:
        yield outputs
    except BaseException:
        outputs.discard()
        raise
    finally:
        _ACTIVE = None
    outputs.commit()


def _probe(directory: Path, why: str) -> None:
    """Create and remove a file in ``directory``: the only sure test that it can be written."""
    try:
        fd, probe = tempfile.mkstemp(prefix=f"{_STAGING_PREFIX}probe-", dir=directory)
    except OSError as exc:
        raise HyperstatError(f"{directory}: the directory cannot be written ({exc.strerror}), so {why}.") from None
    os.close(fd)
    os.unlink(probe)


def check_writable(files: Iterable = (), directories: Iterable = ()) -> None:
    """Refuse, before any work, output locations that cannot be written.

    A file output must not be a directory, an existing one must be replaceable, and its
    folder (or the nearest existing one, when folders are to be created) must be writable;
    a directory output must not be a file, and it (or its nearest existing ancestor) must be
    writable.  Nothing is created: the check writes and removes one hidden probe file.

    Raises
    ------
    HyperstatError
        One sentence naming the location.
    """
    for f in files:
        f = _absolute(f)
        if f.is_dir():
            raise HyperstatError(f"{f}: is a directory; give a file name for this output.")
        if f.exists() and not f.is_file():
            raise HyperstatError(f"{f}: is not a regular file (a device or a pipe); give a file name for this output.")
        if f.exists() and not os.access(f, os.W_OK):
            raise HyperstatError(f"{f}: exists and cannot be replaced (read-only or immutable).")
        _probe(_anchor(f.parent), f"{f} cannot be written")
    for d in directories:
        d = _absolute(d)
        if d.exists() and not d.is_dir():
            raise HyperstatError(f"{d}: is a file; this output is a directory.")
        _probe(_anchor(d), f"no output can go to {d}")


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + ``os.replace``).

    The temporary file is ``.NAME.XXXX.part`` next to ``path``; it is removed if the
    write fails or the process is interrupted (``SIGINT``, or ``SIGTERM`` under the
    command line).  A ``SIGKILL`` cannot be caught: it may leave that hidden ``.part``
    file, never a partial ``path``; the next successful write of ``path`` removes it.
    Inside :func:`all_or_nothing`, the file is staged and written when the block ends.
    The environment variable ``HYPERSTAT_TEST_WRITE_DELAY`` (seconds) pauses half-way
    through each write, so that tests can kill a process in the middle of one.
    """
    if _ACTIVE is not None and _ACTIVE.covers(path):
        return _ACTIVE.stage(path, data)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    started = time.time()
    tmp = None
    try:
        # the temporary file's name is chosen before it is created, and removed below whatever interrupts this
        # block: a SIGTERM that lands right after the creation leaves no hidden file (tempfile.mkstemp would have)
        for _ in range(100):
            tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}.part"
            try:
                fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o600)
                break
            except FileExistsError:  # another file's name: not ours to remove
                tmp = None
        else:
            raise FileExistsError(f"no free name for a temporary file beside {path}")
        _write_file(fd, data)
        os.replace(tmp, path)
    except BaseException:
        if tmp is not None:
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
