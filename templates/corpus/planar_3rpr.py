"""Planar 3-RPR parallel manipulator: three legs of a base hinge, an actuated slide and a platform hinge.

Units: lengths in mm, angles in rad.

Leg ``i`` (at 120 degrees): the hinge ``Ai`` on the base (axis z), the actuated slide ``Li`` along
the leg, the hinge ``Ci`` on the platform (axis z).  Leg 1 places the platform frame ``P``; legs 2
and 3 close on it through ``P2`` and ``P3`` (the platform's own geometry).  ``A1`` is the
reference.

Theory.  Bodies: base, platform and two per leg: 8; joints: 9 (6 revolutes, 3 slides); loops: 2.
Kutzbach in space: 6 x 7 - 5 x 9 = -3; in the plane 3 x 7 - 2 x 9 = 3, the true mobility.  Screws:
the nine joint screws span the three planar motions only (rotation about z, translations in
x-y): rank 9 - 3 = 6 in the 12 loop equations, so the degree of over-constraint is 12 - 6 = 6,
three per loop (the hinges must stay parallel and the slides in the plane).  Known conditions:
every hinge axis parallel to z and every slide normal to it; to first order 19 independent
conditions on the joint geometry, two fewer than the planar 3-RRR's 21 because a slide's place
is no geometry, only its direction (the stationarity analysis and an independent screw
computation agree).

Theory: mobility 3, degree of over-constraint 6, assembly conditions 19.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton

TOLERANCING = {
    "task": ["x", "y", "rz"],
    "measurements": {"kind": "positions", "targets_mm": [[40.0, 0.0, 0.0], [-20.0, 35.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.02, "orientation_rad": 1e-4},
}


@dataclass
class Parameters:
    """3-RPR dimensions (mm)."""

    base_radius: float = param(250.0, "mm", "radius of the circle through the base hinges", minimum=0.0,
                               exclusive_minimum=True)
    platform_radius: float = param(60.0, "mm", "radius of the circle through the platform hinges", minimum=0.0,
                                   exclusive_minimum=True)
    twist: float = param(0.5, "rad", "rotation of the platform at home", minimum=-1.5, maximum=1.5)
    stroke: float = param(15.0, "mm", "slide travel each way from home (every combination of the three slides "
                          "assembles within it)", minimum=0.0, exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the 3-RPR at home: the platform centred, turned by ``twist``."""
    p = make_parameters(Parameters, overrides)
    sk = Skeleton("planar_3rpr", base="R0", parameters=p, marker_size=0.1 * p.base_radius,
                  description="Planar 3-RPR parallel manipulator")
    z = (0.0, 0.0, 1.0)
    sk.frame("P", (0, 0, 0), z, (math.cos(p.twist), math.sin(p.twist), 0.0))
    r = 0.02 * p.base_radius
    for i in (1, 2, 3):
        phi = math.pi / 2 + 2 * math.pi * (i - 1) / 3
        a = p.base_radius * np.array([math.cos(phi), math.sin(phi), 0.0])
        c = p.platform_radius * np.array([math.cos(phi + p.twist), math.sin(phi + p.twist), 0.0])
        length = float(np.linalg.norm(c - a))
        sk.revolute(f"A{i}", a, z, x_axis=(1, 0, 0), defects="" if i == 1 else "IJKabc")
        sk.prismatic(f"L{i}", a, c - a, role="actuated", home=length, range=(length - p.stroke, length + p.stroke))
        sk.revolute(f"C{i}", c, z)
        names = [f"A{i}", f"L{i}", f"C{i}"]
        if i > 1:
            sk.fixed(f"P{i}", target="P")
            names.append(f"P{i}")
        sk.chain(f"leg{i}", "R0", "P", names)
        sk.link(f"leg{i}", [f"A{i}", f"C{i}"], r)
    sk.output = "P"
    sk.link("base", ["A1", "A2", "A3", "A1"], r)
    sk.link("platform", ["C1", "C2", "C3", "C1"], r)
    return sk
