"""RCCC spatial four-bar: one revolute on the base and three cylindrical joints (each a revolute and a slide on one axis).

Units: lengths in mm, angles in rad.

Four skew axes at home: ``1`` (the input revolute on the base, actuated, the reference), then the
cylindrical joints ``2`` (revolute ``2r`` and slide ``2p``), ``3`` and ``4`` (``4`` back to the
base).  The input chain 1, 2 places the frame ``L23`` of the link between joints 2 and 3; the chain
4, 3 closes on it through the fixed transform ``X`` (that link's geometry).  Output: the frame
``P`` on that link.

Theory.  Bodies: base, three links and one between each cylindrical joint's revolute and slide:
7; joints: 7 (4 revolutes, 3 slides); one loop.  Kutzbach: 6 x 6 - 5 x 7 = 1.  Screws: the seven
joint screws span all six dimensions: mobility 7 - 6 = 1, degree of over-constraint 0, no
assembly condition (a general RCCC moves whatever its proportions).

Theory: mobility 1, degree of over-constraint 0, assembly conditions 0.
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

#: the four axes at home (point, direction) for size 100 mm
_AXES = {"1": ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
         "2": ((0.8, 0.3, 0.2), (0.3, -0.4, 0.9)),
         "3": ((1.3, 1.1, 0.5), (-0.5, 0.2, 0.8)),
         "4": ((0.2, 1.2, -0.1), (0.6, 0.7, 0.4))}


@dataclass
class Parameters:
    """Size of the linkage (mm) and the slides' travel."""

    size: float = param(100.0, "mm", "scale of the four axes' placement", minimum=0.0, exclusive_minimum=True)
    stroke: float = param(200.0, "mm", "travel of each slide either way from home", minimum=0.0,
                          exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the RCCC at home."""
    p = make_parameters(Parameters, overrides)
    axes = {k: (p.size * np.array(o), np.array(d) / np.linalg.norm(d)) for k, (o, d) in _AXES.items()}
    sk = Skeleton("rccc", base="R0", parameters=p, marker_size=0.2 * p.size, description="RCCC spatial four-bar")
    o, u = axes["1"]
    sk.revolute("1", o, u, role="actuated", x_axis=(1, 0, 0), defects="", home=0.0, range=(-0.4, 0.4))
    for k in "234":
        o, u = axes[k]
        sk.revolute(f"{k}r", o, u)
        sk.prismatic(f"{k}p", o, u, range=(-p.stroke, p.stroke))
    sk.fixed("X", target="L23")
    o2, u2 = axes["2"]
    o3 = axes["3"][0]
    sk.frame("P", 0.5 * (o2 + o3), u2, np.cross(u2, o3 - o2))
    sk.chain("input", "R0", "L23", ["1", "2r", "2p"])
    sk.chain("output", "R0", "L23", ["4r", "4p", "3r", "3p", "X"])
    sk.chain("tool", "L23", "P", [])
    sk.output = "P"
    r = 0.04 * p.size
    for a, b in (("1", "2r"), ("2r", "3r"), ("3r", "4r"), ("4r", "1")):
        sk.link(f"link{a[0]}{b[0]}" if a != "4r" else "base", [a, b], r)
    return sk
