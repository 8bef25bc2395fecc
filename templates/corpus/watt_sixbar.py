"""Watt six-bar linkage (planar, one input): a four-bar whose coupler and rocker carry a second dyad.

Units: lengths in mm, angles in rad.

The four-bar: the crank turns about ``OA`` (actuated, the reference) and carries ``A``; the
coupler (a ternary link with ``A``, ``B`` and ``C``) and the rocker (a ternary link with ``OB``,
``B`` and ``D``) meet at ``B``.  The dyad: a link from ``C`` to ``E`` and a link from ``E`` to ``D``.
All axes along z.  Chains: ``crank`` (OA, A) places the coupler frame ``CP``; ``rocker`` (OB)
places the rocker frame ``RK``; ``couple`` (B, ``XB``) closes the four-bar on ``CP``; ``dyad``
(C, E) places the frame ``ED`` of the link E-D; ``close`` (D, ``XD``) closes the second loop on
it.  Output: the frame ``P`` at ``E``.  ``scale`` multiplies every coordinate.

Theory.  Bodies: 6 (ground, crank, coupler, rocker, and the dyad's two links; the coupler and
the rocker are the two adjacent ternary links of Watt's chain); joints: 7 revolutes; loops: 2.
Kutzbach in the plane: 3 x 5 - 2 x 7 = 1, the true mobility; in space: 6 x 5 - 5 x 7 = -5.
Screws: the seven joint screws span the three planar motions: rank 7 - 1 = 6 in the 12 loop
equations, so the degree of over-constraint is 12 - 6 = 6, three per loop.  Known conditions:
every axis parallel to z and the joints' plane common; to first order 16 independent
conditions on the joint geometry (the stationarity analysis and an independent screw
computation agree).

Theory: mobility 1, degree of over-constraint 6, assembly conditions 16.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton

TOLERANCING = {
    "task": ["x", "y"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.002},
    "spec": {"position_mm": 0.05, "orientation_rad": None},
}

#: joint positions at home (mm, for scale 1)
_POINTS = {"OA": (0.0, 0.0), "A": (18.1, 46.6), "OB": (150.0, 0.0), "B": (130.0, 90.0), "C": (80.0, 140.0),
           "D": (190.0, 100.0), "E": (150.0, 170.0)}


@dataclass
class Parameters:
    """Scale of the linkage."""

    scale: float = param(1.0, "1", "factor applied to every joint position", minimum=0.0, exclusive_minimum=True)


def build(**overrides: float) -> Skeleton:
    """Skeleton of the Watt six-bar at home."""
    p = make_parameters(Parameters, overrides)
    at = {k: p.scale * np.array([x, y, 0.0]) for k, (x, y) in _POINTS.items()}
    z = (0.0, 0.0, 1.0)
    sk = Skeleton("watt_sixbar", base="R0", parameters=p, marker_size=10.0 * p.scale,
                  description="Watt six-bar linkage (planar)")
    sk.revolute("OA", at["OA"], z, role="actuated", x_axis=(1, 0, 0), defects="", home=0.0, range=(-0.3, 0.3))
    for name in ("A", "OB", "B", "C", "E", "D"):
        sk.revolute(name, at[name], z)
    sk.fixed("XB", target="CP")
    sk.fixed("XD", target="ED")
    sk.frame("P", at["E"], z, (1, 0, 0))
    sk.chain("crank", "R0", "CP", ["OA", "A"])
    sk.chain("rocker", "R0", "RK", ["OB"])
    sk.chain("couple", "RK", "CP", ["B", "XB"])
    sk.chain("dyad", "CP", "ED", ["C", "E"])
    sk.chain("close", "RK", "ED", ["D", "XD"])
    sk.chain("tool", "ED", "P", [])
    sk.output = "P"
    r = 2.0 * p.scale
    sk.link("base", ["OA", "OB"], r)
    sk.link("crank", ["OA", "A"], r)
    sk.link("coupler", ["A", "B", "C", "A"], r)
    sk.link("rocker", ["OB", "B", "D", "OB"], r)
    sk.link("dyad1", ["C", "E"], r)
    sk.link("dyad2", ["E", "D"], r)
    return sk
