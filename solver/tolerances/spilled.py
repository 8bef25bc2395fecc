"""Arrays of one row per sampled configuration kept in a temporary file and read a block at a time.

Units: those of the values stored (the sample: mm and rad).

``hyperstat accuracy`` over 1,000,000 draws keeps 684,861 configurations (82 MiB) and eight coefficients per
configuration (44 MiB), and the values stage two allocations' task-restricted coefficients (44 MiB more): the
command's peak memory grew with the count (issue 39: 280 MiB against 160 MiB at 100,000 draws).  A
:class:`SpilledArray` holds such an array in an unlinked temporary file (the operating system's page cache, not
the process' memory) and hands out copies of the rows asked for (``a[i:j]``, ``a[[i, j]]``, ``a[i]``); its
reductions (:meth:`SpilledArray.max`, :meth:`SpilledArray.min`, :meth:`SpilledArray.mean`) read it a block at a
time and give numpy's own bits (the mean by numpy's pairwise summation, replayed over the blocks).  What reads a
whole sample reads it through :func:`row_blocks`, which takes a plain array as well.

Examples
--------
>>> b = SpilledArray.empty((2,))
>>> b.append(np.arange(6.0).reshape(3, 2))
>>> b.append(np.array([[6.0, 7.0]]))
>>> len(b), b.shape, b[1].tolist(), b[[0, 3]].tolist(), b[1:3, 0].tolist(), b.max()
(4, (4, 2), [2.0, 3.0], [[0.0, 1.0], [6.0, 7.0]], [2.0, 4.0], 7.0)
>>> [(s, x.shape) for s, x in row_blocks(b, 3)]
[(0, (3, 2)), (3, (1, 2))]
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import threading

import numpy as np

__all__ = ["SpilledArray", "row_blocks", "take_rows", "pairwise_sum", "array_digest", "BLOCK"]

#: rows read at a time by the reductions and :func:`row_blocks` (a block of the Triflex-II's sample: 7.5 MiB)
BLOCK = 65536
#: numpy's pairwise summation: below this many elements a block is summed by eight accumulators (PW_BLOCKSIZE)
_PAIRWISE = 128


class SpilledArray:
    """A float64 array of ``rows`` rows of shape ``row_shape`` in an unlinked temporary file (see the module).

    Parameters
    ----------
    rows : int
        Number of rows (the file's length; rows never written read as zeros).
    row_shape : tuple
        Shape of a row: ``()`` for one value per configuration, ``(n_q,)`` for a sample.
    directory : str, optional
        Where the temporary file is made (default: :func:`tempfile.gettempdir`).

    Writes (``a[i:j] = x``, :meth:`append`) and reads may come from several threads: each is one positioned
    system call (``pwrite``/``preadv``) of its own rows.
    """

    def __init__(self, rows: int, row_shape: tuple = (), directory: str | None = None) -> None:
        self.row_shape = tuple(int(s) for s in row_shape)
        self._row_items = int(np.prod(self.row_shape)) if self.row_shape else 1
        self._row_bytes = 8 * self._row_items
        self._file = tempfile.TemporaryFile(dir=directory)
        self._fd = self._file.fileno()
        self._rows = int(rows)
        self._written = 0  # rows appended so far (append writes after them)
        self._lock = threading.Lock()
        os.ftruncate(self._fd, self._rows * self._row_bytes)

    @classmethod
    def empty(cls, row_shape: tuple = (), directory: str | None = None) -> "SpilledArray":
        """A file of no rows, grown by :meth:`append`."""
        return cls(0, row_shape, directory)

    # ------------------------------------------------------------------ shape
    def __len__(self) -> int:
        return self._rows

    @property
    def shape(self) -> tuple:
        return (self._rows,) + self.row_shape

    @property
    def ndim(self) -> int:
        return 1 + len(self.row_shape)

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(float)

    @property
    def nbytes(self) -> int:
        return self._rows * self._row_bytes

    @property
    def size(self) -> int:
        return self._rows * self._row_items

    # ------------------------------------------------------------------ writes
    def _write(self, start: int, values: np.ndarray) -> None:
        data = np.ascontiguousarray(values, dtype="<f8")
        view = memoryview(data.reshape(-1)).cast("B")
        offset, done = start * self._row_bytes, 0
        while done < len(view):
            done += os.pwrite(self._fd, view[done:], offset + done)

    def __setitem__(self, index, values) -> None:
        if not isinstance(index, slice):
            raise TypeError("a SpilledArray is written by row slices a[i:j] = rows")
        start, stop, step = index.indices(self._rows)
        if step != 1:
            raise TypeError("a SpilledArray is written by contiguous row slices")
        values = np.broadcast_to(np.asarray(values, dtype=float), (stop - start,) + self.row_shape)
        self._write(start, values)

    def append(self, rows: np.ndarray) -> None:
        """Write ``rows`` after the last row appended, growing the file when needed."""
        rows = np.asarray(rows, dtype=float).reshape((-1,) + self.row_shape)
        with self._lock:
            at = self._written
            self._written = at + len(rows)
            self._rows = max(self._rows, self._written)
        self._write(at, rows)

    def resize(self, rows: int) -> None:
        """``rows`` rows, the rows appended so far being those (what another process appended to this file)."""
        with self._lock:
            self._rows = self._written = int(rows)
            os.ftruncate(self._fd, self._rows * self._row_bytes)

    # ------------------------------------------------------------------ reads
    def _read(self, start: int, stop: int) -> np.ndarray:
        out = np.empty((max(stop - start, 0),) + self.row_shape)
        view = memoryview(out.reshape(-1)).cast("B")
        offset, done = start * self._row_bytes, 0
        while done < len(view):
            got = os.preadv(self._fd, [view[done:]], offset + done)
            if got <= 0:  # beyond the end of the file: rows never written are zeros
                view[done:] = bytes(len(view) - done)
                break
            done += got
        return out

    def __getitem__(self, index):
        if isinstance(index, tuple):  # a[rows, columns]: the rows, then numpy's indexing of them
            rows = self[index[0]]
            if isinstance(index[0], (int, np.integer)):
                return rows[index[1:]]
            return rows[(slice(None),) + index[1:]]
        if isinstance(index, slice):
            start, stop, step = index.indices(self._rows)
            if step == 1:
                return self._read(start, stop)
            return take_rows(self, np.arange(start, stop, step))
        if isinstance(index, (int, np.integer)):
            i = int(index)
            if i < 0:
                i += self._rows
            if not 0 <= i < self._rows:
                raise IndexError(f"row {index} of {self._rows}")
            return self._read(i, i + 1)[0]
        idx = np.asarray(index)
        if idx.dtype == bool:
            idx = np.nonzero(idx)[0]
        return take_rows(self, idx)

    def __array__(self, dtype=None, copy=None) -> np.ndarray:  # the whole array (a copy: for small ones only)
        out = self._read(0, self._rows)
        return out if dtype is None else out.astype(dtype)

    def copy(self) -> np.ndarray:
        """The whole array in memory."""
        return self._read(0, self._rows)

    # ------------------------------------------------------------------ reductions (numpy's bits)
    def max(self) -> float:
        """``numpy.max`` of every element (NaN if any is NaN)."""
        return _extreme(self, np.max)

    def min(self) -> float:
        """``numpy.min`` of every element (NaN if any is NaN)."""
        return _extreme(self, np.min)

    def sum(self) -> float:
        """``numpy.sum`` of a one-value-per-row array, bit for bit (numpy's pairwise summation over the blocks)."""
        if self.row_shape:
            raise TypeError("sum: one value per row only")
        return pairwise_sum(self)

    def mean(self) -> float:
        """``numpy.mean`` of a one-value-per-row array, bit for bit (its pairwise sum divided by the count)."""
        if not self._rows:
            return float("nan")
        return float(np.float64(pairwise_sum(self)) / self._rows)

    def __del__(self) -> None:
        try:
            self._file.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


def _extreme(a: SpilledArray, fn) -> float:
    if not len(a) or not a.size:
        raise ValueError("zero-size array to reduction operation which has no identity")
    best = None
    for _, block in row_blocks(a):
        v = fn(block)
        if np.isnan(v):
            return float("nan")
        best = v if best is None else fn(np.array([best, v]))
    return float(best)


def pairwise_sum(a) -> float:
    """``numpy.add.reduce`` of a one-dimensional float64 array, bit for bit, reading ``a`` a block at a time.

    numpy sums a contiguous float64 array pairwise: a part of more than 128 elements is split at
    ``n // 2`` rounded down to a multiple of 8 and the halves' sums added; the recursion is replayed
    here down to parts of at most :data:`BLOCK` elements, each summed by numpy itself (the same
    subtree of the same recursion).

    >>> x = np.random.default_rng(1).random(200_001) * 1e3
    >>> s = SpilledArray(len(x)); s[:] = x
    >>> pairwise_sum(s) == float(np.sum(x)), s.mean() == float(np.mean(x))
    (True, True)
    """
    def part(lo: int, n: int) -> np.float64:
        if n <= max(BLOCK, _PAIRWISE):  # numpy sums a part of at most 128 elements without splitting it
            return np.add.reduce(a[lo:lo + n])
        half = n // 2
        half -= half % 8
        return part(lo, half) + part(lo + half, n - half)

    return float(part(0, len(a)))


def row_blocks(a, size: int = BLOCK):
    """``(start, rows)`` of ``a`` (an ndarray or a :class:`SpilledArray`) ``size`` rows at a time."""
    for start in range(0, len(a), size):
        yield start, a[start:start + size]


def take_rows(a, index) -> np.ndarray:
    """The rows ``index`` of ``a`` (an ndarray or a :class:`SpilledArray`, read block by block), in that order."""
    idx = np.asarray(index, dtype=np.int64).reshape(-1)
    if isinstance(a, np.ndarray):
        return a[idx]
    n = len(a)
    if len(idx) and (idx.min() < -n or idx.max() >= n):
        raise IndexError(f"row index out of {n} rows")
    idx = np.where(idx < 0, idx + n, idx)
    out = np.empty((len(idx),) + a.row_shape)
    order = np.argsort(idx, kind="stable")
    sorted_idx = idx[order]
    at = 0
    while at < len(sorted_idx):  # the rows falling in one block of the file read at once
        lo = int(sorted_idx[at])
        hi = min(lo + BLOCK, n)
        end = int(np.searchsorted(sorted_idx, hi, side="left"))
        span = int(sorted_idx[end - 1]) + 1 - lo
        block = a[lo:lo + span] if span <= 64 or (end - at) * 64 >= span else None
        if block is not None:
            out[order[at:end]] = block[sorted_idx[at:end] - lo]
        else:  # a few rows far apart: one read each
            for k in range(at, end):
                out[order[k]] = a[int(sorted_idx[k])]
        at = end
    return out


def array_digest(a, header: bytes = b"") -> str:
    """SHA-256 of ``header`` and the little-endian bytes of ``a`` (an ndarray or a :class:`SpilledArray`, read
    block by block): the digest of the whole array's bytes, without them in memory at once."""
    h = hashlib.sha256(header)
    for _, block in row_blocks(a):
        data = np.ascontiguousarray(block, dtype=np.asarray(block).dtype.newbyteorder("<"))
        h.update(memoryview(data.reshape(-1)).cast("B"))
    return h.hexdigest()
