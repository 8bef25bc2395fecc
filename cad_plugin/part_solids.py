"""A part of a drawing as a solid whose toleranced and datum features are real faces.

Units: lengths in mm (the base frame at the home configuration, as ``report.json``'s ``drawings``).

A part drawing (``report.json`` ``drawings[*]``, contract in ``docs/drawing-format.md``) names its features
by kind, point, direction, length and diameter.  A workshop tolerances faces, not axes: :func:`part_solid`
builds a solid on which every feature exists as one or more faces, and finds those faces again on the
finished solid by their geometry (never by construction history, which the Boolean operations rewrite).
What each feature becomes:

* an ``axis`` on the fixed side of a revolute (``bore``): a cylindrical hole of the feature's diameter and
  length (the span of the joint's supports) through a boss; on the moving side (``journal``, also any axis
  named pin, trunnion or shaft): a pin of that diameter and length standing on a collar;
* an ``axis`` on the fixed side of a prismatic joint (``guide way``): a rectangular channel along the axis,
  as wide as the diameter, half as deep; the feature is its two flanks and its floor; on the moving side
  (``slide``): the bar that fits that channel, the feature its two sides and its bottom;
* a ``plane`` whose normal runs along an axis feature of its joint (an end face, shoulder or stop): the face
  at the end of that bore, journal or slide, on the side its normal points away from (the bore's end face
  and the journal's shoulder of one joint are one plane); a plane whose normal is across a guide way or a
  slide (a flank): that channel's or bar's side; any other plane: a pad whose outward normal is the
  direction;
* a ``median plane`` through an axis feature of its joint (a keyway, a drive slot): a slot cut along that
  journal or bore, the feature its two flanks; any other median plane: the two faces ``length_mm`` apart;
* a ``point``: a spherical socket (the centre of a ball joint).

The contract places a plane at its joint's centre; drawn at the end of its bore, the plane is parallel to
it, shifted along its own normal by half the bore's length (``PartSolid.assumed`` says so, and the STEP
file's face is that drawn face).  The features are joined by bars along the shortest tree through their
points, from material to material (never through a bore).  Sizes the drawing does not give (a diameter, a
keyway's width) are assumed and listed in :attr:`PartSolid.assumed`, so that the page that draws the part
says so.

>>> d = {"part": "rod", "features": [
...     {"id": "rod.journal2", "kind": "axis", "side": "moving", "element": "2", "point_mm": [0, 0, 0],
...      "direction": [0, -1, 0], "length_mm": 20, "diameter_mm": 20},
...     {"id": "rod.bore3", "kind": "axis", "side": "fixed", "element": "3", "point_mm": [120, 0, 0],
...      "direction": [0, -1, 0], "length_mm": 20, "diameter_mm": 20}]}
>>> s = part_solid(d)
>>> sorted(s.faces), [f.geomType() for f in s.faces["rod.bore3"]]
(['rod.bore3', 'rod.journal2'], ['CYLINDER'])

The solid is built with OCCT's own calls (:mod:`hyperstat.cad_plugin.occ_solids`, the calls CadQuery makes, so
the same shapes): the report's part pages need no CadQuery import.  :attr:`PartSolid.shape` and
:attr:`PartSolid.faces` give CadQuery's wrappers of them (the STEP export uses them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from hyperstat.solver.errors import HyperstatError

__all__ = ["PartSolid", "part_solid", "feature_frame", "DEFAULT_DIAMETER_MM", "DEFAULT_LENGTH_MM"]

#: a bore's or journal's diameter (a guide way's width) when the drawing gives none: the 20 mm of the default
#: ISO 286 fit (:data:`hyperstat.solver.tolerances.declaration.DEFAULT_CLEARANCES`)
DEFAULT_DIAMETER_MM = 20.0
#: a feature's length when the drawing gives none
DEFAULT_LENGTH_MM = 20.0
_PAD_MM = 3.0  # thickness of a pad behind a free plane, and of a journal's collar
_PIN_WORDS = ("journal", "pin", "trunnion", "shaft")
_SLIDE_WORDS = ("slide",)


@dataclass
class PartSolid:
    """A part's solid and, per feature id, the faces that realise the feature.

    ``wrapped`` and ``face_shapes`` are OCCT's shapes (OCP's ``TopoDS_Shape`` and ``TopoDS_Face``);
    :attr:`shape` and :attr:`faces` are the same as CadQuery objects (CadQuery imported on first use)."""

    part: str
    wrapped: Any  # TopoDS_Shape: the solid
    face_shapes: dict = field(default_factory=dict)  # feature id -> list of TopoDS_Face
    features: dict = field(default_factory=dict)  # feature id -> the drawing's feature (dict)
    assumed: list = field(default_factory=list)  # sentences: sizes and places the drawing did not give
    parsed: dict = field(default_factory=dict)  # feature id -> _Feature: the geometry drawn (role, point, sizes)

    @cached_property
    def shape(self) -> Any:
        """The solid as a ``cadquery.Shape`` (a ``Solid`` or ``Compound``, as CadQuery's operations would give)."""
        import cadquery as cq

        return cq.Shape.cast(self.wrapped)

    @cached_property
    def faces(self) -> dict:
        """Feature id -> list of ``cadquery.Face`` (one wrapper per face, shared by the features it realises)."""
        import cadquery as cq

        made: dict = {}
        return {fid: [made.setdefault(id(f), cq.Face(f)) for f in found] for fid, found in self.face_shapes.items()}


def _unit(v, where: str) -> np.ndarray:
    a = np.asarray(v, dtype=float) if v is not None else np.zeros(0)
    n = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
    if not n > 0 or not np.all(np.isfinite(a)):
        raise HyperstatError(f"{where}: direction must be a non-zero vector [x, y, z], got {v!r}.")
    return a / n


def feature_frame(direction: np.ndarray, hint: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``v, w`` completing ``direction`` to a right-handed frame; ``w`` leans towards ``hint``.

    >>> v, w = feature_frame(np.array([0.0, 0.0, 1.0]))
    >>> float(abs(v @ w)) < 1e-12 and abs(float(np.linalg.det([v, w, [0, 0, 1.0]])) - 1) < 1e-12
    True
    """
    u = direction / np.linalg.norm(direction)
    if hint is not None:
        h = hint - (hint @ u) * u
        if np.linalg.norm(h) > 1e-9:
            w = h / np.linalg.norm(h)
            return np.cross(w, u), w
    k = int(np.argmin(np.abs(u)))
    e = np.zeros(3)
    e[k] = 1.0
    v = np.cross(u, e)
    v /= np.linalg.norm(v)
    return v, np.cross(u, v)


class _Feature:
    """A feature's geometry, read and checked from the drawing's dict; :func:`_place` sets what is drawn."""

    def __init__(self, f: dict, part: str, joint_type: str | None, default_diameter: float = DEFAULT_DIAMETER_MM):
        where = f"drawing of part '{part}', feature '{f.get('id', '?')}'"
        self.id = str(f.get("id") or "")
        if not self.id:
            raise HyperstatError(f"drawing of part '{part}': a feature has no 'id'.")
        self.kind = str(f.get("kind", ""))
        if self.kind not in ("axis", "plane", "median plane", "point"):
            raise HyperstatError(f"{where}: kind must be 'axis', 'plane', 'median plane' or 'point', "
                                 f"got {self.kind!r}.")
        p = np.asarray(f.get("point_mm"), dtype=float) if f.get("point_mm") is not None else None
        if p is None or p.shape != (3,) or not np.all(np.isfinite(p)):
            raise HyperstatError(f"{where}: point_mm must be [x, y, z] in mm, got {f.get('point_mm')!r}.")
        self.given = p
        self.p = p.copy()
        self.u = _unit(f.get("direction"), where) if self.kind != "point" or f.get("direction") is not None else \
            np.array([0.0, 0.0, 1.0])
        for key in ("length_mm", "diameter_mm"):
            v = f.get(key)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise HyperstatError(f"{where}: {key} must be a positive number (mm) or null, got {v!r}.")
        self.length_given = f.get("length_mm") is not None
        self.length = float(f["length_mm"]) if self.length_given else DEFAULT_LENGTH_MM
        self.diameter_given = f.get("diameter_mm") is not None
        self.diameter = float(f["diameter_mm"]) if self.diameter_given else default_diameter
        self.element = str(f.get("element") or "")
        self.name = str(f.get("name") or self.id)
        side = f.get("side")
        words = self.name.lower()
        self.role = self.kind
        if self.kind == "axis":
            if joint_type == "P" or any(w in words for w in _SLIDE_WORDS + ("guide",)):
                moving = side == "moving" if side else any(w in words for w in _SLIDE_WORDS)
                self.role = "slide" if moving else "guide"
            else:
                moving = side == "moving" if side else any(w in words for w in _PIN_WORDS)
                self.role = "journal" if moving else "bore"
        elif self.kind == "point":
            self.role = "socket"
        self.wall = max(0.3 * self.diameter, min(4.0, 0.5 * self.diameter))
        self.pad = min(_PAD_MM, 0.15 * self.diameter)  # a pad's or a collar's thickness
        self.host: _Feature | None = None  # the axis feature a plane or median plane belongs to
        self.v = self.w = None  # a guide way's or slide's cross-section axes (flanks along v, open along w)
        self.width = 0.0  # a slot's width (median plane on a host)
        self.collar = None  # a journal's collar side (unit vector from the pin to its collar)

    @property
    def outer_radius(self) -> float:
        """A boss's, collar's or housing's radius (mm): the diameter's half and a wall."""
        return 0.5 * self.diameter + self.wall


def _host(f: _Feature, features: list[_Feature]) -> _Feature | None:
    """The axis feature a plane or median plane belongs to: of the same joint, its axis through the plane's point."""
    best = None
    for g in features:
        if g.kind != "axis" or g is f:
            continue
        r = f.given - g.given
        off_axis = np.linalg.norm(r - (r @ g.u) * g.u)
        if off_axis < 1e-6 * max(1.0, g.length) and abs(float(r @ g.u)) <= 0.5 * g.length + 1e-9:
            if best is None or (g.element == f.element and best.element != f.element):
                best = g
    return best


def _place(features: list[_Feature], centroid: np.ndarray) -> list[str]:
    """Decide what each plane and median plane is (see the module docstring) and where it is drawn."""
    notes: list[str] = []
    shifted: list[str] = []
    slots: list[str] = []
    for g in features:  # guide ways and slides: their cross-section, flanks across the flank feature's normal
        if g.role in ("guide", "slide"):
            flank = next((f for f in features if f.kind == "plane" and f.element == g.element
                          and abs(float(f.u @ g.u)) < 1e-6 and _host(f, features) is g), None)
            hint = g.p - centroid if np.linalg.norm(g.p - centroid) > 1e-6 else None
            if flank is not None:
                g.v = flank.u
                w = np.cross(g.u, g.v)
                if hint is not None and w @ hint < 0:
                    w = -w
                g.w = w
            else:
                g.v, g.w = feature_frame(g.u, hint)
    for f in features:
        if f.kind == "plane":
            host = _host(f, features)
            f.host = host
            if host is None:
                f.role = "pad"
            elif abs(abs(float(f.u @ host.u)) - 1) < 1e-6:
                f.role = "end"
                at_end = abs(abs(float((f.given - host.given) @ host.u)) - 0.5 * host.length) < 1e-6 * host.length
                end = f.given if at_end else host.given - 0.5 * host.length * f.u
                if np.linalg.norm(end - f.given) > 1e-9:
                    shifted.append(f.id)
                f.p = end
                if host.role == "journal":
                    host.collar = -f.u
            elif abs(float(f.u @ host.u)) < 1e-6 and host.role in ("guide", "slide"):
                f.role = "flank"
                f.p = host.given + 0.5 * host.diameter * f.u
            else:
                f.role = "pad"
        elif f.kind == "median plane":
            host = _host(f, features)
            if host is not None and host.role in ("bore", "journal") and abs(float(f.u @ host.u)) < 1e-6:
                f.role, f.host = "slot", host
                f.width = max(0.25 * host.diameter, 3.0)
                if not f.length_given:
                    f.length = f.width
                if not f.length_given:
                    slots.append(f"{f.id} {f.length:g} mm")
            else:
                f.role = "median"
    for g in features:
        if g.role == "journal" and g.collar is None:
            g.collar = -g.u
    if shifted:
        notes.append("end faces, shoulders and stops drawn at the end of their bore, journal or slide, parallel to "
                     "the plane through the joint's centre that the drawing gives: " + ", ".join(shifted))
    if slots:
        notes.append("keyway and drive slot widths assumed: " + ", ".join(slots))
    for f in features:
        if f.role == "pad":
            _clear_pad(f, features, notes)
    return notes


def _inside(point: np.ndarray, radius: float, g: _Feature) -> bool:
    """Whether a disc of ``radius`` at ``point`` would meet body ``g``'s material (a bore's boss, a journal and
    its collar, a guide way's block, a slide's plate, a socket), approximated by a cylinder around its axis."""
    if g.role in ("bore", "journal", "guide", "slide"):
        reach = g.outer_radius * (1.5 if g.role in ("guide", "slide") else 1.0)
        r = point - g.p
        along = float(r @ g.u)
        extra = g.pad if g.role == "journal" else 0.0
        return abs(along) <= 0.5 * g.length + extra + radius and \
            float(np.linalg.norm(r - along * g.u)) < reach + radius
    if g.role == "socket":
        return float(np.linalg.norm(point - g.p)) < g.outer_radius + radius
    return False


def _clear_pad(f: _Feature, features: list[_Feature], notes: list[str]) -> None:
    """Move a free plane's pad within its plane until it meets no other body (a stop or a mounting face drawn at
    a bore's centre would be swallowed by the boss)."""
    radius = max(f.outer_radius, 0.5 * f.length)
    others = [g for g in features if g is not f and g.role in ("bore", "journal", "guide", "slide", "socket")]
    if not any(_inside(f.p, radius, g) for g in others):
        return
    e1, e2 = feature_frame(f.u)
    step = radius + max(g.outer_radius for g in others)
    for k in range(1, 40):
        for d in (e1, -e1, e2, -e2, (e1 + e2) / math.sqrt(2), (e1 - e2) / math.sqrt(2), (-e1 + e2) / math.sqrt(2),
                  (-e1 - e2) / math.sqrt(2)):
            q = f.p + 0.5 * k * step * d
            if not any(_inside(q, radius, g) for g in others):
                notes.append(f"{f.id} drawn {0.5 * k * step:.3g} mm beside the point the drawing gives, in its plane "
                             "(that point lies in another feature's material)")
                f.p = q
                return


def _cylinder(radius: float, start: np.ndarray, axis: np.ndarray, length: float):
    from hyperstat.cad_plugin import occ_solids

    return occ_solids.cylinder(radius, length, start, axis)


def _box(centre: np.ndarray, u: np.ndarray, v: np.ndarray, w: np.ndarray, size: tuple[float, float, float]):
    """A box of ``size`` (along u, v, w) centred on ``centre`` (w's sign is free: the box is symmetric, and the
    placement must be a rotation, never a mirror, or OCCT turns the solid inside out)."""
    from OCP.gp import gp_Trsf

    from hyperstat.cad_plugin import occ_solids

    w = np.cross(u, v)
    box = occ_solids.box(*size, pnt=(-size[0] / 2, -size[1] / 2, -size[2] / 2))
    t = gp_Trsf()
    t.SetValues(u[0], v[0], w[0], centre[0], u[1], v[1], w[1], centre[1], u[2], v[2], w[2], centre[2])
    return occ_solids.moved(box, t)


def _material_and_voids(features: list[_Feature]) -> tuple[list, list]:
    """Solids to fuse (bosses, pins, blocks, pads) and to cut (bores, channels, slots, sockets)."""
    from hyperstat.cad_plugin import occ_solids

    solids, voids = [], []
    for f in features:
        d, L, R = f.diameter, f.length, f.outer_radius
        if f.role == "bore":
            solids.append(_cylinder(R, f.p - 0.5 * L * f.u, f.u, L))
            voids.append(_cylinder(0.5 * d, f.p - (0.5 * L + 0.1) * f.u, f.u, L + 0.2))
        elif f.role == "journal":
            solids.append(_cylinder(0.5 * d, f.p - 0.5 * L * f.u, f.u, L))
            base = f.p + 0.5 * L * f.collar
            solids.append(_cylinder(R, base, f.collar, f.pad))
        elif f.role == "guide":  # a block with a channel open along w: floor at -d/2 w, flanks at +-d/2 v
            solids.append(_box(f.p - 0.5 * (0.5 * d + f.wall) * f.w, f.u, f.v, f.w,
                               (L, d + 2 * f.wall, 0.5 * d + f.wall)))
            # the channel is as long as the block (flush: a longer cut would carve a bar's end beyond it)
            voids.append(_box(f.p - 0.25 * d * f.w + 0.5e-3 * f.w, f.u, f.v, f.w, (L, d, 0.5 * d + 1e-3)))
        elif f.role == "slide":  # the bar that fits the channel, on a plate above it
            solids.append(_box(f.p - 0.25 * d * f.w, f.u, f.v, f.w, (L, d, 0.5 * d)))
            solids.append(_box(f.p + 0.5 * f.wall * f.w, f.u, f.v, f.w, (L, d + 2 * f.wall, f.wall)))
        elif f.role == "pad":
            solids.append(_cylinder(max(R, 0.5 * L), f.p, -f.u, f.pad))
        elif f.role == "median":
            solids.append(_cylinder(max(R, 10.0), f.p - 0.5 * L * f.u, f.u, L))
        elif f.role == "slot":  # along the host's axis, at its surface, across the median plane's normal
            h = f.host
            t = np.cross(f.u, h.u)
            t /= np.linalg.norm(t)
            depth = 0.25 * h.diameter
            if h.role == "journal":  # from 0.1 mm beyond the pin's free end to 0.5 mm short of its collar
                centre, length = h.p + 0.5 * h.diameter * t - 0.3 * h.collar, h.length - 0.4
            else:  # a hub's keyway: through the boss
                centre, length = h.p + 0.5 * h.diameter * t, h.length + 0.2
            voids.append(_box(centre, h.u, f.u, t, (length, f.length, 2 * depth)))
        elif f.role == "socket":
            solids.append(occ_solids.sphere(R, f.p, angle1_deg=-90, angle2_deg=90))
            voids.append(occ_solids.sphere(0.5 * d, f.p, angle1_deg=-90, angle2_deg=90))
    return solids, voids


def _tree(points: np.ndarray) -> list[tuple[int, int]]:
    """Edges of the shortest tree through ``points`` (Prim)."""
    n = len(points)
    if n < 2:
        return []
    inside, edges = {0}, []
    while len(inside) < n:
        best = min(((i, j) for i in inside for j in range(n) if j not in inside),
                   key=lambda e: float(np.linalg.norm(points[e[0]] - points[e[1]])))
        edges.append(best)
        inside.add(best[1])
    return edges


def _attach(f: _Feature, target: np.ndarray) -> np.ndarray:
    """Where a bar towards ``target`` meets feature ``f``'s material (never inside a bore, channel or pin)."""
    r = target - f.p
    if f.role == "guide":
        return f.p - (0.5 * f.diameter + 0.5 * f.wall) * f.w
    if f.role == "slide":
        return f.p + 0.5 * f.wall * f.w
    if f.role == "journal":
        return f.p + (0.5 * f.length + 0.5 * f.pad) * f.collar
    if f.role == "pad":
        return f.p - 0.5 * f.pad * f.u
    if f.role == "median":
        return f.p
    mid = 0.5 * f.diameter + 0.5 * f.wall  # in the wall of a bore or socket
    if f.role == "socket":
        return f.p + mid * r / max(float(np.linalg.norm(r)), 1e-12)
    lateral = r - (r @ f.u) * f.u
    if np.linalg.norm(lateral) > 1e-6 * max(1.0, float(np.linalg.norm(r))):
        return f.p + mid * lateral / np.linalg.norm(lateral)
    v, _ = feature_frame(f.u)
    return f.p + np.sign(r @ f.u) * 0.5 * f.length * f.u + mid * v  # along the axis: from the boss's end face


def _bars(features: list[_Feature]) -> list:
    """Bars along the shortest tree through the bodies (bores, journals, guide ways, slides, pads, sockets)."""
    bodies = [f for f in features if f.role not in ("end", "flank", "slot")]
    points = np.array([f.p for f in bodies])
    out = []
    for i, j in _tree(points):
        a, b = bodies[i], bodies[j]
        if np.linalg.norm(a.p - b.p) < 1e-6:
            continue  # bodies at one point (a cross's two axes): they already meet
        pa, pb = _attach(a, b.p), _attach(b, a.p)
        d = pb - pa
        n = float(np.linalg.norm(d))
        if n > 1e-6:
            out.append(_cylinder(0.4 * min(a.outer_radius, b.outer_radius), pa, d / n, n))
    return out


def _fuse(shapes: list):
    from hyperstat.cad_plugin import occ_solids

    first, rest = shapes[0], shapes[1:]
    return occ_solids.clean(occ_solids.fuse(first, *rest) if rest else first)


def _cylinder_of(face) -> tuple[np.ndarray, np.ndarray, float]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    cyl = BRepAdaptor_Surface(face).Cylinder()
    ax = cyl.Axis()
    d, o = ax.Direction(), ax.Location()
    return np.array([d.X(), d.Y(), d.Z()]), np.array([o.X(), o.Y(), o.Z()]), float(cyl.Radius())


def _sphere_of(face) -> tuple[np.ndarray, float]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    sph = BRepAdaptor_Surface(face).Sphere()
    c = sph.Location()
    return np.array([c.X(), c.Y(), c.Z()]), float(sph.Radius())


class _FaceGeometry:
    """A face's (a TopoDS_Face's) type, centre, normal, cylinder and sphere, each computed once (every feature of the
    part tests every face: the centre integrates the face's area)."""

    def __init__(self, face) -> None:
        from hyperstat.cad_plugin import occ_solids

        self.face = face
        self.kind = occ_solids.face_type(face)
        self._centre = self._normal = self._cylinder = self._sphere = None

    @property
    def centre(self) -> np.ndarray:
        if self._centre is None:
            from hyperstat.cad_plugin.occ_solids import face_centre

            self._centre = np.array(face_centre(self.face))
        return self._centre

    @property
    def normal(self) -> np.ndarray:
        if self._normal is None:
            from hyperstat.cad_plugin.occ_solids import face_normal

            self._normal = np.array(face_normal(self.face))
        return self._normal

    @property
    def cylinder(self) -> tuple[np.ndarray, np.ndarray, float]:
        if self._cylinder is None:
            self._cylinder = _cylinder_of(self.face)
        return self._cylinder

    @property
    def sphere(self) -> tuple[np.ndarray, float]:
        if self._sphere is None:
            self._sphere = _sphere_of(self.face)
        return self._sphere


def _matches(face, f: _Feature, tol: float) -> bool:
    """Whether ``face`` (a TopoDS_Face or its :class:`_FaceGeometry`) realises (part of) feature ``f`` (geometry within
    ``tol`` mm and 1e-6 rad)."""
    g = face if isinstance(face, _FaceGeometry) else _FaceGeometry(face)
    kind = g.kind
    if f.role in ("bore", "journal"):
        if kind != "CYLINDER":
            return False
        r = g.centre - f.p
        axis, origin, radius = g.cylinder
        return (abs(radius - 0.5 * f.diameter) <= tol and abs(abs(float(axis @ f.u)) - 1) < 1e-6
                and np.linalg.norm(np.cross(f.p - origin, axis)) < tol and abs(float(r @ f.u)) <= 0.5 * f.length + tol)
    if f.role == "socket":
        if kind != "SPHERE":
            return False
        c, radius = g.sphere
        return abs(radius - 0.5 * f.diameter) <= tol and np.linalg.norm(c - f.p) < tol
    if kind != "PLANE":
        return False
    centre = g.centre
    r = centre - f.p
    normal = g.normal
    if f.role in ("guide", "slide"):  # the channel's (the bar's) flanks and floor (bottom)
        return (abs(float(normal @ f.u)) < 1e-6 and abs(float(r @ f.u)) <= 0.5 * f.length + tol
                and abs(float(r @ f.v)) <= 0.5 * f.diameter + tol and -0.5 * f.diameter - tol <= float(r @ f.w) < -tol)
    if abs(abs(float(normal @ f.u)) - 1) > 1e-6:
        return False
    if f.role == "slot":
        h = f.host
        return any(abs(float((centre - (f.p + s * 0.5 * f.length * f.u)) @ f.u)) < tol for s in (-1, 1)) and \
            abs(float((centre - h.p) @ h.u)) <= 0.5 * h.length + h.pad + tol and \
            float(np.linalg.norm((centre - h.p) - ((centre - h.p) @ h.u) * h.u)) <= h.outer_radius + tol
    offsets = [-0.5 * f.length, 0.5 * f.length] if f.role == "median" else [0.0]
    reach = f.host.outer_radius if f.host is not None and f.role == "end" else \
        (0.5 * f.host.length if f.host is not None else max(f.outer_radius, f.length))
    for off in offsets:
        q = f.p + off * f.u
        lateral = (centre - q) - ((centre - q) @ f.u) * f.u
        if abs(float((centre - q) @ f.u)) < tol and np.linalg.norm(lateral) <= reach + tol:
            return True
    return False


def _default_diameter(raw: list) -> float:
    """The diameter assumed where the drawing gives none (mm): :data:`DEFAULT_DIAMETER_MM`, or two thirds of the
    shortest distance between two of the part's axes when that is less (a template drawn a few mm wide)."""
    points = []
    for f in raw:
        try:
            if f.get("kind") == "axis":
                points.append(np.asarray(f["point_mm"], dtype=float).reshape(3))
        except (KeyError, TypeError, ValueError):
            continue
    gaps = [float(np.linalg.norm(a - b)) for i, a in enumerate(points) for b in points[i + 1:]]
    gaps = [g for g in gaps if g > 1e-6 and math.isfinite(g)]
    return min(DEFAULT_DIAMETER_MM, min(gaps) / 1.5) if gaps else DEFAULT_DIAMETER_MM


def part_solid(drawing: dict, joint_types: dict | None = None) -> PartSolid:
    """The solid of one part drawing, with the faces of each of its features (see the module docstring).

    Parameters
    ----------
    drawing : dict
        One entry of ``report.json``'s ``drawings`` (``part``, ``features``).
    joint_types : dict, optional
        Element name -> ``"R"`` or ``"P"`` (``report.json``'s ``joints``): an axis of a prismatic joint is a
        guide way or a slide.

    Raises
    ------
    HyperstatError
        A feature with a bad field, or one that no face of the solid realises.
    """
    part = str(drawing.get("part") or "")
    raw = drawing.get("features")
    if not part or not isinstance(raw, list):
        raise HyperstatError("a drawing needs a 'part' name and a list of 'features'.")
    types = {str(k): v for k, v in (joint_types or {}).items()}
    default = _default_diameter(raw)
    features = [_Feature(f, part, types.get(str(f.get("element"))), default) for f in raw]
    if not features:
        raise HyperstatError(f"drawing of part '{part}': it has no feature to draw.")
    ids = [f.id for f in features]
    if len(set(ids)) != len(ids):
        raise HyperstatError(f"drawing of part '{part}': feature id '{next(i for i in ids if ids.count(i) > 1)}' "
                             "is given twice.")
    centroid = np.mean([f.p for f in features], axis=0)
    notes = _place(features, centroid)
    assumed = sorted({f"{'guide way and slide widths' if f.role in ('guide', 'slide') else 'diameters'} "
                      f"{default:.3g} mm (the drawing gives none)"
                      for f in features if f.kind == "axis" and not f.diameter_given})
    assumed += notes
    assumed.append("walls, collars and bars join the features (not toleranced)")
    from hyperstat.cad_plugin import occ_solids

    solids, voids = _material_and_voids(features)
    shape = _fuse(solids + _bars(features))
    if voids:
        shape = occ_solids.clean(occ_solids.cut(shape, *voids))
    pieces = occ_solids.solids(shape)
    if len(pieces) > 1:  # a bar's end cap cut off by a bore or a channel: a sliver, not part of the part
        shape = max(pieces, key=occ_solids.volume)
    tol = 1e-5 * max(1.0, max(float(np.linalg.norm(f.p)) for f in features))  # 10 nm at 1 m
    geometry = [_FaceGeometry(face) for face in occ_solids.faces(shape)]  # each face's centre, normal, ... once
    faces = {f.id: [g.face for g in geometry if _matches(g, f, tol)] for f in features}
    missing = [fid for fid, found in faces.items() if not found]
    if missing:
        raise HyperstatError(f"drawing of part '{part}': no face of its solid realises feature '{missing[0]}' "
                             "(two features overlap or one lies inside another's material).")
    return PartSolid(part, shape, faces, {f["id"]: f for f in raw}, assumed, {f.id: f for f in features})
