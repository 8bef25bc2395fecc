"""Planar five-bar linkage: two actuated revolutes at the base, two proximal and two distal links.

Units: lengths in mm, angles in rad.

Joints (all revolute, axes along z): 1 at ``A = (0, 0)`` and 5 at ``E = (base, 0)`` are actuated;
2 at ``B`` and 4 at ``D`` are the elbows, 3 at ``C`` joins the two distal links.  The left chain
``1, 2, 3`` defines the frame ``R3`` of the distal link ``CD`` after joint 3; the right chain ``5, 4``
reaches the same link at ``D`` and closes the loop through the fixed transform 6 (the link ``DC``
itself, with its defects).  Output: the frame ``P`` at ``C``.  As a spatial model the planar loop
is over-constrained three times (6 closure equations, 3 passive joints): the axes must stay
parallel and the joints in one plane.  Joint 1 is the reference (no defect).  Home: the elbows
out, ``C`` at ``(base / 2, height)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton

#: Tolerancing declaration (hyperstat.solver.tolerances.declaration): a planar pick-and-place or plotter mechanism:
#: the task is the position of C in the plane (x, y); a tracker target at C measures it; plain pin joints (the
#: defaults, ISO 286 H7/g6 on 20 mm).
TOLERANCING = {
    "task": ["x", "y"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.02, "orientation_rad": None},
}


@dataclass
class Parameters:
    """Five-bar dimensions (mm)."""

    base: float = param(100.0, "mm", "distance between the actuated joints A and E", minimum=0.0,
                        exclusive_minimum=True)
    proximal: float = param(80.0, "mm", "length of the links AB and ED", minimum=0.0, exclusive_minimum=True)
    distal: float = param(100.0, "mm", "length of the links BC and DC", minimum=0.0, exclusive_minimum=True)
    height: float = param(110.0, "mm", "height of C above the base line at home", minimum=0.0,
                          exclusive_minimum=True)
    section: float = param(4.0, "mm", "radius of the link bars drawn in CAD", minimum=0.0, exclusive_minimum=True)


def _elbow(origin: np.ndarray, target: np.ndarray, l1: float, l2: float, sign: float) -> np.ndarray:
    """Elbow point of a two-link chain from ``origin`` to ``target`` (``sign`` picks the branch)."""
    v = target - origin
    r = float(np.linalg.norm(v))
    if not abs(l1 - l2) < r < l1 + l2:
        from hyperstat.solver.errors import TemplateError

        raise TemplateError(f"C at {r:g} mm from a base joint cannot be reached with links of {l1:g} and {l2:g} mm.")
    alpha = math.acos((l1 * l1 + r * r - l2 * l2) / (2 * l1 * r))
    theta = math.atan2(v[1], v[0]) + sign * alpha
    return origin + l1 * np.array([math.cos(theta), math.sin(theta), 0.0])


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.atan2(b[1] - a[1], b[0] - a[0])


def build(**overrides: float) -> Skeleton:
    """Skeleton of the five-bar at home (elbows out).

    Returns
    -------
    Skeleton
    """
    p = make_parameters(Parameters, overrides)
    a = np.zeros(3)
    e = np.array([p.base, 0.0, 0.0])
    c = np.array([p.base / 2, p.height, 0.0])
    b = _elbow(a, c, p.proximal, p.distal, +1.0)
    d = _elbow(e, c, p.proximal, p.distal, -1.0)
    z = (0.0, 0.0, 1.0)
    t_ab, t_bc, t_cd = _angle(a, b), _angle(b, c), _angle(c, d)
    t_ed, t_dc = _angle(e, d), _angle(d, c)
    sk = Skeleton("five_bar", base="R0", parameters=p, marker_size=0.25 * p.proximal,
                  description="Planar five-bar linkage (two actuated base revolutes)")
    sk.revolute("1", a, z, role="actuated", x_axis=(1, 0, 0), defects="", home=t_ab, range=(t_ab - 0.4, t_ab + 0.4))
    sk.revolute("2", b, z, home=t_bc - t_ab, range=(-2 * math.pi, 2 * math.pi))
    sk.revolute("3", c, z, home=t_cd - t_bc, range=(-2 * math.pi, 2 * math.pi))
    sk.revolute("5", e, z, role="actuated", x_axis=(1, 0, 0), home=t_ed, range=(t_ed - 0.4, t_ed + 0.4))
    sk.revolute("4", d, z, home=t_dc - t_ed, range=(-2 * math.pi, 2 * math.pi))
    sk.fixed("6", target="R3")
    sk.frame("P", c, z, (1, 0, 0))
    sk.chain("left", "R0", "R3", ["1", "2", "3"])
    sk.chain("right", "R0", "R3", ["5", "4", "6"])
    sk.chain("tool", "R3", "P", [])
    sk.output = "P"
    sk.link("proximal_left", ["1", "2"], p.section)
    sk.link("distal_left", ["2", "3"], p.section)
    sk.link("proximal_right", ["5", "4"], p.section)
    sk.link("distal_right", ["4", c], p.section)
    sk.link("base", [a, e], p.section)
    return sk


if "show_object" in globals():  # CQ-editor
    from hyperstat.cad_plugin.assembly import build_assembly

    show_object(build_assembly(build()))  # noqa: F821
