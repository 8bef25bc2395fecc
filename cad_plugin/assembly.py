"""CadQuery assembly of a skeleton: link solids and one marker triad per frame; STEP export.

Units: lengths in mm, angles in rad.

Node layout (names legal in CadQuery queries, ``[A-Za-z][A-Za-z0-9_]*``):

* ``m_<element>``: marker of a joint frame ``L_i`` or of a fixed transform, placed at
  the frame's pose at home; children ``x``, ``y``, ``z`` are arrow solids coloured red,
  green, blue along the frame's axes (paper 1, Fig. 1), and, when an analysis is
  given, ``v`` a sphere coloured by the element's verdict;
* ``f_<frame>``: marker of a configuration frame (base, platform, tool, and frames
  such as ``R51`` that a chain defines);
* ``link_<name>``: the link bars and the joint barrels, grey.

STEP keeps node names, placements and colours but drops metadata, so
:func:`export_step` writes a *sidecar* JSON next to the STEP file with the joint
types, roles, ranges, defects and chains, keyed by node name.  The placements are
read back from the STEP file itself (:mod:`hyperstat.cad_plugin.extract`).
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hyperstat.solver.atomic import dumps_json, write_bytes, write_text
from hyperstat.solver.kinematics.build import FrameSpec, JointSpec
from hyperstat.solver.errors import TemplateError

if TYPE_CHECKING:  # pragma: no cover
    import cadquery as cq

    from hyperstat.cad_plugin.skeleton import Skeleton

__all__ = [
    "AXIS_COLORS",
    "VERDICT_COLORS",
    "SIDECAR_FORMAT",
    "build_assembly",
    "sidecar",
    "export_step",
    "sidecar_path",
    "location_from_matrix",
    "matrix_from_location",
    "element_verdicts",
]

AXIS_COLORS = {"x": (0.9, 0.1, 0.1), "y": (0.1, 0.75, 0.1), "z": (0.1, 0.25, 0.95)}
#: colour per verdict class, shared by CAD markers, pyvista views and the report
VERDICT_COLORS = {
    "forced": (0.85, 0.1, 0.6),  # magenta
    "coupled": (1.0, 0.55, 0.0),  # orange
    "free-influential": (0.0, 0.7, 0.8),  # cyan
    "free-non-influent": (0.55, 0.55, 0.55),  # grey
    "none": (0.95, 0.95, 0.95),  # no defect / gauge only
}
SIDECAR_FORMAT = "hyperstat-step-sidecar"
_LEGAL = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def _node(prefix: str, name: str) -> str:
    node = f"{prefix}_{name}"
    if not _LEGAL.match(node):
        raise TemplateError(
            f"element or frame name '{name}' cannot name a CAD node: use letters, digits and underscores only."
        )
    return node


def location_from_matrix(t: np.ndarray) -> "cq.Location":
    """CadQuery location of a rigid 4x4 transform (mm)."""
    import cadquery as cq
    from OCP.gp import gp_Trsf

    tr = gp_Trsf()
    tr.SetValues(*[float(t[i, j]) for i in range(3) for j in range(4)])
    return cq.Location(tr)


def matrix_from_location(loc: "cq.Location") -> np.ndarray:
    """Rigid 4x4 transform of a CadQuery location."""
    tr = loc.wrapped.Transformation()
    out = np.eye(4)
    for i in range(3):
        for j in range(4):
            out[i, j] = tr.Value(i + 1, j + 1)
    return out


def _arrow(size: float, axis: str):
    import cadquery as cq

    r = 0.05 * size
    direction = {"x": cq.Vector(1, 0, 0), "y": cq.Vector(0, 1, 0), "z": cq.Vector(0, 0, 1)}[axis]
    shaft = cq.Solid.makeCylinder(r, 0.75 * size, cq.Vector(0, 0, 0), direction)
    head = cq.Solid.makeCone(2.2 * r, 0.0, 0.25 * size, direction * (0.75 * size), direction)
    return shaft.fuse(head).clean()


def _bar(p: np.ndarray, q: np.ndarray, radius: float):
    import cadquery as cq

    d = q - p
    length = float(np.linalg.norm(d))
    if length < 1e-9:
        return None
    return cq.Solid.makeCylinder(radius, length, cq.Vector(*p), cq.Vector(*(d / length)))


def element_verdicts(analysis: dict | None) -> dict[str, str]:
    """Verdict class per element from an analysis JSON: the most severe of its parameters."""
    if not analysis:
        return {}
    order = ["forced", "coupled", "free-influential", "free-non-influent", "none"]
    out: dict[str, str] = {}
    for p in analysis.get("parameters", []):
        v = p["verdict"]
        if v in ("gauge", "normalisation", "redundant"):  # not a geometric defect of its own
            cls = "none"
        elif v == "free":
            cls = "free-influential" if p.get("influential") else "free-non-influent"
        else:
            cls = v
        el = p["element"]
        if el not in out or order.index(cls) < order.index(out[el]):
            out[el] = cls
    return out


def build_assembly(skeleton: "Skeleton", analysis: dict | None = None) -> "cq.Assembly":
    """CadQuery assembly of ``skeleton`` at home: links, joint barrels, marker triads.

    Parameters
    ----------
    skeleton : Skeleton
        The declared skeleton (it is built if it was not yet).
    analysis : dict, optional
        Output of ``hyperstat analyze --json``; adds a verdict-coloured sphere to
        each joint marker.

    Returns
    -------
    cadquery.Assembly
    """
    import cadquery as cq

    mech = skeleton.mechanism()
    if not _LEGAL.match(mech.name):
        raise TemplateError(f"mechanism name '{mech.name}' cannot name a CAD assembly.")
    poses = skeleton.poses
    meta = sidecar(skeleton)
    assy = cq.Assembly(name=mech.name, metadata={k: v for k, v in meta.items() if k != "nodes"})
    size = skeleton.marker_size
    arrows = {a: _arrow(size, a) for a in "xyz"}
    verdicts = element_verdicts(analysis)
    for node, info in meta["nodes"].items():
        name = info.get("element") or info.get("frame")
        t = poses[name]
        sub = cq.Assembly(name=node, loc=location_from_matrix(t), metadata=info)
        scale = 1.0 if info["kind"] != "frame" else 1.5
        for a in "xyz":
            # a copy per marker: STEP shares repeated shapes and then loses the child names
            shape = arrows[a].copy() if scale == 1.0 else arrows[a].scale(scale)
            sub.add(shape, name=a, color=cq.Color(*AXIS_COLORS[a]))
        if name in verdicts:
            ball = cq.Solid.makeSphere(0.18 * size, angleDegrees1=-90, angleDegrees2=90)
            sub.add(ball, name="v", color=cq.Color(*VERDICT_COLORS[verdicts[name]]))
        assy.add(sub)
    grey = cq.Color(0.6, 0.6, 0.62)
    for link in skeleton.links:
        pts = [skeleton.point(p) for p in link.points]
        bars = [b for b in (_bar(pts[i], pts[i + 1], link.radius) for i in range(len(pts) - 1)) if b is not None]
        if bars:
            assy.add(cq.Compound.makeCompound(bars), name=_node("link", link.name), color=grey)
    barrels = []
    for name, spec in skeleton._items.items():
        if isinstance(spec, JointSpec):
            t = poses[name]
            r = 0.12 * size
            if spec.type == "R":
                z = t[:3, 2]
                barrels.append(_bar(t[:3, 3] - 0.3 * size * z, t[:3, 3] + 0.3 * size * z, r))
            else:
                z = t[:3, 2]
                barrels.append(_bar(t[:3, 3], t[:3, 3] + 0.6 * size * z, 1.6 * r))
    barrels = [b for b in barrels if b is not None]
    if barrels:
        assy.add(cq.Compound.makeCompound(barrels), name="link_joints", color=cq.Color(0.35, 0.35, 0.4))
    return assy


def sidecar(skeleton: "Skeleton") -> dict:
    """Everything STEP drops: joint types, roles, ranges, defects, chains (keyed by node name)."""
    mech = skeleton.mechanism()
    nodes: dict[str, dict] = {}
    for name, spec in skeleton._items.items():
        node = _node("m", name)
        if isinstance(spec, JointSpec):
            nodes[node] = {"kind": "joint", "element": name, "type": spec.type, "role": spec.role,
                           "range": list(spec.range), "home": spec.home, "defects": spec.defects,
                           "defect_names": dict(spec.defect_names)}
        else:
            assert isinstance(spec, FrameSpec)
            nodes[node] = {"kind": "fixed", "element": name, "defects": spec.defects,
                           "defect_names": dict(spec.defect_names)}
            if getattr(spec, "target", None) is not None:  # placed where another chain put that frame
                nodes[node]["target"] = spec.target
    declared = set(skeleton._frames)
    for frame in skeleton.poses:
        if frame in skeleton._items:
            continue
        nodes[_node("f", frame)] = {"kind": "frame", "frame": frame, "declared": frame in declared}
    return {
        "format": SIDECAR_FORMAT,
        "version": 1,
        "units": {"length": "mm", "angle": "rad"},
        "name": mech.name,
        "description": mech.description,
        "base": mech.base,
        "output": mech.output,
        "marker_size": skeleton.marker_size,
        "chains": [{"name": n, "start": s, "end": e, "elements": list(els)} for n, s, e, els in skeleton._chains],
        "metadata": mech.metadata,
        "nodes": nodes,
    }


def sidecar_path(step_path: str | Path) -> Path:
    """Sidecar file of a STEP file: ``name.step`` -> ``name.step.json``."""
    step_path = Path(step_path)
    return step_path.with_name(step_path.name + ".json")


def export_step(skeleton: "Skeleton", path: str | Path, analysis: dict | None = None) -> tuple[Path, Path]:
    """Write the assembly as STEP (mm) and its sidecar, both atomically.

    Returns
    -------
    tuple of Path
        The STEP file and the sidecar.
    """
    import tempfile

    path = Path(path)
    assy = build_assembly(skeleton, analysis)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
        scratch = Path(tmp) / "assembly.step"
        assy.export(str(scratch), exportType="STEP", unit="MM")
        data = scratch.read_bytes()
    data = _strip_timestamp(data)
    meta = sidecar(skeleton)
    meta["step"] = path.name
    meta["step_sha256"] = hashlib.sha256(data).hexdigest()
    write_bytes(path, data)
    side = write_text(sidecar_path(path), dumps_json(meta))
    return path, side


def _strip_timestamp(data: bytes) -> bytes:
    """Replace the FILE_NAME time stamp so that the same skeleton gives the same bytes."""
    return re.sub(rb"FILE_NAME\('([^']*)','[^']*'", rb"FILE_NAME('\1','2000-01-01T00:00:00'", data, count=1)
