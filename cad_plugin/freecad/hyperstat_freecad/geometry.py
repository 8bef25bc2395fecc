"""The skeleton's geometry in the document: STEP import, marker tags, verdict spheres.

Units: mm (FreeCAD's internal length unit, and the STEP files' unit).

``hyperstat build --step`` writes one node per marker (``m_<element>`` for joint
frames and fixed transforms, ``f_<frame>`` for configuration frames) with red, green
and blue arrows, and the link bars.  The import gives one ``App::Part`` per node,
placed at the frame's pose; each is tagged with the dynamic property
``HyperstatNode`` (its node name) so that the markers are found again even when
FreeCAD relabels them.  After an analysis every element's marker receives a sphere
coloured by its verdict (the colours of :mod:`.verdicts`, the same as the CadQuery
and pyvista views), stored as an App property (``HyperstatColor``) so that the
colours exist and are saved also without a GUI, and applied to the view when there
is one.

STEP import needs ``UseLinkGroup`` off (with it on, importing a CadQuery STEP file
crashes ``freecadcmd`` 0.20); duplicate labels are allowed during the import so
that the node names arrive intact when a document holds two skeletons.  Both
preferences are restored afterwards.
"""

from __future__ import annotations

from pathlib import Path

from .runner import HyperstatWorkbenchError
from .verdicts import VERDICT_COLORS, element_verdicts

__all__ = ["import_step", "geometry_root", "markers", "remove_tree", "verdict_spheres", "color_markers",
           "clear_verdicts", "verdict_labels", "coincident_offsets", "SPHERE_SCALE"]

#: verdict sphere radius as a fraction of the marker size (0.18 in the CadQuery / pyvista views;
#: larger here so that the colour shows around the joint barrels at FreeCAD's usual zoom)
SPHERE_SCALE = 0.35
IMPORT_PREFS = "User parameter:BaseApp/Preferences/Mod/Import"
DOCUMENT_PREFS = "User parameter:BaseApp/Preferences/Document"


def _tag(obj, name: str, value: str, tip: str) -> None:
    if name not in obj.PropertiesList:
        obj.addProperty("App::PropertyString", name, "Hyperstat", tip)
        obj.setEditorMode(name, 1)
    setattr(obj, name, value)


def _children(obj) -> list:
    out = list(getattr(obj, "Group", []) or [])
    origin = getattr(obj, "Origin", None)
    if origin is not None:
        out.append(origin)
        out += list(getattr(origin, "OriginFeatures", []) or [])
    return out


def import_step(doc, step: Path, node_names: set[str]):
    """Import ``step`` into ``doc``; return its root ``App::Part``, tagged, with markers tagged.

    Raises
    ------
    HyperstatWorkbenchError
        If the file does not give exactly one top-level object.
    """
    import FreeCAD

    imp = FreeCAD.ParamGet(IMPORT_PREFS)
    docp = FreeCAD.ParamGet(DOCUMENT_PREFS)
    old_link, old_dup = imp.GetBool("UseLinkGroup", True), docp.GetBool("DuplicateLabels", False)
    before = {o.Name for o in doc.Objects}
    imp.SetBool("UseLinkGroup", False)
    docp.SetBool("DuplicateLabels", True)
    try:
        if FreeCAD.GuiUp:
            import ImportGui

            ImportGui.insert(str(step), doc.Name)
        else:
            import Import

            Import.insert(str(step), doc.Name)
        new = [o for o in doc.Objects if o.Name not in before]
        new_names = {o.Name for o in new}
        roots = [o for o in new if not any(p.Name in new_names for p in o.InList)]
        if len(roots) != 1:
            for o in new:
                if doc.getObject(o.Name) is not None:
                    doc.removeObject(o.Name)
            raise HyperstatWorkbenchError(f"{step}: the STEP import gave {len(roots)} top-level objects instead of one.")
        root = roots[0]
        _tag(root, "HyperstatRole", "geometry", "What this object is for hyperstat")
        for o in new:
            if o.TypeId == "App::Part" and o.Label in node_names:
                _tag(o, "HyperstatNode", o.Label, "Node name of the marker in the STEP file and its sidecar")
                _tag(o, "HyperstatRole", "marker", "What this object is for hyperstat")
    finally:
        imp.SetBool("UseLinkGroup", old_link)
        docp.SetBool("DuplicateLabels", old_dup)
    return root


def geometry_root(skeleton):
    """The imported geometry group of a skeleton object (``None`` before the first build)."""
    for child in skeleton.Group:
        if getattr(child, "HyperstatRole", "") == "geometry":
            return child
    return None


def _walk(root) -> list:
    seen, order, stack = set(), [], [root]
    while stack:
        o = stack.pop(0)
        if o is None or o.Name in seen:
            continue
        seen.add(o.Name)
        order.append(o)
        stack.extend(_children(o))
    return order


def markers(skeleton) -> dict:
    """Marker parts of a skeleton's geometry, keyed by node name (``m_11``, ``f_MPS``...)."""
    root = geometry_root(skeleton)
    if root is None:
        return {}
    return {o.HyperstatNode: o for o in _walk(root) if getattr(o, "HyperstatRole", "") == "marker"}


def remove_tree(doc, root) -> None:
    """Delete ``root`` and everything below it (parts, origins, shapes, verdict spheres)."""
    tree = [(o.Name, o.TypeId) for o in _walk(root)]
    origin_types = ("App::Origin", "App::Line", "App::Plane")
    # parts first (a part takes its origin with it), then whatever is left
    for name in [n for n, t in tree if t not in origin_types] + [n for n, t in tree if t in origin_types]:
        if doc.getObject(name) is not None:
            doc.removeObject(name)


def verdict_spheres(skeleton) -> dict:
    """Verdict spheres of a skeleton, keyed by element name."""
    out = {}
    for node, part in markers(skeleton).items():
        for child in part.Group:
            if getattr(child, "HyperstatRole", "") == "verdict":
                out[child.HyperstatElement] = child
    return out


def clear_verdicts(skeleton) -> None:
    """Remove the verdict spheres (the markers stay)."""
    doc = skeleton.Document
    for sphere in verdict_spheres(skeleton).values():
        doc.removeObject(sphere.Name)
    for label in verdict_labels(skeleton).values():
        doc.removeObject(label.Name)


def verdict_labels(skeleton) -> dict:
    """Text labels of the spheres spread around a shared point, keyed by element name."""
    return {o.HyperstatElement: o for o in skeleton.Group if getattr(o, "HyperstatRole", "") == "verdict-label"}


def coincident_offsets(centres: dict[str, tuple[float, float, float]], radius: float,
                       tolerance: float) -> dict[str, tuple[float, float, float]]:
    """Global offsets (mm) that spread spheres of ``radius`` whose centres coincide (within ``tolerance``).

    A group of ``n`` coincident elements is put on a ring of radius ``1.15 r / sin(pi / n)`` in the
    global xy plane, so that neighbouring spheres are at least ``2.3 r`` apart (chord
    ``2 R sin(pi / n)``): every colour shows, none flickers.  Lone elements keep their place.

    >>> off = coincident_offsets({"11": (0, 0, 0), "21": (0, 0, 0), "5": (9, 0, 0)}, 1.0, 1e-6)
    >>> off["5"], round(sum(c * c for c in off["11"]) ** 0.5, 3)
    ((0.0, 0.0, 0.0), 1.15)
    """
    import math

    groups: list[list[str]] = []
    for name in sorted(centres):
        for group in groups:
            if max(abs(a - b) for a, b in zip(centres[name], centres[group[0]])) <= tolerance:
                group.append(name)
                break
        else:
            groups.append([name])
    out = {}
    for group in groups:
        n = len(group)
        if n == 1:
            out[group[0]] = (0.0, 0.0, 0.0)
            continue
        ring = 1.15 * radius / math.sin(math.pi / n)
        for k, name in enumerate(group):
            angle = 2 * math.pi * k / n
            out[name] = (ring * math.cos(angle), ring * math.sin(angle), 0.0)
    return out


def color_markers(skeleton, analysis: dict) -> list[str]:
    """Add a sphere coloured by verdict to every element's marker; return elements without a marker.

    Where several joints share a point (e.g. joints 11, 21 and 41 of the Tripteor), their spheres
    are spread on a small ring around it (:func:`coincident_offsets`) and each gets a text label
    with its element's name, so that forced cannot be mistaken for coupled.
    """
    import FreeCAD
    import Part

    clear_verdicts(skeleton)
    doc = skeleton.Document
    parts = markers(skeleton)
    size = float(skeleton.MarkerSize.Value or 1.0)
    radius = SPHERE_SCALE * size
    missing = []
    verdicts = element_verdicts(analysis)
    placed = {}
    for element in sorted(verdicts):
        part = parts.get(f"m_{element}")
        if part is None:
            missing.append(element)
            continue
        placed[element] = part
    centres = {e: tuple(p.getGlobalPlacement().Base) for e, p in placed.items()}
    offsets = coincident_offsets(centres, radius, 1e-6 * max(size, 1.0))
    for element, part in placed.items():
        verdict = verdicts[element]
        color = VERDICT_COLORS[verdict]
        sphere = doc.addObject("Part::Feature", "Verdict")
        sphere.Shape = Part.makeSphere(radius)
        offset = FreeCAD.Vector(*offsets[element])
        if offset.Length > 0:
            local = part.getGlobalPlacement().Rotation.inverted().multVec(offset)
            sphere.Placement = FreeCAD.Placement(local, FreeCAD.Rotation())
        sphere.Label = f"v_{element}"
        _tag(sphere, "HyperstatRole", "verdict", "What this object is for hyperstat")
        _tag(sphere, "HyperstatElement", element, "Element (joint or fixed transform) of this marker")
        _tag(sphere, "HyperstatVerdict", verdict, "Most severe verdict of the element's defect parameters")
        sphere.addProperty("App::PropertyColor", "HyperstatColor", "Hyperstat", "Colour of the verdict")
        sphere.HyperstatColor = color
        sphere.setEditorMode("HyperstatColor", 1)
        part.addObject(sphere)
        if FreeCAD.GuiUp and sphere.ViewObject is not None:
            sphere.ViewObject.ShapeColor = color
    _label_groups(skeleton, centres, offsets, verdicts, radius)
    if missing:
        FreeCAD.Console.PrintWarning(f"hyperstat: no marker found for element(s) {', '.join(missing)}.\n")
    return missing


def _label_groups(skeleton, centres: dict, offsets: dict, verdicts: dict, radius: float) -> None:
    """One text label per shared point, one line per joint ("11: forced"), above the ring of spheres."""
    import FreeCAD

    doc = skeleton.Document
    groups: dict[tuple, list[str]] = {}
    for element, offset in offsets.items():
        if any(offset):
            key = tuple(round(c, 6) for c in centres[element])
            groups.setdefault(key, []).append(element)
    for members in groups.values():
        members.sort()
        ring = max(sum(c * c for c in offsets[members[0]]) ** 0.5, radius)
        label = doc.addObject("App::Annotation", "VerdictLabel")
        label.LabelText = [f"{e}: {verdicts[e]}" for e in members]
        label.Position = FreeCAD.Vector(*centres[members[0]]) + FreeCAD.Vector(ring, 0, 2.0 * ring)
        _tag(label, "HyperstatRole", "verdict-label", "What this object is for hyperstat")
        _tag(label, "HyperstatElement", ",".join(members), "Joints sharing this point")
        skeleton.addObject(label)  # a plain group: the position stays global
