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

__all__ = ["fourbar_angles", "fourbar_document", "write_fourbar"]


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
