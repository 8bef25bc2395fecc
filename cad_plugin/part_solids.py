"""A part of a drawing as a CadQuery solid whose toleranced and datum features are real faces.

Units: lengths in mm (world frame at the home configuration, as ``report.json``'s ``drawings``).

A part drawing (``report.json`` ``drawings[*]``, see ``docs/drawing-format.md``) names its features by kind,
point, direction, length and diameter.  A workshop tolerances faces, not axes: :func:`part_solid` builds a
solid on which every feature exists as one or more faces, and finds those faces again on the finished solid
by their geometry (never by construction history, which the Boolean operations rewrite):

* an ``axis`` of a revolute joint is a **bore** (a cylindrical face of the feature's diameter and length,
  the span of the joint's supports) in a boss; its end faces are the boss's annular planes;
* an ``axis`` of a prismatic joint is a **guide way**: a rectangular channel along the axis, of the
  feature's width (its diameter) and length; the feature is the channel's two flanks and its floor;
* a ``plane`` is a planar face through the feature's point, normal to its direction: a bore's end face
  when it lies there, else a pad behind it (its direction is its outward normal: the material is behind);
* a ``median plane`` is the pair of parallel faces ``length_mm`` apart, centred on the point;
* a ``point`` is a spherical socket (the centre of a ball joint).

The features are joined by bars along the shortest tree through their points, each bar running from one
feature's material to the other's (never through a bore).  An axis named a pin (trunnion, journal, shaft) is
an external cylinder, as on a universal joint's cross.  Sizes the drawing does not give (a bore's
diameter, the wall around it) are assumed and listed in :attr:`PartSolid.assumed`, so that the page that
draws the part says so.

>>> d = {"part": "rod", "features": [
...     {"id": "rod.bore2", "kind": "axis", "point_mm": [0, 0, 0], "direction": [0, -1, 0], "length_mm": 20,
...      "diameter_mm": 20},
...     {"id": "rod.bore3", "kind": "axis", "point_mm": [120, 0, 0], "direction": [0, -1, 0], "length_mm": 20,
...      "diameter_mm": 20}]}
>>> s = part_solid(d)
>>> sorted(s.faces), [f.geomType() for f in s.faces["rod.bore3"]]
(['rod.bore2', 'rod.bore3'], ['CYLINDER'])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from hyperstat.solver.errors import HyperstatError

if TYPE_CHECKING:  # pragma: no cover
    import cadquery as cq

__all__ = ["PartSolid", "part_solid", "feature_frame", "DEFAULT_DIAMETER_MM", "DEFAULT_LENGTH_MM"]

#: a bore's diameter when the drawing gives none: the 20 mm of the default ISO 286 fit
#: (:data:`hyperstat.solver.tolerances.declaration.DEFAULT_CLEARANCES`)
DEFAULT_DIAMETER_MM = 20.0
#: a feature's length when the drawing gives none
DEFAULT_LENGTH_MM = 20.0
_PAD_MM = 3.0  # thickness of the pad behind a plane feature
_PIN_WORDS = ("pin", "trunnion", "journal", "shaft")  # an axis feature so named is an external cylinder


@dataclass
class PartSolid:
    """A part's solid and, per feature id, the faces that realise the feature."""

    part: str
    shape: Any  # cq.Shape: the solid (or a compound of solids)
    faces: dict = field(default_factory=dict)  # feature id -> list of cq.Face
    features: dict = field(default_factory=dict)  # feature id -> the drawing's feature (dict)
    assumed: list = field(default_factory=list)  # sentences: sizes the drawing did not give
    parsed: dict = field(default_factory=dict)  # feature id -> its checked geometry (sizes used, guide or bore)

    def size_mm(self) -> float:
        """The diagonal of the solid's bounding box (mm)."""
        bb = self.shape.BoundingBox()
        return float(math.sqrt(bb.xlen ** 2 + bb.ylen ** 2 + bb.zlen ** 2))


def _unit(v, where: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
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
    """A feature's geometry, read and checked from the drawing's dict."""

    def __init__(self, f: dict, part: str, joint_type: str | None):
        where = f"drawing of part '{part}', feature '{f.get('id', '?')}'"
        self.id = str(f.get("id") or "")
        if not self.id:
            raise HyperstatError(f"drawing of part '{part}': a feature has no 'id'.")
        self.kind = str(f.get("kind", ""))
        if self.kind not in ("axis", "plane", "median plane", "point"):
            raise HyperstatError(f"{where}: kind must be 'axis', 'plane', 'median plane' or 'point', got {self.kind!r}.")
        p = np.asarray(f.get("point_mm"), dtype=float) if f.get("point_mm") is not None else None
        if p is None or p.shape != (3,) or not np.all(np.isfinite(p)):
            raise HyperstatError(f"{where}: point_mm must be [x, y, z] in mm, got {f.get('point_mm')!r}.")
        self.p = p
        self.u = _unit(f.get("direction"), where) if self.kind != "point" or f.get("direction") is not None else \
            np.array([0.0, 0.0, 1.0])
        self.length_given = f.get("length_mm") is not None
        self.length = float(f["length_mm"]) if self.length_given else DEFAULT_LENGTH_MM
        self.diameter_given = f.get("diameter_mm") is not None
        self.diameter = float(f["diameter_mm"]) if self.diameter_given else DEFAULT_DIAMETER_MM
        if not (self.length > 0 and self.diameter > 0 and math.isfinite(self.length) and math.isfinite(self.diameter)):
            raise HyperstatError(f"{where}: length_mm and diameter_mm must be positive numbers (mm).")
        self.guide = self.kind == "axis" and joint_type == "P"
        name = str(f.get("name") or "").lower()
        self.pin = self.kind == "axis" and not self.guide and any(w in name for w in _PIN_WORDS)
        self.element = str(f.get("element") or "")
        self.wall = max(0.3 * self.diameter, 4.0)

    @property
    def outer_radius(self) -> float:
        return 0.5 * self.diameter * (1.0 if self.pin else 1.0) + (0.0 if self.pin else self.wall)


def _cylinder(radius: float, start: np.ndarray, axis: np.ndarray, length: float):
    import cadquery as cq

    return cq.Solid.makeCylinder(radius, length, cq.Vector(*start), cq.Vector(*axis))


def _box(centre: np.ndarray, u: np.ndarray, v: np.ndarray, w: np.ndarray, size: tuple[float, float, float]):
    """A box of ``size`` (along u, v, w) centred on ``centre``."""
    import cadquery as cq

    box = cq.Solid.makeBox(*size, pnt=cq.Vector(-size[0] / 2, -size[1] / 2, -size[2] / 2))
    return _moved(box, centre, u, v, w)


def _moved(shape, centre: np.ndarray, u: np.ndarray, v: np.ndarray, w: np.ndarray):
    """``shape`` built in the standard frame, moved so that its x, y, z axes become u, v, w at ``centre``."""
    import cadquery as cq
    from OCP.gp import gp_Trsf

    t = gp_Trsf()
    t.SetValues(u[0], v[0], w[0], centre[0], u[1], v[1], w[1], centre[1], u[2], v[2], w[2], centre[2])
    return shape.moved(cq.Location(t))


def _boss_end(f: _Feature, features: list[_Feature]) -> _Feature | None:
    """The bore or pin whose end face plane feature ``f`` is (its plane holds that end), if any."""
    for g in features:
        if g.kind == "axis" and not g.guide and abs(abs(float(f.u @ g.u)) - 1) < 1e-9:
            r = f.p - g.p
            lateral = r - (r @ g.u) * g.u
            if abs(abs(float(r @ g.u)) - 0.5 * g.length) < 1e-6 * max(1.0, g.length) and \
                    np.linalg.norm(lateral) <= g.outer_radius:
                return g
    return None


def _ends(f: _Feature) -> list[_Feature]:
    """The two faces of a median plane as plane features (outward normals)."""
    out = []
    for sign in (-1.0, 1.0):
        g = object.__new__(_Feature)
        g.__dict__.update(f.__dict__)
        g.kind, g.p, g.u = "plane", f.p + sign * 0.5 * f.length * f.u, sign * f.u
        out.append(g)
    return out


def _material_and_voids(features: list[_Feature], centroid: np.ndarray) -> tuple[list, list]:
    """Solids to fuse (bosses, pads, housings) and to cut (bores, channels, sockets), per feature."""
    import cadquery as cq

    solids, voids = [], []
    for f in features:
        if f.pin:
            solids.append(_cylinder(0.5 * f.diameter, f.p - 0.5 * f.length * f.u, f.u, f.length))
        elif f.kind == "axis" and not f.guide:
            solids.append(_cylinder(f.outer_radius, f.p - 0.5 * f.length * f.u, f.u, f.length))
            voids.append(_cylinder(0.5 * f.diameter, f.p - (0.5 * f.length + 0.1) * f.u, f.u, f.length + 0.2))
        elif f.kind == "axis":  # a guide way: a rectangular channel open towards w (away from the part's centre)
            v, w = f.v, f.w = feature_frame(f.u, f.p - centroid if np.linalg.norm(f.p - centroid) > 1e-6 else None)
            width = f.diameter
            depth = 0.5 * f.diameter
            outer = (f.length, width + 2 * f.wall, depth + f.wall)
            solids.append(_box(f.p - 0.5 * (depth + f.wall) * w, f.u, v, w, outer))
            # the channel: its floor half a width below the axis, open at w (1 µm beyond the top face)
            voids.append(_box(f.p - 0.5 * depth * w + 0.5e-3 * w, f.u, v, w, (f.length + 0.2, width, depth + 1e-3)))
        elif f.kind == "plane":
            if _boss_end(f, features) is None:  # a face of its own: a pad behind it (its direction points out)
                solids.append(_cylinder(max(f.outer_radius, 0.5 * f.length), f.p, -f.u, _PAD_MM))
        elif f.kind == "median plane":
            if not any(_boss_end(g, features) is not None for g in _ends(f)):
                solids.append(_cylinder(max(f.outer_radius, 10.0), f.p - 0.5 * f.length * f.u, f.u, f.length))
        else:  # point: a ball socket
            solids.append(cq.Solid.makeSphere(f.outer_radius, cq.Vector(*f.p), angleDegrees1=-90, angleDegrees2=90))
            voids.append(cq.Solid.makeSphere(0.5 * f.diameter, cq.Vector(*f.p), angleDegrees1=-90, angleDegrees2=90))
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
    """Where a bar towards ``target`` meets feature ``f``'s material (never inside its bore or channel)."""
    r = target - f.p
    if f.kind == "axis" and f.guide:
        return f.p - (0.5 * f.diameter + 0.5 * f.wall) * f.w
    if f.kind == "plane":
        return f.p - 0.5 * _PAD_MM * f.u * (1.0 if (target - f.p) @ f.u < 0 else -1.0)
    if f.kind == "median plane" or f.pin:
        return f.p
    mid = 0.5 * f.diameter + 0.5 * f.wall  # in the wall of a bore or socket
    if f.kind == "point":
        return f.p + mid * r / max(float(np.linalg.norm(r)), 1e-12)
    lateral = r - (r @ f.u) * f.u
    if np.linalg.norm(lateral) > 1e-6 * max(1.0, float(np.linalg.norm(r))):
        return f.p + mid * lateral / np.linalg.norm(lateral)
    v, _ = feature_frame(f.u)
    return f.p + np.sign(r @ f.u) * 0.5 * f.length * f.u + mid * v  # along the axis: from the boss's end face


def _bars(features: list[_Feature]) -> list:
    """Bars along the shortest tree through the features' points, from material to material.

    A plane that is a bore's end face, and a median plane whose faces are, are that bore's material already.
    """
    features = [f for f in features if not (f.kind == "plane" and _boss_end(f, features) is not None) and
                not (f.kind == "median plane" and any(_boss_end(g, features) is not None for g in _ends(f)))]
    points = np.array([f.p for f in features])
    out = []
    for i, j in _tree(points):
        a, b = features[i], features[j]
        if np.linalg.norm(a.p - b.p) < 1e-6:
            continue  # features at one point (a cross's two axes): their bosses already meet
        pa, pb = _attach(a, b.p), _attach(b, a.p)
        d = pb - pa
        n = float(np.linalg.norm(d))
        if n > 1e-6:
            out.append(_cylinder(0.4 * min(a.outer_radius, b.outer_radius), pa, d / n, n))
    return out


def _fuse(shapes: list):
    first, rest = shapes[0], shapes[1:]
    return (first.fuse(*rest) if rest else first).clean()


def _close(a: float, b: float, tol: float) -> bool:
    return abs(a - b) <= tol


def _faces_of(shape, f: _Feature, tol: float) -> list:
    """The faces of ``shape`` that realise feature ``f`` (geometry within ``tol`` mm / 1e-6 rad)."""
    out = []
    for face in shape.Faces():
        kind = face.geomType()
        if f.kind == "axis" and not f.guide and kind == "CYLINDER":
            axis, origin, radius = _cylinder_of(face)
            centre = np.array(face.Center().toTuple())
            if (_close(radius, 0.5 * f.diameter, tol) and abs(abs(float(axis @ f.u)) - 1) < 1e-6
                    and np.linalg.norm(np.cross(f.p - origin, axis)) < tol
                    and abs(float((centre - f.p) @ f.u)) <= 0.5 * f.length + tol):
                out.append(face)
        elif f.kind == "point" and kind == "SPHERE":
            centre, radius = _sphere_of(face)
            if _close(radius, 0.5 * f.diameter, tol) and np.linalg.norm(centre - f.p) < tol:
                out.append(face)
        elif kind == "PLANE" and f.kind != "point":
            normal = np.array(face.normalAt().toTuple())
            centre = np.array(face.Center().toTuple())
            if f.kind == "axis":  # the guide way's flanks and floor: faces along the axis within the channel
                r = centre - f.p
                if f.guide and abs(float(normal @ f.u)) < 1e-6 and abs(float(r @ f.u)) <= 0.5 * f.length + tol \
                        and abs(float(r @ f.v)) <= 0.5 * f.diameter + tol and -0.5 * f.diameter - tol <= float(r @ f.w) < -tol:
                    out.append(face)
                continue
            if abs(abs(float(normal @ f.u)) - 1) > 1e-6:
                continue
            offsets = [0.0] if f.kind == "plane" else [-0.5 * f.length, 0.5 * f.length]
            for off in offsets:
                q = f.p + off * f.u
                lateral = (centre - q) - ((centre - q) @ f.u) * f.u
                if abs(float((centre - q) @ f.u)) < tol and np.linalg.norm(lateral) < max(f.outer_radius, f.length):
                    out.append(face)
    return out


def _cylinder_of(face) -> tuple[np.ndarray, np.ndarray, float]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    cyl = BRepAdaptor_Surface(face.wrapped).Cylinder()
    ax = cyl.Axis()
    d, o = ax.Direction(), ax.Location()
    return np.array([d.X(), d.Y(), d.Z()]), np.array([o.X(), o.Y(), o.Z()]), float(cyl.Radius())


def _sphere_of(face) -> tuple[np.ndarray, float]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    sph = BRepAdaptor_Surface(face.wrapped).Sphere()
    c = sph.Location()
    return np.array([c.X(), c.Y(), c.Z()]), float(sph.Radius())


def part_solid(drawing: dict, joint_types: dict | None = None) -> PartSolid:
    """The solid of one part drawing, with the faces of each of its features (see the module docstring).

    Parameters
    ----------
    drawing : dict
        One entry of ``report.json``'s ``drawings`` (``part``, ``features``).
    joint_types : dict, optional
        Element name -> ``"R"`` or ``"P"`` (``report.json``'s ``joints``): an axis of a prismatic joint is a
        guide way.

    Raises
    ------
    HyperstatError
        A feature with a bad field, or one that no face of the solid realises.
    """
    part = str(drawing.get("part") or "")
    raw = drawing.get("features") or []
    if not part or not isinstance(raw, list):
        raise HyperstatError("a drawing needs a 'part' name and a list of 'features'.")
    types = {str(k): v for k, v in (joint_types or {}).items()}
    features = [_Feature(f, part, types.get(str(f.get("element")))) for f in raw]
    if not features:
        raise HyperstatError(f"drawing of part '{part}': it has no feature to draw.")
    assumed = sorted({f"{'guide way' if f.guide else 'bore'} of element {f.element or f.id}: width/diameter "
                      f"{DEFAULT_DIAMETER_MM:g} mm assumed (the drawing gives none)"
                      for f in features if f.kind == "axis" and not f.diameter_given})
    assumed += sorted({f"feature {f.id}: length {DEFAULT_LENGTH_MM:g} mm assumed" for f in features
                       if not f.length_given and f.kind in ("axis", "median plane")})
    assumed.append("walls and bars are drawn to join the features (not toleranced)")
    centroid = np.mean([f.p for f in features], axis=0)
    solids, voids = _material_and_voids(features, centroid)
    shape = _fuse(solids + _bars(features))
    if voids:
        shape = shape.cut(*voids).clean()
    solids_left = shape.Solids()
    if len(solids_left) > 1:  # a bar's end cap cut off by a bore or a channel: a sliver, not part of the part
        shape = max(solids_left, key=lambda x: x.Volume())
    tol = 1e-4 * max(1.0, max(float(np.linalg.norm(f.p)) for f in features))
    faces, missing = {}, []
    for f in features:
        found = _faces_of(shape, f, tol)
        if not found:
            missing.append(f.id)
        faces[f.id] = found
    if missing:
        raise HyperstatError(f"drawing of part '{part}': no face of its solid realises feature '{missing[0]}' "
                             "(two features overlap or one lies inside another's material).")
    return PartSolid(part, shape, faces, {f["id"]: f for f in raw}, assumed, {f.id: f for f in features})
