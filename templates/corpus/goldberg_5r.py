"""Goldberg 5R linkage: two Bennett linkages sharing a link, the shared link removed (one loop of five revolutes).

Units: lengths in mm, angles in rad.

Bennett linkage A has joints 1, 2, 3, 4 (links 1-2 and 3-4 of length ``a`` and twist ``alpha``,
links 2-3 and 4-1 of ``b``, ``beta``); Bennett linkage B shares A's link 4-1 and has joints 4, 1, 6,
5 (links 1-6 and 5-4 of ``c``, ``gamma``, link 6-5 of ``b``, ``beta``), with ``a / sin(alpha) =
b / sin(beta) = c / sin(gamma)``.  Remove the shared link 4-1 and weld A's link 3-4 to B's link
4-5 at joint 4: the loop 1, 2, 3, (3-4-5 welded), 5, 6 remains, five revolutes.  Joint 2 is
actuated and the reference; the base is A's link 1-2 (joints 1 and 2).  The chain 2, 3 places the
welded link's frame ``R3``; the chain 1, 6, 5 closes on it through the fixed transform ``W`` (the
welded link's geometry).  Output: the frame ``P`` at joint 3 on the welded link.

Theory.  One loop, five joints.  Kutzbach: 6 x 4 - 5 x 5 = -1, yet the linkage moves: the five
joint screws span a 4-system at every configuration, so the mobility is 5 - 4 = 1 and the degree
of over-constraint 6 - 4 = 2.  The known conditions are Goldberg's construction (1943): the
welded link and the two links beside it carry the proportions of two Bennett linkages on a
common link.  A 5R loop has fifteen link parameters (a length, a twist and an offset per link);
Goldberg's linkages form a family of five (one length, the three twists, and the angle at which
the two Bennett links are welded), so 15 - 5 = 10 conditions keep the loop mobile (the stationarity
analysis and an independent screw computation both find 10 to first order).

Theory: mobility 1, degree of over-constraint 2, assembly conditions 10.
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
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.05, "orientation_rad": None},
}


@dataclass
class Parameters:
    """Goldberg 5R proportions: one length, three twists, and the two Bennett linkages' home angles."""

    a: float = param(100.0, "mm", "length of A's links 1-2 and 3-4", minimum=0.0, exclusive_minimum=True)
    alpha: float = param(0.6, "rad", "twist of A's links 1-2 and 3-4", minimum=0.05, maximum=3.0)
    beta: float = param(1.0, "rad", "twist of the shared link 4-1 and of 2-3 and 6-5", minimum=0.05, maximum=3.0)
    gamma: float = param(1.4, "rad", "twist of B's links 1-6 and 5-4", minimum=0.05, maximum=3.0)
    home_a: float = param(1.0, "rad", "A's angle at joint 1 at home", minimum=0.2, maximum=2.9)
    home_b: float = param(0.8, "rad", "B's angle at joint 4 at home", minimum=0.2, maximum=2.9)


def _dh(theta: float, length: float, twist: float) -> np.ndarray:
    """Standard DH step: rotate theta about z, move ``length`` along the new x, twist about it."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(twist), math.sin(twist)
    return np.array([[ct, -st * ca, st * sa, length * ct], [st, ct * ca, -ct * sa, length * st],
                     [0.0, sa, ca, 0.0], [0.0, 0.0, 0.0, 1.0]])


def _rz(angle: float) -> np.ndarray:
    return _dh(angle, 0.0, 0.0)


def _bennett_angle(first: float, twist1: float, twist2: float) -> float:
    """Bennett's closure: the second joint angle from the first, for the twists of the links after each."""
    if abs(math.sin((twist2 - twist1) / 2)) < 1e-3:
        raise TemplateError("neighbouring twists must differ: with equal twists a Bennett linkage degenerates.")
    k = math.sin((twist2 + twist1) / 2) / math.sin((twist2 - twist1) / 2)
    return 2 * math.atan(k / math.tan(first / 2))


def build(**overrides: float) -> Skeleton:
    """Skeleton of the Goldberg 5R linkage at home."""
    p = make_parameters(Parameters, overrides)
    b = p.a * math.sin(p.beta) / math.sin(p.alpha)
    c = p.a * math.sin(p.gamma) / math.sin(p.alpha)
    # Bennett A from joint 1 (world frame): 1 -> 2 -> 3 -> 4 (-> 1)
    theta = p.home_a
    phi = _bennett_angle(theta, p.alpha, p.beta)
    f1 = np.eye(4)
    f2 = f1 @ _dh(theta, p.a, p.alpha)
    f3 = f2 @ _dh(phi, b, p.beta)
    f4 = f3 @ _dh(-theta, p.a, p.alpha)
    # Bennett B on A's link 4 -> 1: 4 -> 1 -> 6 -> 5 (-> 4)
    psi4 = p.home_b
    psi1 = _bennett_angle(psi4, p.beta, p.gamma)
    h4 = f4 @ _rz(-phi) @ _rz(-psi4)  # B's frame at joint 4, so that h4 DH(psi4, b, beta) is f1
    assert np.allclose(h4 @ _dh(psi4, b, p.beta), f1, atol=1e-9)
    f6 = f1 @ _dh(psi1, c, p.gamma)
    f5 = f6 @ _dh(-psi4, b, p.beta)
    axis = {name: f[:3, 2] for name, f in (("1", f1), ("2", f2), ("3", f3), ("5", f5), ("6", f6))}
    point = {name: f[:3, 3] for name, f in (("1", f1), ("2", f2), ("3", f3), ("5", f5), ("6", f6))}
    sk = Skeleton("goldberg_5r", base="R0", parameters=p, marker_size=0.2 * p.a,
                  description="Goldberg 5R linkage (two Bennett linkages on a common link)")
    sk.revolute("2", point["2"], axis["2"], role="actuated", x_axis=f2[:3, 0], defects="", home=0.0,
                range=(-0.25, 0.25))
    sk.revolute("3", point["3"], axis["3"])
    sk.revolute("1", point["1"], axis["1"])
    sk.revolute("6", point["6"], axis["6"])
    sk.revolute("5", point["5"], axis["5"])
    sk.fixed("W", target="R3")
    sk.frame("P", point["3"], axis["3"], f3[:3, 0])
    sk.chain("A", "R0", "R3", ["2", "3"])
    sk.chain("B", "R0", "R3", ["1", "6", "5", "W"])
    sk.chain("tool", "R3", "P", [])
    sk.output = "P"
    r = 0.04 * p.a
    sk.link("base", ["1", "2"], r)
    sk.link("link23", ["2", "3"], r)
    sk.link("welded", ["3", f4[:3, 3], "5"], r)
    sk.link("link56", ["5", "6"], r)
    sk.link("link61", ["6", "1"], r)
    return sk
