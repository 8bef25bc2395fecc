"""3-UPU translational parallel manipulator (Tsai): three legs universal - actuated slide - universal.

Units: lengths in mm, angles in rad.

Leg ``i`` (at 120 degrees): on the base at ``A_i`` a universal joint of two revolutes, ``Ui1``
about the tangent ``a_i`` of the base circle and ``Ui2`` about ``b_i``, normal to ``a_i`` and to the
leg; the actuated slide ``Li`` along the leg; on the platform at ``B_i`` a universal joint whose
axes are the same directions in reverse order, ``Ui3`` about ``b_i`` and ``Ui4`` about ``a_i``.
Leg 1 places the platform frame ``P``; legs 2 and 3 close on it through ``P2`` and ``P3`` (the
platform's own geometry).  ``U11`` (the first joint of the first chain) is the reference.

Theory.  Bodies: base, platform and four per leg (two crosses, two leg halves): 14; joints:
15 (12 revolutes, 3 slides); loops: 2.  Kutzbach: 6 x 13 - 5 x 15 = 3.  Screws: each leg's
five joints span a 5-system whose reciprocal is a couple about ``a_i x b_i``; the three couples
are independent, so the platform only translates: mobility 3, the 15 screws have rank 12 in the
12 loop equations, degree of over-constraint 0, and no assembly condition.  Tsai's conditions
(each universal joint's outer axes parallel, ``a_i`` on the base and on the platform, and its
inner axes parallel, ``b_i``) do not make it assemble: they make it *translate*.  Broken, the
machine still assembles and moves, with a parasitic rotation of the platform: they are
accuracy conditions on the orientation, not assembly conditions.

Theory: mobility 3, degree of over-constraint 0, assembly conditions 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton

TOLERANCING = {
    "task": ["position", "orientation"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0], [80.0, 0.0, 0.0], [0.0, 80.0, 0.0]],
                     "noise_mm": 0.005},
    "spec": {"position_mm": 0.05, "orientation_rad": 2e-4},
}


@dataclass
class Parameters:
    """3-UPU dimensions (mm)."""

    base_radius: float = param(250.0, "mm", "radius of the circle through the base joints", minimum=0.0,
                               exclusive_minimum=True)
    platform_radius: float = param(120.0, "mm", "radius of the circle through the platform joints", minimum=0.0,
                                   exclusive_minimum=True)
    height: float = param(400.0, "mm", "platform height above the base at home", minimum=0.0, exclusive_minimum=True)
    stroke: float = param(60.0, "mm", "slide travel each way from home", minimum=0.0, exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the 3-UPU at home: the platform centred above the base."""
    p = make_parameters(Parameters, overrides)
    sk = Skeleton("tsai_3upu", base="R0", parameters=p, marker_size=0.1 * p.height,
                  description="3-UPU translational parallel manipulator (Tsai)")
    sk.frame("P", (0, 0, p.height), (0, 0, 1), (1, 0, 0))
    r = 0.02 * p.height
    for i in (1, 2, 3):
        phi = math.pi / 2 + 2 * math.pi * (i - 1) / 3
        radial = np.array([math.cos(phi), math.sin(phi), 0.0])
        a = np.array([-math.sin(phi), math.cos(phi), 0.0])
        base = p.base_radius * radial
        top = np.array([0.0, 0.0, p.height]) + p.platform_radius * radial
        length = float(np.linalg.norm(top - base))
        s = (top - base) / length
        b = np.cross(s, a)
        sk.revolute(f"U{i}1", base, a, defects="" if i == 1 else "IJKabc")
        sk.revolute(f"U{i}2", base, b)
        sk.prismatic(f"L{i}", base, s, role="actuated", home=length, range=(length - p.stroke, length + p.stroke))
        sk.revolute(f"U{i}3", top, b)
        sk.revolute(f"U{i}4", top, a)
        names = [f"U{i}1", f"U{i}2", f"L{i}", f"U{i}3", f"U{i}4"]
        if i > 1:
            sk.fixed(f"P{i}", target="P")
            names.append(f"P{i}")
        sk.chain(f"leg{i}", "R0", "P", names)
        sk.link(f"leg{i}", [base, top], r)
    sk.output = "P"
    sk.link("base", [f"U{i}1" for i in (1, 2, 3, 1)], r)
    sk.link("platform", [f"U{i}4" for i in (1, 2, 3, 1)], r)
    return sk
