"""Frames: exp/log, adjoints, the D matrix and the smooth defect parameterisation."""

import numpy as np
import pytest

from hyperstat.solver.kinematics.frames import (
    adjoint,
    apply_motion,
    axis_frame,
    invert_transform,
    minimal_rotation,
    minimal_rotation_velocity,
    motion_matrix,
    se3_exp,
    se3_log,
    skew,
    so3_exp,
    so3_log,
    unskew,
)

rng = np.random.default_rng(7)


def test_so3_exp_log_round_trip_including_near_pi():
    w = rng.normal(size=(200, 3))
    w *= (rng.random((200, 1)) * 3.1) / np.linalg.norm(w, axis=1, keepdims=True)
    w[:5] *= np.pi / np.linalg.norm(w[:5], axis=1, keepdims=True) * (1 - 1e-7)
    r = so3_exp(w)
    assert np.allclose(r @ np.swapaxes(r, 1, 2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(r), 1.0)
    assert np.allclose(so3_exp(so3_log(r)), r, atol=1e-9)


def test_se3_exp_log_round_trip():
    xi = np.concatenate([rng.normal(size=(100, 3)), 100 * rng.normal(size=(100, 3))], axis=1)
    xi[:, :3] *= 2.0 / np.maximum(np.linalg.norm(xi[:, :3], axis=1, keepdims=True), 2.0)
    t = se3_exp(xi)
    assert np.allclose(se3_log(t), xi, atol=1e-9)


def test_adjoint_maps_body_twists_to_parent():
    # T exp([xi_body]) = exp([Ad(T) xi_body]) T
    t = se3_exp(np.r_[rng.normal(size=3), 50 * rng.normal(size=3)])
    xi = 1e-3 * rng.normal(size=6)
    lhs = t @ se3_exp(xi)
    rhs = se3_exp(adjoint(t) @ xi) @ t
    assert np.allclose(lhs, rhs, atol=1e-12)


def test_invert_transform():
    t = se3_exp(np.r_[rng.normal(size=3), 50 * rng.normal(size=3)])
    assert np.allclose(invert_transform(t) @ t, np.eye(4), atol=1e-12)


def test_axis_frame_follows_the_paper_and_is_right_handed():
    for _ in range(50):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        r = axis_frame(n)
        assert np.allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(r), 1.0)
        assert np.allclose(r[:, 2], n)
        # x on the common perpendicular of the new axis and the previous z axis (Fig. 1)
        i, j, _ = n
        assert np.allclose(r[:, 0], np.array([-j, i, 0.0]) / np.hypot(i, j))


def test_the_papers_printed_d_matrix_is_not_orthonormal_but_ours_is():
    # Paper 1, eq. (4): y column printed as (-I K/s, +J K/s, s); with J, K != 0 it is not
    # orthogonal to the x column (-J/s, I/s, 0).  Ours uses -J K/s.
    n = np.array([0.3, 0.5, 0.0])
    n[2] = np.sqrt(1 - n[0] ** 2 - n[1] ** 2)
    i, j, k = n
    s = np.hypot(i, j)
    x_paper = np.array([-j / s, i / s, 0.0])
    y_paper = np.array([-i * k / s, j * k / s, s])
    assert abs(x_paper @ y_paper) > 0.1
    r = axis_frame(n)
    assert np.allclose(r[:, 0], x_paper)
    assert np.allclose(r[:, 1], np.array([-i * k / s, -j * k / s, s]))


def test_axis_parallel_to_previous_z_keeps_previous_x():
    assert np.allclose(axis_frame(np.array([0.0, 0.0, 1.0])), np.eye(3))
    r = axis_frame(np.array([0.0, 0.0, -1.0]))
    assert np.allclose(r.T @ r, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)


def test_defect_rotation_is_smooth_at_an_axis_parallel_to_previous_z():
    # The paper's common-perpendicular frame jumps by 90 deg between nearby axes around
    # e_z; the minimal rotation that carries the nominal frame does not.
    n0 = np.array([0.0, 0.0, 1.0])
    for d in (np.array([1e-7, 0, 0]), np.array([0, 1e-7, 0])):
        n = (n0 + d) / np.linalg.norm(n0 + d)
        assert np.linalg.norm(minimal_rotation(n0, n) - np.eye(3)) < 2e-7
    a, b = axis_frame(np.array([1e-7, 0, 1.0])), axis_frame(np.array([0, 1e-7, 1.0]))
    assert np.linalg.norm(a - b) > 1.0  # the paper's convention is discontinuous there


def test_minimal_rotation_velocity_matches_finite_differences():
    a = rng.normal(size=3)
    a /= np.linalg.norm(a)
    b = a + 0.2 * rng.normal(size=3)
    b /= np.linalg.norm(b)
    db = rng.normal(size=3)
    db -= (db @ b) * b
    h = 1e-7
    r0 = minimal_rotation(a, b)
    r1 = minimal_rotation(a, b + h * db)
    fd = unskew((r1 - r0) / h @ r0.T)
    assert np.allclose(minimal_rotation_velocity(a, b, db), fd, atol=1e-6)


def test_skew_unskew():
    v = rng.normal(size=(4, 3))
    w = rng.normal(size=(4, 3))
    assert np.allclose(np.einsum("kij,kj->ki", skew(v), w), np.cross(v, w))
    assert np.allclose(unskew(skew(v)), v)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 0.5, np.pi - 1e-9])
def test_so3_log_small_and_large_angles(angle):
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    assert np.allclose(so3_log(so3_exp(angle * axis)), angle * axis, atol=1e-7)


@pytest.mark.parametrize("kind", ["R", "P"])
def test_apply_motion_equals_the_product_with_the_motion_matrix(kind):
    frames = se3_exp(rng.normal(size=(50, 6)) * [1, 1, 1, 100, 100, 100])
    q = rng.uniform(-4, 4, size=50) * (1 if kind == "R" else 50)
    moved = apply_motion(frames, kind, q)
    assert np.allclose(moved, frames @ motion_matrix(kind, q), rtol=0, atol=1e-12 * np.abs(frames).max())
    # the joint moves along or about the z axis of its frame: that axis and, for R, the origin stay
    assert np.array_equal(moved[:, :, 2], frames[:, :, 2])
    if kind == "R":
        assert np.array_equal(moved[:, :, 3], frames[:, :, 3])
