"""The datum system of a part (ISO 5459) and the components of its features' deviations relative to it.

Units: mm and rad; directions in the base frame at the home configuration.

A part's drawing refers every frame to a **datum reference frame** built from the part's own
features, one letter each (:func:`datum_system`):

* ``A``, primary: the axis of the part's reference feature, the journal (or slide) of the joint that
  leads to it, or on the base the bore of the reference joint (the first joint of the first chain):
  it locks the two tilts and the two shifts across it;
* ``B``, secondary: a plane normal to ``A`` (the journal's shoulder, the slide's stop, the bore's end
  face): it locks the translation along ``A``;
* ``C``, tertiary, when the rotation about ``A`` matters: a slide's flank (a prismatic joint turns
  nothing about its axis), a driven journal's keyway or a driven bore's drive reference (the angle of
  the actuator), or, on a part with at least two other bores, the axis of another bore (one parallel
  to ``A`` preferred).  On a part entered through a passive revolute with a single other bore, the
  rotation about ``A`` is that joint's own motion: no ``C``, and nothing on the drawing depends on it.

A feature's deviation relative to that frame is split into **components** (:class:`Component`), each
a linear function of the defect parameters (paper 1, eq. 4, linearised): an axis has two tilts (rad)
and two shifts of its middle across it (mm), a face one shift along its normal (mm).  Their directions
are chosen so that a frame can state them: the tilt *toward* ``A`` (``oriented_by`` ``"A"``: a
perpendicularity or angularity zone to ``A`` states it), the tilt that is a rotation *about* ``A``
(``affected``: it needs ``C``), a shift along ``A`` (located by ``B``), a shift across ``A`` (located
by ``A``; by ``C`` when a rotation about ``A`` moves it).

>>> import numpy as np
>>> _basis(np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 0.0]))[0].round(3).tolist()
[0.707, 0.707, 0.0]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.tolerances.parts import Feature, Part

__all__ = ["Datum", "Component", "DatumSystem", "datum_system"]

_TOL = 1e-9
_AXES = ("bore", "journal", "guide", "slide")
_PLANES = ("face", "shoulder", "stop", "seatface", "seatflat")


@dataclass
class Datum:
    """One datum letter of a part: the feature it names and its precedence."""

    letter: str
    feature: Feature
    precedence: str


@dataclass
class Component:
    """One component of a feature's deviation relative to its part's datum system.

    Attributes
    ----------
    feature : Feature
    group : str
        ``tilt`` (rad), ``shift`` (mm, across an axis at its middle) or ``normal`` (mm, along a face's normal).
    direction : ndarray (3,)
        The direction the deviation is measured along (base frame): a zone's normal.
    row : ndarray (n_xi,)
        The component per unit of every defect parameter.
    affected : bool
        A rotation of the part about ``A`` changes it (it needs datum ``C``).
    oriented_by : str
        ``A``: the direction lies in the plane of the feature and ``A`` (a tilt toward ``A``, a shift
        along ``A``): stated by ``A`` (and ``B``); ``C``: it needs ``C`` (or a cylindrical zone).
    along_a : bool
        A translation along ``A`` changes it (it needs datum ``B``).
    """

    feature: Feature
    group: str
    direction: np.ndarray
    row: np.ndarray
    affected: bool
    oriented_by: str
    along_a: bool
    key: str = ""


@dataclass
class DatumSystem:
    """A part's datums and the components of its features' deviations (see the module docstring)."""

    part: Part
    a: Feature
    b: Feature | None
    c: Feature | None
    datums: list
    nu_c: np.ndarray | None
    components: list = field(default_factory=list)

    def letter(self, feature: Feature) -> str | None:
        """The datum letter of a feature, if it is one."""
        return next((d.letter for d in self.datums if d.feature is feature), None)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _basis(n: np.ndarray, hint: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors across ``n``: the first along ``hint`` projected across ``n`` (or any), the second ``n x`` it."""
    if hint is not None:
        h = hint - (hint @ n) * n
        if np.linalg.norm(h) > 1e-9:
            e1 = _unit(h)
            return e1, np.cross(n, e1)
    e = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = _unit(e - (e @ n) * n)
    return e1, np.cross(n, e1)


def _pick(part: Part, role: str, element: str) -> Feature | None:
    return next((f for f in part.features if f.role == role and f.element == element), None)


def _choose(part: Part, mechanism) -> tuple[Feature, Feature | None, Feature | None]:
    """A, B, C of a part (see the module docstring)."""
    joints = {j.name: j for j in mechanism.joints}
    if part.entry is not None:
        j = joints[part.entry]
        a = _pick(part, "journal" if j.type == "R" else "slide", j.name)
        b = _pick(part, "shoulder" if j.type == "R" else "stop", j.name)
        if j.type == "P":
            return a, b, _pick(part, "sflank", j.name)
        if j.role == "actuated":
            return a, b, _pick(part, "keyway", j.name)
        others = [f for f in part.features if f.role in _AXES and f is not a]
        return a, b, (_other_axis(a, others) if len(others) >= 2 else None)
    # the base: the bore (or guide) of the first joint of the first chain
    first = next(el for ci in mechanism.topology["order"] for el in mechanism.chains[ci].elements
                 if el.name in joints and any(f.element == el.name for f in part.features))
    j = joints[first.name]
    a = _pick(part, "bore" if j.type == "R" else "guide", j.name)
    b = _pick(part, "face", j.name) if j.type == "R" else None
    if j.type == "P":
        return a, b, _pick(part, "flank", j.name)
    if j.role == "actuated":
        return a, b, _pick(part, "drive", j.name)
    mounting = next((f for f in part.features if f.role == "mounting"), None)
    if mounting is not None:
        return a, b, mounting
    others = [f for f in part.features if f.role in _AXES and f is not a]
    return a, b, _other_axis(a, others)


def _other_axis(a: Feature, others: list) -> Feature | None:
    """An axis not coaxial with ``a``: one parallel to it (offset) preferred, else the first."""
    def coaxial(f: Feature) -> bool:
        d = f.point - a.point
        return abs(abs(f.direction @ a.direction) - 1) < _TOL and np.linalg.norm(d - (d @ a.direction) *
                                                                              a.direction) < 1e-6
    candidates = [f for f in others if not coaxial(f)]
    parallel = [f for f in candidates if abs(abs(f.direction @ a.direction) - 1) < _TOL]
    return (parallel or candidates or [None])[0]


def _point_rows(disp: dict, f: Feature, part: Part, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(omega rows, displacement rows of point p), (3, n_xi) each, of the node carrying ``f``."""
    d = disp[f.node]
    o = part.nodes[f.node][:3, 3]
    w = d[:3]
    return w, d[3:] - np.cross(p - o, w.T).T


def datum_system(part: Part, mechanism, disp: dict) -> DatumSystem:
    """The datum system of ``part`` and the components of its features (see the module docstring).

    Parameters
    ----------
    disp : dict
        Node -> (6, n_xi) small displacement per unit defect (:func:`hyperstat.solver.tolerances.parts.node_displacements`).
    """
    fa, fb, fc = _choose(part, mechanism)
    a, pa = fa.direction, fa.point
    perp = np.eye(3) - np.outer(a, a)
    w_a, v_a = _point_rows(disp, fa, part, pa)
    w_d0 = perp @ w_a
    v_d0 = perp @ v_a
    if fb is not None:
        _, v_b = _point_rows(disp, fb, part, fb.point)
        d = fb.point - pa
        v_d0 = v_d0 + np.outer(a, a @ v_b - np.cross(d, a) @ w_d0)
    nu_c = None
    theta = np.zeros(w_a.shape[1])
    if fc is not None:
        w_c, v_c = _point_rows(disp, fc, part, fc.point)
        if fc.kind != "axis":
            nu_c = fc.direction - (fc.direction @ a) * a
            nu_c = _unit(nu_c)
            theta = a @ w_c
        elif abs(abs(fc.direction @ a) - 1) < _TOL:  # parallel to A, offset: its position across
            e = perp @ (fc.point - pa)
            r = float(np.linalg.norm(e))
            e /= r
            nu_c = np.cross(a, e)
            v_at = v_d0 - np.cross(fc.point - pa, w_d0.T).T
            theta = nu_c @ (v_c - v_at) / r
        else:  # another direction: its rotation about A
            c = fc.direction
            ac = np.cross(a, c)
            nu_c = _unit(ac)
            rel = np.cross((w_c - w_d0).T, c).T
            theta = ac @ rel / float(ac @ ac)
    w_d = w_d0 + np.outer(a, theta)
    letters = [("A", fa, "primary")] + ([("B", fb, "secondary")] if fb is not None else []) + \
        ([("C" if fb is not None else "B", fc, "tertiary" if fb is not None else "secondary")] if fc is not None else [])
    ds = DatumSystem(part, fa, fb, fc, [Datum(*x) for x in letters], nu_c)

    def rel(f: Feature, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w, v = _point_rows(disp, f, part, p)
        return w - w_d, v - (v_d0 - np.cross(p - pa, w_d.T).T)

    for f in part.features:
        if f is fa or f is fb or (f.kind != "axis" and f.role not in _PLANES):
            continue
        if f.kind == "axis":
            n = f.direction
            w, v = rel(f, f.point)
            u = np.cross(a, n)
            if np.linalg.norm(u) > 1e-9:
                t_aff = _unit(u)
                tilts = [(np.cross(n, t_aff), False, "A"), (t_aff, True, "C")]
            else:
                e1, e2 = _basis(n, nu_c if nu_c is not None else part.nodes[f.node][:3, 0])
                tilts = [(e1, False, "C"), (e2, False, "C")]
            s = np.cross(a, f.point - pa)
            s = s - (s @ n) * n
            if np.linalg.norm(s) > 1e-6:
                s_aff = _unit(s)
                s_un = np.cross(n, s_aff)
                shifts = [(s_un, False, "A" if abs(abs(s_un @ a) - 1) < _TOL else "C"), (s_aff, True, "C")]
            elif np.linalg.norm(u) > 1e-9:
                s1 = _unit(u)
                s2 = np.cross(n, s1)
                shifts = [(s1, False, "C"), (s2, False, "A" if abs(abs(s2 @ a) - 1) < _TOL else "C")]
            else:
                e1, e2 = _basis(n, nu_c if nu_c is not None else part.nodes[f.node][:3, 0])
                shifts = [(e1, False, "C"), (e2, False, "C")]
            c_parallel = f is fc and abs(abs(fc.direction @ a) - 1) < _TOL
            for k, (m, aff, by) in enumerate(tilts):
                if f is fc and aff and not c_parallel:
                    continue  # the component that makes it datum C: its rotation about A
                row = np.cross(n, m) @ w
                ds.components.append(Component(f, "tilt", m, row, aff, by, False, f"{f.id}:tilt{k}"))
            for k, (m, aff, by) in enumerate(shifts):
                if c_parallel and aff:
                    continue  # the component that makes it datum C: its position about A
                row = m @ v
                ds.components.append(Component(f, "shift", m, row, aff, by, abs(m @ a) > _TOL, f"{f.id}:shift{k}"))
        else:
            n = f.direction
            _, v = rel(f, f.point)
            aff = abs(n @ np.cross(a, f.point - pa)) > 1e-6
            ds.components.append(Component(f, "normal", n, n @ v, aff, "A" if abs(abs(n @ a) - 1) < _TOL else "C",
                                           abs(n @ a) > _TOL, f"{f.id}:normal"))
    return ds
