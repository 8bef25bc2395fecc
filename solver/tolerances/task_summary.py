"""What the tolerance values need of the task rows over a workspace sample, reduced block by block.

Units: task rotation rows in rad and position rows in mm per unit of each tolerance direction (rad or
mm); the coefficients are their largest singular values (rad/mm, rad/rad, mm/mm, mm/rad).

The values stage (:func:`hyperstat.solver.tolerances.values.assign_values`) reads the task rows of
the accuracy-critical and compensable directions at every sampled configuration, ``(K, r, n)``
(:func:`hyperstat.solver.tolerances.values.task_maps`), for four things only:

* the task-restricted coefficients of each allocation (paper 2, eq. 18 on the task rows: the
  largest singular value of the rotation and position rows of the length and of the angle
  directions), one value per configuration, from which the worst-case searches start;
* whether a direction moves the task at all (the second-order share of the calibrated budget);
* the first-order variance of each direction over the sample (the contributions): the mean over
  the configurations of the squared task rows summed over the rows.

:class:`TaskAccumulator` computes these from one block of rows at a time, so the ``(K, r, n)``
rows of a whole sample are never held (issue 39: 216 bytes per configuration of the Triflex-II,
147 MiB at 683,000 configurations); what is kept per configuration is one number per coefficient
and allocation.  The coefficients are the same bits as from the whole rows (each configuration's
singular values are computed alone); the variance is a sum over blocks instead of one
``numpy.mean``, which differs by round-off (1e-16 relative).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TaskSummary", "TaskAccumulator", "sigma_max", "task_coefficients", "value_columns"]


def sigma_max(block: np.ndarray) -> np.ndarray:
    """Largest singular value of each matrix of a stack (K, r, c); 0 for an empty matrix.

    >>> float(sigma_max(np.array([[[3.0, 0.0], [0.0, 4.0]]]))[0])
    4.0
    """
    if block.shape[1] == 0 or block.shape[2] == 0:
        return np.zeros(block.shape[0])
    return np.linalg.svd(block, compute_uv=False)[:, 0]


def task_coefficients(rot: np.ndarray, pos: np.ndarray, is_length: np.ndarray) -> dict:
    """``delta_gP, epsilon_gP, delta_gR, epsilon_gR`` (eq. 18 on the task rows) at each configuration, (K,) each.

    ``rot`` and ``pos``: task rotation (rad) and position (mm) rows per unit of each direction, (K, r, n);
    ``is_length``: which directions are lengths (the others angles).
    """
    out = {}
    for kind, cols in (("P", is_length), ("R", ~is_length)):
        out[f"delta_g{kind}"] = sigma_max(rot[:, :, cols])
        out[f"epsilon_g{kind}"] = sigma_max(pos[:, :, cols])
    return out


def value_columns(influential: list) -> tuple[np.ndarray, list]:
    """The directions' kinds and the allocations' columns of the tolerances with a value from accuracy.

    ``influential``: the accuracy-critical and compensable tolerances in the order of their
    directions.  Returns ``is_length`` (n,) and the two column sets the values stage allocates
    over: the accuracy-critical ones (calibrated) and all of them (uncalibrated).
    """
    is_length = np.array([t.unit == "mm" for t in influential], dtype=bool)
    critical = np.array([t.cls == "accuracy-critical" for t in influential], dtype=bool)
    return is_length, [critical, np.ones(len(influential), dtype=bool)]


@dataclass
class TaskSummary:
    """The reductions of the task rows over a sample (see the module docstring).

    Attributes
    ----------
    configurations : int
        K, the number of configurations reduced.
    n_rot, n_pos : int
        Number of task rotation and position rows.
    directions : int
        n, the number of tolerance directions.
    is_length : ndarray of bool, (n,)
    coefficients : dict
        Column set (a tuple of bool, see :meth:`of`) -> {coefficient name: (K,) values}.
    moves_rotation, moves_position : ndarray of bool, (n,)
        Whether the direction has a nonzero task rotation (position) row at some configuration.
    square_sums : ndarray, (n,)
        Sum over the configurations of the squared task rows of each direction, summed over the position
        rows when there are any, else over the rotation rows (mm^2 or rad^2 per unit^2).
    """

    configurations: int
    n_rot: int
    n_pos: int
    directions: int
    is_length: np.ndarray
    coefficients: dict
    moves_rotation: np.ndarray
    moves_position: np.ndarray
    square_sums: np.ndarray

    def of(self, cols: np.ndarray) -> dict:
        """The per-configuration coefficients of the column set ``cols`` (bool, (n,))."""
        key = tuple(bool(c) for c in cols)
        if key not in self.coefficients:
            raise ValueError("task_maps_at: the summary holds no coefficients of these columns "
                             f"({sum(key)} of {len(key)}).")
        return self.coefficients[key]

    def as_tuple(self) -> tuple:
        """Every field as plain values and arrays (what the cache of results keys on)."""
        coefficients = [(list(key), [values[name] for name in sorted(values)])
                        for key, values in sorted(self.coefficients.items())]
        return (self.configurations, self.n_rot, self.n_pos, self.directions, self.is_length, coefficients,
                self.moves_rotation, self.moves_position, self.square_sums)

    def mean_squares(self) -> np.ndarray:
        """Mean over the configurations of the squared task rows of each direction (see ``square_sums``)."""
        return self.square_sums / max(self.configurations, 1)


class TaskAccumulator:
    """Reduces task rows block by block into a :class:`TaskSummary`.

    Parameters
    ----------
    configurations : int
        K, the total number of configurations (the per-configuration coefficients are written in place).
    n_rot, n_pos : int
        Task rotation rows (the first ``n_rot`` of the ``r`` rows) and position rows (the others).
    is_length : ndarray of bool, (n,)
    column_sets : list of ndarray of bool
        The allocations' column sets (:func:`value_columns`).
    spill : bool
        Keep the per-configuration coefficients in temporary files
        (:class:`~hyperstat.solver.tolerances.spilled.SpilledArray`) instead of memory.

    :meth:`add` may run on several threads at once: each call writes its own rows of the
    coefficients and returns its block's partial sums, which :meth:`finish` adds in block order
    (the result does not depend on the threads).

    Examples
    --------
    >>> rows = np.arange(24.0).reshape(2, 3, 4)  # 2 configurations, 1 rotation + 2 position rows, 4 directions
    >>> acc = TaskAccumulator(2, 1, 2, np.array([True, True, False, False]), [np.ones(4, dtype=bool)])
    >>> parts = {0: acc.add(0, rows[:1]), 1: acc.add(1, rows[1:])}
    >>> s = acc.finish(parts)
    >>> bool(np.allclose(s.square_sums, (rows[:, 1:] ** 2).sum(axis=(0, 1))))
    True
    """

    def __init__(self, configurations: int, n_rot: int, n_pos: int, is_length: np.ndarray,
                 column_sets: list, spill: bool = False) -> None:
        self.k, self.n_rot, self.n_pos = int(configurations), int(n_rot), int(n_pos)
        self.is_length = np.asarray(is_length, dtype=bool)
        self.sets = {tuple(bool(c) for c in cols): np.asarray(cols, dtype=bool) for cols in column_sets if np.any(cols)}
        if spill:  # per-configuration coefficients in temporary files (issue 39: memory independent of the count)
            from hyperstat.solver.tolerances.spilled import SpilledArray

            def zeros():
                return SpilledArray(self.k)
        else:
            def zeros():
                return np.zeros(self.k)
        self.coefficients = {key: {name: zeros() for name in ("delta_gP", "epsilon_gP", "delta_gR",
                                                               "epsilon_gR")} for key in self.sets}

    def add(self, start: int, rows: np.ndarray) -> tuple:
        """Reduce the task rows (k, r, n) of configurations ``start .. start + k``; returns the block's partial sums."""
        rot, pos = rows[:, :self.n_rot], rows[:, self.n_rot:]
        sl = slice(start, start + len(rows))
        for key, cols in self.sets.items():
            for name, values in task_coefficients(rot[:, :, cols], pos[:, :, cols], self.is_length[cols]).items():
                self.coefficients[key][name][sl] = values
        variance_rows = pos if pos.shape[1] else rot
        return (np.any(rot != 0, axis=(0, 1)), np.any(pos != 0, axis=(0, 1)),
                np.sum(np.sum(variance_rows**2, axis=1), axis=0))

    def finish(self, parts: dict) -> TaskSummary:
        """The summary from the partial sums of every block (``{start: add(...)}``), added in block order."""
        n = len(self.is_length)
        moves_r, moves_p, sums = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n)
        for start in sorted(parts):
            r, p, s = parts[start]
            moves_r |= r
            moves_p |= p
            sums = sums + s
        return TaskSummary(self.k, self.n_rot, self.n_pos, n, self.is_length,
                           self.coefficients, moves_r, moves_p, sums)
