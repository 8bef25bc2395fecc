"""6-UPS Gough-Stewart platform: a parallel mechanism that is NOT over-constrained.

Units: lengths in mm, angles in rad.

Six legs, each a universal joint at the base (joints ``1k``, ``2k`` for leg ``k``), an
actuated prismatic leg (``3k``) and a spherical joint at the platform as three
concurrent revolutes (``4k``, ``5k``, ``6k``); a fixed transform (``7k``) carries each leg
onto the platform frame ``P``.  Six legs of five passive degrees of freedom leave the
platform six: mobility 6, degree of over-constraint 0, so the stationarity analysis
must force nothing.  Base joints on a circle of radius ``base_radius`` at
``120 k +- base_angle``, platform joints at ``120 k + 60 -+ platform_angle`` (the
classic crossed layout), platform at ``height`` above the base at home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton


#: Tolerancing declaration (hyperstat.solver.tolerances.declaration): a hexapod positions a full pose; a 6-D probe
#: measures the platform pose.
TOLERANCING = {
    "task": ["position", "orientation"],
    "measurements": {"kind": "poses", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.005, "noise_rad": 1e-5},
    "spec": {"position_mm": 0.05, "orientation_rad": 1e-4},
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
    """Hexapod dimensions (mm, rad)."""

    base_radius: float = param(500.0, "mm", "radius of the base joint circle", minimum=0.0, exclusive_minimum=True)
    platform_radius: float = param(250.0, "mm", "radius of the platform joint circle", minimum=0.0,
                                   exclusive_minimum=True)
    base_angle: float = param(math.radians(15.0), "rad", "half angle between paired base joints", minimum=0.0,
                              maximum=math.pi / 3)
    platform_angle: float = param(math.radians(15.0), "rad", "half angle between paired platform joints",
                                  minimum=0.0, maximum=math.pi / 3)
    height: float = param(700.0, "mm", "platform height at home", minimum=0.0, exclusive_minimum=True)
    stroke: float = param(60.0, "mm", "leg stroke on each side of the home length", minimum=0.0,
                          exclusive_minimum=True)
    section: float = param(10.0, "mm", "radius of the link bars drawn in CAD", minimum=0.0, exclusive_minimum=True)


def joint_points(p: Parameters) -> tuple[np.ndarray, np.ndarray]:
    """Base and platform joint centres (6 x 3 each, mm): base frame, platform frame at home."""
    base, plat = [], []
    for k in range(3):
        for sign in (-1.0, 1.0):
            a = 2 * math.pi * k / 3 + sign * p.base_angle
            b = 2 * math.pi * k / 3 + sign * (math.pi / 3 - p.platform_angle)
            base.append((p.base_radius * math.cos(a), p.base_radius * math.sin(a), 0.0))
            plat.append((p.platform_radius * math.cos(b), p.platform_radius * math.sin(b), 0.0))
    return np.array(base), np.array(plat)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the hexapod at its home configuration (platform level, centred).

    Returns
    -------
    Skeleton
    """
    p = make_parameters(Parameters, overrides)
    base, plat = joint_points(p)
    lift = np.array([0.0, 0.0, p.height])
    sk = Skeleton("hexapod", base="R0", parameters=p, marker_size=40.0,
                  description="6-UPS Gough-Stewart platform (not over-constrained)")
    sk.frame("P", lift, (0, 0, 1), (1, 0, 0))
    for k in range(6):
        leg = str(k + 1)
        a, b = base[k], plat[k] + lift
        d = (b - a) / np.linalg.norm(b - a)
        length = float(np.linalg.norm(b - a))
        tangent = np.array([-a[1], a[0], 0.0]) / np.linalg.norm(a[:2])
        second = np.cross(d, tangent)
        second /= np.linalg.norm(second)
        ortho = np.cross(d, second)
        sk.revolute("1" + leg, a, tangent, range=(-0.8, 0.8))
        sk.revolute("2" + leg, a, second, range=(-0.8, 0.8))
        sk.prismatic("3" + leg, a, d, role="actuated", home=length,
                     range=(length - p.stroke, length + p.stroke))
        sk.revolute("4" + leg, b, d, range=(-1.2, 1.2))
        sk.revolute("5" + leg, b, second, range=(-1.2, 1.2))
        sk.revolute("6" + leg, b, ortho, range=(-1.2, 1.2))
        sk.fixed("7" + leg, lift, (0, 0, 1), (1, 0, 0))
        sk.chain("leg" + leg, "R0", "P", [f"{j}{leg}" for j in range(1, 8)])
        sk.link("leg" + leg, [a, b], p.section)
    sk.output = "P"
    ring_b = [tuple(v) for v in base] + [tuple(base[0])]
    ring_p = [tuple(v + lift) for v in plat] + [tuple(plat[0] + lift)]
    sk.link("base", ring_b, p.section)
    sk.link("platform", ring_p, p.section)
    return sk


if "show_object" in globals():  # CQ-editor
    from hyperstat.cad_plugin.assembly import build_assembly

    show_object(build_assembly(build()))  # noqa: F821
