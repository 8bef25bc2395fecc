"""The attainable linear worst case equals the maximum over every sign pattern, the triangle bound is above it.

Units: any (the matrices are task rows per unit tolerance times the values).  The expected value is
the brute-force maximum over all 2^n sign patterns, with n = 11 to 13 so that the walk (not the
enumeration used up to ten tolerances) is what is tested, on matrices with the structure real
mechanisms give: exactly parallel columns, integer (coplanar, tied) columns, zero and round-off columns.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from hyperstat.solver.tolerances.bounds import attainable, triangle


def _every_pattern(a: np.ndarray) -> np.ndarray:
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=a.shape[2])))
    return np.max(np.linalg.norm(a @ signs.T, axis=1), axis=1)


def _structured(kind: str, rng, r: int, n: int) -> np.ndarray:
    a = rng.normal(size=(4, r, n))
    if kind == "parallel":
        a[:, :, 1] = 0.5 * a[:, :, 0]
        a[:, :, 2] = -2.0 * a[:, :, 0]
    elif kind == "integer":
        a = rng.integers(-1, 2, size=a.shape).astype(float)
    elif kind == "zero and round-off":
        a[:, :, 0] = 0.0
        a[:, :, 3:6] *= 1e-13
    return a


@pytest.mark.parametrize("kind", ["generic", "parallel", "integer", "zero and round-off"])
@pytest.mark.parametrize("rows", [2, 3])
def test_attainable_is_the_maximum_over_every_sign_pattern(kind, rows):
    rng = np.random.default_rng(len(kind) + 10 * rows)
    for n in (11, 12, 13):
        a = _structured(kind, rng, rows, n)
        want = _every_pattern(a)
        got = attainable(a)
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12 * np.max(np.abs(a))), (kind, rows, n, got, want)
        assert np.all(triangle(a) >= got * (1 - 1e-12))


def test_one_row_is_the_sum_of_magnitudes_and_no_tolerance_is_zero():
    a = np.array([[[1.0, -2.0, 0.5] * 5]])
    assert attainable(a)[0] == pytest.approx(17.5, rel=1e-15) == triangle(a)[0]
    assert attainable(np.zeros((2, 3, 0))).tolist() == [0.0, 0.0]
    assert attainable(np.zeros((0, 3, 5))).shape == (0,)  # an empty stack (no configuration) is no error


def test_blocks_of_the_enumeration_give_the_same_maximum(monkeypatch):
    """The sign patterns are enumerated in blocks of configurations (memory); any block size gives the same values."""
    import hyperstat.solver.tolerances.bounds as bounds

    a = np.random.default_rng(3).normal(size=(37, 3, 9))
    whole = _every_pattern(a)
    monkeypatch.setattr(bounds, "PATTERN_BLOCK", 3 * 512 * 5)  # 5 configurations per block, the last one short
    assert np.array_equal(attainable(a), whole)


def _stacked_walk(blk: np.ndarray) -> np.ndarray:
    """The walk as the versions before issue 39 computed it: every arc's pattern as a (B, n_i, 2n, 3) stack."""
    n = blk.shape[2]
    cols = np.swapaxes(blk, 1, 2)
    norm = np.linalg.norm(cols, axis=2)
    scale = np.maximum(norm.max(axis=1), 1e-300)
    unit = cols / np.maximum(norm, 1e-300)[..., None]
    e1 = np.cross(unit, np.eye(3)[np.argmin(np.abs(unit), axis=2)])
    e1 /= np.maximum(np.linalg.norm(e1, axis=2), 1e-300)[..., None]
    e2 = np.cross(unit, e1)
    c, d = e1 @ blk, e2 @ blk
    tied = np.hypot(c, d) <= 1e-12 * scale[:, None, None]
    group = np.where(tied, np.sign(unit @ blk), 0.0) @ cols
    phi = np.arctan2(d, c)
    up, down = np.mod(phi - np.pi / 2, 2 * np.pi), np.mod(phi + np.pi / 2, 2 * np.pi)
    base = np.where(~tied, np.where(up < down, -1.0, 1.0), 0.0)
    order = np.argsort(np.concatenate([up, down], axis=2), axis=2)
    steps = np.take_along_axis(np.concatenate([np.where(~tied, 2.0, 0.0), np.where(~tied, -2.0, 0.0)], axis=2),
                               order, axis=2)
    which = np.concatenate([np.arange(n), np.arange(n)])[order]
    delta = steps[..., None] * np.take_along_axis(cols[:, None, :, :], which[..., None], axis=2)
    w = (base @ cols)[:, :, None, :] + np.cumsum(delta, axis=2)
    return np.maximum(np.linalg.norm(w + group[:, :, None, :], axis=3).max(axis=(1, 2)),
                      np.linalg.norm(w - group[:, :, None, :], axis=3).max(axis=(1, 2)))


@pytest.mark.parametrize("kind", ["generic", "parallel", "integer", "zero and round-off"])
def test_the_half_turn_walk_is_the_whole_turn_walk_to_the_last_places(kind):
    """Walking half of each circle (issue 39: the other half gives the same patterns with every sign flipped) and
    comparing the circle's two sides through ``|w|^2 + |g|^2 + 2 |w . g|`` gives the maxima of the whole turn's
    stacked walk to a few units of the last place (the same patterns, summed in another order), also where the
    squares of the entries would underflow or overflow (each matrix is walked scaled by a power of two); the blocks sized by the number of tolerances change no bit (72
    tolerances: the hexapod's)."""
    from hyperstat.solver.tolerances.bounds import _walk_circles

    rng = np.random.default_rng(7 + len(kind))
    for n in (1, 2, 5, 11, 24, 72):
        a = _structured(kind, rng, 3, max(n, 6))[:, :, :n] if kind != "generic" else rng.normal(size=(5, 3, n))
        for scale in (1.0, 1e-160, 1e160):  # where squares of the entries would underflow or overflow
            want = _stacked_walk(a) * scale  # |a s| scales with a (the stacked walk's own squares leave the range)
            got = _walk_circles(a * scale)
            assert np.allclose(got, want, rtol=64 * n * np.finfo(float).eps, atol=0), (kind, n, scale, got / want - 1)
            assert np.all(got <= want * (1 + 64 * n * np.finfo(float).eps)), (kind, n, scale)
    a = rng.normal(size=(9, 3, 40))
    assert np.array_equal(attainable(a), np.concatenate([_walk_circles(a[i:i + 1]) for i in range(9)]))
