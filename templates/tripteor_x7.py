"""Tripteor X7 (Exechon type) parallel kinematic machine tool, paper 1 section 4.2, eq. (9).

Units: lengths in mm, angles in rad.

Architecture (Fig. 4-5 of paper 1):

* legs 1 and 3 are UPR: a universal joint at the base (first axis ``u``, joints 11 and
  13, *collinear*; second axis ``v``, joints 21 and 23), an actuated prismatic joint
  along the leg (41, 43), and a revolute at the platform (51, 53) parallel to ``v``;
* leg 2 is SPR: a spherical joint at the base as three concurrent revolutes (12, 22,
  32), an actuated prismatic (42) and a platform revolute (52);
* the fixed transforms ``D_R52^R51`` (62) and ``D_R53^R51`` (63) carry legs 2 and 3 onto
  leg 1's platform frame ``R51`` (eq. 9), where the three legs close;
* ``T_R51^MPS`` places the moving-platform frame MPS, and a two-axis wrist (joints 6,
  C axis, and 7, A axis) carries the tool ``T``.

Parameters are named as in Table 2 (75 for the parallel architecture: ``D_ICS^L11`` is
the reference and carries none); the wrist adds ``dI6 ... dc7``.  With the frame
conventions of Fig. 1 the components come out as in the paper's tables (e.g. the
normalisation of ``z_L21`` falls on ``dI21`` and the perpendicularity ``u1 _|_ v1`` on
``dK21``, as in Table 4).

Dimensions are those of a mid-size machine: base U joints 800 mm apart on the common
``u`` axis (along y), the S joint 550 mm away on x, platform joints 300 mm apart,
800 mm below the base at home; strokes +-150 mm.  The home configuration puts the
legs 1 and 3 in the plane x = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton


#: Tolerancing declaration (hyperstat.solver.tolerances.declaration): a 5-axis machine tool machines with the tool
#: tip and the tool-axis direction (the rotation about the spindle does not matter); a laser tracker measures two
#: targets on a tool-axis adapter (tip and 100 mm up) at 107 poses, their offsets identified with the defects; spec
#: of a finishing machine tool.
TOLERANCING = {
    "task": ["position", "tool-axis"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0], [0.0, 0.0, 100.0]], "noise_mm": 0.005,
                     "offsets": "unknown", "poses": 107},
    "spec": {"position_mm": 0.05, "orientation_rad": 2e-4},
    "clearances": {"R": {"radial_mm": 0.005, "axial_mm": 0.005, "span_mm": 50.0, "twist_rad": 0.0, "side": "fixed",
                         "source": "ISO 5753-1 Group 2 (C2) radial internal clearance of a deep groove ball bearing, "
                                   "bore over 18 to 24 mm: 0 to 10 µm, i.e. +-5 µm radial play; tilt: two such "
                                   "bearings 50 mm apart (span assumed); axial play assumed equal to the radial; a "
                                   "preloaded bearing has none"},
                   "P": {"radial_mm": 0.002, "axial_mm": 0.0, "span_mm": 200.0, "twist_rad": 2e-5, "side": "fixed",
                         "source": "assumed (no public standard gives the play of a preloaded linear guide or ball "
                                   "screw): 2 µm on two pads 200 mm apart in a guide at the joint's fixed frame (a leg "
                                   "sliding through its base joint), so 20 µrad of tilt, and 20 µrad of twist"}},
}

@dataclass
class Parameters:
    """Tripteor X7 dimensions (mm)."""

    base_half_width: float = param(400.0, "mm", "half distance between the U joints of legs 1 and 3 (along u = y)",
                                   minimum=0.0, exclusive_minimum=True)
    base_leg2_offset: float = param(550.0, "mm", "distance of leg 2's S joint from the u axis (along x)",
                                    minimum=0.0, exclusive_minimum=True)
    platform_half_width: float = param(150.0, "mm", "half distance between the platform revolutes of legs 1 and 3",
                                       minimum=0.0, exclusive_minimum=True)
    platform_leg2_offset: float = param(200.0, "mm", "x offset of leg 2's platform revolute from the platform centre",
                                        minimum=0.0, exclusive_minimum=True)
    depth: float = param(800.0, "mm", "depth of the platform below the base at home", minimum=0.0,
                         exclusive_minimum=True)
    stroke: float = param(150.0, "mm", "actuator stroke on each side of the home length", minimum=0.0,
                          exclusive_minimum=True)
    wrist_c_offset: float = param(100.0, "mm", "platform centre to the C axis origin (down)", minimum=0.0)
    wrist_a_offset: float = param(100.0, "mm", "C axis origin to the A axis (down)", minimum=0.0,
                                  exclusive_minimum=True)
    tool_length: float = param(150.0, "mm", "A axis to the tool tip (down)", minimum=0.0, exclusive_minimum=True)
    section: float = param(12.0, "mm", "radius of the link bars drawn in CAD", minimum=0.0, exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the Tripteor X7 at its home configuration (legs 1 and 3 in the plane x = 0).

    Parameters
    ----------
    **overrides : float
        Any field of :class:`Parameters` (mm).

    Returns
    -------
    Skeleton
    """
    p = make_parameters(Parameters, overrides)
    ex, ey, ez = np.eye(3)
    a1 = np.array([0.0, -p.base_half_width, 0.0])
    a3 = np.array([0.0, p.base_half_width, 0.0])
    a2 = np.array([p.base_leg2_offset, 0.0, 0.0])
    b1 = np.array([0.0, -p.platform_half_width, -p.depth])
    b3 = np.array([0.0, p.platform_half_width, -p.depth])
    b2 = np.array([p.platform_leg2_offset, 0.0, -p.depth])
    centre = np.array([0.0, 0.0, -p.depth])
    l1, l2, l3 = (float(np.linalg.norm(b - a)) for a, b in ((a1, b1), (a2, b2), (a3, b3)))
    d1, d2, d3 = ((b - a) / np.linalg.norm(b - a) for a, b in ((a1, b1), (a2, b2), (a3, b3)))
    sk = Skeleton("tripteor_x7", base="ICS", parameters=p, marker_size=60.0,
                  description="Tripteor X7 / Exechon-type PKM, paper 1 section 4.2 (Guyon et al. 2022)")
    u_rng, s_rng, w_rng = (-0.8, 0.8), (-1.2, 1.2), (-1.0, 1.0)
    stroke = p.stroke
    # leg 1: U (11 u1 = y, reference, no defect; 21 v1 = x), P 41, R 51 (w1 // v1)
    sk.revolute("11", a1, ey, defects="", range=u_rng)
    sk.revolute("21", a1, ex, range=u_rng)
    sk.prismatic("41", a1, d1, role="actuated", home=l1, range=(l1 - stroke, l1 + stroke))
    sk.revolute("51", b1, ex, range=w_rng)
    # leg 2: S as three concurrent revolutes (12 u2 = x, 22 v2 = y, 32 u'2 = z), P 42, R 52 (w2 = y)
    sk.revolute("12", a2, ex, range=s_rng)
    sk.revolute("22", a2, ey, range=s_rng)
    sk.revolute("32", a2, ez, range=s_rng)
    sk.prismatic("42", a2, d2, role="actuated", home=l2, range=(l2 - stroke, l2 + stroke))
    sk.revolute("52", b2, ey, range=w_rng)
    sk.fixed("62", target="R51")
    # leg 3: U (13 u3 = y, collinear with u1; 23 v3 = x), P 43, R 53 (w3 // v3)
    sk.revolute("13", a3, ey, range=u_rng)
    sk.revolute("23", a3, ex, range=u_rng)
    sk.prismatic("43", a3, d3, role="actuated", home=l3, range=(l3 - stroke, l3 + stroke))
    sk.revolute("53", b3, ex, range=w_rng)
    sk.fixed("63", target="R51")
    # platform frame and wrist (C axis 6 along z, A axis 7 along y), tool T
    c6 = centre - p.wrist_c_offset * ez
    c7 = c6 - p.wrist_a_offset * ez
    tip = c7 - p.tool_length * ez
    sk.frame("MPS", centre, ez, ex)
    sk.revolute("6", c6, ez, role="actuated", range=(-math.pi, math.pi))
    sk.revolute("7", c7, ey, role="actuated", range=(-math.pi / 3, math.pi / 3))
    sk.frame("T", tip, ez, ex)
    sk.chain("leg1", "ICS", "R51", ["11", "21", "41", "51"])
    sk.chain("platform", "R51", "MPS", [])
    sk.chain("leg2", "ICS", "R51", ["12", "22", "32", "42", "52", "62"])
    sk.chain("leg3", "ICS", "R51", ["13", "23", "43", "53", "63"])
    sk.chain("wrist", "MPS", "T", ["6", "7"])
    sk.output = "T"
    r = p.section
    sk.link("base", [a1, a3], r)
    sk.link("base_leg2", [(0.0, 0.0, 0.0), a2], r)
    sk.link("leg1", ["41", b1], r)
    sk.link("leg2", ["42", b2], r)
    sk.link("leg3", ["43", b3], r)
    sk.link("platform", [b1, b3], r)
    sk.link("platform_leg2", [centre, b2], r)
    sk.link("spindle", [centre, c6, c7, tip], r)
    return sk


if "show_object" in globals():  # CQ-editor
    from hyperstat.cad_plugin.assembly import build_assembly

    show_object(build_assembly(build()))  # noqa: F821
