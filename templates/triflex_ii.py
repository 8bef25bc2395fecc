"""Triflex-II, the PRRR-PRRU-PRRS translational parallel manipulator of paper 2, section 5.

Units: lengths in mm, angles in rad; paper 2 writes lengths in "l.u." (length
units), and the default ``length_unit`` of 1 mm makes 1 l.u. = 1 mm so that the
accuracy coefficients compare digit for digit with eqs. (26)-(31).

Geometry (paper 2, Fig. 2, data of section 5.3, in l.u.): ``a_b = 20/47``,
``a_p = 30/47``, ``d_p = 45/94``, ``d_s = 40/47``, ``a2 = a3 = 40/47``,
``a6 = a7 = 36/47``, ``a11 = a12 = 1``.

* PRRR leg: actuated slide ``d1`` along ``z_b`` (joint 1), revolutes 2, 3, 4 parallel
  to ``z_b`` through ``O1``, ``O2``, ``A3`` (``A3 = O_p - a_p i_b``);
* PRRU leg: actuated slide ``d5`` along ``x_b`` on the line through ``B1 = (0, -a_b, 0)``
  (joint 5), revolutes 6, 7 parallel to ``x_b`` through ``O5``, ``O6``, the universal
  joint at ``A1 = O_p - d_p j_b``: 8 along ``x_b`` and 9 along ``j_p`` (fixed to the
  platform);
* PRRS leg: actuated slide ``d10`` along ``y_b`` (joint 10), revolutes 11, 12 parallel
  to ``y_b`` through ``O10``, ``O11``, the spherical joint at ``A2 = O_p + d_s j_b`` as
  three revolutes 13 (``i12``), 14 (``i12 x j_p``), 15 (``j_p``).

Geometric errors: the paper's nine (section 5.1), the constants calibration cannot
absorb; every other constant is taken without error, as in the paper:

=========  =====================================  =========================
paper      meaning                                hyperstat defect
=========  =====================================  =========================
alpha2     tilt of axis 3 about ``i2``             ``dJ3`` (named ``alpha2``)
d2         shift of ``O2`` along ``k2``             ``dc3`` (named ``d2``)
alpha3     tilt of axis 4 about ``i3``             ``dJ4`` (``alpha3``)
d3         shift of ``A3`` along ``k3``             ``dc4`` (``d3``)
alpha6     tilt of axis 7 about ``u6``             ``dJ7`` (``alpha6``)
d6         shift of ``O6`` along ``i6``             ``dc7`` (``d6``)
alpha7     tilt of axis 8 about ``u7``             ``dJ8`` (``alpha7``)
d7         shift of ``A1`` along ``i7``             ``dc8`` (``d7``)
alpha8     U axes off perpendicular (about u8)    ``dK9`` (``alpha8``)
=========  =====================================  =========================

The joint-invariant tilts turn about the same lines as the paper's (eqs. 21, 23);
with the frames used here ``alpha2 = -dJ3`` and so on (a sign only: norms and
accuracy coefficients do not depend on it).  The home configuration has the elbows
``theta3`` and ``theta7`` in ``(0, pi)`` as in the paper's figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton


#: Tolerancing declaration (hyperstat.solver.tolerances.declaration): a translational manipulator, so the task is
#: the platform position (paper 2, section 5.3 allocates against a position accuracy).
TOLERANCING = {
    "task": ["position"],
    "measurements": {"kind": "positions", "targets_mm": [[0.0, 0.0, 0.0]], "noise_mm": 0.001},
    "spec": {"position_mm": 0.01, "orientation_rad": None},
}

@dataclass
class Parameters:
    """Triflex-II data (paper 2, section 5.3) in length units, and the home position."""

    length_unit: float = param(1.0, "mm", "one l.u. of paper 2, in mm", minimum=0.0, exclusive_minimum=True)
    a_b: float = param(20 / 47, "1", "base: O_b to B1 (l.u.)", minimum=0.0)
    a_p: float = param(30 / 47, "1", "platform: A3 to O_p (l.u.)", minimum=0.0)
    d_p: float = param(45 / 94, "1", "platform: O_p to A1 (l.u.)", minimum=0.0)
    d_s: float = param(40 / 47, "1", "platform: O_p to A2 (l.u.)", minimum=0.0)
    a2: float = param(40 / 47, "1", "PRRR leg: O1 to O2 (l.u.)", minimum=0.0, exclusive_minimum=True)
    a3: float = param(40 / 47, "1", "PRRR leg: O2 to A3 (l.u.)", minimum=0.0, exclusive_minimum=True)
    a6: float = param(36 / 47, "1", "PRRU leg: O5 to O6 (l.u.)", minimum=0.0, exclusive_minimum=True)
    a7: float = param(36 / 47, "1", "PRRU leg: O6 to A1 (l.u.)", minimum=0.0, exclusive_minimum=True)
    a11: float = param(1.0, "1", "PRRS leg: O10 to O11 (l.u.)", minimum=0.0, exclusive_minimum=True)
    a12: float = param(1.0, "1", "PRRS leg: O11 to A2 (l.u.)", minimum=0.0, exclusive_minimum=True)
    home_x: float = param(0.25, "1", "platform point O_p at home, x (l.u.)")
    home_y: float = param(0.15, "1", "platform point O_p at home, y (l.u.)")
    home_z: float = param(0.3, "1", "platform point O_p at home, z (l.u.)")
    section: float = param(0.02, "1", "radius of the link bars drawn in CAD (l.u.)", minimum=0.0,
                           exclusive_minimum=True)


def _elbow(start: np.ndarray, end: np.ndarray, l1: float, l2: float, normal: np.ndarray) -> np.ndarray:
    """Elbow point of a planar two-link chain, on the side giving an elbow angle in (0, pi)."""
    d = end - start
    r = float(np.linalg.norm(d))
    if not abs(l1 - l2) < r < l1 + l2:
        from hyperstat.solver.errors import TemplateError

        raise TemplateError(f"the home position is out of reach of a leg (needs {abs(l1 - l2):.3g} < {r:.3g} "
                            f"< {l1 + l2:.3g} l.u.)")
    a = (l1**2 - l2**2 + r**2) / (2 * r)
    h = math.sqrt(max(l1**2 - a**2, 0.0))
    u = d / r
    side = np.cross(normal, u)  # rotate u by +90 deg about the normal
    return start + a * u - h * side


def build(**overrides: float) -> Skeleton:
    """Skeleton of the Triflex-II at its home configuration.

    Returns
    -------
    Skeleton
    """
    p = make_parameters(Parameters, overrides)
    s = p.length_unit
    ex, ey, ez = np.eye(3)
    op = s * np.array([p.home_x, p.home_y, p.home_z])
    a3 = op - s * p.a_p * ex
    a1 = op - s * p.d_p * ey
    a2 = op + s * p.d_s * ey
    # PRRR: O1 on the z_b axis at the height of A3; elbow O2 in the horizontal plane
    o1 = np.array([0.0, 0.0, a3[2]])
    o2 = _elbow(o1, a3, s * p.a2, s * p.a3, ez)
    # PRRU: O5 on the line through B1 parallel to x_b, at the abscissa of A1; elbow in the y-z plane
    o5 = np.array([a1[0], -s * p.a_b, 0.0])
    o6 = _elbow(o5, a1, s * p.a6, s * p.a7, ex)
    # PRRS: O10 on the y_b axis at the ordinate of A2; elbow in the x-z plane
    o10 = np.array([0.0, a2[1], 0.0])
    o11 = _elbow(o10, a2, s * p.a11, s * p.a12, ey)
    i2, i3 = (o2 - o1) / np.linalg.norm(o2 - o1), (a3 - o2) / np.linalg.norm(a3 - o2)
    u6, u7 = (o6 - o5) / np.linalg.norm(o6 - o5), (a1 - o6) / np.linalg.norm(a1 - o6)
    u11, i12 = (o11 - o10) / np.linalg.norm(o11 - o10), (a2 - o11) / np.linalg.norm(a2 - o11)
    i13 = np.cross(i12, ey)
    i13 /= np.linalg.norm(i13)

    sk = Skeleton("triflex_ii", base="Ob", parameters=p, marker_size=0.08 * s,
                  description="Triflex-II PRRR-PRRU-PRRS translational parallel manipulator (paper 2, Simas & Di Gregorio)")
    rev = (-2 * math.pi, 2 * math.pi)
    # PRRR leg
    sk.prismatic("1", (0, 0, 0), ez, role="actuated", x_axis=ex, defects="", home=float(a3[2]),
                 range=(-1.2 * s, 1.2 * s))
    sk.revolute("2", o1, ez, x_axis=i2, defects="", range=rev)
    sk.revolute("3", o2, ez, x_axis=i3, defects="Jc", defect_names={"J": "alpha2", "c": "d2"}, range=rev)
    sk.revolute("4", a3, ez, x_axis=ex, defects="Jc", defect_names={"J": "alpha3", "c": "d3"}, range=rev)
    # PRRU leg
    sk.prismatic("5", (0, -s * p.a_b, 0), ex, role="actuated", x_axis=ey, defects="", home=float(a1[0]),
                 range=(float(a1[0]) - 0.8 * s, float(a1[0]) + 0.8 * s))
    sk.revolute("6", o5, ex, x_axis=u6, defects="", range=rev)
    sk.revolute("7", o6, ex, x_axis=u7, defects="Jc", defect_names={"J": "alpha6", "c": "d6"}, range=rev)
    sk.revolute("8", a1, ex, x_axis=ey, defects="Jc", defect_names={"J": "alpha7", "c": "d7"}, range=rev)
    sk.revolute("9", a1, ey, x_axis=ez, defects="K", defect_names={"K": "alpha8"}, range=rev)
    # PRRS leg
    sk.prismatic("10", (0, 0, 0), ey, role="actuated", x_axis=ez, defects="", home=float(a2[1]),
                 range=(float(a2[1]) - 0.8 * s, float(a2[1]) + 0.8 * s))
    sk.revolute("11", o10, ey, x_axis=u11, defects="", range=rev)
    sk.revolute("12", o11, ey, x_axis=i12, defects="", range=rev)
    sk.revolute("13", a2, i12, defects="", range=rev)
    sk.revolute("14", a2, i13, defects="", range=rev)
    sk.revolute("15", a2, ey, defects="", range=rev)
    sk.frame("Op", op, ez, ex)
    sk.chain("PRRR", "Ob", "Op", ["1", "2", "3", "4"])
    sk.chain("PRRU", "Ob", "Op", ["5", "6", "7", "8", "9"])
    sk.chain("PRRS", "Ob", "Op", ["10", "11", "12", "13", "14", "15"])
    sk.output = "Op"
    # the legs' inverse kinematics in closed form (hyperstat.solver.kinematics.closed_form): each slide moves the
    # platform point along its own axis (d1 = z, d5 = x, d10 = y + d_s), each leg is a planar two-link arm whose
    # elbow keeps its home side, and the joints after the elbow undo the arm's turn (the platform translates)
    sk.metadata["closed_form"] = {
        "platform": {"actuated": {"1": [0.0, 0.0, 1.0], "5": [1.0, 0.0, 0.0], "10": [0.0, 1.0, 0.0]}},
        "legs": [{"type": "planar-2r", "normal": [0.0, 0.0, 1.0], "slide": "1", "joints": ["2", "3"], "tip": "4",
                  "follow": ["4"]},
                 {"type": "planar-2r", "normal": [1.0, 0.0, 0.0], "slide": "5", "joints": ["6", "7"], "tip": "8",
                  "follow": ["8"], "fixed": ["9"]},
                 {"type": "planar-2r", "normal": [0.0, 1.0, 0.0], "slide": "10", "joints": ["11", "12"], "tip": "13",
                  "follow": ["15"], "fixed": ["13", "14"]}]}
    r = s * p.section
    sk.link("PRRR", [(0, 0, 0), o1, o2, a3], r)
    sk.link("PRRU", [(0, -s * p.a_b, 0), o5, o6, a1], r)
    sk.link("PRRS", [(0, 0, 0), o10, o11, a2], r)
    sk.link("platform", [a3, op, a1, a2], r)
    return sk


def workspace(p: Parameters) -> dict:
    """The workspace of paper 2, section 5.3: the whole intersection of the three cylinders, elbows in [0, pi].

    Actuated ranges: the bounding box of the cylinders' intersection (``d1 = z``,
    ``d5 = x``, ``d10 = y + d_s``): the PRRR leg keeps ``O_p`` within ``a2 + a3`` of the
    axis through ``(a_p, 0)`` parallel to ``z_b``, the PRRU leg within ``a6 + a7`` of the
    line through ``(0, d_p - a_b, 0)`` parallel to ``x_b``, the PRRS leg within
    ``a11 + a12`` of ``y_b``.  Passive ranges: the elbow angles ``theta3`` (from ``i2`` to
    ``i3`` about ``z_b``) and ``theta7`` (from ``u6`` to ``u7`` about ``x_b``) in
    ``[0, pi]``, the branch of the paper's Figs. 5-6; joint values count from home, so
    the range of joint 3 is ``[-theta3_home, pi - theta3_home]``.  Lengths in mm, angles in rad.
    """
    s = p.length_unit
    ex, ey, ez = np.eye(3)
    r_rrr, r_rru, r_rrs = s * (p.a2 + p.a3), s * (p.a6 + p.a7), s * (p.a11 + p.a12)
    y_rru = s * (p.d_p - p.a_b)
    op = s * np.array([p.home_x, p.home_y, p.home_z])
    a3, a1 = op - s * p.a_p * ex, op - s * p.d_p * ey
    o1, o5 = np.array([0.0, 0.0, a3[2]]), np.array([a1[0], -s * p.a_b, 0.0])
    o2, o6 = _elbow(o1, a3, s * p.a2, s * p.a3, ez), _elbow(o5, a1, s * p.a6, s * p.a7, ex)

    def angle(u: np.ndarray, v: np.ndarray, n: np.ndarray) -> float:
        return math.atan2(float(np.dot(np.cross(u, v), n)), float(np.dot(u, v)))

    theta3 = angle(o2 - o1, a3 - o2, ez)
    theta7 = angle(o6 - o5, a1 - o6, ex)
    z = min(r_rru, r_rrs)
    x = (max(s * p.a_p - r_rrr, -r_rrs), min(s * p.a_p + r_rrr, r_rrs))
    y = (max(-r_rrr, y_rru - r_rru), min(r_rrr, y_rru + r_rru))
    return {"ranges": {"1": (-z, z), "5": x, "10": (y[0] + s * p.d_s, y[1] + s * p.d_s),
                       "3": (-theta3, math.pi - theta3), "7": (-theta7, math.pi - theta7)},
            "note": "paper 2, section 5.3: the whole cylinder intersection, elbows theta3 and theta7 in [0, pi]"}


if "show_object" in globals():  # CQ-editor
    from hyperstat.cad_plugin.assembly import build_assembly

    show_object(build_assembly(build()))  # noqa: F821
