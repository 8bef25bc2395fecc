"""A part drawing as STEP AP242 with semantic PMI (OCCT's XCAF GD&T objects), written and read back.

Units: lengths in mm (the STEP file's length unit is the millimetre, tolerance values included).

:func:`write_part_step` writes one part of ``report.json``'s ``drawings`` (see ``docs/drawing-format.md``): the
part's solid (:func:`hyperstat.cad_plugin.part_solids.part_solid`), each feature's faces as named sub-shapes
(the feature id; a face that realises several features carries their ids joined by ``|``), each datum
(ISO 5459: its letter, its precedence in each frame that cites it, its datum feature's faces) and each
geometric tolerance (ISO 1101: characteristic, zone value in mm, ``⌀`` for a cylindrical zone, the datum
system, the toleranced feature's faces, the frame id as the tolerance's name) as OCCT's
``XCAFDimTolObjects_*`` objects, written by ``STEPCAFControl_Writer`` in the AP242 schema.  The file is read
back by ``STEPCAFControl_Reader`` (:func:`read_part_step`) and compared with the drawing before it is kept:
a file whose PMI does not say what the drawing says is never written.

What OCCT 7.9 (the OCP of CadQuery 2.8) keeps and what it does not, found by trying (the same facts are in
``docs/drawing-format.md``):

* kept through write and read: characteristic, value, ``⌀`` (zone form "cylindrical or circular"), the
  datum system's letters in order of precedence, the datum features' and toleranced features' faces
  (with their names when ``write/read.stepcaf.subshapes.name`` are on), tolerances without datums, and
  several faces per feature;
* **the writer states every tolerance value in metres** (``SI_UNIT($,.METRE.)``) although the value is
  in the document's unit (mm), which any conforming reader takes as 1000 times the zone; this module
  gives those unit entities their ``.MILLI.`` prefix after the transfer, so the file says mm;
* the writer adds a ``RUNOUT_ZONE_DEFINITION`` with an angle in a "plane angle unit" named metre to
  every cylindrical zone; the unit is renamed radian here (the entity stays: harmless, unused by readers);
* not written: the tolerance's name and the ISO 1101 intersection / orientation plane indicators
  (``SetAffectedPlane``: kept in the XCAF document, absent from the file).  The name is set here on the
  ``GEOMETRIC_TOLERANCE`` entity after the transfer (the reader returns it as the semantic name); the
  zone's direction has no AP242 entity OCCT writes, so it travels in the tolerance's description
  (words) and in ``report.json``, not as semantics;
* one XCAF datum has one precedence: a datum cited at several precedences gets one XCAF datum per
  (letter, precedence), all on the same faces, and the reader returns one datum label per reference;
* the default schema (AP214) crashes the writer (a segmentation fault) on a datum that no tolerance
  cites; AP242 does not.
"""

from __future__ import annotations

import contextlib
import math
import tempfile
from pathlib import Path
from typing import Iterator

from hyperstat.solver.errors import HyperstatError

__all__ = ["write_part_step", "read_part_step", "drawing_pmi", "part_step_bytes", "CHARACTERISTICS", "compare_pmi",
           "ascii_words"]

#: ISO 1101 characteristic (the drawing's word) -> XCAFDimTolObjects_GeomToleranceType member suffix
CHARACTERISTICS = {
    "straightness": "Straightness", "flatness": "Flatness", "circularity": "CircularityOrRoundness",
    "cylindricity": "Cylindricity", "profile of a line": "ProfileOfLine", "profile of a surface": "ProfileOfSurface",
    "parallelism": "Parallelism", "perpendicularity": "Perpendicularity", "angularity": "Angularity",
    "position": "Position", "coaxiality": "Coaxiality", "concentricity": "Concentricity", "symmetry": "Symmetry",
    "circular run-out": "CircularRunout", "total run-out": "TotalRunout",
}
_PRECEDENCE = ("primary", "secondary", "tertiary")


def _zone_form(shape: str | None) -> str:
    """The STEP zone form of a drawing's zone shape: ``diameter`` (cylinder, circle), ``sphere`` or ``width``."""
    s = (shape or "").lower()
    if "sphere" in s:
        return "sphere"
    return "diameter" if ("cylinder" in s or "circle" in s) else "width"


def drawing_pmi(drawing: dict) -> dict:
    """What a part's STEP must carry, from its drawing: datums and frames (mm).

    Returns
    -------
    dict
        ``{"part", "datums": {letter: [feature ids]}, "frames": [{"id", "characteristic", "zone_mm",
        "zone_form", "datum_system": [letters], "features": [feature ids]}]}``; frames sorted by id.

    >>> drawing_pmi({"part": "p", "datums": [{"letter": "A", "feature": "p.b"}], "frames": [{"id": "p-F1",
    ...   "feature": "p.c", "characteristic": "parallelism", "zone_mm": 0.02, "zone_shape": "cylinder",
    ...   "datum_system": ["A"]}]})["frames"][0]["zone_form"]
    'diameter'
    """
    datums = {str(d["letter"]): [str(d["feature"])] for d in drawing.get("datums") or []}
    frames = []
    for f in drawing.get("frames") or []:
        frames.append({"id": str(f["id"]), "characteristic": str(f["characteristic"]).lower(),
                       "zone_mm": float(f["zone_mm"]), "zone_form": _zone_form(f.get("zone_shape")),
                       "datum_system": [str(x) for x in f.get("datum_system") or []],
                       "features": [str(f["feature"])]})
    return {"part": str(drawing.get("part")), "datums": datums, "frames": sorted(frames, key=lambda x: x["id"])}


@contextlib.contextmanager
def _statics(values: dict) -> Iterator[None]:
    """Set OCCT's global translation parameters for a block and put the previous values back."""
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Controller

    STEPCAFControl_Controller.Init_s()
    old = {}
    for key, value in values.items():
        if isinstance(value, int):
            old[key] = Interface_Static.IVal_s(key)
            Interface_Static.SetIVal_s(key, value)
        else:
            old[key] = Interface_Static.CVal_s(key)
            Interface_Static.SetCVal_s(key, value)
    try:
        yield
    finally:
        for key, value in old.items():
            (Interface_Static.SetIVal_s if isinstance(value, int) else Interface_Static.SetCVal_s)(key, value)


def _new_document():
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document
    from OCP.UnitsMethods import UnitsMethods_LengthUnit
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    app = XCAFApp_Application.GetApplication_s()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    app.InitDocument(doc)
    XCAFDoc_DocumentTool.SetLengthUnit_s(doc, 1.0, UnitsMethods_LengthUnit.UnitsMethods_LengthUnit_Millimeter)
    return doc


def _set_name(label, text: str) -> None:
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name

    TDataStd_Name.Set_s(label, TCollection_ExtendedString(text))


def _name(label) -> str | None:
    from OCP.TDataStd import TDataStd_Name

    if label.IsNull() or not label.IsAttribute(TDataStd_Name.GetID_s()):
        return None
    attr = TDataStd_Name()
    label.FindAttribute(TDataStd_Name.GetID_s(), attr)
    return attr.Get().ToExtString()


def _labels(*labels):
    from OCP.TDF import TDF_LabelSequence

    seq = TDF_LabelSequence()
    for lab in labels:
        seq.Append(lab)
    return seq


def _face_labels(shape_tool, root, solid) -> dict:
    """One named sub-shape label per face that realises a feature; feature id -> [labels]."""
    owners: dict = {}  # face hash -> (face, [feature ids])
    for fid, faces in solid.faces.items():
        for face in faces:
            key = next((k for k, (g, _) in owners.items() if g.isSame(face)), None)
            if key is None:
                key = len(owners)
                owners[key] = (face, [])
            owners[key][1].append(fid)
    out: dict = {}
    for face, fids in owners.values():
        lab = shape_tool.AddSubShape(root, face.wrapped)
        if lab.IsNull():
            raise HyperstatError(f"part '{solid.part}': OCCT did not accept a face of feature '{fids[0]}' as a "
                                 "sub-shape of the part.")
        _set_name(lab, "|".join(fids))
        for fid in fids:
            out.setdefault(fid, []).append(lab)
    return out


_ASCII = {"\u00b1": "+-", "\u2300": "diameter ", "\u00b5": "u", "\u2225": "//", "\u27c2": "perpendicular",
          "\u22a5": "perpendicular", "\u2220": "angle", "\u2316": "position", "\u25ce": "coaxial", "\u2264": "<=",
          "\u2265": ">=", "\u2212": "-", "\u00d7": "x", "\u2026": "..."}


def ascii_words(text: str) -> str:
    """``text`` in ASCII for a STEP string (ISO 10303-21 strings are ASCII): the drawing's symbols spelled out.

    >>> ascii_words("within \u2300 0.02 mm (\u00b1 0.01 mm)")
    'within diameter  0.02 mm (+- 0.01 mm)'
    """
    out = "".join(_ASCII.get(c, c) for c in text)
    return out.encode("ascii", "replace").decode("ascii")


def _describe(frame: dict) -> str:
    """The words a tolerance's description carries: what the semantics of OCCT's AP242 cannot (mm), in ASCII."""
    words = [str(frame.get("text") or "")]
    direction = frame.get("zone_direction")
    if direction is not None:
        words.append("zone direction (" + ", ".join(f"{float(c):.6g}" for c in direction)
                     + ") in the drawing's frame (base frame, home configuration)")
    ind = frame.get("indicator")
    if ind:
        words.append(f"{ind.get('kind', '')} {ind.get('relation', '')} to datum {ind.get('datum', '')}".strip())
    if frame.get("value_kind"):
        words.append(str(frame["value_kind"]))
    return ascii_words("; ".join(w for w in words if w))


def _fix_units(model, names: list[str], descriptions: list[str], zones: list[float]) -> None:
    """After the transfer: name the tolerances, give their values the unit they are in (mm), fix angle units."""
    from OCP.StepBasic import StepBasic_SiPrefix, StepBasic_SiUnitAndPlaneAngleUnit, StepBasic_SiUnitName
    from OCP.StepDimTol import StepDimTol_GeometricTolerance
    from OCP.TCollection import TCollection_HAsciiString

    k = 0
    for i in range(1, model.NbEntities() + 1):
        ent = model.Value(i)
        if isinstance(ent, StepDimTol_GeometricTolerance):  # (IsKind costs 1 ms a call through OCP)
            if k >= len(names):
                raise HyperstatError("OCCT wrote more geometric tolerances than the drawing has frames.")
            if not math.isclose(ent.Magnitude().ValueComponent(), zones[k], rel_tol=1e-12):
                raise HyperstatError(f"OCCT wrote the geometric tolerances in another order than the frames "
                                     f"({names[k]}).")
            ent.SetName(TCollection_HAsciiString(ascii_words(names[k])))
            ent.SetDescription(TCollection_HAsciiString(descriptions[k]))
            unit = ent.Magnitude().UnitComponent().NamedUnit()
            if hasattr(unit, "HasPrefix") and not unit.HasPrefix() and \
                    unit.Name() == StepBasic_SiUnitName.StepBasic_sunMetre:
                unit.SetPrefix(StepBasic_SiPrefix.StepBasic_spMilli)
            k += 1
        elif isinstance(ent, StepBasic_SiUnitAndPlaneAngleUnit) and \
                ent.Name() == StepBasic_SiUnitName.StepBasic_sunMetre:
            ent.SetName(StepBasic_SiUnitName.StepBasic_sunRadian)
    if k != len(names):
        raise HyperstatError(f"OCCT wrote {k} geometric tolerances for {len(names)} frames.")


def part_step_bytes(solid, drawing: dict) -> bytes:
    """The AP242 STEP file of one part with its PMI (see the module docstring); checked by reading it back.

    Parameters
    ----------
    solid : PartSolid
        :func:`hyperstat.cad_plugin.part_solids.part_solid` of ``drawing``.
    drawing : dict
        The part's drawing (``report.json`` ``drawings[*]``).
    """
    import OCP.XCAFDimTolObjects as X
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs
    from OCP.TCollection import TCollection_HAsciiString
    from OCP.XCAFDoc import XCAFDoc_Datum, XCAFDoc_DimTolTool, XCAFDoc_DocumentTool, XCAFDoc_GeomTolerance
    from OCP.XSControl import XSControl_WorkSession

    from hyperstat.cad_plugin.assembly import _strip_timestamp

    part = solid.part
    doc = _new_document()
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    dimtol: XCAFDoc_DimTolTool = XCAFDoc_DocumentTool.DimTolTool_s(doc.Main())
    root = shapes.AddShape(solid.shape.wrapped, False)
    _set_name(root, part)
    faces = _face_labels(shapes, root, solid)
    datum_feature = {str(d["letter"]): str(d["feature"]) for d in drawing.get("datums") or []}
    datum_labels: dict = {}

    def datum(letter: str, position: int):
        if (letter, position) not in datum_labels:
            if letter not in datum_feature or datum_feature[letter] not in faces:
                raise HyperstatError(f"drawing of part '{part}': datum {letter} names no feature of the part.")
            lab = dimtol.AddDatum()
            obj = X.XCAFDimTolObjects_DatumObject()
            obj.SetName(TCollection_HAsciiString(letter))
            obj.SetPosition(position)
            XCAFDoc_Datum.Set_s(lab).SetObject(obj)
            dimtol.SetDatum(_labels(*faces[datum_feature[letter]]), lab)
            datum_labels[(letter, position)] = lab
        return datum_labels[(letter, position)]

    names, descriptions, zones = [], [], []
    for frame in drawing.get("frames") or []:
        fid = str(frame["id"])
        kind = CHARACTERISTICS.get(str(frame.get("characteristic", "")).lower())
        if kind is None:
            raise HyperstatError(f"drawing of part '{part}', frame {fid}: characteristic "
                                 f"{frame.get('characteristic')!r} is not an ISO 1101 characteristic OCCT writes.")
        if str(frame.get("feature")) not in faces:
            raise HyperstatError(f"drawing of part '{part}', frame {fid}: feature {frame.get('feature')!r} is not "
                                 "a feature of the part.")
        zone = float(frame["zone_mm"])
        if not (zone > 0 and math.isfinite(zone)):
            raise HyperstatError(f"drawing of part '{part}', frame {fid}: zone_mm must be a positive number (mm).")
        lab = dimtol.AddGeomTolerance()
        obj = X.XCAFDimTolObjects_GeomToleranceObject()
        obj.SetType(getattr(X, f"XCAFDimTolObjects_GeomToleranceType_{kind}"))
        obj.SetValue(zone)
        form = _zone_form(frame.get("zone_shape"))
        if form != "width":
            obj.SetTypeOfValue(X.XCAFDimTolObjects_GeomToleranceTypeValue_Diameter if form == "diameter" else
                               X.XCAFDimTolObjects_GeomToleranceTypeValue_SphericalDiameter)
        XCAFDoc_GeomTolerance.Set_s(lab).SetObject(obj)
        dimtol.SetGeomTolerance(_labels(*faces[str(frame["feature"])]), lab)
        for k, letter in enumerate(frame.get("datum_system") or []):
            dimtol.SetDatumToGeomTol(datum(str(letter), k + 1), lab)
        names.append(fid)
        descriptions.append(_describe(frame))
        zones.append(zone)
    with _statics({"write.step.schema": "AP242DIS", "write.stepcaf.subshapes.name": 1, "write.step.unit": "MM",
                   "xstep.cascade.unit": "MM"}):
        writer = STEPCAFControl_Writer(XSControl_WorkSession(), False)
        writer.SetDimTolMode(True)
        writer.SetNameMode(True)
        writer.SetColorMode(False)
        if not writer.Transfer(doc, STEPControl_AsIs):
            raise HyperstatError(f"part '{part}': OCCT's STEP writer refused the part's document.")
        _fix_units(writer.Writer().Model(), names, descriptions, zones)
        with tempfile.TemporaryDirectory() as tmp:
            scratch = Path(tmp) / "part.step"
            writer.Write(str(scratch))
            if not scratch.is_file():
                raise HyperstatError(f"part '{part}': OCCT's STEP writer wrote nothing.")
            back = read_part_step(scratch)
            data = scratch.read_bytes()
    problems = compare_pmi(drawing_pmi(drawing), back)
    if problems:
        raise HyperstatError(f"part '{part}': the STEP file read back does not say what the drawing says "
                             f"({problems[0]}); it was not written.")
    return _strip_timestamp(data)


def write_part_step(solid, drawing: dict, path: str | Path) -> Path:
    """Write :func:`part_step_bytes` to ``path`` atomically (inside a report's all-or-nothing block, with it)."""
    from hyperstat.solver.atomic import write_bytes

    return write_bytes(path, part_step_bytes(solid, drawing))


def read_part_step(path: str | Path) -> dict:
    """The PMI of a part's STEP file as OCCT's reader gives it (GD&T mode on), in the form of :func:`drawing_pmi`.

    Datums come with the precedences they are cited at (``{"A": {"features": [...], "precedences": [1]}}``);
    a frame's or a datum's features are the features whose faces are exactly its faces (usually one; several
    when two features of the drawing are one face).
    """
    from OCP.IFSelect import IFSelect_ReturnStatus
    from OCP.STEPCAFControl import STEPCAFControl_Reader
    from OCP.TDF import TDF_LabelSequence
    from OCP.XCAFDoc import XCAFDoc_Datum, XCAFDoc_DimTolTool, XCAFDoc_DocumentTool, XCAFDoc_GeomTolerance
    import OCP.XCAFDimTolObjects as X

    path = Path(path)
    doc = _new_document()
    with _statics({"read.stepcaf.subshapes.name": 1}):
        reader = STEPCAFControl_Reader()
        reader.SetGDTMode(True)
        reader.SetNameMode(True)
        if reader.ReadFile(str(path)) != IFSelect_ReturnStatus.IFSelect_RetDone or not reader.Transfer(doc):
            raise HyperstatError(f"{path}: OCCT's STEP reader cannot read it.")
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    dimtol = XCAFDoc_DocumentTool.DimTolTool_s(doc.Main())
    free = TDF_LabelSequence()
    shapes.GetFreeShapes(free)
    part = _name(free.Value(1)) if free.Length() else None
    # feature id -> the names of the faces that carry it (every named face of the part)
    all_faces: dict = {}
    for k in range(1, free.Length() + 1):
        subs = TDF_LabelSequence()
        shapes.GetSubShapes_s(free.Value(k), subs)
        for j in range(1, subs.Length() + 1):
            n = _name(subs.Value(j)) or ""
            for fid in n.split("|"):
                all_faces.setdefault(fid, set()).add(n)

    def faces_of(label) -> list[str]:
        first, second = TDF_LabelSequence(), TDF_LabelSequence()
        XCAFDoc_DimTolTool.GetRefShapeLabel_s(label, first, second)
        return [_name(first.Value(k)) or "" for k in range(1, first.Length() + 1)]

    def features_of(names: list[str]) -> list[str]:
        """The features whose faces are exactly ``names`` (several when two features are one face: a slide's
        stop drawn on a bore's end face)."""
        wanted = set(names)
        candidates = set.intersection(*(set(n.split("|")) for n in names)) if names else set()
        return sorted(c for c in candidates if all_faces.get(c) == wanted)

    tol_labels = TDF_LabelSequence()
    dimtol.GetGeomToleranceLabels(tol_labels)
    raw = []
    types = {v: k for k, v in CHARACTERISTICS.items()}
    for i in range(1, tol_labels.Length() + 1):
        lab = tol_labels.Value(i)
        obj = XCAFDoc_GeomTolerance.Set_s(lab).GetObject()
        kind = str(obj.GetType()).rsplit("_", 1)[-1]
        value_type = obj.GetTypeOfValue()
        form = ("diameter" if value_type == X.XCAFDimTolObjects_GeomToleranceTypeValue_Diameter else
                "sphere" if value_type == X.XCAFDimTolObjects_GeomToleranceTypeValue_SphericalDiameter else "width")
        refs = TDF_LabelSequence()
        XCAFDoc_DimTolTool.GetDatumWithObjectOfTolerLabels_s(lab, refs)
        system = []
        for k in range(1, refs.Length() + 1):
            dobj = XCAFDoc_Datum.Set_s(refs.Value(k)).GetObject()
            system.append((int(dobj.GetPosition()), dobj.GetName().ToCString(), faces_of(refs.Value(k))))
        name = obj.GetSemanticName()
        raw.append({"id": name.ToCString() if name is not None else "", "characteristic": types.get(kind, kind),
                    "zone_mm": float(obj.GetValue()), "zone_form": form, "system": sorted(system),
                    "faces": faces_of(lab)})
    datums: dict = {}
    frames = []
    for r in raw:
        for position, letter, names in r["system"]:
            entry = datums.setdefault(letter, {"features": features_of(names), "precedences": []})
            if position not in entry["precedences"]:
                entry["precedences"].append(position)
        frames.append({"id": r["id"], "characteristic": r["characteristic"], "zone_mm": r["zone_mm"],
                       "zone_form": r["zone_form"], "datum_system": [letter for _, letter, _ in r["system"]],
                       "precedences": [p for p, _, _ in r["system"]], "features": features_of(r["faces"])})
    return {"part": part, "datums": datums, "frames": sorted(frames, key=lambda x: x["id"])}


def compare_pmi(expected: dict, got: dict, rel: float = 1e-9) -> list[str]:
    """Differences between a drawing's PMI (:func:`drawing_pmi`) and a STEP file's (:func:`read_part_step`).

    Datums are compared on the datums the frames cite (a STEP file carries a datum through the
    tolerances that reference it).  A feature read back may come with others that are the very same faces
    (a slide's stop on a bore's end face): the drawing's feature must be among them.  Returns sentences;
    empty when they agree.
    """
    out = []
    if got.get("part") != expected["part"]:
        out.append(f"part name {got.get('part')!r} instead of {expected['part']!r}")
    cited = {d for f in expected["frames"] for d in f["datum_system"]}
    for letter in sorted(cited):
        g = got["datums"].get(letter)
        if g is None:
            out.append(f"datum {letter} is missing")
        elif not set(expected["datums"].get(letter) or ["?"]) <= set(g["features"]):
            out.append(f"datum {letter} is on {g['features']} instead of {expected['datums'].get(letter)}")
    extra = sorted(set(got["datums"]) - cited)
    if extra:
        out.append(f"datum {extra[0]} is not cited by the drawing")
    by_id = {f["id"]: f for f in got["frames"]}
    for f in expected["frames"]:
        g = by_id.get(f["id"])
        if g is None:
            out.append(f"frame {f['id']} is missing")
            continue
        if not set(f["features"]) <= set(g["features"]):
            out.append(f"frame {f['id']}: on {g['features']!r} instead of {f['features']!r}")
        for key in ("characteristic", "zone_form", "datum_system"):
            if g[key] != f[key]:
                out.append(f"frame {f['id']}: {key} {g[key]!r} instead of {f[key]!r}")
        if not math.isclose(g["zone_mm"], f["zone_mm"], rel_tol=rel):
            out.append(f"frame {f['id']}: zone {g['zone_mm']!r} mm instead of {f['zone_mm']!r} mm")
        if g["precedences"] != list(range(1, len(f["datum_system"]) + 1)):
            out.append(f"frame {f['id']}: datum precedences {g['precedences']} instead of 1, 2, ...")
    if len(got["frames"]) != len(expected["frames"]):
        out.append(f"{len(got['frames'])} frames instead of {len(expected['frames'])}")
    return out

