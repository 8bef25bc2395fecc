"""Spherical four-bar linkage: four revolute joints whose axes meet at one point (a spatial, over-constrained loop).

Units: lengths in mm, angles in rad.

Joints 1 (actuated, the reference) and 4 on the base, 2 between the crank and the coupler, 3 between the
coupler and the rocker; every axis passes through the centre O.  The crank chain 1, 2 places the coupler
frame R2; the rocker chain 4, 3 closes on it through the fixed transform 5 (the coupler's own geometry,
with its defects).  The output frame P sits on the coupler, ``radius`` from O.  The link arcs are angles
between neighbouring axes.

Theory.  One loop, four joints.  Kutzbach: 6 x 3 - 5 x 4 = -2, yet the linkage moves: four rotations
about lines through one point span only the 3-system of rotations about that point, so the
mobility is 4 - 3 = 1 and the degree of over-constraint 6 - 3 = 3.  The known conditions: the four
axes meet at one point.  In link terms, each link's two axes intersect (four lengths zero) at the
same point (four offsets zero): 8 conditions, and the four arcs are free.

Theory: mobility 1, degree of over-constraint 3, assembly conditions 8.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton
from hyperstat.solver.errors import TemplateError

TOLERANCING = {
    "task": ["orientation"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0], [60.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": None, "orientation_rad": 2e-4},
}


@dataclass
class Parameters:
    """Arcs of the spherical four-bar (rad) and the size it is drawn at (mm)."""

    base_arc: float = param(1.2, "rad", "angle between the base axes 1 and 4", minimum=0.1, maximum=2.5)
    crank_arc: float = param(0.5, "rad", "angle between the axes 1 and 2", minimum=0.1, maximum=2.5)
    coupler_arc: float = param(1.1, "rad", "angle between the axes 2 and 3", minimum=0.1, maximum=2.5)
    rocker_arc: float = param(0.9, "rad", "angle between the axes 4 and 3", minimum=0.1, maximum=2.5)
    home_crank: float = param(1.0, "rad", "crank angle of the home configuration", minimum=-math.pi,
                              maximum=math.pi)
    radius: float = param(100.0, "mm", "distance from the centre at which the links are drawn", minimum=0.0,
                          exclusive_minimum=True)


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``v`` rotated about the unit ``axis`` by ``angle`` (Rodrigues)."""
    return (v * math.cos(angle) + np.cross(axis, v) * math.sin(angle)
            + axis * float(axis @ v) * (1 - math.cos(angle)))


def build(**overrides: float) -> Skeleton:
    """Skeleton of the spherical four-bar at home."""
    p = make_parameters(Parameters, overrides)
    u1 = np.array([0.0, 0.0, 1.0])
    u4 = np.array([math.sin(p.base_arc), 0.0, math.cos(p.base_arc)])
    u2 = _rotate(_rotate(u1, np.array([0.0, 1.0, 0.0]), -p.crank_arc), u1, p.home_crank)
    # u3: at coupler_arc from u2 and rocker_arc from u4 (two circles on the unit sphere)
    n = np.cross(u2, u4)
    c2, c4, g = math.cos(p.coupler_arc), math.cos(p.rocker_arc), float(u2 @ u4)
    if np.linalg.norm(n) < 1e-9:
        raise TemplateError("the axes 2 and 4 coincide at home: choose another home_crank.")
    a = (c2 - c4 * g) / (1 - g * g)
    b = (c4 - c2 * g) / (1 - g * g)
    rest = 1.0 - float(np.linalg.norm(a * u2 + b * u4)) ** 2
    if rest < 0:
        raise TemplateError("the coupler and rocker arcs cannot close the loop at home_crank; change the arcs.")
    u3 = a * u2 + b * u4 + math.sqrt(rest) * n / np.linalg.norm(n)
    o = np.zeros(3)
    sk = Skeleton("spherical_4r", base="R0", parameters=p, marker_size=0.3 * p.radius,
                  description="Spherical four-bar linkage (axes through one point)")
    sk.revolute("1", o, u1, role="actuated", x_axis=(1, 0, 0), defects="", home=0.0, range=(-0.4, 0.4))
    sk.revolute("2", o, u2, range=(-math.pi, math.pi))
    sk.revolute("4", o, u4, range=(-math.pi, math.pi))
    sk.revolute("3", o, u3, range=(-math.pi, math.pi))
    sk.fixed("5", target="R2")
    tip = p.radius * (u2 + u3) / np.linalg.norm(u2 + u3)
    sk.frame("P", tip, tip / np.linalg.norm(tip), u3 - u2)
    sk.chain("crank", "R0", "R2", ["1", "2"])
    sk.chain("rocker", "R0", "R2", ["4", "3", "5"])
    sk.chain("tool", "R2", "P", [])
    sk.output = "P"
    r = p.radius
    sk.link("base", [r * u1, o, r * u4], 0.05 * r)
    sk.link("crank", [r * u1, r * u2], 0.05 * r)
    sk.link("coupler", [r * u2, tip, r * u3], 0.05 * r)
    sk.link("rocker", [r * u4, r * u3], 0.05 * r)
    return sk
