"""Delta robot with parallelograms, all joints revolute: three legs R-R-(4R parallelogram)-R, a translating platform.

Units: lengths in mm, angles in rad.

Leg ``i`` (i = 1, 2, 3, at 120 degrees): the actuated hinge ``Ai`` on the base, its axis ``u_i``
tangent to the base circle; the upper arm (``arm``, horizontal at home) to the elbow ``Bi``, axis
``u_i``; the elbow carries the top bar of a parallelogram, whose two rods (``rod``) hinge at the
four corners ``Qia, Qib`` (top) and ``Qic, Qid`` (bottom) about the normal ``w_i`` of the
parallelogram's plane; the bottom bar hinges on the platform at ``Ci``, axis ``u_i``.  Chains:
``arm_i`` (A, B) places the top bar, ``rod_i`` (Qa, Qc) places the bottom bar, ``rod2_i`` (Qb, Qd)
closes the parallelogram through the fixed transform ``Fi`` (the bottom bar's geometry), and
``wrist_i`` (C) reaches the platform frame ``P``: leg 1's places it, legs 2 and 3 close on it
through ``P2``, ``P3`` (the platform's own geometry).  A1 is the reference.

Theory.  Bodies: base, platform, and per leg the arm, the top bar, two rods and the bottom bar:
17; joints: 21 revolutes; independent loops: 21 - 17 + 1 = 5 (three parallelograms, two through
the platform).  Kutzbach: 6 x 16 - 5 x 21 = -9.  Screws: each leg's three hinges parallel to
``u_i`` and the parallelogram's translation span the rotation about ``u_i`` and all three
translations (a 4-system); each leg leaves the platform its three translations, the three legs
together nothing else, so the mobility is 3 (translations) and the 21 joint screws have rank
21 - 3 = 18 in the 30 loop equations: degree of over-constraint 30 - 18 = 12 (three per planar
parallelogram written in space, three for the platform's rotations forbidden twice).  The known
conditions keep each parallelogram's four hinges parallel and its opposite sides equal, and each
leg's hinges ``u_i`` parallel (the three directions ``u_i`` are free): to first order they are 47
independent conditions on the joint geometry (the stationarity analysis and an independent screw
computation agree).

Theory: mobility 3, degree of over-constraint 12, assembly conditions 47.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton
from hyperstat.solver.errors import TemplateError

TOLERANCING = {
    "task": ["position"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.005},
    "spec": {"position_mm": 0.05, "orientation_rad": None},
}


@dataclass
class Parameters:
    """Delta dimensions (mm)."""

    base_radius: float = param(200.0, "mm", "radius of the circle through the actuated hinges", minimum=0.0,
                               exclusive_minimum=True)
    platform_radius: float = param(50.0, "mm", "radius of the circle through the platform hinges", minimum=0.0,
                                   exclusive_minimum=True)
    arm: float = param(200.0, "mm", "upper arm, actuated hinge to elbow", minimum=0.0, exclusive_minimum=True)
    rod: float = param(450.0, "mm", "parallelogram rod length", minimum=0.0, exclusive_minimum=True)
    width: float = param(60.0, "mm", "parallelogram width (distance between the rods)", minimum=0.0,
                         exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the Delta at home: arms horizontal, platform centred below the base."""
    p = make_parameters(Parameters, overrides)
    reach = p.base_radius + p.arm - p.platform_radius
    if not reach < p.rod:
        raise TemplateError(f"the rods ({p.rod:g} mm) must be longer than {reach:g} mm to reach the platform.")
    depth = math.sqrt(p.rod**2 - reach**2)
    sk = Skeleton("delta_r", base="R0", parameters=p, marker_size=0.1 * p.arm,
                  description="Delta robot with parallelograms (revolute joints only)")
    centre = np.array([0.0, 0.0, -depth])
    sk.frame("P", centre, (0, 0, 1), (1, 0, 0))
    r = 0.02 * p.arm
    for i in (1, 2, 3):
        phi = math.pi / 2 + 2 * math.pi * (i - 1) / 3
        radial = np.array([math.cos(phi), math.sin(phi), 0.0])
        u = np.array([-math.sin(phi), math.cos(phi), 0.0])
        a = p.base_radius * radial
        b = a + p.arm * radial
        c = centre + p.platform_radius * radial
        rod = c - b
        w = np.cross(u, rod) / np.linalg.norm(np.cross(u, rod))
        half = 0.5 * p.width * u
        sk.revolute(f"A{i}", a, u, role="actuated", x_axis=radial, defects="" if i == 1 else "IJKabc", home=0.0,
                    range=(-0.3, 0.3))
        sk.revolute(f"B{i}", b, u)
        sk.revolute(f"Q{i}a", b - half, w)
        sk.revolute(f"Q{i}b", b + half, w)
        sk.revolute(f"Q{i}c", c - half, w)
        sk.revolute(f"Q{i}d", c + half, w)
        sk.revolute(f"C{i}", c, u)
        sk.fixed(f"F{i}", target=f"bottom{i}")
        sk.chain(f"arm{i}", "R0", f"top{i}", [f"A{i}", f"B{i}"])
        sk.chain(f"rod{i}", f"top{i}", f"bottom{i}", [f"Q{i}a", f"Q{i}c"])
        sk.chain(f"rod2_{i}", f"top{i}", f"bottom{i}", [f"Q{i}b", f"Q{i}d", f"F{i}"])
        if i == 1:
            sk.chain(f"wrist{i}", f"bottom{i}", "P", [f"C{i}"])
        else:
            sk.fixed(f"P{i}", target="P")
            sk.chain(f"wrist{i}", f"bottom{i}", "P", [f"C{i}", f"P{i}"])
        sk.link(f"arm{i}", [f"A{i}", f"B{i}"], 2 * r)
        sk.link(f"top{i}", [f"Q{i}a", f"Q{i}b"], r)
        sk.link(f"rod{i}a", [f"Q{i}a", f"Q{i}c"], r)
        sk.link(f"rod{i}b", [f"Q{i}b", f"Q{i}d"], r)
        sk.link(f"bottom{i}", [f"Q{i}c", f"Q{i}d"], r)
    sk.output = "P"
    sk.link("base", ["A1", "A2", "A3", "A1"], 2 * r)
    sk.link("platform", ["C1", "C2", "C3", "C1"], 2 * r)
    return sk
