"""Arrays kept in a temporary file and read a block at a time (issue 39: ``accuracy``'s memory independent of the
count): the same numbers as the arrays in memory.  The sampler, the maps and the searches on a spilled Triflex-II
sample are tested in ``test_task_summary.py`` (its fixture).

Units: mm and rad.  Expected values come from the whole-array path (numpy on the array in memory, the sampler,
the maps and the searches given the sample in memory), computed here; no timing is asserted.
"""

from __future__ import annotations

import numpy as np
import pytest

from hyperstat.solver.tolerances import spilled, worst_case
from hyperstat.solver.tolerances.spilled import SpilledArray, pairwise_sum, take_rows


def _spilled(a: np.ndarray) -> SpilledArray:
    s = SpilledArray(len(a), a.shape[1:])
    s[:] = a
    return s


def test_the_reductions_are_numpys_bit_for_bit(monkeypatch):
    monkeypatch.setattr(spilled, "BLOCK", 200)  # many blocks, and parts below numpy's 128 (not split by numpy)
    rng = np.random.default_rng(7)
    for n in (1, 7, 8, 127, 128, 129, 200, 201, 1000, 4099):
        x = rng.random(n) * rng.choice([1.0, 1e-4, 1e6], n) - 0.3
        s = _spilled(x)
        assert pairwise_sum(s) == float(np.sum(x)), n  # numpy's pairwise summation replayed over the blocks
        assert s.mean() == float(np.mean(x)) and s.max() == float(x.max()) and s.min() == float(x.min()), n
        idx = rng.integers(-n, n, 37)
        np.testing.assert_array_equal(take_rows(s, idx), x[idx])
    x[5] = np.nan
    assert np.isnan(_spilled(x).max()) and np.isnan(_spilled(x).min())
    rows = rng.random((1000, 15))
    s = _spilled(rows)
    np.testing.assert_array_equal(s[3:977], rows[3:977])
    np.testing.assert_array_equal(s[[999, 0, 500, 500]], rows[[999, 0, 500, 500]])
    np.testing.assert_array_equal(s[10:20, [2, 4]], rows[10:20, [2, 4]])
    np.testing.assert_array_equal(np.asarray(s), rows)
    from hyperstat.solver.cli.cached import _digest

    assert _digest(s) == _digest(rows) != _digest(rows[:-1])  # the cache's key of the sample: the same


def test_the_top_rows_are_ordered_by_value_then_row():
    v, i = worst_case._top(np.zeros(0), np.zeros(0, np.int64), np.array([1.0, 3.0, 3.0, 2.0]), np.arange(4), 3)
    assert v.tolist() == [3.0, 3.0, 2.0] and i.tolist() == [1, 2, 3]
    v, i = worst_case._top(v, i, np.array([3.0, 5.0]), np.array([9, 8]), 3)
    assert v.tolist() == [5.0, 3.0, 3.0] and i.tolist() == [8, 1, 2]


@pytest.mark.parametrize("n", [0, 3])
def test_small_and_empty_files(n):
    s = SpilledArray.empty((2,))
    s.append(np.ones((n, 2)))
    assert len(s) == n and s.shape == (n, 2) and np.asarray(s).shape == (n, 2)
    assert worst_case._spread(s, 10).shape == (n, 2)
