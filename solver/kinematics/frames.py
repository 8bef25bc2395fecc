"""Rigid-body frames: the D, M and T matrices of the joint-invariant model.

Units: lengths in mm, angles in rad.  Every function accepts stacked inputs
(leading batch dimensions) so that many configurations are evaluated at once.

Conventions
-----------
* A homogeneous transform ``T`` has shape ``(..., 4, 4)``; ``T[..., :3, :3]`` is
  the rotation and ``T[..., :3, 3]`` the origin, both expressed in the parent frame.
* A twist is the 6-vector ``(omega, v)``: angular velocity first, then the
  velocity of the point that coincides with the origin of the frame the twist is
  written in (paper 2, footnote 2: a revolute of unit axis ``s`` through ``Q`` has
  the unit screw ``(s, Q x s)``).
* ``D`` (paper 1, Fig. 1, eq. 4) places the joint frame ``L_i`` in the previous
  frame ``P_{i-1}``; its z axis is the joint axis ``n_i = (I_i, J_i, K_i)`` and its
  origin a point ``(A_i, B_i, C_i)`` of the axis.  The paper's printed matrix has a
  sign error in its y column (``+J K`` instead of ``-J K``) and is undefined when the
  axis is parallel to the previous z axis; :func:`axis_frame` builds a right-handed
  orthonormal frame in every case.
* Orientation defects ``(dI, dJ, dK)`` perturb the axis, ``n = (n0 + dn)/|n0 + dn|``,
  and the nominal frame is carried along by the minimal rotation that takes
  ``n0`` to ``n`` (:func:`minimal_rotation`).  This is smooth at ``dn = 0`` whatever
  the direction of ``n0``; the component of ``dn`` along ``n0`` has no effect to
  first order (it is the normalisation gauge ``n . dn = 0``).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "cross",
    "skew",
    "unskew",
    "so3_exp",
    "so3_log",
    "so3_left_jacobian",
    "se3_exp",
    "se3_log",
    "adjoint",
    "make_transform",
    "invert_transform",
    "rot_z",
    "trans_z",
    "axis_frame",
    "minimal_rotation",
    "minimal_rotation_velocity",
    "defect_rotation",
    "motion_matrix",
    "apply_motion",
]

_EPS = 1e-12


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (broadcasting), faster than ``np.cross`` on small stacks."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def skew(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix ``[v]`` such that ``[v] w = v x w``; shape ``(..., 3, 3)``."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def unskew(m: np.ndarray) -> np.ndarray:
    """Vector of the skew-symmetric part of ``m``; inverse of :func:`skew`."""
    m = np.asarray(m, dtype=float)
    return 0.5 * np.stack(
        [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]],
        axis=-1,
    )


def so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (Rodrigues), shape ``(..., 3, 3)``."""
    w = np.asarray(w, dtype=float)
    theta2 = np.sum(w * w, axis=-1)[..., None, None]
    theta = np.sqrt(theta2)
    small = theta < 1e-6
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0 + theta2**2 / 120.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0 + theta2**2 / 720.0, (1.0 - np.cos(safe)) / (safe * safe))
    k = skew(w)
    return np.eye(3) + a * k + b * (k @ k)


def so3_log(r: np.ndarray) -> np.ndarray:
    """Rotation vector of the rotation matrix ``r`` (inverse of :func:`so3_exp`)."""
    r = np.asarray(r, dtype=float)
    cos = np.clip((np.trace(r, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    axis_sin = unskew(r)  # = sin(theta) * axis
    sin = np.sin(theta)
    small = theta < 1e-6
    near_pi = theta > np.pi - 1e-4
    factor = np.where(small, 1.0 + theta**2 / 6.0, theta / np.where(small | (sin < _EPS), 1.0, sin))
    out = axis_sin * factor[..., None]
    if np.any(near_pi):
        # Near pi the skew part vanishes: read the axis from the symmetric part.
        sym = 0.5 * (r + np.swapaxes(r, -1, -2)) - cos[..., None, None] * np.eye(3)
        diag = np.diagonal(sym, axis1=-2, axis2=-1)
        idx = np.argmax(diag, axis=-1)
        col = np.take_along_axis(sym, idx[..., None, None].repeat(3, axis=-1), axis=-2)[..., 0, :]
        col = col / np.linalg.norm(col, axis=-1, keepdims=True)
        sign = np.sign(np.sum(col * axis_sin, axis=-1, keepdims=True))
        sign = np.where(sign == 0, 1.0, sign)
        out = np.where(near_pi[..., None], col * sign * theta[..., None], out)
    return out


def so3_left_jacobian(w: np.ndarray) -> np.ndarray:
    """Left Jacobian of SO(3): ``d exp(w) = [J_l(w) dw] exp(w)`` (shape ``(..., 3, 3)``)."""
    return _left_jacobian(np.asarray(w, dtype=float))


def _left_jacobian(w: np.ndarray) -> np.ndarray:
    theta2 = np.sum(w * w, axis=-1)[..., None, None]
    theta = np.sqrt(theta2)
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    c = np.where(small, 1.0 / 6.0 - theta2 / 120.0, (safe - np.sin(safe)) / (safe**3))
    k = skew(w)
    return np.eye(3) + b * k + c * (k @ k)


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """Homogeneous transform ``exp([xi])`` of the twist ``xi = (omega, v)``."""
    xi = np.asarray(xi, dtype=float)
    w, v = xi[..., :3], xi[..., 3:]
    out = np.zeros(xi.shape[:-1] + (4, 4))
    out[..., :3, :3] = so3_exp(w)
    out[..., :3, 3] = np.einsum("...ij,...j->...i", _left_jacobian(w), v)
    out[..., 3, 3] = 1.0
    return out


def se3_log(t: np.ndarray) -> np.ndarray:
    """Twist ``xi = (omega, v)`` with ``se3_exp(xi) = t`` (principal branch)."""
    t = np.asarray(t, dtype=float)
    w = so3_log(t[..., :3, :3])
    jl = _left_jacobian(w)
    v = np.linalg.solve(jl, t[..., :3, 3][..., None])[..., 0]
    return np.concatenate([w, v], axis=-1)


def adjoint(t: np.ndarray) -> np.ndarray:
    """Adjoint ``Ad(T)`` mapping twists written in frame ``T`` to the parent frame."""
    t = np.asarray(t, dtype=float)
    r, p = t[..., :3, :3], t[..., :3, 3]
    out = np.zeros(t.shape[:-2] + (6, 6))
    out[..., :3, :3] = r
    out[..., 3:, 3:] = r
    out[..., 3:, :3] = skew(p) @ r
    return out


def make_transform(rotation: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Homogeneous transform from a rotation ``(..., 3, 3)`` and an origin ``(..., 3)``."""
    rotation = np.asarray(rotation, dtype=float)
    origin = np.asarray(origin, dtype=float)
    shape = np.broadcast_shapes(rotation.shape[:-2], origin.shape[:-1])
    out = np.zeros(shape + (4, 4))
    out[..., :3, :3] = rotation
    out[..., :3, 3] = origin
    out[..., 3, 3] = 1.0
    return out


def invert_transform(t: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform without a general matrix inverse."""
    t = np.asarray(t, dtype=float)
    r = np.swapaxes(t[..., :3, :3], -1, -2)
    return make_transform(r, -np.einsum("...ij,...j->...i", r, t[..., :3, 3]))


def rot_z(theta: np.ndarray) -> np.ndarray:
    """Motion matrix of a revolute joint: rotation about z by ``theta`` (paper 1, eq. 5)."""
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros(theta.shape + (4, 4))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    out[..., 2, 2] = 1.0
    out[..., 3, 3] = 1.0
    return out


def trans_z(x: np.ndarray) -> np.ndarray:
    """Motion matrix of a prismatic joint: translation along z by ``x`` (paper 1, eq. 5)."""
    x = np.asarray(x, dtype=float)
    out = np.zeros(x.shape + (4, 4))
    out[..., 0, 0] = out[..., 1, 1] = out[..., 2, 2] = out[..., 3, 3] = 1.0
    out[..., 2, 3] = x
    return out


def motion_matrix(kind: str, q: np.ndarray) -> np.ndarray:
    """``M`` for a joint of type ``"R"`` (angle, rad) or ``"P"`` (length, mm)."""
    return rot_z(q) if kind == "R" else trans_z(q)


def apply_motion(frame: np.ndarray, kind: str, q: np.ndarray) -> np.ndarray:
    """``frame @ M(q)`` without forming ``M`` (paper 1, eq. 5), for stacks of frames.

    A rotation about z mixes the first two columns of ``frame``; a translation along z adds
    ``q`` times its third column to its origin.  The same as ``frame @ motion_matrix(kind, q)``
    to round-off, about twice as fast for a (K, 4, 4) stack.

    Parameters
    ----------
    frame : ndarray, (K, 4, 4)
        Frames ``L`` of the joint.
    kind : {"R", "P"}
        Joint type.
    q : ndarray, (K,)
        Joint values (rad or mm).
    """
    q = np.asarray(q, dtype=float)[..., None]
    out = np.array(frame, dtype=float, copy=True)
    if kind == "R":
        c, s = np.cos(q), np.sin(q)
        x, y = frame[..., :, 0], frame[..., :, 1]
        out[..., :, 0] = c * x + s * y
        out[..., :, 1] = c * y - s * x
    else:
        out[..., :3, 3] += q * frame[..., :3, 2]
    return out


def axis_frame(axis: np.ndarray, x_hint: np.ndarray | None = None) -> np.ndarray:
    """Right-handed orthonormal rotation whose z column is ``axis``.

    Without ``x_hint`` the x column follows paper 1 (Fig. 1): it lies on the common
    perpendicular of the new axis and the previous z axis, ``x = (e_z x n)/|e_z x n|``,
    i.e. ``(-J, I, 0)/sqrt(I^2 + J^2)``; the y column is ``n x x``.  When the axis is
    parallel to the previous z axis the common perpendicular is undefined and the
    previous x axis is used (``x = e_x``), which is what the paper does implicitly
    when it sets identity matrices for parallel links.  With ``x_hint`` the x column
    is the component of ``x_hint`` orthogonal to ``axis``.
    """
    n = np.asarray(axis, dtype=float)
    n = n / np.linalg.norm(n)
    if x_hint is None:
        x = np.cross([0.0, 0.0, 1.0], n)
        if np.linalg.norm(x) < 1e-9:
            x = np.array([1.0, 0.0, 0.0])
    else:
        x = np.asarray(x_hint, dtype=float)
        x = x - np.dot(x, n) * n
        if np.linalg.norm(x) < 1e-9:
            raise ValueError("x_hint is parallel to the axis")
    x = x / np.linalg.norm(x)
    y = np.cross(n, x)
    return np.stack([x, y, n], axis=-1)


def minimal_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector ``a`` onto unit vector ``b``.

    ``R = I + [v] + [v]^2 / (1 + c)`` with ``v = a x b`` and ``c = a . b``; smooth for
    ``b`` near ``a`` (the only regime the small-defect model uses).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    v = cross(a, b)
    c = np.sum(a * b, axis=-1)[..., None, None]
    k = skew(v)
    return np.eye(3) + k + (k @ k) / (1.0 + c)


def minimal_rotation_velocity(a: np.ndarray, b: np.ndarray, db: np.ndarray) -> np.ndarray:
    """Angular velocity ``omega`` of ``minimal_rotation(a, b)`` when ``b`` moves by ``db``.

    ``dR R^T = [omega]``; ``db`` has shape ``(..., 3)`` or ``(..., k, 3)`` for ``k``
    directions at once (then ``omega`` has shape ``(..., k, 3)``).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    db = np.asarray(db, dtype=float)
    multi = db.ndim > b.ndim
    if multi:
        a = a[..., None, :]
        b = b[..., None, :]
    v = cross(a, b)
    c = np.sum(a * b, axis=-1)[..., None, None]
    dv = cross(a, db)
    dc = np.sum(a * db, axis=-1)[..., None, None]
    k, dk = skew(v), skew(dv)
    r = np.eye(3) + k + (k @ k) / (1.0 + c)
    dr = dk + (dk @ k + k @ dk) / (1.0 + c) - (k @ k) * dc / (1.0 + c) ** 2
    return unskew(dr @ np.swapaxes(r, -1, -2))


def defect_rotation(axis0: np.ndarray, d_axis: np.ndarray) -> np.ndarray:
    """Rotation carrying the nominal axis ``axis0`` to ``normalize(axis0 + d_axis)``."""
    n = np.asarray(axis0, dtype=float) + np.asarray(d_axis, dtype=float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return minimal_rotation(np.broadcast_to(axis0, n.shape), n)
