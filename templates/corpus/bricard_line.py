"""Line-symmetric Bricard linkage: a loop of six revolutes, symmetric under a half-turn about a line.

Units: lengths in mm, angles in rad.

Three joint axes 1, 2, 3 are chosen freely (``size`` scales them); axes 4, 5, 6 are their images
under the half-turn about the z axis, so that the loop 1-2-3-4-5-6 has opposite links equal: link
4-5 is the image of 1-2, 5-6 of 2-3, 6-1 of 3-4.  The base is the link 6-1; joint 1 is actuated and
the reference.  The chain 1, 2, 3 places the frame ``R3`` of the link 3-4; the chain 6, 5, 4
closes on it through the fixed transform ``X`` (that link's own geometry).  Output: the frame
``P`` at joint 3 on the link 3-4.

Theory.  One loop, six joints.  Kutzbach: 6 x 5 - 5 x 6 = 0, yet the linkage moves: its half-turn
symmetry persists through the motion, the six joint screws span a 5-system, so the mobility is
6 - 5 = 1 and the degree of over-constraint 6 - 5 = 1.  Bricard's conditions (1897) on the
eighteen link parameters of a 6R loop: opposite links have equal lengths, twists and offsets
(``a1 = a4, a2 = a5, a3 = a6``, the same for the twists and the offsets): 9 conditions; the
family left has the nine parameters of three lines about the symmetry line (twelve, less the
rotation about it and the shift along it, less the motion).  To first order all nine are
independent (the stationarity analysis and an independent screw computation both find 9).

The actuated range is one-sided, ``(-0.05, 1.2)`` rad: below home the linkage reaches a turning
point at about -0.15 rad, and sampling a wide range keeps the nine conditions well separated
from round-off.

Theory: mobility 1, degree of over-constraint 1, assembly conditions 9.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton

TOLERANCING = {
    "task": ["position"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.05, "orientation_rad": None},
}

#: the three free axes at home: (point, direction), for size 100 mm
_AXES = (((1.0, 0.0, 0.0), (0.2, 0.3, 1.0)),
         ((0.6, 0.8, 0.4), (1.0, 0.2, 0.3)),
         ((-0.2, 0.9, 0.9), (0.3, 1.0, -0.2)))

@dataclass
class Parameters:
    """Size of the linkage (mm)."""

    size: float = param(100.0, "mm", "scale of the three free axes (their distance from the symmetry line)",
                        minimum=0.0, exclusive_minimum=True)

def build(**overrides: float) -> Skeleton:
    """Skeleton of the line-symmetric Bricard linkage at home."""
    p = make_parameters(Parameters, overrides)
    half_turn = np.diag([-1.0, -1.0, 1.0])  # about the z axis
    axes = {}
    for k, (point, direction) in enumerate(_AXES, start=1):
        o, u = p.size * np.array(point), np.array(direction) / np.linalg.norm(direction)
        axes[str(k)] = (o, u)
        axes[str(k + 3)] = (half_turn @ o, half_turn @ u)
    sk = Skeleton("bricard_line", base="R0", parameters=p, marker_size=0.2 * p.size,
                  description="Line-symmetric Bricard 6R linkage")
    for name in ("1", "2", "3", "6", "5", "4"):
        o, u = axes[name]
        if name == "1":
            x = np.cross(u, (0.0, 0.0, 1.0))
            sk.revolute(name, o, u, role="actuated", x_axis=x, defects="", home=0.0, range=(-0.05, 1.2))
        else:
            sk.revolute(name, o, u)
    sk.fixed("X", target="R3")
    o3, u3 = axes["3"]
    sk.frame("P", o3, u3, np.cross(u3, axes["4"][0] - o3))
    sk.chain("left", "R0", "R3", ["1", "2", "3"])
    sk.chain("right", "R0", "R3", ["6", "5", "4", "X"])
    sk.chain("tool", "R3", "P", [])
    sk.output = "P"
    r = 0.04 * p.size
    sk.link("base", ["6", "1"], r)
    for a, b in (("1", "2"), ("2", "3"), ("3", "4"), ("4", "5"), ("5", "6")):
        sk.link(f"link{a}{b}", [a, b], r)
    return sk
