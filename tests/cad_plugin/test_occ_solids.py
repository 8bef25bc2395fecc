"""occ_solids makes the shapes CadQuery makes: each call against CadQuery's own method, compared as OCCT's BRep text.

The report's part pages build their solids with :mod:`hyperstat.cad_plugin.occ_solids` (OCP directly) so that their
child process needs no CadQuery import.  The promise is "the same shapes as CadQuery", so the reference here is
CadQuery itself (the installed version), not numbers: a CadQuery upgrade that changes how it calls OCCT fails these
tests instead of silently changing the part drawings.  Units: mm, degrees where named ``*_deg``.
"""

from __future__ import annotations

import math
import os
import tempfile

import pytest

cq = pytest.importorskip("cadquery")

from OCP.BRepTools import BRepTools  # noqa: E402
from OCP.gp import gp_Trsf  # noqa: E402

from hyperstat.cad_plugin import occ_solids  # noqa: E402


def brep(shape) -> str:
    """OCCT's BRep text of a shape (its topology, geometry and tolerances, to the last digit written)."""
    fd, path = tempfile.mkstemp(suffix=".brep")
    os.close(fd)
    try:
        assert BRepTools.Write_s(shape, path)
        with open(path) as f:
            return f.read()
    finally:
        os.remove(path)


def _placement() -> gp_Trsf:
    """A rotation about a skew axis and a translation (a proper rigid motion)."""
    from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt, gp_Vec

    t = gp_Trsf()
    t.SetRotation(gp_Ax1(gp_Pnt(1.0, -2.0, 0.5), gp_Dir(0.2, 0.9, -0.4)), 0.7)
    move = gp_Trsf()
    move.SetTranslation(gp_Vec(12.0, -3.5, 40.0))
    return move.Multiplied(t)


def test_the_primitives_are_cadquerys() -> None:
    pairs = [
        (cq.Solid.makeCylinder(5.0, 30.0, cq.Vector(1, 2, 3), cq.Vector(0.3, 0.4, 0.8)),
         occ_solids.cylinder(5.0, 30.0, (1, 2, 3), (0.3, 0.4, 0.8))),
        (cq.Solid.makeBox(10.0, 4.0, 7.5, pnt=cq.Vector(-5, -2, -3.75)),
         occ_solids.box(10.0, 4.0, 7.5, pnt=(-5, -2, -3.75))),
        (cq.Solid.makeSphere(6.0, cq.Vector(3, -1, 2), angleDegrees1=-90, angleDegrees2=90),
         occ_solids.sphere(6.0, (3, -1, 2), angle1_deg=-90, angle2_deg=90)),
    ]
    for made_by_cadquery, made_here in pairs:
        assert brep(made_by_cadquery.wrapped) == brep(made_here)


def test_placement_booleans_and_clean_are_cadquerys() -> None:
    """A pinned, stepped block with a bore and a socket: moved, fused, cut and cleaned both ways, the same BRep, solids,
    faces (in the same order), volume, face centres and normals, and bounding box."""
    t = _placement()
    block_cq = cq.Solid.makeBox(40.0, 20.0, 10.0, pnt=cq.Vector(-20, -10, -5)).moved(cq.Location(t))
    block = occ_solids.moved(occ_solids.box(40.0, 20.0, 10.0, pnt=(-20, -10, -5)), t)
    assert brep(block_cq.wrapped) == brep(block)
    pin_cq = cq.Solid.makeCylinder(4.0, 25.0, cq.Vector(-12, 0, -2), cq.Vector(0, 0, 1)).moved(cq.Location(t))
    pin = occ_solids.moved(occ_solids.cylinder(4.0, 25.0, (-12, 0, -2), (0, 0, 1)), t)
    ball_cq = cq.Solid.makeSphere(7.0, cq.Vector(20, 0, 0), angleDegrees1=-90, angleDegrees2=90).moved(cq.Location(t))
    ball = occ_solids.moved(occ_solids.sphere(7.0, (20, 0, 0), angle1_deg=-90, angle2_deg=90), t)
    # a second block flush with the first: the fused top and sides are split faces and edges that clean() unifies
    step_cq = cq.Solid.makeBox(10.0, 20.0, 10.0, pnt=cq.Vector(20, -10, -5)).moved(cq.Location(t))
    step = occ_solids.moved(occ_solids.box(10.0, 20.0, 10.0, pnt=(20, -10, -5)), t)
    bore_cq = cq.Solid.makeCylinder(3.0, 30.0, cq.Vector(5, 0, -15), cq.Vector(0, 0, 1)).moved(cq.Location(t))
    bore = occ_solids.moved(occ_solids.cylinder(3.0, 30.0, (5, 0, -15), (0, 0, 1)), t)
    seat_cq = cq.Solid.makeSphere(4.0, cq.Vector(20, 0, 0), angleDegrees1=-90, angleDegrees2=90).moved(cq.Location(t))
    seat = occ_solids.moved(occ_solids.sphere(4.0, (20, 0, 0), angle1_deg=-90, angle2_deg=90), t)

    whole_cq = block_cq.fuse(step_cq, pin_cq, ball_cq).clean().cut(bore_cq, seat_cq).clean()
    whole = occ_solids.clean(occ_solids.cut(occ_solids.clean(occ_solids.fuse(block, step, pin, ball)), bore, seat))
    assert brep(whole_cq.wrapped) == brep(whole)
    assert [brep(s.wrapped) for s in whole_cq.Solids()] == [brep(s) for s in occ_solids.solids(whole)]
    faces_cq, faces = whole_cq.Faces(), occ_solids.faces(whole)
    assert len(faces_cq) == len(faces) > 6
    for fc, f in zip(faces_cq, faces):
        assert brep(fc.wrapped) == brep(f)  # built twice: equal text, not the same OCCT object
        assert fc.geomType() == occ_solids.face_type(f)
        assert fc.Center().toTuple() == occ_solids.face_centre(f)
        assert fc.normalAt().toTuple() == occ_solids.face_normal(f)
    assert whole_cq.Volume() == occ_solids.volume(whole)
    bb = whole_cq.BoundingBox()
    assert (bb.xmin, bb.ymin, bb.zmin, bb.xmax, bb.ymax, bb.zmax) == occ_solids.bounding_box(whole)
    # and a value that does not come from CadQuery: the block's volume, less what the cut takes, is in range
    assert 50.0 * 20.0 * 10.0 < occ_solids.volume(whole) < 50.0 * 20.0 * 10.0 + math.pi * 4.0 ** 2 * 25.0 \
        + 2.0 / 3.0 * math.pi * 7.0 ** 3
