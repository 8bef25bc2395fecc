"""SCARA robot, serial RRPR (no loop): the serial case of the joint-invariant model.

Units: lengths in mm, angles in rad.

Joint 1 (shoulder) and 2 (elbow) are revolutes about the vertical, 3 the vertical
quill (prismatic), 4 the wrist roll; all four axes are parallel, the case the
Denavit-Hartenberg parameters handle badly and the joint invariants handle well
(Chanal et al. 2021, ref. [11] of paper 1).  The tool frame is a fixed transform with
all six rigid-body defects (``IJKabc`` and the roll ``G``), so that eq. (1) of paper 1
applies: ``C = 4R + 2P + 6 = 20`` independent parameters for a full-pose output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton


#: Tolerancing declaration (hyperstat.solver.tolerances.declaration): a SCARA places a part and turns it about the
#: vertical (position and rz); a 6-D probe measures the tool pose.
TOLERANCING = {
    "task": ["position", "rz"],
    "measurements": {"kind": "poses", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.005, "noise_rad": 1e-5},
    "spec": {"position_mm": 0.05, "orientation_rad": 5e-4},
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
    """SCARA dimensions (mm)."""

    column: float = param(400.0, "mm", "height of the arm above the base", minimum=0.0, exclusive_minimum=True)
    arm1: float = param(350.0, "mm", "shoulder to elbow", minimum=0.0, exclusive_minimum=True)
    arm2: float = param(300.0, "mm", "elbow to quill", minimum=0.0, exclusive_minimum=True)
    quill_stroke: float = param(150.0, "mm", "vertical stroke of the quill", minimum=0.0, exclusive_minimum=True)
    tool_offset: float = param(40.0, "mm", "tool tip offset from the wrist axis", minimum=0.0)
    tool_length: float = param(120.0, "mm", "tool tip below the arm", minimum=0.0, exclusive_minimum=True)
    section: float = param(15.0, "mm", "radius of the link bars drawn in CAD", minimum=0.0, exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the SCARA at its home configuration (arm stretched along x, quill up).

    Returns
    -------
    Skeleton
    """
    p = make_parameters(Parameters, overrides)
    sk = Skeleton("scara", base="R0", parameters=p, marker_size=40.0,
                  description="SCARA robot RRPR (serial, parallel axes)")
    h, x2, x3 = p.column, p.arm1, p.arm1 + p.arm2
    sk.revolute("1", (0, 0, 0), (0, 0, 1), role="actuated", range=(-2.5, 2.5))
    sk.revolute("2", (x2, 0, h), (0, 0, 1), role="actuated", range=(-2.5, 2.5))
    sk.prismatic("3", (x3, 0, h), (0, 0, 1), role="actuated", range=(-p.quill_stroke, 0.0))
    sk.revolute("4", (x3, 0, h), (0, 0, 1), role="actuated", range=(-math.pi, math.pi))
    sk.fixed("5", (x3 + p.tool_offset, 0, h - p.tool_length), (0, 0, -1), (1, 0, 0), defects="IJKabcG")
    sk.chain("arm", "R0", "T", ["1", "2", "3", "4", "5"])
    sk.output = "T"
    sk.link("column", [(0, 0, 0), (0, 0, h)], p.section)
    sk.link("arm1", [(0, 0, h), "2"], p.section)
    sk.link("arm2", ["2", "3"], p.section)
    sk.link("quill", ["4", (x3, 0, h - p.tool_length), "5"], 0.5 * p.section)
    return sk


if "show_object" in globals():  # CQ-editor
    from hyperstat.cad_plugin.assembly import build_assembly

    show_object(build_assembly(build()))  # noqa: F821
