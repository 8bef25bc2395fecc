"""A planar 3-RRR parallel robot: a triangular base and a triangular platform joined by three legs of two links each, all nine axes parallel; the three base joints actuated; task: platform x, y and rotation about z.

Units: lengths in mm, angles in rad.

Base joints A1, A2, A3 (actuated) on a circle of radius ``base_radius``; elbows B1, B2, B3; platform
joints C1, C2, C3 on a circle of radius ``platform_radius``; every axis along z.  Leg 1 places the
platform frame P; legs 2 and 3 close on it through the fixed transforms P2 and P3 (the platform
triangle's own geometry).  A1 is the reference joint (no defects).

Theory.  8 bodies (base, 6 leg links, platform), 9 revolute joints, 2 independent loops.
Kutzbach in space: 6 (8 - 1) - 5 x 9 = -3; true mobility 3 (planar x, y, rz), so the degree of
over-constraint is 3 - (-3) = 6 (three per loop: out-of-plane translation and two tilts).

Theory: mobility 3, degree of over-constraint 6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton
from hyperstat.solver.errors import TemplateError

TOLERANCING = {
    "task": ["x", "y", "rz"],
    "measurements": {"kind": "positions",
                     "targets_mm": [[45.0, 0.0, 0.0], [-20.0, 40.0, 0.0]],
                     "noise_mm": 0.002},
    "spec": {"position_mm": 0.02, "orientation_rad": 1e-4},
}


@dataclass
class Parameters:
    """3-RRR dimensions (mm) and the drawn bar section."""

    base_radius: float = param(220.0, "mm", "radius of the circle through A1, A2, A3", minimum=0.0,
                               exclusive_minimum=True)
    platform_radius: float = param(60.0, "mm", "radius of the circle through C1, C2, C3", minimum=0.0,
                                   exclusive_minimum=True)
    proximal: float = param(140.0, "mm", "length of the links A-B", minimum=0.0, exclusive_minimum=True)
    distal: float = param(120.0, "mm", "length of the links B-C", minimum=0.0, exclusive_minimum=True)
    section: float = param(5.0, "mm", "radius of the bars drawn", minimum=0.0, exclusive_minimum=True)


def _elbow(a: np.ndarray, c: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """Elbow B of the leg A -> C, on the left of A -> C (law of cosines in the plane z = 0)."""
    v = c - a
    d = float(np.linalg.norm(v))
    if not abs(l1 - l2) < d < l1 + l2:
        raise TemplateError(f"a platform joint {d:g} mm from its base joint is out of reach of links "
                            f"{l1:g} mm and {l2:g} mm.")
    gamma = math.acos((l1 * l1 + d * d - l2 * l2) / (2 * l1 * d))
    ang = math.atan2(v[1], v[0]) + gamma
    return a + l1 * np.array([math.cos(ang), math.sin(ang), 0.0])


def build(**overrides: float) -> Skeleton:
    """Skeleton of the 3-RRR at home: platform centred over the base, not rotated."""
    p = make_parameters(Parameters, overrides)
    sk = Skeleton("rrr3_user", base="R0", parameters=p, marker_size=0.2 * p.distal,
                  description="Planar 3-RRR parallel robot, user-written")
    z = (0.0, 0.0, 1.0)
    for i in (1, 2, 3):
        t = math.pi / 2 + 2 * math.pi * (i - 1) / 3
        u = np.array([math.cos(t), math.sin(t), 0.0])
        a, c = p.base_radius * u, p.platform_radius * u
        b = _elbow(a, c, p.proximal, p.distal)
        sk.revolute(f"A{i}", a, z, role="actuated", x_axis=(1, 0, 0),
                    defects="" if i == 1 else "IJKabc", range=(-0.25, 0.25))
        sk.revolute(f"B{i}", b, z, range=(-math.pi, math.pi))
        sk.revolute(f"C{i}", c, z, range=(-math.pi, math.pi))
        sk.link(f"proximal{i}", [f"A{i}", f"B{i}"], p.section)
        sk.link(f"distal{i}", [f"B{i}", f"C{i}"], p.section)
    sk.frame("P", (0.0, 0.0, 0.0), z, (1.0, 0.0, 0.0))
    sk.fixed("P2", target="P")
    sk.fixed("P3", target="P")
    sk.chain("leg1", "R0", "P", ["A1", "B1", "C1"])
    sk.chain("leg2", "R0", "P", ["A2", "B2", "C2", "P2"])
    sk.chain("leg3", "R0", "P", ["A3", "B3", "C3", "P3"])
    sk.output = "P"
    sk.link("base", ["A1", "A2", "A3", "A1"], p.section)
    sk.link("platform", ["C1", "C2", "C3", "C1"], p.section)
    return sk
