"""On-disk cache of a model's expensive results: computed once per model, inputs, options and version.

Units: none (the results keep their own: mm, rad).

A user who runs ``hyperstat report``, then ``hyperstat export-controller``, then opens the
FreeCAD workbench on the same model waits for the same workspace sample, tolerance values and
diagnosis three times.  This module stores such results in a folder (default
``~/.cache/hyperstat``, or ``$XDG_CACHE_HOME/hyperstat``; ``HYPERSTAT_CACHE`` names another
one, ``HYPERSTAT_CACHE=off`` or a command's ``--no-cache`` turns it off) under a **key** that is
the SHA-256 of everything the result depends on (:func:`key`):

* the inputs: the model (its canonical model-file text, and the bytes of the file it came from),
  the data files (their bytes), the configurations the stage starts from;
* the options the stage reads (spec, seed, sample size, workspace ranges, flags);
* the **version** (:func:`code_version`): hyperstat's version, the SHA-256 of the ``solver``
  package's sources (a changed line of the solver is a new version, installed or not) and the
  versions of numpy and scipy.

A stale result is a confident wrong answer, so an entry is used only when it is whole and its
own: each entry holds the key it was stored under, the stage's name, the format version and
the SHA-256 of its payload, and anything that does not match (a corrupted, truncated, foreign
or older entry, a file that does not parse) is ignored, recomputed and overwritten.  Entries
are written atomically (a temporary file in the cache folder, then a rename), never through
the command's output set, and a cache that cannot be written (read-only, full) only costs the
time.  Nothing is ever unpickled: the payload is JSON, numpy arrays inside it as their raw
little-endian bytes (base64) with dtype and shape (:func:`encode`, :func:`decode`), so a
stored float comes back bit for bit.  Removing the folder (or any file in it) is always safe.

Examples
--------
>>> import tempfile
>>> store = Cache(tempfile.mkdtemp())
>>> k = key("demo", {"seed": 0})
>>> store.load("demo", k) is None
True
>>> store.store("demo", k, {"x": np.arange(3.0)})
True
>>> store.load("demo", k)["x"].tolist()
[0.0, 1.0, 2.0]
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import json
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Cache", "key", "encode", "decode", "file_digest", "code_version", "default_directory", "CACHE_ENV",
           "FORMAT"]

#: environment variable naming the cache folder (``off``, ``0`` or ``none``: no cache)
CACHE_ENV = "HYPERSTAT_CACHE"
#: format of an entry; an entry of another format is ignored
FORMAT = "hyperstat-cache-1"
_OFF = {"off", "0", "none", "no", "false"}
#: longest wait (s) for another process computing the same entry (:meth:`Cache.computing`); then computed anyway
LOCK_WAIT_S = 1800.0


def default_directory() -> Path | None:
    """The cache folder: ``$HYPERSTAT_CACHE``, else ``$XDG_CACHE_HOME/hyperstat``, else ``~/.cache/hyperstat``.

    ``None`` when ``HYPERSTAT_CACHE`` turns the cache off.
    """
    env = os.environ.get(CACHE_ENV)
    if env is not None and env.strip():
        return None if env.strip().lower() in _OFF else Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "hyperstat"


_VERSION: str | None = None


def code_version() -> str:
    """hyperstat's version, the SHA-256 of the solver's sources and the numerical libraries' versions (memoised).

    Every result of the solver depends on its code: hashing the sources themselves (about 1 MB,
    a few milliseconds) makes an edited checkout a new version, whatever its version number says.
    """
    global _VERSION
    if _VERSION is None:
        from importlib.metadata import PackageNotFoundError, version

        def installed(name: str) -> str:
            try:
                return version(name)
            except PackageNotFoundError:  # pragma: no cover - a source tree never installed
                return "0+unknown"

        h = hashlib.sha256()
        root = Path(__file__).resolve().parent
        for path in sorted(root.rglob("*.py")):
            h.update(path.relative_to(root).as_posix().encode())
            h.update(b"\0")
            h.update(path.read_bytes())
            h.update(b"\0")
        _VERSION = f"{installed('hyperstat')}+{h.hexdigest()[:32]}/numpy-{np.__version__}/scipy-{installed('scipy')}"
    return _VERSION


def file_digest(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------- the payload
def encode(value: Any) -> Any:
    """JSON-ready form of ``value`` that :func:`decode` turns back into an equal value, bit for bit.

    Handles ``None``, bool, int, float (``nan`` and infinities included), str, lists, tuples, dicts
    (any keys of those kinds), numpy arrays and numpy scalars.  Anything else raises
    :class:`TypeError`: such a result is not cached.

    >>> decode(json.loads(json.dumps(encode({"a": (1, 2.5), 3: float("nan")}))))
    {'a': (1, 2.5), 3: nan}
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, np.bool_):
        return int(value) if isinstance(value, np.integer) else value
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else {"$float": repr(v)}
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            raise TypeError(f"an array of {value.dtype} is not cached")
        data = np.ascontiguousarray(value.astype(value.dtype.newbyteorder("<"), copy=False))
        return {"$array": base64.b64encode(data.tobytes()).decode("ascii"), "dtype": data.dtype.str,
                "shape": list(value.shape)}
    if isinstance(value, tuple):
        return {"$tuple": [encode(v) for v in value]}
    if isinstance(value, list):
        return [encode(v) for v in value]
    if isinstance(value, dict):
        if all(isinstance(k, str) and not k.startswith("$") for k in value):
            return {k: encode(v) for k, v in value.items()}
        return {"$dict": [[encode(k), encode(v)] for k, v in value.items()]}
    raise TypeError(f"a {type(value).__name__} is not cached")


def decode(doc: Any) -> Any:
    """The value :func:`encode` made ``doc`` from."""
    if isinstance(doc, list):
        return [decode(v) for v in doc]
    if not isinstance(doc, dict):
        return doc
    if "$array" in doc:
        dtype = np.dtype(doc["dtype"])
        if dtype.kind not in "biuf":
            raise ValueError("not an array of numbers")
        raw = base64.b64decode(doc["$array"].encode("ascii"), validate=True)
        return np.frombuffer(raw, dtype=dtype).reshape(doc["shape"]).astype(dtype.newbyteorder("="))
    if "$float" in doc:
        return float(doc["$float"])
    if "$tuple" in doc:
        return tuple(decode(v) for v in doc["$tuple"])
    if "$dict" in doc:
        return {_hashable(decode(k)): decode(v) for k, v in doc["$dict"]}
    return {k: decode(v) for k, v in doc.items()}


def _hashable(k: Any) -> Any:
    return tuple(_hashable(v) for v in k) if isinstance(k, (list, tuple)) else k


def key(stage: str, *parts: Any) -> str:
    """SHA-256 (hex) of a stage's name, :func:`code_version` and ``parts`` (anything :func:`encode` takes).

    Arrays enter by their bytes, dtype and shape; dicts in their order (build them in a fixed
    order).
    """
    h = hashlib.sha256()
    h.update(json.dumps([FORMAT, stage, code_version(), encode(list(parts))], sort_keys=False,
                        separators=(",", ":"), allow_nan=False).encode())
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------- the store
class Cache:
    """Entries of the cache folder ``directory``, or a cache that keeps nothing (``directory=None``).

    Parameters
    ----------
    directory : path-like or None
        The folder (created on the first store); ``None``: every :meth:`load` misses and
        :meth:`store` keeps nothing (``--no-cache``).

    Attributes
    ----------
    hits, misses : list of str
        The stages found and not found, in order (what the command says it reused).
    """

    def __init__(self, directory: str | os.PathLike | None) -> None:
        self.directory = None if directory is None else Path(directory)
        self.hits: list[str] = []
        self.misses: list[str] = []

    @property
    def enabled(self) -> bool:
        return self.directory is not None

    def _path(self, stage: str, k: str) -> Path:
        assert self.directory is not None
        return self.directory / stage / k[:2] / f"{k}.json"

    def load(self, stage: str, k: str) -> Any | None:
        """The value stored under ``k`` for ``stage``, or ``None`` (absent, unreadable, corrupted or foreign)."""
        if self.directory is None:
            return None
        try:
            text = self._path(stage, k).read_text(encoding="utf-8")
            header, _, payload = text.partition("\n")
            head = json.loads(header)
            if (not isinstance(head, dict) or head.get("format") != FORMAT or head.get("stage") != stage
                    or head.get("key") != k or head.get("sha256") != hashlib.sha256(payload.encode()).hexdigest()):
                raise ValueError("not this entry")
            value = decode(json.loads(payload))
        except (OSError, ValueError, TypeError, KeyError, UnicodeDecodeError):
            self.misses.append(stage)
            return None
        self.hits.append(stage)
        return value

    @contextlib.contextmanager
    def computing(self, stage: str, k: str):
        """Held while this process computes the entry ``k`` of ``stage``: another process that computes the same
        entry at the same time waits here, then finds it stored (:meth:`load` again inside), instead of computing
        it a second time (two commands on one model at once: FreeCAD's Analyse and a report, a test session's
        workers).  An exclusive ``flock`` on ``KEY.lock`` beside the entry, released when the block ends or the
        process dies; no lock (and no wait) when the folder cannot be written or the platform has no ``flock``.
        After :data:`LOCK_WAIT_S` the caller computes anyway: a lock only ever saves time, never changes a result.
        """
        fd = None
        try:
            import fcntl

            if self.directory is not None:
                path = self._path(stage, k).with_suffix(".lock")
                path.parent.mkdir(parents=True, exist_ok=True)
                fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
                deadline = time.monotonic() + LOCK_WAIT_S
                while True:
                    try:
                        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                        break
                    except BlockingIOError:
                        if time.monotonic() > deadline:
                            os.close(fd)
                            fd = None
                            break
                        time.sleep(0.2)
        except (ImportError, OSError):
            if fd is not None:
                os.close(fd)
            fd = None
        try:
            yield
        finally:
            if fd is not None:
                os.close(fd)  # releases the flock

    def store(self, stage: str, k: str, value: Any) -> bool:
        """Store ``value`` under ``k`` (atomically); False when it cannot be encoded or written."""
        if self.directory is None:
            return False
        try:
            payload = json.dumps(encode(value), separators=(",", ":"))
        except (TypeError, ValueError):
            return False
        header = json.dumps({"format": FORMAT, "stage": stage, "key": k,
                             "sha256": hashlib.sha256(payload.encode()).hexdigest()})
        path = self._path(stage, k)
        tmp = None
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".json", dir=path.parent)
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(header + "\n" + payload)
            os.replace(tmp, path)
            tmp = None
        except OSError:
            return False
        finally:
            if tmp is not None:
                try:
                    os.unlink(tmp)
                except OSError:
                    pass
        return True
