"""Every feature of a part drawing is a face of the part's solid, where report.json says it is (units: mm).

The faces are checked on points sampled on them (the vertices of OCCT's triangulation of each face), against
the feature of ``report.json`` read here: a bore's or journal's points lie at the
diameter's half from the feature's axis and within its length; a plane's points lie in one plane of the
feature's normal, through the feature's point or (an end face, shoulder or stop: the joint's centre is where
the drawing places it) half its bore's length from it along that normal; a median plane's two faces lie at
equal distances on either side of the plane through the feature's point.
"""

from __future__ import annotations

import numpy as np
import pytest

from hyperstat.cad_plugin.part_solids import DEFAULT_DIAMETER_MM, part_solid
from hyperstat.solver.errors import HyperstatError


def _points(face) -> np.ndarray:
    """Points of a face: the vertices of OCCT's triangulation of it (they lie on its surface, within its bounds)."""
    vertices, _ = face.tessellate(0.05)
    return np.array([v.toTuple() for v in vertices])


def _assumed_diameter(drawing: dict) -> float:
    """docs/step-pmi.md: 20 mm, or two thirds of the shortest distance between two of the part's axes if less."""
    pts = [np.array(f["point_mm"], float) for f in drawing["features"] if f["kind"] == "axis"]
    gaps = [np.linalg.norm(a - b) for i, a in enumerate(pts) for b in pts[i + 1:] if np.linalg.norm(a - b) > 1e-6]
    return min([DEFAULT_DIAMETER_MM] + [g / 1.5 for g in gaps])


def _check_part(drawing: dict, joint_types: dict) -> None:
    solid = part_solid(drawing, joint_types)
    default = _assumed_diameter(drawing)
    assert solid.shape.isValid() and len(solid.shape.Solids()) == 1, drawing["part"]
    features = {f["id"]: f for f in drawing["features"]}
    axes = {(f["element"], f.get("side")): f for f in drawing["features"] if f["kind"] == "axis"}
    for fid, f in features.items():
        faces = solid.faces[fid]
        assert faces, fid
        p, n = np.array(f["point_mm"], float), np.array(f["direction"], float)
        n /= np.linalg.norm(n)
        pts = np.vstack([_points(face) for face in faces])
        r = pts - p
        along = r @ n
        if f["kind"] == "axis":
            radial = np.linalg.norm(r - np.outer(along, n), axis=1)
            assert np.all(np.abs(along) <= 0.5 * f["length_mm"] + 1e-6), fid
            if joint_types.get(f["element"]) == "R":  # a bore or journal: a cylinder of the diameter
                d = f["diameter_mm"] or default
                assert np.allclose(radial, 0.5 * d, atol=1e-6), (fid, radial.min(), radial.max())
            else:  # a guide way's or slide's flanks and floor: within the width's half of the axis
                assert np.all(radial <= 0.5 * np.sqrt(2) * (f["diameter_mm"] or default) + 1e-6), fid
        elif f["kind"] == "plane":
            offsets = np.unique(np.round(along, 6))
            assert len(offsets) == 1, (fid, offsets)  # one plane normal to the feature's direction
            host = axes.get((f["element"], f.get("side")))
            allowed = {0.0}
            if host is not None and abs(abs(np.dot(host["direction"], n)) - 1) < 1e-9:
                allowed.add(round(0.5 * host["length_mm"], 6))  # at its bore's, journal's or slide's end
            if host is not None and abs(np.dot(host["direction"], n)) < 1e-9:
                allowed.add(round(0.5 * (host["diameter_mm"] or default), 6))  # a flank
            assert abs(offsets[0]) in allowed, (fid, offsets, allowed)
        else:  # median plane: two faces symmetric about the plane through the point
            offsets = np.unique(np.round(along, 6))
            assert len(offsets) == 2 and abs(offsets[0] + offsets[1]) < 1e-6 and offsets[1] > 0, (fid, offsets)


@pytest.mark.parametrize("which", ["slider_crank_report", "tripteor_report"])
def test_every_feature_is_a_face_where_the_drawing_puts_it(which, request):
    _, doc = request.getfixturevalue(which)
    types = {str(j["element"]): j["type"] for j in doc["joints"]}
    kinds = set()
    for drawing in doc["drawings"]:
        _check_part(drawing, types)
        kinds |= {f["kind"] for f in drawing["features"]}
    assert kinds == {"axis", "plane", "median plane"}


def test_a_feature_the_solid_cannot_carry_is_one_sentence():
    good = {"id": "p.bore1", "kind": "axis", "element": "1", "side": "fixed", "point_mm": [0, 0, 0],
            "direction": [0, 0, 1], "length_mm": 20.0, "diameter_mm": None}
    with pytest.raises(HyperstatError, match=r"part 'p', feature 'p.bore1': direction must be a non-zero vector"):
        part_solid({"part": "p", "features": [{**good, "direction": [0, 0, 0]}]})
    with pytest.raises(HyperstatError, match=r"feature 'p.bore1': length_mm must be a positive number"):
        part_solid({"part": "p", "features": [{**good, "length_mm": -3}]})
    with pytest.raises(HyperstatError, match=r"feature id 'p.bore1' is given twice"):
        part_solid({"part": "p", "features": [good, good]})
    # a small bore inside another bore's hole: the hole takes its boss away, no face of the solid realises it
    inner = {**good, "id": "p.bore2", "element": "2", "diameter_mm": 2.0, "point_mm": [0, 3, 0]}
    with pytest.raises(HyperstatError, match=r"no face of its solid realises feature 'p.bore2'"):
        part_solid({"part": "p", "features": [{**good, "diameter_mm": 20.0}, inner]}, {"1": "R", "2": "R"})
