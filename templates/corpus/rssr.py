"""RSSR spatial four-bar: a crank and a rocker on skew axes, joined by a rod with a ball joint at each end.

Units: lengths in mm, angles in rad.

The crank turns about ``1`` (axis z through the origin, actuated); the rocker about ``2`` (axis x
through ``(distance, 0, height)``).  Each ball joint is three revolutes through its centre (``S1a,
S1b, S1c`` at the crank pin, ``S2a, S2b, S2c`` at the rocker pin, along three orthogonal directions
not aligned with the rod).  The rocker chain places the rocker's frame ``RK`` (its first joint,
``2``, is the reference), the chain ``S2a, S2b, S2c`` from it the rod's frame ``ROD``, and the crank
chain closes on the rod through the fixed transform ``X`` (the rod's geometry).  Output: the frame
``P`` at the rocker pin, on the rocker: not on the rod, whose spin about its own line is free.

Theory.  Bodies: base, crank, rod, rocker and two between each ball joint's revolutes: 8; joints:
8 revolutes; one loop.  Kutzbach: 6 x 7 - 5 x 8 = 2.  Screws: the eight joint screws span all six
dimensions, so the mobility is 8 - 6 = 2: the input motion and the rod's spin about its own line
(an idle motion: the passive joints move with the input held), and the degree of
over-constraint 6 - 6 = 0; no assembly condition.

Theory: mobility 2, degree of over-constraint 0, assembly conditions 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton

TOLERANCING = {
    "task": ["position"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.05, "orientation_rad": None},
}


@dataclass
class Parameters:
    """RSSR dimensions (mm) and home angles (rad)."""

    crank: float = param(50.0, "mm", "crank radius", minimum=0.0, exclusive_minimum=True)
    rocker: float = param(80.0, "mm", "rocker radius", minimum=0.0, exclusive_minimum=True)
    distance: float = param(150.0, "mm", "distance of the rocker axis from the crank axis along x", minimum=0.0,
                            exclusive_minimum=True)
    height: float = param(60.0, "mm", "height of the rocker axis above the crank's plane")
    home_crank: float = param(0.5, "rad", "crank angle at home", minimum=-math.pi, maximum=math.pi)
    home_rocker: float = param(1.2, "rad", "rocker angle at home (the rod length follows)", minimum=-math.pi,
                               maximum=math.pi)


def _triad(direction: np.ndarray) -> list[np.ndarray]:
    """Three orthonormal ball-joint axes, none along ``direction`` (the rod)."""
    d = direction / np.linalg.norm(direction)
    helper = np.array([0.3, 0.5, 0.8])
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    c, s = math.cos(0.6), math.sin(0.6)  # turn the pair about e2 by 0.6 rad off the rod
    a = c * d + s * e1
    b = -s * d + c * e1
    return [a, b, e2]


def build(**overrides: float) -> Skeleton:
    """Skeleton of the RSSR at home."""
    p = make_parameters(Parameters, overrides)
    pin1 = p.crank * np.array([math.cos(p.home_crank), math.sin(p.home_crank), 0.0])
    pivot2 = np.array([p.distance, 0.0, p.height])
    pin2 = pivot2 + p.rocker * np.array([0.0, math.cos(p.home_rocker), math.sin(p.home_rocker)])
    rod = pin2 - pin1
    sk = Skeleton("rssr", base="R0", parameters=p, marker_size=0.2 * p.crank, description="RSSR spatial four-bar")
    sk.revolute("1", (0, 0, 0), (0, 0, 1), role="actuated", x_axis=(1, 0, 0), home=p.home_crank,
                range=(p.home_crank - 0.5, p.home_crank + 0.5))
    sk.revolute("2", pivot2, (1, 0, 0), x_axis=(0, 1, 0), defects="", home=p.home_rocker)
    for name, centre in (("S1", pin1), ("S2", pin2)):
        for tag, axis in zip("abc", _triad(rod)):
            sk.revolute(f"{name}{tag}", centre, axis)
    sk.fixed("X", target="ROD")
    arm = pin2 - pivot2
    sk.frame("P", pin2, (1, 0, 0), arm / np.linalg.norm(arm))
    sk.chain("rocker", "R0", "RK", ["2"])
    sk.chain("rod", "RK", "ROD", ["S2a", "S2b", "S2c"])
    sk.chain("crank", "R0", "ROD", ["1", "S1a", "S1b", "S1c", "X"])
    sk.chain("tool", "RK", "P", [])
    sk.output = "P"
    r = 0.06 * p.crank
    sk.link("base", [(0, 0, 0), (p.distance, 0, 0), pivot2], r)
    sk.link("crank", ["1", pin1], r)
    sk.link("rod", [pin1, pin2], r)
    sk.link("rocker", [pivot2, pin2], r)
    return sk
