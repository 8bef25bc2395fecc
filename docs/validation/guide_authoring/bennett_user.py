"""A Bennett linkage: four revolute joints in a closed spatial loop, opposite links of equal length and twist, a_i / sin(alpha_i) equal, mobility 1; actuate one joint.

Units: lengths in mm, angles in rad.

Joints 1 (actuated, the reference) and 4 on the base; links 1-2 and 3-4 have length ``a`` and twist
``alpha``; links 2-3 and 4-1 have length ``b = a sin(beta) / sin(alpha)`` and twist ``beta``; no offsets.
The home is drawn by Denavit-Hartenberg steps with Bennett's closure (joint angles theta, phi, -theta,
-phi, tan(theta/2) tan(phi/2) = sin((beta+alpha)/2) / sin((beta-alpha)/2)); the template checks that
the fourth step returns to the start.  The crank chain 1, 2 defines the coupler frame R2; the rocker
chain 4, 3 closes on it through the fixed transform 5.  Output P: a point on the coupler.

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
    "measurements": {"kind": "positions",
                     "targets_mm": [[0.0, 0.0, 0.0], [30.0, 0.0, 0.0], [0.0, 30.0, 0.0]],
                     "noise_mm": 0.002},
    "spec": {"position_mm": 0.05, "orientation_rad": None},
}


@dataclass
class Parameters:
    """Bennett proportions and the home angle of the actuated joint."""

    a: float = param(80.0, "mm", "length of links 1-2 and 3-4", minimum=0.0, exclusive_minimum=True)
    alpha: float = param(0.5, "rad", "twist of links 1-2 and 3-4", minimum=0.05, maximum=3.0)
    beta: float = param(1.1, "rad", "twist of links 2-3 and 4-1 (must differ from alpha)", minimum=0.05,
                        maximum=3.0)
    home_angle: float = param(1.2, "rad", "angle of joint 1 at home", minimum=0.2, maximum=2.9)


def _dh(theta: float, length: float, twist: float) -> np.ndarray:
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(twist), math.sin(twist)
    return np.array([[ct, -st * ca, st * sa, length * ct],
                     [st, ct * ca, -ct * sa, length * st],
                     [0.0, sa, ca, 0.0],
                     [0.0, 0.0, 0.0, 1.0]])


def build(**overrides: float) -> Skeleton:
    p = make_parameters(Parameters, overrides)
    if abs(math.sin((p.beta - p.alpha) / 2)) < 1e-3:
        raise TemplateError("alpha and beta must differ, else the Bennett linkage degenerates.")
    b = p.a * math.sin(p.beta) / math.sin(p.alpha)
    theta = p.home_angle
    phi = 2 * math.atan(math.sin((p.beta + p.alpha) / 2) / math.sin((p.beta - p.alpha) / 2)
                        / math.tan(theta / 2))
    steps = ((theta, p.a, p.alpha), (phi, b, p.beta), (-theta, p.a, p.alpha), (-phi, b, p.beta))
    frames = [np.eye(4)]
    for step in steps:
        frames.append(frames[-1] @ _dh(*step))
    if not np.allclose(frames[4], np.eye(4), atol=1e-9 * max(1.0, p.a)):
        raise TemplateError("the Bennett loop does not close at home for these parameters.")
    o = [f[:3, 3] for f in frames[:4]]
    z = [f[:3, 2] for f in frames[:4]]
    sk = Skeleton("bennett_user", base="R0", parameters=p, marker_size=0.2 * p.a,
                  description="Bennett linkage (spatial 4R loop), user-written")
    sk.revolute("1", o[0], z[0], role="actuated", x_axis=(1, 0, 0), defects="", home=theta,
                range=(theta - 1.0, theta + 1.0))
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
