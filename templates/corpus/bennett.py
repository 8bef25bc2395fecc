"""Bennett linkage: a spatial loop of four revolute joints, mobile because of its proportions.

Units: lengths in mm, angles in rad.

Joints 1 (actuated, the reference) and 4 on the base; link 1-2 (length ``a``, twist ``alpha``),
link 2-3 (length ``b``, twist ``beta``), link 3-4 (``a``, ``alpha``) and the base 4-1 (``b``,
``beta``), with ``a / sin(alpha) = b / sin(beta)`` and no offset along any axis.  The home pose is
drawn from Denavit-Hartenberg steps: with joint 1 at ``theta``, joint 2 is at ``phi`` given by
``tan(theta / 2) tan(phi / 2) = sin((beta + alpha) / 2) / sin((beta - alpha) / 2)``, and joints 3 and
4 at ``-theta`` and ``-phi`` (Bennett's closure).  The chain 1, 2 places the coupler frame ``R2``;
the chain 4, 3 closes on it through the fixed transform 5, the coupler's own geometry.  Output:
the frame ``P`` on the coupler, ``b / 2`` along the link 2-3.

Theory.  One loop, four joints.  Kutzbach: 6 x 3 - 5 x 4 = -2, yet the linkage moves: at every
configuration the four joint screws are linearly dependent and span a 3-system, so the mobility
is 4 - 3 = 1 and the degree of over-constraint 6 - 3 = 3.  Bennett's conditions (1903) on the
twelve link parameters of a 4R loop are nine: the four offsets zero, the opposite lengths equal
(two), the opposite twists equal (two), and the ratio ``a / sin(alpha) = b / sin(beta)`` (one).
A general 4R loop does not move at all; these nine keep it mobile.

Theory: mobility 1, degree of over-constraint 3, assembly conditions 9.
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
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0], [40.0, 0.0, 0.0], [0.0, 40.0, 0.0]],
                     "noise_mm": 0.002},
    "spec": {"position_mm": 0.05, "orientation_rad": None},
}


@dataclass
class Parameters:
    """Bennett proportions: one length and two twists (the other length follows), home angle."""

    a: float = param(100.0, "mm", "length of the links 1-2 and 3-4", minimum=0.0, exclusive_minimum=True)
    alpha: float = param(0.6, "rad", "twist of the links 1-2 and 3-4", minimum=0.05, maximum=3.0)
    beta: float = param(1.0, "rad", "twist of the links 2-3 and 4-1 (not equal to alpha)", minimum=0.05,
                        maximum=3.0)
    home_angle: float = param(1.0, "rad", "angle of joint 1 at home (from the common normal to the base link)",
                              minimum=0.2, maximum=2.9)


def _dh(theta: float, length: float, twist: float) -> np.ndarray:
    """Standard DH step: rotate theta about z, move ``length`` along the new x, twist about it."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(twist), math.sin(twist)
    return np.array([[ct, -st * ca, st * sa, length * ct], [st, ct * ca, -ct * sa, length * st],
                     [0.0, sa, ca, 0.0], [0.0, 0.0, 0.0, 1.0]])


def build(**overrides: float) -> Skeleton:
    """Skeleton of the Bennett linkage at home."""
    p = make_parameters(Parameters, overrides)
    if abs(math.sin((p.beta - p.alpha) / 2)) < 1e-3:
        raise TemplateError("alpha and beta must differ: with equal twists the Bennett linkage degenerates.")
    b = p.a * math.sin(p.beta) / math.sin(p.alpha)
    theta = p.home_angle
    phi = 2 * math.atan(math.sin((p.beta + p.alpha) / 2) / math.sin((p.beta - p.alpha) / 2) / math.tan(theta / 2))
    frames = [np.eye(4)]  # the DH frames of joints 1, 2, 3, 4 at home: z along each axis
    for angle, length, twist in ((theta, p.a, p.alpha), (phi, b, p.beta), (-theta, p.a, p.alpha)):
        frames.append(frames[-1] @ _dh(angle, length, twist))
    o = [f[:3, 3] for f in frames]
    z = [f[:3, 2] for f in frames]
    sk = Skeleton("bennett", base="R0", parameters=p, marker_size=0.2 * p.a,
                  description="Bennett linkage (spatial 4R loop)")
    sk.revolute("1", o[0], z[0], role="actuated", x_axis=(1, 0, 0), defects="", home=theta,
                range=(theta - 1.2, theta + 1.2))
    sk.revolute("2", o[1], z[1])
    sk.revolute("4", o[3], z[3])
    sk.revolute("3", o[2], z[2])
    sk.fixed("5", target="R2")
    x23 = (o[2] - o[1]) / b
    sk.frame("P", o[1] + 0.5 * b * x23, z[1], x23)
    sk.chain("crank", "R0", "R2", ["1", "2"])
    sk.chain("rocker", "R0", "R2", ["4", "3", "5"])
    sk.chain("tool", "R2", "P", [])
    sk.output = "P"
    r = 0.04 * p.a
    sk.link("base", ["4", "1"], r)
    sk.link("crank", ["1", "2"], r)
    sk.link("coupler", ["2", "3"], r)
    sk.link("rocker", ["3", "4"], r)
    return sk
