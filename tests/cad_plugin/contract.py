"""Tolerance items with the fields of /work CONTRACT-tolerances (issues 29 and 30), built from real items.

Units: mm and rad, as the items.

The report and the FreeCAD panel render ``value_with_calibration``, ``drawing_value``,
``bounds`` and the ``drawing`` list of ISO 1101 callouts when a tolerance item carries them.
Until the tolerance work computes them, the tests build them here from the real items of
``report.json``, following the contract's types and meanings, so that the renderers are
exercised on every field; the numbers are stand-ins (a compensable value opened tenfold, a
tilt over a 400 mm axis), never expected answers.
"""

from __future__ import annotations

import copy
import re

SYMBOLS = {"parallelism": "\u2225", "perpendicularity": "\u22a5", "position": "\u2316"}


def _joint(feature: str) -> str | None:
    m = re.search(r"(?:joint|fixed|elements?) ([A-Za-z0-9_]+)", feature)
    return m.group(1) if m else None


def _callout(item: dict, characteristic: str, zone: float, datum_joint: str | None) -> dict:
    joint = _joint(item["feature"]) or "?"
    datums = ["A"] if datum_joint else []
    frame = f"|{SYMBOLS[characteristic]}|" + ("\u2300" if characteristic == "position" else "") + f"{zone:g}|" + \
        "".join(f"{d}|" for d in datums)
    return {"characteristic": characteristic, "symbol": SYMBOLS[characteristic], "zone": zone, "unit": "mm",
            "diameter_zone": characteristic == "position", "feature": f"axis of joint {joint}",
            "feature_length": 400.0 if characteristic != "position" else None, "datums": datums,
            "datum_features": {"A": f"axis of joint {datum_joint}"} if datum_joint else {},
            "text": f"axis of joint {joint} {characteristic} within {zone:g} mm", "frame": frame}


def with_contract_fields(doc: dict) -> dict:
    """A copy of a report (or analysis) JSON whose tolerance items carry every field of the contract."""
    doc = copy.deepcopy(doc)
    items = doc["tolerances"]["items"]
    datum = next((_joint(t["feature"]) for t in items if t["class"] == "assembly"), None)
    for t in items:
        value = t.get("value")
        t.setdefault("value_with_calibration", None)
        t.setdefault("value_with_calibration_limit", None)
        t.setdefault("bounds", None)
        t.setdefault("drawing", [])
        if t["class"] == "compensable" and value is not None:
            t["value_with_calibration"] = 10.0 * value
            t["value_with_calibration_limit"] = "identification noise"
        if t["class"] == "accuracy-critical" and value is not None:
            t["bounds"] = {"attainable_linear_worst_case": 0.9 * value, "triangle_bound": 1.2 * value, "unit": "mm"}
        if t["class"] in ("assembly", "accuracy-critical"):
            if value is None:  # an analysis JSON (classes only): a stand-in size for the zone
                value = 1e-3 if t["unit"] == "rad" else 0.01
            if t["unit"] == "rad":
                t["drawing"] = [_callout(t, "parallelism", round(400.0 * value, 3), datum)]
            else:
                t["drawing"] = [_callout(t, "position", round(2.0 * value, 3), datum)]
            if t.get("kind") == "relation":  # a condition may need several callouts
                t["drawing"].append(_callout(t, "perpendicularity", round(0.5 * t["drawing"][0]["zone"], 3), datum))
        t["drawing_value"] = t["value_with_calibration"] if t["value_with_calibration"] is not None else t.get("value")
    return doc
