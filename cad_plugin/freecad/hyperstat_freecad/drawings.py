"""The part drawings of the report as the workbench shows them: per part its frames and datums, in words.

Units: mm (zones, lengths, points in the base frame at the home configuration, as ``report.json``).

Pure Python (no FreeCAD import).  ``report.json``'s ``drawings`` (contract: ``docs/drawing-format.md``)
become the rows of the Results panel's *Part drawings* tab (:func:`frame_rows`, :func:`datum_rows`) and the
labels the 3D view shows at the features (:func:`feature_labels`): the same frames, cells and datum letters
as the printed part drawings.
"""

from __future__ import annotations

__all__ = ["frame_rows", "datum_rows", "feature_labels", "zone_words", "frame_text", "FRAME_COLUMNS", "DATUM_COLUMNS"]

FRAME_COLUMNS = ["part", "frame", "tolerances", "toleranced feature", "frame as drawn", "zone (mm)", "datums", "value"]
DATUM_COLUMNS = ["part", "datum", "precedence", "datum feature"]


def _direction(d) -> str:
    """A unit direction in words: ``+z``, or ``(0.5, 0, 0.866)``."""
    names = "xyz"
    k = max(range(3), key=lambda i: abs(d[i]))
    if abs(abs(d[k]) - 1) < 1e-9:
        return ("+" if d[k] > 0 else "-") + names[k]
    return "(" + ", ".join(f"{round(c, 3) + 0.0:.3g}" for c in d) + ")"


def frame_text(frame: dict) -> str:
    """The frame's cells: ``|⌖|⌀0.159|A|``, then its plane indicator (``orientation plane ⟂ C``).

    >>> frame_text({"characteristic": "parallelism", "zone_mm": 0.0284, "zone_shape": "two parallel planes",
    ...             "datum_system": ["A", "C"], "indicator": {"kind": "orientation plane", "datum": "C",
    ...             "relation": "parallel"}})
    '|\u2225|0.0284|A|C| orientation plane \u2225 C'
    """
    symbols = {"parallelism": "\u2225", "perpendicularity": "\u27c2", "angularity": "\u2220", "position": "\u2316",
               "coaxiality": "\u25ce", "symmetry": "\u232f", "flatness": "\u23e5", "straightness": "\u23e4"}
    shape = str(frame.get("zone_shape") or "")
    zone = ("\u2300" if ("cylinder" in shape or "circle" in shape) else "") + f"{float(frame['zone_mm']):.3g}"
    cells = [symbols.get(str(frame.get("characteristic", "")), str(frame.get("characteristic", ""))), zone]
    cells += [str(x) for x in frame.get("datum_system") or []]
    text = "|" + "|".join(cells) + "|"
    ind = frame.get("indicator")
    if ind:
        rel = str(ind.get("relation", ""))
        rel = {"parallel": "\u2225", "perpendicular": "\u27c2"}.get(rel, rel)
        text += f" {ind.get('kind', '')} {rel} {ind.get('datum', '')}"
    return text


def zone_words(frame: dict) -> str:
    """``two parallel planes 0.05 mm apart, normal to +z`` / ``cylinder of diameter 0.02 mm``."""
    shape = str(frame.get("zone_shape") or "zone")
    z = f"{float(frame['zone_mm']):.3g}"
    if "cylinder" in shape or "circle" in shape or "sphere" in shape:
        return f"{shape} of diameter {z} mm"
    text = f"{shape} {z} mm apart"
    d = frame.get("zone_direction")
    if d is not None:
        text += ", normal to " + _direction(d)
    return text


def _features(drawing: dict) -> dict:
    return {f["id"]: f for f in drawing.get("features") or []}


def frame_rows(drawings: list) -> list[list[str]]:
    """One row per frame of every part: part, frame id, tolerances, feature, frame as drawn, zone, datums, value.

    >>> frame_rows([{"part": "rod", "features": [{"id": "rod.bore3", "name": "bore of joint 3"}], "frames": [
    ...     {"id": "rod-F2", "tolerances": ["T3", "T4"], "feature": "rod.bore3", "characteristic": "parallelism",
    ...      "zone_mm": 0.024, "zone_shape": "cylinder", "datum_system": ["A"], "value_kind": "without calibration"}]}])
    [['rod', 'rod-F2', 'T3, T4', 'bore of joint 3', '|\u2225|\u23000.024|A|', 'cylinder of diameter 0.024 mm', 'A', 'without calibration']]
    """
    rows = []
    for d in drawings or []:
        features = _features(d)
        for fr in d.get("frames") or []:
            feature = features.get(fr.get("feature"), {})
            rows.append([str(d["part"]), str(fr["id"]), ", ".join(fr.get("tolerances") or []) or "-",
                         str(feature.get("name") or fr.get("feature", "")), frame_text(fr), zone_words(fr),
                         "|".join(fr.get("datum_system") or []) or "none", str(fr.get("value_kind", ""))])
    return rows


def datum_rows(drawings: list) -> list[list[str]]:
    """One row per datum of every part: part, letter, precedence, datum feature (its name)."""
    rows = []
    for d in drawings or []:
        features = _features(d)
        for x in d.get("datums") or []:
            rows.append([str(d["part"]), str(x["letter"]), str(x.get("precedence", "")),
                         str(features.get(x["feature"], {}).get("name") or x["feature"])])
    return rows


def feature_labels(drawings: list) -> list[dict]:
    """A label per feature that carries a frame or a datum: ``{"feature", "part", "point", "lines"}``.

    ``point`` is the feature's ``point_mm`` (base frame, home configuration: where the skeleton shows the
    joint); ``lines`` are the part and feature, its datum letter, and its frames as drawn.
    """
    out = []
    for d in drawings or []:
        features = _features(d)
        letters = {x["feature"]: x["letter"] for x in d.get("datums") or []}
        frames: dict = {}
        for fr in d.get("frames") or []:
            frames.setdefault(fr.get("feature"), []).append(fr)
        for fid, f in features.items():
            if fid not in letters and fid not in frames:
                continue
            lines = [f"{d['part']}: {f.get('name') or fid}" + (f" [datum {letters[fid]}]" if fid in letters else "")]
            lines += [f"{fr['id']} {frame_text(fr)}" for fr in frames.get(fid, [])]
            out.append({"feature": fid, "part": str(d["part"]), "point": [float(c) for c in f["point_mm"]],
                        "lines": lines})
    return out
