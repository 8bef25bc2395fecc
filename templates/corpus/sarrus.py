"""Sarrus linkage: a platform lifted by two hinged legs whose hinge directions differ (6R, one loop).

Units: lengths in mm, angles in rad.

Leg A hinges about x (joints A1 on the base, A2 at the knee, A3 under the platform), leg B about
y (B1, B2, B3); each leg is two links of length ``link`` folding in its own vertical plane.  The
platform moves straight up and down.  A1 is actuated and the reference; leg A places the
platform frame ``P``; leg B closes on it through the fixed transform ``PB`` (the platform's own
geometry between B3 and P).

Theory.  One loop, six revolutes.  Each leg's three parallel hinges generate the planar motions
normal to its hinge (two translations and the rotation about the hinge direction); the two
planar groups, about x and about y, share only the translation along z.  The six joint screws
have rank 5 at every configuration: mobility 6 - 5 = 1, degree of over-constraint 6 - 5 = 1
(Kutzbach: 6 x 5 - 5 x 6 = 0).  The one constraint of the loop is a couple about z: the legs
together forbid the platform to turn about the vertical.

Conditions.  Exactly, for finite defects, Sarrus' sufficient conditions (1853) are eight: in each
leg the three hinges stay parallel (the knee's to the base's, the platform's to the knee's, two
angles each).  To first order, which is what a tolerance sees, fewer count: a defect matters for
assembly only through the rotation about z it asks of the platform at each height, and that
rotation is a combination of three independent functions of the fold, so there are 3 assembly
conditions (the stationarity analysis and an independent screw computation agree).  The other
combinations of hinge tilts break the loop at second order only: 1e-4 rad of tilt misses the
loop by about 5e-8 mm (``hyperstat analyze --verify``), far below any joint clearance.

Theory: mobility 1, degree of over-constraint 1, assembly conditions 3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton
from hyperstat.solver.errors import TemplateError

TOLERANCING = {
    "task": ["z"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.02, "orientation_rad": None},
}


@dataclass
class Parameters:
    """Sarrus dimensions (mm)."""

    link: float = param(100.0, "mm", "length of each leg link (hinge to hinge)", minimum=0.0, exclusive_minimum=True)
    height: float = param(120.0, "mm", "platform height above the base at home", minimum=0.0, exclusive_minimum=True)
    offset: float = param(60.0, "mm", "distance of each leg's hinges from the vertical axis through P", minimum=0.0,
                          exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the Sarrus linkage at home."""
    p = make_parameters(Parameters, overrides)
    if not p.height < 2 * p.link:
        raise TemplateError(f"the height {p.height:g} mm must be less than two links ({2 * p.link:g} mm).")
    knee = math.sqrt(p.link**2 - (p.height / 2) ** 2)  # how far each knee sticks out
    h, d = p.height, p.offset
    sk = Skeleton("sarrus", base="R0", parameters=p, marker_size=0.2 * p.link, description="Sarrus linkage (6R)")
    home = math.atan2(-h / 2, knee)  # A1's angle, from -y about +x, to the lower link
    sk.revolute("A1", (0, -d, 0), (1, 0, 0), role="actuated", x_axis=(0, -1, 0), defects="", home=home,
                range=(home - 0.25, home + 0.25))
    sk.revolute("A2", (0, -d - knee, h / 2), (1, 0, 0))
    sk.revolute("A3", (0, -d, h), (1, 0, 0))
    sk.revolute("B1", (d, 0, 0), (0, 1, 0))
    sk.revolute("B2", (d + knee, 0, h / 2), (0, 1, 0))
    sk.revolute("B3", (d, 0, h), (0, 1, 0))
    sk.frame("P", (0, 0, h), (0, 0, 1), (1, 0, 0))
    sk.fixed("PB", target="P")
    sk.chain("legA", "R0", "P", ["A1", "A2", "A3"])
    sk.chain("legB", "R0", "P", ["B1", "B2", "B3", "PB"])
    sk.output = "P"
    r = 0.04 * p.link
    sk.link("base", ["A1", "B1"], r)
    sk.link("platform", ["A3", "B3"], r)
    for leg in "AB":
        sk.link(f"lower{leg}", [f"{leg}1", f"{leg}2"], r)
        sk.link(f"upper{leg}", [f"{leg}2", f"{leg}3"], r)
    return sk
