"""A Sarrus linkage written as a model file from its closed-form geometry.

Units: lengths in mm, angles in rad.

Two limbs of three parallel revolutes join a base and a platform: each limb's hinges are
horizontal (limb A's along the base x axis, limb B's turned by ``angle`` about z), the limb's
lower and upper hinges on one vertical line ``w`` away from the platform's axis, its knee between
two links of lengths ``lower`` and ``upper``; the platform translates along z (mobility 1: each
limb alone leaves the platform the motions of a plane, and the two planes share only the vertical
translation).  Every joint carries the six defects
``I J K a b c``; limb B reaches the platform frame through a fixed element with six defects too.

Nothing here uses hyperstat: the placements are written from the geometry at home (every joint at
zero, the limbs folded at ``fold``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

__all__ = ["sarrus_document", "write_sarrus"]


def _frame(origin, z, x) -> np.ndarray:
    z, x = np.asarray(z, float), np.asarray(x, float)
    t = np.eye(4)
    t[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    t[:3, 3] = origin
    return t


def _placement(t: np.ndarray) -> dict:
    return {"origin": [float(v) for v in t[:3, 3]], "z_axis": [float(v) for v in t[:3, 2]],
            "x_axis": [float(v) for v in t[:3, 0]]}


def sarrus_document(lower: float = 120.0, upper: float = 95.0, w: float = 80.0, fold: float = 0.7,
                    angle: float = 1.2, name: str = "sarrus", both: bool = False) -> dict:
    """The model file (format ``hyperstat-model`` 1) of the Sarrus linkage at home (see the module docstring).

    Parameters
    ----------
    lower, upper : float
        Lengths of each limb's lower and upper links (mm).
    w : float
        Distance of each limb's hinges from the vertical axis of the platform (mm).
    fold : float
        Angle of the lower links above the base plane at home (rad).
    angle : float
        Angle between the two limbs' hinge axes (rad; the platform translates for any angle but 0).
    """
    knee = (lower * math.cos(fold), lower * math.sin(fold))  # in the limb's plane: (horizontal, vertical)
    top = (0.0, knee[1] + math.sqrt(upper**2 - knee[0]**2))  # the upper hinge straight above the lower one
    h = top[1]
    platform = _frame((0.0, 0.0, h), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0))
    chains = []
    for limb, heading in (("A", 0.0), ("B", angle)):
        axis = np.array([math.cos(heading), math.sin(heading), 0.0])  # the hinges of the limb
        out = np.cross([0.0, 0.0, 1.0], axis)  # horizontal, in the limb's plane
        foot = -w * out
        points = [foot, foot + knee[0] * out + np.array([0, 0, knee[1]]), foot + np.array([0, 0, top[1]])]
        parent = np.eye(4)
        elements = []
        for k, p in enumerate(points):
            along = (points[k + 1] - p) if k < 2 else (points[1] - p)
            x = along - np.dot(along, axis) * axis
            absolute = _frame(p, axis, x / np.linalg.norm(x))
            relative = np.linalg.inv(parent) @ absolute
            elements.append({"kind": "joint", "name": f"{limb}{k + 1}", "type": "R",
                             "role": "actuated" if (limb == "A" and k == 0) else "passive",
                             "placement": _placement(relative), "defects": list("IJKabc"),
                             "range": [-1.2, 1.2], "home": 0.0})
            parent = absolute
        elements.append({"kind": "fixed", "name": f"P{limb}", "placement": _placement(np.linalg.inv(parent) @ platform),
                         "defects": list("IJKabcG") if (limb == "B" or both) else []})
        chains.append({"name": f"limb{limb}", "start": "R0", "end": "P", "elements": elements})
    return {"format": "hyperstat-model", "version": 1, "units": {"length": "mm", "angle": "rad"}, "name": name,
            "base": "R0", "output": "P",
            "description": f"Sarrus linkage: links {lower} and {upper} mm, hinges {w} mm from the axis, limbs "
                           f"{angle} rad apart, folded {fold} rad",
            "chains": chains, "metadata": {"links_mm": {"lower": lower, "upper": upper, "w": w}, "fold_rad": fold,
                                           "angle_rad": angle}}


def write_sarrus(path: Path, **kwargs) -> Path:
    """Write :func:`sarrus_document` to ``path`` (JSON) and return the path."""
    path = Path(path)
    path.write_text(json.dumps(sarrus_document(**kwargs), indent=1))
    return path
