"""The few solid-modelling calls of a part drawing, made with OCCT (OCP) directly, as CadQuery 2.x makes them.

Units: lengths in mm, angles in degrees where named ``*_deg`` (CadQuery's convention, converted as it does).

:func:`hyperstat.cad_plugin.part_solids.part_solid` builds a part from cylinders, boxes and spheres joined and cut
by Boolean operations, then finds its features' faces by their geometry.  With CadQuery, the report's part pages'
child would import it for these calls alone: about 1.3-1.5 s of CPU (measured with ``python -X importtime``),
of which OCP itself is 0.56 s but VTK (CadQuery's shapes module imports ``vtkmodules`` and ``OCP.IVtkVTK``)
is 0.5 s, ezdxf 0.1 s and CadQuery's own Python the rest.  Each function here makes exactly the OCCT calls, with
the same arguments and options, as the CadQuery method it names (``cadquery/occ_impl/shapes.py`` and ``geom.py``
of CadQuery 2.8), so that the shapes, hence the hidden-line drawings, are bit for bit those CadQuery makes.
They take and return OCP objects (``TopoDS_Shape``); :class:`hyperstat.cad_plugin.part_solids.PartSolid` wraps
them as CadQuery shapes only when asked (the STEP export, the tests).

>>> c = cylinder(10.0, 20.0, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
>>> round(volume(c), 6) == round(3.141592653589793 * 100 * 20, 6), sorted(face_type(f) for f in faces(c))
(True, ['CYLINDER', 'PLANE', 'PLANE'])
"""

from __future__ import annotations

import math
from typing import Any, Sequence

__all__ = ["cylinder", "box", "sphere", "moved", "fuse", "cut", "clean", "solids", "faces", "volume", "face_type",
           "face_centre", "face_normal", "bounding_box"]

Vec3 = Sequence[float]


def _pnt(p: Vec3):
    """``cq.Vector(*p).toPnt()``: a gp_Pnt of the gp_Vec's XYZ."""
    from OCP.gp import gp_Pnt, gp_Vec

    return gp_Pnt(gp_Vec(float(p[0]), float(p[1]), float(p[2])).XYZ())


def _dir(d: Vec3):
    """``cq.Vector(*d).toDir()``: a gp_Dir of the gp_Vec's XYZ (normalised by gp_Dir)."""
    from OCP.gp import gp_Dir, gp_Vec

    return gp_Dir(gp_Vec(float(d[0]), float(d[1]), float(d[2])).XYZ())


def _ax2(pnt: Vec3, direction: Vec3):
    from OCP.gp import gp_Ax2

    return gp_Ax2(_pnt(pnt), _dir(direction))


def cylinder(radius: float, height: float, pnt: Vec3, direction: Vec3, angle_deg: float = 360.0) -> Any:
    """``cq.Solid.makeCylinder(radius, height, Vector(*pnt), Vector(*direction), angle_deg)``: a TopoDS_Shape."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder

    return BRepPrimAPI_MakeCylinder(_ax2(pnt, direction), radius, height, math.radians(angle_deg)).Shape()


def box(length: float, width: float, height: float, pnt: Vec3 = (0.0, 0.0, 0.0),
        direction: Vec3 = (0.0, 0.0, 1.0)) -> Any:
    """``cq.Solid.makeBox(length, width, height, pnt=Vector(*pnt), dir=Vector(*direction))``: a TopoDS_Shape."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox

    return BRepPrimAPI_MakeBox(_ax2(pnt, direction), length, width, height).Shape()


def sphere(radius: float, pnt: Vec3, direction: Vec3 = (0.0, 0.0, 1.0), angle1_deg: float = 0.0,
           angle2_deg: float = 90.0, angle3_deg: float = 360.0) -> Any:
    """``cq.Solid.makeSphere(radius, Vector(*pnt), Vector(*direction), angle1_deg, angle2_deg, angle3_deg)``."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeSphere

    return BRepPrimAPI_MakeSphere(_ax2(pnt, direction), radius, math.radians(angle1_deg), math.radians(angle2_deg),
                                  math.radians(angle3_deg)).Shape()


def moved(shape: Any, trsf: Any) -> Any:
    """``shape.moved(cq.Location(trsf))``: the shape placed by the transformation ``trsf`` (a gp_Trsf)."""
    from OCP.TopLoc import TopLoc_Location

    return shape.Moved(TopLoc_Location(trsf))


def _boolean(op: Any, first: Any, tools: Sequence[Any]) -> Any:
    """CadQuery's ``Shape._bool_op``: ``first`` as the argument, ``tools`` as the tools, run in parallel."""
    from OCP.TopTools import TopTools_ListOfShape

    arg = TopTools_ListOfShape()
    arg.Append(first)
    tool = TopTools_ListOfShape()
    for t in tools:
        tool.Append(t)
    op.SetArguments(arg)
    op.SetTools(tool)
    op.SetRunParallel(True)
    op.Build()
    return op.Shape()


def fuse(first: Any, *others: Any) -> Any:
    """``first.fuse(*others)`` (no glue, no fuzzy value)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse

    return _boolean(BRepAlgoAPI_Fuse(), first, others)


def cut(shape: Any, *tools: Any) -> Any:
    """``shape.cut(*tools)`` (no fuzzy value)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut

    return _boolean(BRepAlgoAPI_Cut(), shape, tools)


def clean(shape: Any) -> Any:
    """``shape.clean()``: faces and edges of one surface or curve unified (edges, faces, concat B-splines; no
    internal edges)."""
    from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain

    upgrader = ShapeUpgrade_UnifySameDomain(shape, True, True, True)
    upgrader.AllowInternalEdges(False)
    upgrader.Build()
    return upgrader.Shape()


def _entities(shape: Any, kind: Any) -> list:
    """CadQuery's ``Shape._entities``: the sub-shapes of a kind in the order of an indexed map."""
    from OCP.TopExp import TopExp
    from OCP.TopTools import TopTools_IndexedMapOfShape

    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, kind, found)
    return list(found)


def solids(shape: Any) -> list:
    """``shape.Solids()``: its solids (TopoDS_Solid), in CadQuery's order."""
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopoDS import TopoDS

    return [TopoDS.Solid_s(s) for s in _entities(shape, TopAbs_SOLID)]


def faces(shape: Any) -> list:
    """``shape.Faces()``: its faces (TopoDS_Face), in CadQuery's order."""
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopoDS import TopoDS

    return [TopoDS.Face_s(f) for f in _entities(shape, TopAbs_FACE)]


def volume(solid: Any) -> float:
    """``solid.Volume()`` of a solid or compound (mm³): OCCT's volume properties at their default precision."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(solid, props)
    return props.Mass()


#: ``cadquery.occ_impl.shape_protocols.geom_LUT_FACE``'s names, by the GeomAbs_SurfaceType's name
_SURFACE_NAMES = {"GeomAbs_Plane": "PLANE", "GeomAbs_Cylinder": "CYLINDER", "GeomAbs_Cone": "CONE",
                  "GeomAbs_Sphere": "SPHERE", "GeomAbs_Torus": "TORUS", "GeomAbs_BezierSurface": "BEZIER",
                  "GeomAbs_BSplineSurface": "BSPLINE", "GeomAbs_SurfaceOfRevolution": "REVOLUTION",
                  "GeomAbs_SurfaceOfExtrusion": "EXTRUSION", "GeomAbs_OffsetSurface": "OFFSET",
                  "GeomAbs_OtherSurface": "OTHER"}


def face_type(face: Any) -> str:
    """``face.geomType()``: ``"PLANE"``, ``"CYLINDER"``, ``"SPHERE"``, ..."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    return _SURFACE_NAMES[BRepAdaptor_Surface(face).GetType().name]


def face_centre(face: Any) -> tuple[float, float, float]:
    """``face.Center().toTuple()``: the centre of mass of the face's area (mm)."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    c = props.CentreOfMass()
    return c.X(), c.Y(), c.Z()


def face_normal(face: Any) -> tuple[float, float, float]:
    """``face.normalAt().toTuple()``: the unit normal at the middle of the face's parameter ranges."""
    from OCP.BRepGProp import BRepGProp_Face
    from OCP.BRepTools import BRepTools
    from OCP.gp import gp_Pnt, gp_Vec

    u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
    p, vn = gp_Pnt(), gp_Vec()
    BRepGProp_Face(face).Normal(0.5 * (u0 + u1), 0.5 * (v0 + v1), p, vn)
    n = gp_Vec(vn.XYZ()).Normalized()
    return n.X(), n.Y(), n.Z()


def bounding_box(shape: Any) -> tuple[float, float, float, float, float, float]:
    """``shape.BoundingBox()``'s ``xmin, ymin, zmin, xmax, ymax, zmax`` (mm): OCCT's optimal box, as CadQuery's
    ``BoundBox._fromTopoDS`` computes it."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    bbox = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, bbox)
    return bbox.Get()
