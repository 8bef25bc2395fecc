"""Part drawings in the form of ``report.json``'s ``drawings`` (docs/drawing-format.md), built from a mechanism.

Units: mm and rad.

The part drawings are computed by the tolerance work (issue 36, items 1-6).  Where a report does not carry
them yet, the renderers, the STEP writer and the FreeCAD panel are exercised on these: one drawing per
declared link, its joints as features (a bore per revolute, a guide way per prismatic, the first bore's end
face), datum A the first bore, B its end face, and per other feature a parallelism and a position frame.
The numbers are stand-ins (zones of 0.02 and 0.05 mm), never expected answers.
"""

from __future__ import annotations

import numpy as np


def _on_link(point: np.ndarray, pts: np.ndarray, tol: float = 1e-6) -> bool:
    for a, b in zip(pts[:-1], pts[1:]):
        d = b - a
        t = float(np.clip((point - a) @ d / max(d @ d, 1e-30), 0.0, 1.0))
        if np.linalg.norm(a + t * d - point) < tol * max(1.0, float(np.linalg.norm(d))):
            return True
    return len(pts) == 1 and np.linalg.norm(pts[0] - point) < tol


def standin_drawings(mechanism) -> list[dict]:
    """Stand-in part drawings of ``mechanism`` (see the module docstring)."""
    from hyperstat.solver.kinematics.model import Joint
    from hyperstat.solver.tolerances.declaration import declaration_of
    from hyperstat.solver.tolerances.drawing import _Geometry

    decl = declaration_of(mechanism)
    geo = _Geometry(mechanism, decl)
    joints = {n: el for n, el in geo.kind.items() if isinstance(el, Joint)}
    out = []
    taken: set = set()
    for link in mechanism.metadata.get("links") or []:
        pts = np.asarray(link["points"], dtype=float)
        elements = []
        for n in joints:  # a joint on the link's bars, one per point (joints at one point belong to several bodies)
            if n not in taken and _on_link(geo.origin(n), pts) and \
                    all(np.linalg.norm(geo.origin(n) - geo.origin(e)) > 1e-6 for e in elements):
                elements.append(n)
        taken.update(elements)
        if not elements:
            continue
        part = link["name"]
        features, frames = [], []
        for n in elements:
            span = decl.clearance(n, joints[n].type)["span_mm"]
            length = float(span) if np.isfinite(span) else 20.0
            features.append({"id": f"{part}.j{n}", "kind": "axis", "element": n,
                             "name": f"{'guide way' if joints[n].type == 'P' else 'bore'} of joint {n}",
                             "point_mm": [float(c) for c in geo.origin(n)],
                             "direction": [float(c) for c in geo.axis(n)], "length_mm": length,
                             "diameter_mm": 20.0 if joints[n].type == "R" else None,
                             "length_source": "declared support span"})
        first = features[0]
        p0, u0 = np.array(first["point_mm"]), np.array(first["direction"])
        features.append({"id": f"{part}.face{first['element']}", "kind": "plane", "element": first["element"],
                         "name": f"end face of joint {first['element']}",
                         "point_mm": [float(c) for c in p0 + 0.5 * first["length_mm"] * u0],
                         "direction": [float(c) for c in u0], "length_mm": None, "diameter_mm": None,
                         "length_source": "solid"})
        datums = [{"letter": "A", "feature": first["id"], "precedence": "primary"},
                  {"letter": "B", "feature": features[-1]["id"], "precedence": "secondary"}]
        k = 0
        for f in features[1:-1]:
            p, u = np.array(f["point_mm"]), np.array(f["direction"])
            parallel = abs(abs(float(u @ u0)) - 1) < 1e-9
            k += 1
            frames.append({"id": f"{part}-F{k}", "tolerances": [], "feature": f["id"],
                           "characteristic": "parallelism" if parallel else "perpendicularity",
                           "zone_mm": 0.02, "zone_shape": "cylinder", "zone_direction": None, "indicator": None,
                           "datum_system": ["A"], "ted": [], "value_kind": "without calibration",
                           "note": "stand-in", "text": f"{f['name']} to datum A within \u23000.02 mm"})
            k += 1
            frames.append({"id": f"{part}-F{k}", "tolerances": [], "feature": f["id"], "characteristic": "position",
                           "zone_mm": 0.05, "zone_shape": "two parallel planes",
                           "zone_direction": [float(c) for c in u0], "indicator":
                               {"kind": "intersection plane", "datum": "B", "relation": "parallel"},
                           "datum_system": ["A", "B"],
                           "ted": [{"from": "B", "distance_mm": float(abs((p - p0) @ u0)),
                                    "direction": [float(c) for c in u0]}],
                           "value_kind": "with calibration" if k % 4 == 0 else "without calibration",
                           "note": "stand-in", "text": f"{f['name']} in position relative to A|B within 0.05 mm"})
        k += 1
        frames.append({"id": f"{part}-F{k}", "tolerances": [], "feature": features[-1]["id"],
                       "characteristic": "perpendicularity", "zone_mm": 0.01, "zone_shape": "two parallel planes",
                       "zone_direction": [float(c) for c in u0], "indicator": None, "datum_system": ["A"], "ted": [],
                       "value_kind": "without calibration", "note": "stand-in",
                       "text": f"{features[-1]['name']} perpendicular to datum A within 0.01 mm"})
        out.append({"part": part, "title": f"{part} (stand-in drawing)", "elements": elements,
                    "units": {"length": "mm", "angle": "rad"}, "features": features, "datums": datums,
                    "frames": frames})
    return out
