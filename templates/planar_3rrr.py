"""Planar 3-RRR parallel robot: three legs of two links from a fixed base triangle to a moving platform triangle.

Units: lengths in mm, angles in rad.

Architecture.  Leg ``i`` (``i = 1, 2, 3``) is a revolute ``1i`` at the base point ``A_i`` (actuated), a
proximal link to the elbow revolute ``2i`` at ``B_i`` (passive), a distal link to the platform revolute
``3i`` at ``C_i`` (passive).  Every axis is along ``z``: the legs move in the plane ``z = 0``.  The base
joints sit on a circle of radius ``base_radius`` at 90, 210 and 330 degrees, the platform joints on a
circle of radius ``platform_radius`` about the platform centre, at the same angles when the platform is
at home (centre at the origin, not turned).  Leg 1 defines the platform frame ``R31`` (after joint 31);
legs 2 and 3 reach it through the fixed transforms ``42`` and ``43`` (the platform's own geometry between
its joints, with its defects), where the loops close.  The output ``P`` is at the platform centre.  Joint
11 is the reference (no defect).

Theory (what the test checks by its own computation).

* **Mobility 3** (the platform's ``x``, ``y`` and turn ``rz`` in its plane): by the planar Grübler count
  ``3 (n - 1) - 2 g = 3 * 7 - 2 * 9 = 3`` with ``n = 8`` bodies (base, 3 proximal, 3 distal links, the
  platform) and ``g = 9`` revolutes; the actuated joints ``11, 12, 13`` fix it away from singularities.
* **Degree of over-constraint 6**: as a spatial model the spatial count gives ``6 (n - 1) - 5 g = -3``, so
  ``6 = 3 - (-3)`` equations are redundant: the mechanism has ``g - n + 1 = 2`` independent loops, each
  with 6 closure equations of which a planar loop uses only 3 (``x``, ``y``, ``rz``); the other 3 per
  loop (the rotations about ``x`` and ``y``, the translation along ``z``) hold only by construction.
* **Known conditions** (the 6 assembly conditions): all nine axes stay parallel (the out-of-plane tilts
  ``dI``, ``dJ`` of every axis, relative to its neighbour), and the legs' planes coincide (the
  out-of-plane shifts ``dc`` along the axes add up to zero around each loop).  Every in-plane defect
  (the ``da``, ``db`` of the joints, the platform's in-plane geometry) is admissible: the passive joints
  absorb it, and it moves the platform in its plane (compensable by calibration, or non-influent).

Tolerancing: the task is the platform's planar pose (``x``, ``y``, ``rz``); a tracker measures two targets
on the platform (its centre and 40 mm along its ``x`` axis); plain pin joints (ISO 286 H7/g6 on 20 mm, the
defaults).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton

#: Tolerancing declaration (hyperstat.solver.tolerances.declaration): the platform's planar pose is the task; two
#: targets on the platform measured by a tracker; plain pin joints (the defaults); spec of a light planar
#: positioning stage.
TOLERANCING = {
    "task": ["x", "y", "rz"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0], [40.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.02, "orientation_rad": 2e-4},
}

_ANGLES = (math.pi / 2, math.pi / 2 + 2 * math.pi / 3, math.pi / 2 + 4 * math.pi / 3)


@dataclass
class Parameters:
    """3-RRR dimensions (mm)."""

    base_radius: float = param(200.0, "mm", "radius of the circle of the base joints A_i", minimum=0.0,
                               exclusive_minimum=True)
    platform_radius: float = param(80.0, "mm", "radius of the circle of the platform joints C_i", minimum=0.0,
                                   exclusive_minimum=True)
    proximal: float = param(120.0, "mm", "length of the links A_i B_i", minimum=0.0, exclusive_minimum=True)
    distal: float = param(120.0, "mm", "length of the links B_i C_i", minimum=0.0, exclusive_minimum=True)
    stroke: float = param(0.1, "rad", "actuated range on each side of the home angle (the box stays away from the "
                          "singular configurations)", minimum=0.0, exclusive_minimum=True, maximum=1.0)
    section: float = param(5.0, "mm", "radius of the link bars drawn in CAD", minimum=0.0, exclusive_minimum=True)


def _elbow(origin: np.ndarray, target: np.ndarray, l1: float, l2: float, sign: float) -> np.ndarray:
    """Elbow point of a two-link chain from ``origin`` to ``target`` (``sign`` picks the branch)."""
    v = target - origin
    r = float(np.linalg.norm(v))
    if not abs(l1 - l2) < r < l1 + l2:
        from hyperstat.solver.errors import TemplateError

        raise TemplateError(f"the platform joint at {r:g} mm from its base joint cannot be reached with links of "
                            f"{l1:g} and {l2:g} mm.")
    alpha = math.acos((l1 * l1 + r * r - l2 * l2) / (2 * l1 * r))
    theta = math.atan2(v[1], v[0]) + sign * alpha
    return origin + l1 * np.array([math.cos(theta), math.sin(theta), 0.0])


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.atan2(b[1] - a[1], b[0] - a[0])


def build(**overrides: float) -> Skeleton:
    """Skeleton of the 3-RRR at home (platform centred, not turned; every elbow turned the same way).

    Parameters
    ----------
    **overrides : float
        Any field of :class:`Parameters` (mm, rad).

    Returns
    -------
    Skeleton
    """
    p = make_parameters(Parameters, overrides)
    z = (0.0, 0.0, 1.0)
    sk = Skeleton("planar_3rrr", base="R0", parameters=p, marker_size=0.2 * p.proximal,
                  description="Planar 3-RRR parallel robot (three actuated base revolutes)")
    centre = np.zeros(3)
    a_pts, c_pts = [], []
    for k, ang in enumerate(_ANGLES):
        i = k + 1
        a = p.base_radius * np.array([math.cos(ang), math.sin(ang), 0.0])
        c = centre + p.platform_radius * np.array([math.cos(ang), math.sin(ang), 0.0])
        b = _elbow(a, c, p.proximal, p.distal, +1.0)
        t_ab, t_bc, t_cp = _angle(a, b), _angle(b, c), _angle(c, centre)
        sk.revolute(f"1{i}", a, z, role="actuated", x_axis=(1, 0, 0), defects="" if i == 1 else "IJKabc",
                    home=t_ab, range=(t_ab - p.stroke, t_ab + p.stroke))
        sk.revolute(f"2{i}", b, z, home=t_bc - t_ab, range=(-2 * math.pi, 2 * math.pi))
        sk.revolute(f"3{i}", c, z, home=t_cp - t_bc, range=(-2 * math.pi, 2 * math.pi))
        a_pts.append(a)
        c_pts.append(c)
    sk.fixed("42", target="R31")
    sk.fixed("43", target="R31")
    sk.frame("P", centre, z, (1, 0, 0))
    sk.chain("leg1", "R0", "R31", ["11", "21", "31"])
    sk.chain("leg2", "R0", "R31", ["12", "22", "32", "42"])
    sk.chain("leg3", "R0", "R31", ["13", "23", "33", "43"])
    sk.chain("tool", "R31", "P", [])
    sk.output = "P"
    r = p.section
    sk.link("base", [a_pts[0], a_pts[1], a_pts[2], a_pts[0]], r)
    for i in (1, 2, 3):
        sk.link(f"proximal{i}", [f"1{i}", f"2{i}"], r)
        sk.link(f"distal{i}", [f"2{i}", f"3{i}"], r)
    sk.link("platform", [c_pts[0], c_pts[1], c_pts[2], c_pts[0]], r)
    return sk


if "show_object" in globals():  # CQ-editor
    from hyperstat.cad_plugin.assembly import build_assembly

    show_object(build_assembly(build()))  # noqa: F821
