"""Tolerance classes of the defect parameters and the joints, and the tolerance table, as the report gives them.

Units: the JSON is in mm and rad; nothing here depends on them.

Pure Python (no FreeCAD import).  The classes, their colours and legend words are the
project's one definition (``hyperstat_palette``, beside the workbench package: the same file
the report and the pictures read), so that FreeCAD shows the classes, counts and colours of
the printed report.  The analysis JSON is ``hyperstat analyze --json`` (classes, tolerance
ids); the tolerance values come from the report's JSON (``hyperstat report``).
"""

from __future__ import annotations

from hyperstat_palette import (CLASS_COLORS, CLASS_LABELS, CLASS_ORDER, CLASS_RGB, TOLERANCE_CLASSES, callout_text,
                               element_classes, tolerance_counts)

__all__ = ["CLASS_COLORS", "CLASS_LABELS", "CLASS_ORDER", "CLASS_RGB", "TOLERANCE_CLASSES", "callout_text",
           "element_classes", "tolerance_counts", "parameter_classes", "tolerance_rows", "value_text",
           "relations_of"]


def parameter_classes(analysis: dict | None) -> dict:
    """Tolerance class of every defect parameter (``tolerances.parameters[name]["class"]``).

    >>> parameter_classes({"tolerances": {"parameters": {"dK41": {"class": "assembly"}}}})
    {'dK41': 'assembly'}
    """
    table = ((analysis or {}).get("tolerances") or {}).get("parameters") or {}
    return {name: str(entry.get("class")) for name, entry in table.items() if isinstance(entry, dict)}


def value_text(item: dict, key: str = "value") -> str:
    """``"± 0.0408 mm"``, rounded down to three significant digits as the report prints it; ``"-"`` for none.

    >>> value_text({"value": 0.040893, "unit": "mm"}), value_text({"value": None, "unit": "rad"})
    ('± 0.0408 mm', '-')
    """
    import math

    v = item.get(key)
    if v is None:
        return "-"
    v = float(v)
    if v != 0 and math.isfinite(v):
        scale = 10.0 ** (2 - math.floor(math.log10(abs(v))))
        v = math.floor(abs(v) * scale * (1 + 1e-12)) / scale * (1 if v > 0 else -1)
    return f"± {v:.3g} {item.get('unit', '')}".rstrip()


def tolerance_rows(tolerances: dict) -> list[list[str]]:
    """The tolerance table: id, class, statement, feature, without calibration, with calibration, drawing.

    >>> tolerance_rows({"items": [{"id": "T1", "class": "assembly", "statement": "dK41 = 0", "feature": "joint 41",
    ...                            "value": 0.0016318, "unit": "rad", "drawing": [{"frame": "|//|0.65|A|"}]}]})
    [['T1', 'assembly', 'dK41 = 0', 'joint 41', '± 0.00163 rad', '-', '|//|0.65|A|']]
    """
    rows = []
    for t in tolerances.get("items", []):
        frames = " ".join(c.get("frame", "") for c in t.get("drawing") or [] if isinstance(c, dict))
        rows.append([str(t["id"]), str(t["class"]), str(t.get("statement", "")), str(t.get("feature", "")),
                     value_text(t), value_text(t, "value_with_calibration"),
                     frames or (value_text(t, "drawing_value") if t.get("drawing_value") is not None else "-")])
    return rows


def relations_of(tolerances: dict) -> list[str]:
    """The assembly conditions that tie several defects together (``T13: dK21 - dK23 = 0``)."""
    return [f"{t['id']}: {t['statement']}" for t in tolerances.get("items", [])
            if t.get("class") == "assembly" and len(t.get("terms") or t.get("parameters") or []) > 1]
