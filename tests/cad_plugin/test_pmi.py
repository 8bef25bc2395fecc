"""A part's STEP AP242, read back by OCCT's STEP reader, carries the datums, frames and features of report.json.

Units: mm.

``hyperstat report --step-drawings`` writes ``parts/PART.step`` per part drawing (the session's reports,
``tests/cad_plugin/conftest.py``).  Each file is read with OCCT's ``STEPCAFControl_Reader`` (GD&T mode), and what
it says is compared here, field by field, with the part's drawing in ``report.json``: every frame (its id, ISO 1101
characteristic, zone value in mm, cylindrical zone or not, datum system in order of precedence, the toleranced
feature's faces), every datum the frames cite (its letter, its datum feature's faces).  The file's own text is
also read as ISO 10303-21, without OCCT: the schema is AP242, every tolerance value is stated in millimetres,
the frames are named.
"""

from __future__ import annotations

import math
import re

import pytest

from hyperstat.cad_plugin.pmi import read_part_step
from hyperstat.cad_plugin.report import step_name, write_report
from hyperstat.solver.errors import HyperstatError


@pytest.mark.parametrize("which", ["slider_crank_report", "tripteor_report"])
def test_each_part_step_read_back_by_occt_says_what_the_drawing_says(which, request):
    from hyperstat.cad_plugin.part_solids import part_solid

    out, doc = request.getfixturevalue(which)
    types = {str(j["element"]): j["type"] for j in doc["joints"]}
    drawings = doc["drawings"]
    assert sorted(p.name for p in (out / "parts").iterdir()) == sorted(f"{step_name(d['part'])}.step" for d in drawings)
    frames_seen = 0
    for d in drawings:
        got = read_part_step(out / "parts" / f"{step_name(d['part'])}.step")
        solid = part_solid(d, types)  # which features of the drawing are the same faces
        same_faces = {a: {b for b in solid.faces if {hash(x) for x in solid.faces[b]} ==
                          {hash(x) for x in solid.faces[a]}} for a in solid.faces}
        assert got["part"] == d["part"]
        datum_feature = {x["letter"]: x["feature"] for x in d["datums"]}
        by_id = {f["id"]: f for f in got["frames"]}
        assert sorted(by_id) == sorted(f["id"] for f in d["frames"]), d["part"]
        for f in d["frames"]:
            g = by_id[f["id"]]
            assert g["characteristic"] == f["characteristic"], f["id"]
            assert math.isclose(g["zone_mm"], f["zone_mm"], rel_tol=1e-12), (f["id"], g["zone_mm"], f["zone_mm"])
            assert (g["zone_form"] == "diameter") == (f["zone_shape"] == "cylinder"), f["id"]
            assert g["datum_system"] == f["datum_system"]
            assert g["precedences"] == list(range(1, len(f["datum_system"]) + 1))
            # the feature, with any other feature that is the very same faces (a stop on a bore's end face)
            assert f["feature"] in g["features"] and set(g["features"]) <= same_faces[f["feature"]], (f["id"], g)
            frames_seen += 1
        cited = {letter for f in d["frames"] for letter in f["datum_system"]}
        assert set(got["datums"]) == cited, d["part"]
        for letter in cited:
            assert datum_feature[letter] in got["datums"][letter]["features"], (d["part"], letter)
            assert set(got["datums"][letter]["features"]) <= same_faces[datum_feature[letter]], (d["part"], letter)
    assert frames_seen == sum(len(d["frames"]) for d in drawings) >= 10


def _entities(text: str) -> dict:
    """The DATA section of an ISO 10303-21 file: entity number -> its text (one line)."""
    data = text.split("DATA;", 1)[1]
    pattern = r"#(\d+)\s*=\s*(.*?);\s*(?=#\d+\s*=|ENDSEC)"
    return {int(m.group(1)): re.sub(r"\s+", " ", m.group(2)) for m in re.finditer(pattern, data, flags=re.S)}


def test_the_step_text_states_ap242_millimetres_and_the_frame_names(tripteor_report):
    out, doc = tripteor_report
    drawing = max(doc["drawings"], key=lambda d: len(d["frames"]))  # the platform: the most frames
    text = (out / "parts" / f"{step_name(drawing['part'])}.step").read_text()
    assert "AP242_MANAGED_MODEL_BASED_3D_ENGINEERING_MIM_LF" in text
    assert text.isascii()  # ISO 10303-21: strings are ASCII (the frames' words are written in ASCII)
    ents = _entities(text)
    tolerances = {n: e for n, e in ents.items() if "GEOMETRIC_TOLERANCE(" in e}
    assert len(tolerances) == len(drawing["frames"])
    zones = {}
    for e in tolerances.values():
        name, magnitude = re.search(r"GEOMETRIC_TOLERANCE\('([^']*)',.*?,\s*#(\d+)\s*,\s*#\d+\s*\)", e).groups()
        m = re.match(r"LENGTH_MEASURE_WITH_UNIT\(LENGTH_MEASURE\(([^)]*)\)\s*,\s*#(\d+)\s*\)", ents[int(magnitude)])
        value, unit = float(m.group(1)), ents[int(m.group(2))]
        assert "LENGTH_UNIT()" in unit and "SI_UNIT(.MILLI.,.METRE.)" in unit, unit  # the value is in mm
        zones[name] = value
    assert zones == {f["id"]: pytest.approx(f["zone_mm"], rel=1e-12) for f in drawing["frames"]}
    assert text.count("TOLERANCE_ZONE_FORM('cylindrical or circular')") == \
        sum(f["zone_shape"] == "cylinder" for f in drawing["frames"])
    letters = sorted(set(re.findall(r"DATUM\('[^']*',\s*'[^']*',\s*#\d+,\s*\.[TF]\.,\s*'([A-Z])'\)", text)))
    assert letters == sorted({x for f in drawing["frames"] for x in f["datum_system"]})
    assert not re.search(r"PLANE_ANGLE_UNIT\(\) SI_UNIT\(\$,\.METRE\.\)", " ".join(ents.values()))


def test_a_step_file_is_the_same_bytes_each_time_and_a_bad_drawing_writes_nothing(slider_crank_report, tmp_path):
    from hyperstat.cad_plugin.part_solids import part_solid
    from hyperstat.cad_plugin.pmi import part_step_bytes

    out, doc = slider_crank_report
    types = {str(j["element"]): j["type"] for j in doc["joints"]}
    part = max(doc["drawings"], key=lambda d: len(d["frames"]))
    again = part_step_bytes(part_solid(part, types), part)
    assert again == (out / "parts" / f"{step_name(part['part'])}.step").read_bytes()  # the report's own file
    bad = dict(part, frames=[{**part["frames"][0], "feature": f"{part['part']}.nothing"}] + part["frames"][1:])
    with pytest.raises(HyperstatError, match=rf"part '{part['part']}', frame {part['frames'][0]['id']}: feature "
                                             rf"'{part['part']}.nothing' is not a feature of the part"):
        write_report({**doc, "drawings": [bad]}, tmp_path / "c", None, None, {"views": "<svg></svg>"},
                     step_drawings=True)
    assert not (tmp_path / "c").exists()  # neither the report nor any part's STEP file


def test_a_part_that_cannot_be_drawn_gets_a_page_that_says_why_and_no_step(slider_crank_report, tmp_path):
    """A part whose features cannot all be faces of one solid (a small bore inside a bigger one's hole) still
    has its page, with the reason where its views would be; --step-drawings refuses in one sentence."""
    _, doc = slider_crank_report
    bore = {"id": "p.bore1", "kind": "axis", "element": "1", "side": "fixed", "point_mm": [0, 0, 0],
            "direction": [0, 0, 1], "length_mm": 20.0, "diameter_mm": 20.0, "name": "bore of joint 1"}
    inner = {**bore, "id": "p.bore2", "element": "2", "diameter_mm": 2.0, "point_mm": [0, 3, 0], "name": "bore 2"}
    frame = {"id": "p-F1", "tolerances": [], "feature": "p.bore2", "characteristic": "parallelism", "zone_mm": 0.02,
             "zone_shape": "cylinder", "zone_direction": None, "indicator": None, "datum_system": ["A"], "ted": [],
             "value_kind": "without calibration", "note": ""}
    drawing = {"part": "p", "features": [bore, inner], "datums": [{"letter": "A", "feature": "p.bore1",
                                                                   "precedence": "primary"}], "frames": [frame]}
    doc = {**doc, "drawings": [drawing]}
    write_report(doc, tmp_path / "a", None, None, {"views": "<svg></svg>"})
    page = (tmp_path / "a" / "report.html").read_text()
    part = page[page.index('<section class="part-page" id="part-p">'):]
    assert "The views of this part could not be drawn</b>: drawing of part &#x27;p&#x27;: no face of its solid " \
           "realises feature &#x27;p.bore2&#x27;" in part and "p-F1" in part
    with pytest.raises(HyperstatError, match=r"--step-drawings: part 'p' cannot be written as STEP: drawing of part "
                                             r"'p': no face of its solid realises feature 'p.bore2'"):
        write_report(doc, tmp_path / "b", None, None, {"views": "<svg></svg>"}, step_drawings=True)
    assert not (tmp_path / "b").exists()
