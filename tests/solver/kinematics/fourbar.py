"""Planar four-bar (4R) loops written as model files from their closed-form geometry.

Units: lengths in mm, angles in rad.

The loop: ground pivots ``A0 = (0, 0, 0)`` and ``B0 = (d, 0, 0)``, crank ``A0 A`` (length
``a``, joint 1, actuated), coupler ``A B`` (length ``b``, joint 2), rocker ``B0 B``
(length ``c``, joint 4 at ``B0``), joint 3 at ``B``.  Chain ``crank`` is
``1 -> 2 -> 3`` and reaches the rocker frame ``F``; chain ``rocker`` is ``4 -> 5`` (a
fixed element, the rocker's far end) and closes the loop at ``F``.  Every joint and the
fixed element carry the six defects ``I J K a b c``.

Nothing here uses hyperstat: positions come from the intersection of two circles,
with the assembly branch ``sigma = sign((B0 - A) x (B - A))_z``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["fourbar_angles", "fourbar_document", "write_fourbar", "defects_from_axes", "planar_points",
           "spherical_axes", "bennett_axes"]


def _wrap(x):
    return (np.asarray(x) + np.pi) % (2 * np.pi) - np.pi


def fourbar_angles(a: float, b: float, c: float, d: float, theta, sigma: int) -> np.ndarray:
    """Joint values ``(q1, q2, q3, q4)`` (rad) of the 4R loop at crank angles ``theta`` on branch ``sigma``.

    ``q1 = theta``, ``q2 = psi - theta``, ``q3 = phi - psi``, ``q4 = phi`` with ``psi`` and
    ``phi`` the absolute angles of the coupler ``A -> B`` and the rocker ``B0 -> B``.
    Angles are wrapped to ``[-pi, pi)``.
    """
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    ax, ay = a * np.cos(theta), a * np.sin(theta)
    ex, ey = d - ax, -ay  # A -> B0
    ell = np.hypot(ex, ey)
    cos_g = (b * b + ell * ell - c * c) / (2 * b * ell)
    if np.any(np.abs(cos_g) > 1 + 1e-12):
        raise ValueError("the loop does not assemble at some crank angle")
    g = np.arccos(np.clip(cos_g, -1, 1))
    base = np.arctan2(ey, ex)
    psi = base + sigma * g  # rotating e towards B by +g gives (B0 - A) x (B - A) > 0
    bx, by = ax + b * np.cos(psi), ay + b * np.sin(psi)
    phi = np.arctan2(by, bx - d)
    return np.stack([theta, _wrap(psi - theta), _wrap(phi - psi), _wrap(phi)], axis=1)


def _placement(x: float) -> dict:
    return {"origin": [x, 0.0, 0.0], "z_axis": [0.0, 0.0, 1.0], "x_axis": [1.0, 0.0, 0.0]}


def fourbar_document(a: float, b: float, c: float, d: float, home_theta: float, sigma: int,
                     crank_range: tuple[float, float], name: str = "fourbar") -> dict:
    """The model file (format ``hyperstat-model`` 1) of the 4R loop assembled at ``home_theta`` on ``sigma``."""
    q = fourbar_angles(a, b, c, d, home_theta, sigma)[0]
    wide = [-3 * np.pi, 3 * np.pi]

    def joint(name, x, role, home, rng):
        return {"kind": "joint", "name": name, "type": "R", "role": role, "placement": _placement(x),
                "defects": list("IJKabc"), "range": [float(rng[0]), float(rng[1])], "home": float(home)}

    return {
        "format": "hyperstat-model", "version": 1, "units": {"length": "mm", "angle": "rad"},
        "name": name, "base": "R0", "output": "F",
        "description": f"planar 4R loop a={a} b={b} c={c} d={d} mm, branch sigma={sigma}",
        "chains": [
            {"name": "crank", "start": "R0", "end": "F", "elements": [
                joint("1", 0.0, "actuated", q[0], crank_range),
                joint("2", a, "passive", q[1], wide),
                joint("3", b, "passive", q[2], wide)]},
            {"name": "rocker", "start": "R0", "end": "F", "elements": [
                joint("4", d, "passive", q[3], wide),
                {"kind": "fixed", "name": "5", "placement": _placement(c), "defects": list("IJKabc")}]},
        ],
        "metadata": {"links_mm": {"a": a, "b": b, "c": c, "d": d}, "sigma": sigma},
    }


def write_fourbar(path: Path, *args, **kwargs) -> Path:
    """Write :func:`fourbar_document` to ``path`` (JSON) and return the path."""
    path = Path(path)
    path.write_text(json.dumps(fourbar_document(*args, **kwargs), indent=1))
    return path


# ----------------------------------------------------------------------------- exact defected geometries
# Independent of hyperstat: frames are built here with their own minimal rotation.

def _minrot(n: np.ndarray) -> np.ndarray:
    """Rotation taking z to the unit vector ``n`` about an axis orthogonal to both (Rodrigues)."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, n)
    s, c = np.linalg.norm(v), float(z @ n)
    if s < 1e-15:
        return np.eye(3)
    k = v / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def _frame(rot: np.ndarray, origin) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = origin
    return t


def _rz(q: float) -> np.ndarray:
    c, s = np.cos(q), np.sin(q)
    return _frame(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), (0, 0, 0))


def _local(parent: np.ndarray, point, axis, nominal_origin) -> tuple[np.ndarray, dict, np.ndarray]:
    """Element matrix of an axis (world ``point``, ``axis``) placed in ``parent``, and its defects."""
    inv = np.linalg.inv(parent)
    n = inv[:3, :3] @ np.asarray(axis, float)
    n = n / np.linalg.norm(n)
    p = (inv @ np.r_[np.asarray(point, float), 1.0])[:3]
    dn = n / n[2] - np.array([0, 0, 1.0])
    dp = p - np.asarray(nominal_origin, float)
    d = _frame(_minrot(n), p)
    return d, {"I": dn[0], "J": dn[1], "a": dp[0], "b": dp[1], "c": dp[2]}, parent @ d


def defects_from_axes(a: float, b: float, c: float, d: float, q_home, points, axes) -> dict:
    """Defects (by parameter name, rad / mm) of the model of :func:`fourbar_document` whose
    joint axes at the home joint values ``q_home = (q1, q2, q3)`` are the world lines
    ``points[i] + t axes[i]`` (i = 1..4, pivots O, A, B, B0).

    The crank, coupler and ground axes are placed in turn (each in the frame its element is
    placed in); the rocker's far end (fixed element 5) is whatever closes the loop at home
    exactly, with the rocker angle ``q4`` chosen so that element 5 needs no roll about its
    own axis (swing-twist decomposition).  Returns the defects and ``q4``.
    """
    out = {}
    world = np.eye(4)
    p1 = world
    for name, nominal, q in (("1", (0, 0, 0), q_home[0]), ("2", (a, 0, 0), q_home[1]), ("3", (b, 0, 0), q_home[2])):
        i = int(name) - 1
        _, dfx, lframe = _local(p1, points[i], axes[i], nominal)
        out.update({f"d{k}{name}": v for k, v in dfx.items()})
        p1 = lframe @ _rz(q)
    f = p1
    _, dfx, l4 = _local(world, points[3], axes[3], (d, 0, 0))
    out.update({f"d{k}4": v for k, v in dfx.items()})
    m = np.linalg.inv(l4) @ f
    twist = _minrot(m[:3, 2]).T @ m[:3, :3]
    q4 = float(np.arctan2(twist[1, 0], twist[0, 0]))
    d5 = np.linalg.inv(l4 @ _rz(q4)) @ f
    n5 = d5[:3, 2]
    assert np.allclose(d5[:3, :3], _minrot(n5), atol=1e-12)
    dn = n5 / n5[2] - np.array([0, 0, 1.0])
    dp = d5[:3, 3] - np.array([c, 0, 0.0])
    out.update({"dI5": dn[0], "dJ5": dn[1], "da5": dp[0], "db5": dp[1], "dc5": dp[2]})
    return {"defects": out, "q4": q4}


def planar_points(a: float, b: float, c: float, d: float, q) -> list:
    """World pivots O, A, B, B0 (mm) of the planar loop at joint values ``q``."""
    q1, q2 = q[0], q[1]
    pa = np.array([a * np.cos(q1), a * np.sin(q1), 0.0])
    pb = pa + b * np.array([np.cos(q1 + q2), np.sin(q1 + q2), 0.0])
    return [np.zeros(3), pa, pb, np.array([d, 0.0, 0.0])]


def spherical_axes(points: list, apex) -> list:
    """Axes through ``apex`` from each pivot (a spherical four-bar), oriented along +z."""
    out = []
    for p in points:
        n = (np.asarray(apex, float) - p) / np.linalg.norm(np.asarray(apex, float) - p)
        out.append(n if n[2] > 0 else -n)
    return out


def bennett_axes(a: float, b: float, alpha: float, beta: float, theta1: float, guess,
                 start_heading: float = 0.0) -> tuple[list, list]:
    """World pivots and axes of a Bennett loop (links a, b, a, b; twists alpha, beta, alpha, beta).

    The Denavit-Hartenberg loop ``S prod Rz(t_i) Tx(a_i) Rx(alpha_i) = S`` with the start frame
    ``S = Rz(start_heading)`` at the origin (its x axis along the closing link), ``t1 = theta1``,
    solved for ``t2, t3, t4`` by least squares from ``guess`` (scipy), checked closed to 1e-11.
    """
    from scipy.optimize import least_squares

    lengths, twists = (a, b, a, b), (alpha, beta, alpha, beta)

    def link(i, t):
        ca, sa = np.cos(twists[i]), np.sin(twists[i])
        rx = _frame(np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]]), (0, 0, 0))
        return _rz(t) @ _frame(np.eye(3), (lengths[i], 0, 0)) @ rx

    start = _rz(start_heading)

    def frames(t):
        out, cur = [], start.copy()
        for i, ti in enumerate((theta1, *t)):
            out.append(cur)
            cur = cur @ link(i, ti)
        return out, cur

    def resid(t):
        _, end = frames(t)
        return np.r_[(end - start)[:3, :3].ravel(), (end - start)[:3, 3] / a]

    sol = least_squares(resid, np.asarray(guess, float), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    if np.max(np.abs(resid(sol.x))) > 1e-11:
        raise ValueError(f"the Bennett loop does not close at this crank angle (residual {np.max(np.abs(resid(sol.x))):.1e})")
    fr, _ = frames(sol.x)
    return [f[:3, 3].copy() for f in fr], [f[:3, 2].copy() for f in fr]
