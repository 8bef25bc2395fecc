"""Linear worst cases of a set of tolerances: the attainable one and the triangle bound, each named for what it is.

Units: mm (position rows) or rad (rotation rows).

With every tolerance ``i`` within ``+- v_i`` along its direction, the first-order task error at a
configuration is ``J (s o v)`` with ``J`` the task rows per unit of each tolerance and ``s`` in
``[-1, 1]^n``.  Two numbers are printed, and they must not be confused:

* the **attainable linear worst case** ``max_s |J (s o v)|``: the largest error some machine within
  its tolerances actually has (the maximum of a convex function over a box is at a corner, so ``s``
  is a sign pattern).  It is computed exactly for up to three task rows: the optimal sign pattern
  is ``sign(J^T u)`` for the direction ``u`` of the error, which is constant on the cells of the
  arrangement of the planes ``u . J_i = 0``; every cell touches a vertex ``+-(J_i x J_j)``
  (three rows; ``+-J_i`` rotated a right angle for two), and the four patterns around each vertex
  cover the cells (:func:`attainable`);
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


def attainable(a: np.ndarray, chunk: int = 64) -> np.ndarray:
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
    if n == 0 or r == 0:
        return np.zeros(k)
    if r == 1:
        return np.sum(np.abs(a[:, 0]), axis=1)
    if n <= 10 or r > 3:  # every sign pattern (r > 3 does not occur: at most three task rows of one kind)
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=n)))
        return np.max(np.linalg.norm(a @ signs.T, axis=1), axis=1)
    out = np.zeros(k)
    if r == 2:  # a vertex is orthogonal to one column: the pattern around it leaves that column's sign free
        first, second = np.arange(n), None
    else:  # a vertex is orthogonal to two columns: both signs free
        first, second = np.triu_indices(n, 1)
    cols = np.arange(len(first))
    choices = [(si, sj) for si in (-1.0, 1.0) for sj in ((-1.0, 1.0) if second is not None else (0.0,))]
    for start in range(0, k, chunk):
        blk = a[start:start + chunk]  # (B, r, n)
        if r == 2:
            us = np.stack([-blk[:, 1, first], blk[:, 0, first]], axis=1)  # (B, 2, P)
        else:
            us = np.cross(blk[:, :, first], blk[:, :, second], axis=1)  # (B, 3, P)
        best = np.zeros(len(blk))
        signs = np.sign(np.einsum("brp,brn->bpn", us, blk))  # (B, P, n): the pattern at each vertex (one side)
        for flip in (1.0, -1.0):  # the vertex and its opposite
            for si, sj in choices:
                pattern = flip * signs
                pattern[:, cols, first] = si
                if second is not None:
                    pattern[:, cols, second] = sj
                norms = np.linalg.norm(np.einsum("brn,bpn->bpr", blk, pattern), axis=2)
                best = np.maximum(best, norms.max(axis=1))
        out[start:start + chunk] = best
    return out


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
        a = self.rows(np.atleast_2d(q)) * self.values_[None, None, :]
        return {"attainable": attainable(a), "triangle": triangle(a)}
