"""Slider-rod-crank of paper 1 (Guyon et al. 2022), section 4.1, Table 1, eqs. (4)-(7).

Units: lengths in mm, angles in rad.

Joints as numbered in the paper: 1 the crank pivot (actuated, the reference: its
``D_R0^L1`` carries no defect), 2 the crank pin, 3 the pin between rod and slider
block, 4 the slide (prismatic, passive).  The crank chain reaches the slider frame
``RF`` through ``T_R3^RF`` (a shift ``L3`` along ``x_R3``), the slide through
``T_R4^RF`` (eq. 6); equality of the two is the closure of eq. (7).  With the home
configuration chosen, the matrices the builder derives are exactly the paper's
``D`` and ``T`` of eqs. (4) and (6) (Table 1: ``A2 = L1``, ``A3 = L2``, ``A4 = L4``).
Output: the slider frame ``RF``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hyperstat.cad_plugin.params import param
from hyperstat.cad_plugin.skeleton import Skeleton


#: Tolerancing declaration (hyperstat.solver.tolerances.declaration): the task is the slider's stroke along
#: x_R0, a tracker target on the slider block measures it; pins and slide are plain fits (the defaults, ISO 286
#: H7/g6 on 20 mm); spec of a light tooling slide.
TOLERANCING = {
    "task": ["x"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.02, "orientation_rad": None},
}

@dataclass
class Parameters:
    """Slider-crank dimensions (mm) and home crank angle (rad)."""

    L1: float = param(40.0, "mm", "crank length, pivot 1 to pin 2 (Table 1: A2)", minimum=0.0, exclusive_minimum=True)
    L2: float = param(120.0, "mm", "rod length, pin 2 to pin 3 (Table 1: A3); must exceed L1", minimum=0.0,
                      exclusive_minimum=True)
    L3: float = param(25.0, "mm", "pin 3 to the slider frame RF along x_R3 (eq. 6)", minimum=0.0)
    L4: float = param(30.0, "mm", "origin of the slide on x_R0 (Table 1: A4)")
    home_angle: float = param(math.pi / 3, "rad", "crank angle theta1 of the home configuration",
                              minimum=-math.pi, maximum=math.pi)
    section: float = param(4.0, "mm", "radius of the link bars drawn in CAD", minimum=0.0, exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the slider-rod-crank at its home configuration.

    Parameters
    ----------
    **overrides : float
        Any field of :class:`Parameters` (mm / rad).

    Returns
    -------
    Skeleton
    """
    from hyperstat.cad_plugin.params import make_parameters

    p = make_parameters(Parameters, overrides)
    if p.L2 <= p.L1:
        from hyperstat.solver.errors import TemplateError

        raise TemplateError(f"parameter 'L2' ({p.L2:g} mm) must exceed 'L1' ({p.L1:g} mm) for the crank to turn.")
    t1 = p.home_angle
    t12 = math.asin(-p.L1 * math.sin(t1) / p.L2)  # rod angle: the slider stays on x_R0
    pin2 = (p.L1 * math.cos(t1), 0.0, p.L1 * math.sin(t1))
    pin3 = (pin2[0] + p.L2 * math.cos(t12), 0.0, 0.0)
    slider = (pin3[0] + p.L3, 0.0, 0.0)
    x4 = slider[0] - p.L4
    stroke = (p.L2 - p.L1 + p.L3 - p.L4, p.L2 + p.L1 + p.L3 - p.L4)  # x4 over a full crank turn
    sk = Skeleton("slider_crank", base="R0", parameters=p, marker_size=0.25 * p.L1,
                  description="Slider-rod-crank, paper 1 section 4.1 (Guyon et al. 2022)")
    # z_L1 = -y_R0 (Table 1: I1, J1, K1 = 0, -1, 0); x_L1 = x_R0 as in the paper.
    sk.revolute("1", (0, 0, 0), (0, -1, 0), role="actuated", x_axis=(1, 0, 0), defects="", home=t1,
                range=(-math.pi, math.pi))
    sk.revolute("2", pin2, (0, -1, 0), home=t12 - t1, range=(-2 * math.pi, 2 * math.pi))
    sk.revolute("3", pin3, (0, -1, 0), home=-t12, range=(-math.pi, math.pi))
    sk.prismatic("4", (p.L4, 0, 0), (1, 0, 0), home=x4, range=(stroke[0] - 1.0, stroke[1] + 1.0))
    sk.frame("RF", slider, (0, 0, 1), (1, 0, 0))
    sk.chain("crank", "R0", "RF", ["1", "2", "3"])
    sk.chain("slide", "R0", "RF", ["4"])
    sk.output = "RF"
    sk.link("crank", ["1", "2"], p.section)
    sk.link("rod", ["2", "3"], p.section)
    sk.link("block", ["3", "RF"], p.section)
    sk.link("guide", [(p.L4, 0, 0), (p.L4 + stroke[1] + p.L3, 0, 0)], 0.5 * p.section)
    return sk


if "show_object" in globals():  # CQ-editor
    from hyperstat.cad_plugin.assembly import build_assembly

    show_object(build_assembly(build()))  # noqa: F821
