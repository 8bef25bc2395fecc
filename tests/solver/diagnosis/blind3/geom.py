"""Rigid-body helpers of the fifth blind generator (own code, nothing from hyperstat).

Units: mm, rad.  Homogeneous transforms are 4x4 numpy arrays.
"""

from __future__ import annotations

import numpy as np


def skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def rotvec_to_matrix(w):
    """Rodrigues' formula."""
    w = np.asarray(w, dtype=float)
    th = float(np.linalg.norm(w))
    if th < 1e-12:
        k = skew(w)
        return np.eye(3) + k + 0.5 * k @ k
    k = skew(w / th)
    return np.eye(3) + np.sin(th) * k + (1.0 - np.cos(th)) * (k @ k)


def matrix_to_rotvec(r):
    r = np.asarray(r, dtype=float)
    c = (np.trace(r) - 1.0) / 2.0
    c = min(1.0, max(-1.0, c))
    th = np.arccos(c)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if th < 1e-7:
        return 0.5 * v
    if np.pi - th < 1e-6:
        # near pi: axis from the symmetric part
        b = (r + np.eye(3)) / 2.0
        i = int(np.argmax(np.diag(b)))
        axis = b[:, i] / np.sqrt(max(b[i, i], 1e-300))
        axis /= np.linalg.norm(axis)
        if np.dot(axis, v) < 0:
            axis = -axis
        return axis * th
    return v * (th / (2.0 * np.sin(th)))


def matrix_to_quaternion(r):
    """Unit quaternion (w, x, y, z), w >= 0."""
    w = matrix_to_rotvec(r)
    th = np.linalg.norm(w)
    if th < 1e-15:
        return np.array([1.0, 0.0, 0.0, 0.0])
    ax = w / th
    q = np.concatenate([[np.cos(th / 2.0)], np.sin(th / 2.0) * ax])
    if q[0] < 0:
        q = -q
    return q


def hom(r=None, t=None):
    m = np.eye(4)
    if r is not None:
        m[:3, :3] = r
    if t is not None:
        m[:3, 3] = t
    return m


def inv(m):
    r = m[:3, :3]
    out = np.eye(4)
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ m[:3, 3]
    return out


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return hom(np.array([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=float))


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return hom(np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=float))


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return hom(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=float))


def trans(x, y, z):
    return hom(t=np.array([x, y, z], dtype=float))


def rpy_matrix(roll, pitch, yaw):
    """URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return (rot_z(yaw) @ rot_y(pitch) @ rot_x(roll))[:3, :3]


def small_transform(rv, t):
    """A (small) rigid displacement: rotation vector rv, translation t (mm)."""
    return hom(rotvec_to_matrix(rv), np.asarray(t, dtype=float))


def placement_matrix(origin, z_axis, x_axis):
    z = np.asarray(z_axis, dtype=float)
    x = np.asarray(x_axis, dtype=float)
    y = np.cross(z, x)
    r = np.column_stack([x, y, z])
    return hom(r, np.asarray(origin, dtype=float))


def pose_error(t_a, t_b):
    """6-vector (rotation vector of R_b R_a^T, p_b - p_a) in the world frame."""
    return np.concatenate([matrix_to_rotvec(t_b[:3, :3] @ t_a[:3, :3].T), t_b[:3, 3] - t_a[:3, 3]])
