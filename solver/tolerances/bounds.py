"""Linear worst cases of a set of tolerances: the attainable one and the triangle bound, each named for what it is.

Units: mm (position rows) or rad (rotation rows).

With every tolerance ``i`` within ``+- v_i`` along its direction, the first-order task error at a
configuration is ``J (s o v)`` with ``J`` the task rows per unit of each tolerance and ``s`` in
``[-1, 1]^n``.  Two numbers are printed, and they must not be confused:

* the **attainable linear worst case** ``max_s |J (s o v)|``: the largest error some machine within
  its tolerances actually has (the maximum of a convex function over a box is at a corner, so ``s``
  is a sign pattern).  It is computed exactly for up to three task rows: the optimal sign pattern
  is ``sign(J^T u)`` for the direction ``u`` of the error, which is constant on the cells of the
  arrangement of the great circles ``u . J_i = 0``; every cell lies next to some circle, and a walk
  around each circle meets the cells next to it one sign flip at a time (:func:`attainable`; every
  sign pattern up to ten tolerances).  Parallel and coplanar columns are handled (an earlier
  enumeration of the cells around the circles' crossings missed patterns when columns were
  parallel, and read up to 17 % low on such test matrices);
* the **triangle bound** ``sum_i |J_i| v_i``: every tolerance at its extreme *and* every error
  pointing the same way, which no machine need reach (the Triflex-II: 0.0128 mm against an
  attainable 0.0091 mm for a 0.01 mm spec).

Both are maximised over the workspace by the one worst-case engine
(:func:`hyperstat.solver.tolerances.worst_case.search_extremes`) through :class:`LinearWorstCase`.
"""

from __future__ import annotations

import itertools

import numpy as np

from hyperstat.solver.tolerances.worst_case import Objective

__all__ = ["attainable", "triangle", "LinearWorstCase"]


def triangle(a: np.ndarray) -> np.ndarray:
    """``sum_i |a_i|`` for the columns of each (r, n) matrix of a stack (K, r, n)."""
    return np.sum(np.linalg.norm(a, axis=1), axis=1)


#: configurations per block of :meth:`LinearWorstCase.values` (the same values whatever the block)
VALUES_BLOCK = 16384
#: floats of one block of the sign-pattern enumeration (8 MiB; the same maxima whatever the block)
PATTERN_BLOCK = 1 << 20


#: entries (matrices x circles x crossings) of one block of the circle walk: its temporaries stay in a core's L2 cache
#: (2 MiB here).  Measured on the half-circle walk (issue 39), random normal matrices: 5-12 matrices of 48-72
#: tolerances per block took 0.22 s and 0.50 s per 2,000 matrices, 16 and 10 (37,000-52,000 entries) 0.32 s and 0.72 s
WALK_BLOCK = 27648


def attainable(a: np.ndarray, chunk: int | None = None) -> np.ndarray:
    """``max_{s in {-1, 1}^n} |a s|`` for each (r, n) matrix of a stack (K, r, n), exactly for r <= 3.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.array([[[1.0, 1.0, 0.0], [0.0, 1.0, 1.0]]])
    >>> round(float(attainable(a)[0]), 12), round(float(triangle(a)[0]), 12)  # (2, 2) by s = (1, 1, 1)
    (2.828427124746, 3.414213562373)
    """
    a = np.asarray(a, dtype=float)
    k, r, n = a.shape
    if n == 0 or r == 0 or k == 0:
        return np.zeros(k)
    if r == 1:
        return np.sum(np.abs(a[:, 0]), axis=1)
    if n <= 10 or r > 3:  # every sign pattern (r > 3 does not occur: at most three task rows of one kind)
        # s and -s give the same |a s|: the patterns whose first sign is + are enough (half the work; issue 39)
        signs = np.array([(1.0,) + rest for rest in itertools.product((-1.0, 1.0), repeat=n - 1)])
        step = max(1, PATTERN_BLOCK // (r * len(signs)))  # configurations per block: memory (K r 2^n floats)
        return np.concatenate([np.max(np.linalg.norm(a[i:i + step] @ signs.T, axis=1), axis=1)
                               for i in range(0, k, step)])
    if r == 2:  # a flat zonotope in three dimensions: the same walk
        a = np.concatenate([a, np.zeros((k, 1, n))], axis=1)
    out = np.zeros(k)
    if chunk is None:  # the same values whatever the block (each matrix is walked alone)
        chunk = int(min(64, max(1, WALK_BLOCK // (n * n))))
    for start in range(0, k, chunk):
        out[start:start + chunk] = _walk_circles(a[start:start + chunk])
    return out


def _walk_circles(blk: np.ndarray) -> np.ndarray:
    """``max_s |a s|`` for a stack (B, 3, n), walking around half of the great circle ``u . a_i = 0`` of every column.

    Along the circle of column ``i`` (``u = e1 cos t + e2 sin t``) the sign of ``u . a_k`` flips at two
    antipodal angles per column ``k``; between consecutive crossings the pattern is that of a cell of the
    arrangement next to the circle, with ``s_i = +-1`` on its two sides, and every cell lies next to some
    circle.  Half a turn is enough: at ``t + pi`` every sign is flipped (``u -> -u``), and ``|a (-s)| = |a s|``;
    on ``[0, pi)`` each column flips exactly once, so a circle's patterns are built by one sort and one cumulative
    sum of ``n`` steps (``O(n^2 log n)`` per matrix, half the steps of a whole turn; issue 39).  Columns parallel to
    ``a_i`` (within 1e-12 of the largest column: ``a_i`` itself, exact copies, columns below the round-off) take
    ``s_i`` times the sign of their projection on ``a_i``.  Simultaneous crossings (coplanar columns) are taken one
    at a time: the patterns in between are sign patterns too, so the maximum is never above the true one.

    The two sides ``w +- g`` of the circle (``g``: the parallel columns with their signs) are compared through
    ``|w +- g|^2 = |w|^2 + |g|^2 +- 2 w . g``, whose larger is ``|w|^2 + |g|^2 + 2 |w . g|`` (a sum of
    non-negative terms: no cancellation), summed one component at a time along the contiguous last axis; one square
    root of the largest.  The maxima agree with a whole turn's stacked walk to a few units of the last place
    (tested): the same patterns, their sums in another order.
    """
    b_, _, n = blk.shape
    # each matrix scaled by the power of two just above its largest entry (exact: the same bits once scaled back),
    # so that the squared lengths below neither underflow nor overflow whatever the unit
    big = np.max(np.abs(blk), axis=(1, 2))
    power = np.ldexp(1.0, np.frexp(np.where(big > 0, big, 1.0))[1])[:, None, None]
    blk = blk / power
    cols = np.swapaxes(blk, 1, 2)  # (B, n, 3)
    norm = np.linalg.norm(cols, axis=2)
    scale = np.maximum(norm.max(axis=1), 1e-300)
    unit = cols / np.maximum(norm, 1e-300)[..., None]
    e1 = np.cross(unit, np.eye(3)[np.argmin(np.abs(unit), axis=2)])  # the axis least aligned: a regular cross product
    e1 /= np.maximum(np.linalg.norm(e1, axis=2), 1e-300)[..., None]
    e2 = np.cross(unit, e1)
    c, d = e1 @ blk, e2 @ blk  # (B, n_i, n_k): u(t) . a_k = c cos t + d sin t
    tied = _within(c, d, 1e-12 * scale)
    group = np.where(tied, np.sign(unit @ blk), 0.0) @ cols  # the tied columns with their signs, (B, n_i, 3)
    # the crossing of column k in [0, pi] is at pi/2 + the angle of +-(c, d) taken with c >= 0; the sign just before
    # it (the start of the half turn) is + for c >= 0 (it turns negative there) and - for c < 0
    negative = c < 0
    crossing = np.arctan2(np.where(negative, -d, d), np.abs(c))  # in [-pi/2, pi/2]: the order of the crossings
    before = np.where(tied, 0.0, np.where(negative, -1.0, 1.0))
    order = np.argsort(crossing, axis=2)  # (B, n_i, n)
    steps = np.take_along_axis(before, order, axis=2)
    steps *= -2.0
    # the column crossed at each step, as a row of the (B n, 3) columns: one plain gather per component
    which = order + (n * np.arange(b_))[:, None, None]
    comp = np.ascontiguousarray(cols.reshape(b_ * n, 3).T)  # (3, B n)
    start = before @ cols  # (B, n_i, 3): the pattern before the first crossing
    squares = dots = None  # |w|^2 and w . g of every arc, (B, n_i, n)
    for x in range(3):
        w = np.cumsum(steps * comp[x][which], axis=2)  # the pattern of every arc, component x
        w += start[:, :, x, None]
        wg = w * group[:, :, x, None]
        w *= w
        if squares is None:
            squares, dots = w, wg
        else:
            squares += w
            dots += wg
    np.abs(dots, out=dots)
    dots *= 2.0
    squares += dots
    squares += np.einsum("bix,bix->bi", group, group)[:, :, None]
    return np.sqrt(squares.max(axis=(1, 2))) * power[:, 0, 0]


def _within(c: np.ndarray, d: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """``numpy.hypot(c, d) <= radius[:, None, None]`` for (B, m, n) stacks, decided from ``c^2 + d^2`` where that is
    clear by far (a margin of 1e-9 against the round-off of a few units in 1e-16 of the squares) and by ``hypot`` itself
    elsewhere, and wherever the squares could underflow: the same booleans, without ``hypot`` on every entry.

    >>> c = np.array([[[3.0, 1e-13, 3e-12]]]); d = np.array([[[4.0, 0.0, 4e-12]]])
    >>> _within(c, d, np.array([5e-12])).tolist(), (np.hypot(c, d) <= 5e-12).tolist()
    ([[[False, True, True]]], [[[False, True, True]]])
    """
    r = radius[:, None, None]
    r2 = r * r
    sq = c * c + d * d
    tied = sq < r2 * (1.0 - 1e-9)
    unsure = ~(tied | (sq > r2 * (1.0 + 1e-9))) | (r2 < 1e-280) | (r2 > 1e280)
    if unsure.any():
        tied[unsure] = np.hypot(c[unsure], d[unsure]) <= np.broadcast_to(r, c.shape)[unsure]
    return tied


class LinearWorstCase(Objective):
    """The attainable linear worst case and the triangle bound of tolerances at their values, per configuration.

    Parameters
    ----------
    kin : Kinematics
    rows : callable
        ``rows(q) -> (K, r, n)``: the task rows (one kind: position in mm or rotation in rad) per unit of
        each tolerance at configurations ``q``.
    values : ndarray, (n,)
        The tolerances' values.
    """

    names = ("attainable", "triangle")

    def __init__(self, rows, values: np.ndarray) -> None:
        self.rows, self.values_ = rows, np.asarray(values, dtype=float)

    def values(self, q: np.ndarray) -> dict:
        q = np.atleast_2d(q)
        out = {"attainable": np.empty(len(q)), "triangle": np.empty(len(q))}
        for start in range(0, len(q), VALUES_BLOCK):  # a whole sample's rows at once held 300 MiB at 700,000
            a = self.rows(q[start:start + VALUES_BLOCK]) * self.values_[None, None, :]
            out["attainable"][start:start + VALUES_BLOCK] = attainable(a)
            out["triangle"][start:start + VALUES_BLOCK] = triangle(a)
        return out

    def pick(self, q: np.ndarray, which: list) -> np.ndarray:
        """Each configuration's own function only: the search's paths of the triangle bound do not pay for the
        sign-pattern walk of the attainable worst case (each matrix's value is computed alone: the same numbers as
        :meth:`values`)."""
        q = np.atleast_2d(q)
        out = np.empty(len(q))
        want = np.array([w == "attainable" for w in which], dtype=bool)
        for start in range(0, len(q), VALUES_BLOCK):
            sl = slice(start, start + VALUES_BLOCK)
            a = self.rows(q[sl]) * self.values_[None, None, :]
            w = want[sl]
            block = np.empty(len(a))
            if w.any():
                block[w] = attainable(a[w])
            if (~w).any():
                block[~w] = triangle(a[~w])
            out[sl] = block
        return out
