"""Extraction: skeleton (CadQuery assembly or STEP file + sidecar) -> solver model.

Units: lengths in mm, angles in rad.

Every frame pose comes from the CAD data itself: the placement of each marker node
(``m_<element>``, ``f_<frame>``), which STEP stores.  The sidecar (or, for an
in-memory assembly, the node metadata) gives what STEP cannot hold: joint types,
roles, ranges, defects and the chains.  The poses go through the same
:class:`hyperstat.solver.kinematics.build.MechanismBuilder` as the template, with the x axes taken from
the markers, so the extracted model equals the template's to the precision of the
STEP file (13 significant digits).  A marker that is missing, or whose arrows do not
lie along its frame's axes, is a clear error naming it.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from hyperstat.solver.kinematics.build import MechanismBuilder
from hyperstat.solver.errors import ModelError
from hyperstat.solver.kinematics.model import Mechanism

from hyperstat.cad_plugin.assembly import SIDECAR_FORMAT, matrix_from_location, sidecar_path

__all__ = ["extract_from_assembly", "extract_from_step", "read_sidecar", "step_length_unit"]


def _walk(assy, parent=np.eye(4), prefix=""):
    """Yield (node name, world 4x4, node) for every child node, depth first."""
    for child in assy.children:
        t = parent @ (matrix_from_location(child.loc) if child.loc is not None else np.eye(4))
        yield child.name, t, child
        yield from _walk(child, t, f"{prefix}{child.name}/")


def _check_marker(node_name: str, t: np.ndarray, node, size: float, where: str) -> None:
    """The arrow solids of a marker must run along its frame's axes (geometry check)."""
    arrows = {c.name: c for c in node.children if c.name in ("x", "y", "z")}
    missing = [a for a in "xyz" if a not in arrows]
    if missing:
        raise ModelError(f"{where}: marker '{node_name}' has no '{missing[0]}' arrow.")
    for i, a in enumerate("xyz"):
        child = arrows[a]
        shape = child.obj.val() if hasattr(child.obj, "val") else child.obj
        if shape is None:
            raise ModelError(f"{where}: marker '{node_name}' arrow '{a}' has no solid.")
        local = matrix_from_location(child.loc) if child.loc is not None else np.eye(4)
        c = shape.Center()
        centre = (t @ local @ np.array([c.x, c.y, c.z, 1.0]))[:3]
        offset = centre - t[:3, 3]
        axis = t[:3, i]
        along = float(offset @ axis)
        across = float(np.linalg.norm(offset - along * axis))
        if along <= 0 or across > 1e-6 * max(size, 1.0):
            raise ModelError(
                f"{where}: marker '{node_name}' is inconsistent: its {a} arrow does not lie along the frame's {a} axis."
            )


def _rebuild(meta: dict, poses: dict[str, np.ndarray], where: str) -> Mechanism:
    """Mechanism from sidecar data and marker poses (world, home)."""
    try:
        b = MechanismBuilder(meta["name"], base=meta["base"], description=meta.get("description", ""))
        b.metadata = dict(meta.get("metadata", {}))
        b.output = meta["output"]
        for node, info in meta["nodes"].items():
            kind = info["kind"]
            if kind == "frame":
                if info.get("declared") and info["frame"] != meta["base"]:
                    t = poses[node]
                    b.frame(info["frame"], t[:3, 3], t[:3, 2], t[:3, 0])
                continue
            t = poses[node]
            if kind == "joint":
                fn = b.revolute if info["type"] == "R" else b.prismatic
                fn(info["element"], t[:3, 3], t[:3, 2], role=info["role"], x_axis=t[:3, 0], defects=info["defects"],
                   defect_names=info.get("defect_names", {}), range=tuple(info["range"]), home=info["home"])
            else:
                b.fixed(info["element"], t[:3, 3], t[:3, 2], t[:3, 0], defects=info["defects"],
                        defect_names=info.get("defect_names", {}), target=info.get("target"))
        for ch in meta["chains"]:
            b.chain(ch["name"], ch["start"], ch["end"], ch["elements"])
    except (KeyError, TypeError) as exc:
        raise ModelError(f"{where}: the sidecar lacks field {exc} or has it in the wrong form.") from None
    mech = b.build()
    return mech


def extract_from_assembly(assy) -> Mechanism:
    """Model of an in-memory assembly built by :func:`hyperstat.cad_plugin.assembly.build_assembly`."""
    meta = dict(assy.metadata or {})
    nodes = {}
    poses = {}
    for name, t, node in _walk(assy):
        if node.metadata and "kind" in node.metadata and (name.startswith("m_") or name.startswith("f_")):
            nodes[name] = dict(node.metadata)
            poses[name] = t
            _check_marker(name, t, node, meta.get("marker_size", 1.0), f"assembly '{assy.name}'")
    meta["nodes"] = nodes
    return _rebuild(meta, poses, f"assembly '{assy.name}'")


def step_length_unit(path: str | Path) -> str:
    """Length unit declared in a STEP file's header ('MILLI.METRE', 'METRE', 'INCH', ...)."""
    head = Path(path).read_bytes()[:200000].decode("latin-1", errors="replace")
    m = re.search(r"SI_UNIT\(\s*(\.\w+\.|\$)\s*,\s*\.METRE\.\s*\)", head)
    if m:
        prefix = m.group(1).strip(".")
        return "METRE" if prefix == "$" else f"{prefix}.METRE"
    if "CONVERSION_BASED_UNIT('INCH'" in head.upper():
        return "INCH"
    return "unknown"


def read_sidecar(path: str | Path) -> dict:
    """Read and check a sidecar file."""
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: the sidecar of the STEP file is missing (expected next to it).")
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: the sidecar is not valid JSON ({exc}).") from None
    if not isinstance(meta, dict) or meta.get("format") != SIDECAR_FORMAT:
        raise ModelError(f"{path}: field 'format' must be \"{SIDECAR_FORMAT}\".")
    if meta.get("version") != 1:
        raise ModelError(f"{path}: field 'version' is {meta.get('version')!r}, this hyperstat reads version 1.")
    if meta.get("units") != {"length": "mm", "angle": "rad"}:
        raise ModelError(f"{path}: field 'units' must be {{\"length\": \"mm\", \"angle\": \"rad\"}}.")
    if not isinstance(meta.get("nodes"), dict):
        raise ModelError(f"{path}: field 'nodes' is missing.")
    return meta


def extract_from_step(step: str | Path, sidecar: str | Path | None = None) -> Mechanism:
    """Model of a STEP file written by ``hyperstat build --step`` (marker poses from the STEP).

    Raises
    ------
    ModelError
        If the STEP file or its sidecar is missing or unreadable, the STEP file is not
        in millimetres, or a marker named by the sidecar is missing or inconsistent.
    """
    import cadquery as cq

    step = Path(step)
    if not step.is_file():
        raise ModelError(f"{step}: no such STEP file.")
    meta = read_sidecar(sidecar if sidecar is not None else sidecar_path(step))
    unit = step_length_unit(step)
    if unit != "MILLI.METRE":
        raise ModelError(f"{step}: the STEP file's length unit is {unit}; hyperstat expects millimetres (MILLI.METRE).")
    try:
        assy = cq.Assembly.importStep(str(step))
    except Exception as exc:  # noqa: BLE001 - OCCT raises many kinds
        raise ModelError(f"{step}: cannot be read as a STEP assembly ({exc.__class__.__name__}).") from None
    found = {name: (t, node) for name, t, node in _walk(assy)}
    poses = {}
    for node_name in meta["nodes"]:
        if node_name not in found:
            raise ModelError(f"{step}: marker '{node_name}' named by the sidecar is missing from the STEP file.")
        t, node = found[node_name]
        _check_marker(node_name, t, node, float(meta.get("marker_size", 1.0)), str(step))
        poses[node_name] = t
    extra = [n for n in found if re.match(r"^[mf]_", n) and n not in meta["nodes"]]
    if extra:
        raise ModelError(f"{step}: marker '{extra[0]}' in the STEP file is not described by the sidecar.")
    return _rebuild(meta, poses, str(step))
