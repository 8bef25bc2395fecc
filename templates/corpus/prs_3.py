"""3-PRS parallel manipulator: three vertical actuated slides, each with a hinge and a rod to a spherical joint.

Units: lengths in mm, angles in rad.

Leg ``i`` (at 120 degrees): the actuated slide ``Li`` along z at radius ``base_radius``; on the
slider the hinge ``Hi`` about the tangent ``u_i`` of the base circle; the rod (``rod``) in the
leg's radial plane to the spherical joint at the platform, three revolutes through one point,
``Si1`` along the rod, ``Si2`` along ``u_i`` and ``Si3`` normal to both.  Leg 1 places the platform
frame ``P``; legs 2 and 3 close on it through ``P2`` and ``P3``.  ``L1`` is the reference.

Theory.  Bodies: base, platform and four per leg (slider, rod, two between the spherical
joint's revolutes): 14; joints: 15 (12 revolutes, 3 slides); loops: 2.  Kutzbach: 6 x 13 -
5 x 15 = 3.  Screws: each leg's five joint screws span a 5-system whose reciprocal is a force
through the spherical joint's centre along the hinge axis ``u_i``; the three forces are
independent, so the 15 screws have rank 12 in the 12 loop equations: mobility 3 (the platform's
height and two tilts, with parasitic motions), degree of over-constraint 0, no assembly
condition.

Theory: mobility 3, degree of over-constraint 0, assembly conditions 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton
from hyperstat.solver.errors import TemplateError

TOLERANCING = {
    "task": ["z", "rx", "ry"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0], [80.0, 0.0, 0.0], [0.0, 80.0, 0.0]],
                     "noise_mm": 0.005},
    "spec": {"position_mm": 0.02, "orientation_rad": 1e-4},
}


@dataclass
class Parameters:
    """3-PRS dimensions (mm)."""

    base_radius: float = param(250.0, "mm", "radius of the circle of the slides", minimum=0.0, exclusive_minimum=True)
    platform_radius: float = param(100.0, "mm", "radius of the circle through the spherical joints", minimum=0.0,
                                   exclusive_minimum=True)
    rod: float = param(250.0, "mm", "rod length, hinge to spherical joint", minimum=0.0, exclusive_minimum=True)
    height: float = param(300.0, "mm", "platform height at home", minimum=0.0, exclusive_minimum=True)
    stroke: float = param(40.0, "mm", "slide travel each way from home", minimum=0.0, exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the 3-PRS at home: the platform level, centred above the base."""
    p = make_parameters(Parameters, overrides)
    inward = p.base_radius - p.platform_radius
    if not inward < p.rod:
        raise TemplateError(f"the rod ({p.rod:g} mm) must be longer than the radii's difference ({inward:g} mm).")
    drop = math.sqrt(p.rod**2 - inward**2)  # the hinge sits this far below the platform
    sk = Skeleton("prs_3", base="R0", parameters=p, marker_size=0.1 * p.rod, description="3-PRS parallel manipulator")
    sk.frame("P", (0, 0, p.height), (0, 0, 1), (1, 0, 0))
    r = 0.02 * p.rod
    z = np.array([0.0, 0.0, 1.0])
    for i in (1, 2, 3):
        phi = math.pi / 2 + 2 * math.pi * (i - 1) / 3
        radial = np.array([math.cos(phi), math.sin(phi), 0.0])
        u = np.array([-math.sin(phi), math.cos(phi), 0.0])
        foot = p.base_radius * radial
        hinge = foot + (p.height - drop) * z
        centre = np.array([0.0, 0.0, p.height]) + p.platform_radius * radial
        along = (centre - hinge) / p.rod
        sk.prismatic(f"L{i}", foot, z, role="actuated", defects="" if i == 1 else "IJK", home=p.height - drop,
                     range=(p.height - drop - p.stroke, p.height - drop + p.stroke))
        sk.revolute(f"H{i}", hinge, u)
        sk.revolute(f"S{i}1", centre, along)
        sk.revolute(f"S{i}2", centre, u)
        sk.revolute(f"S{i}3", centre, np.cross(along, u))
        names = [f"L{i}", f"H{i}", f"S{i}1", f"S{i}2", f"S{i}3"]
        if i > 1:
            sk.fixed(f"P{i}", target="P")
            names.append(f"P{i}")
        sk.chain(f"leg{i}", "R0", "P", names)
        sk.link(f"slide{i}", [foot, foot + (p.height + p.stroke) * z], r)
        sk.link(f"rod{i}", [f"H{i}", f"S{i}1"], r)
    sk.output = "P"
    sk.link("platform", [f"S{i}1" for i in (1, 2, 3, 1)], r)
    return sk
