"""The skeleton's geometry in the document: STEP import, marker tags, class spheres and callouts.

Units: mm (FreeCAD's internal length unit, and the STEP files' unit).

``hyperstat build --step`` writes one node per marker (``m_<element>`` for joint
frames and fixed transforms, ``f_<frame>`` for configuration frames) with red, green
and blue arrows, and the link bars.  The import gives one ``App::Part`` per node,
placed at the frame's pose; each is tagged with the dynamic property
``HyperstatNode`` (its node name) so that the markers are found again even when
FreeCAD relabels them.  After an analysis every element's marker receives a sphere
in the colour of its tolerance class (:mod:`.classes`: the colours of the report and the
pictures), stored as an App property (``HyperstatColor``) so that the colours exist and
are saved also without a GUI, and applied to the view when there is one, and a callout
with its tolerance ids.

STEP import needs ``UseLinkGroup`` off (with it on, importing a CadQuery STEP file
crashes ``freecadcmd`` 0.20); duplicate labels are allowed during the import so
that the node names arrive intact when a document holds two skeletons.  Both
preferences are restored afterwards.
"""

from __future__ import annotations

from pathlib import Path

from .classes import CLASS_RGB, callout_text, element_classes
from .runner import HyperstatWorkbenchError

__all__ = ["import_step", "read_step", "update_in_place", "geometry_root", "markers", "remove_tree", "class_spheres", "color_markers",
           "clear_classes", "callout_labels", "coincident_offsets", "SPHERE_SCALE"]

#: class sphere radius as a fraction of the marker size (0.18 in the CadQuery / pyvista views;
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


def _tree(root) -> dict:
    """The objects below ``root`` keyed by their path of labels (a marker by its node name), origins left out."""
    out = {}

    def walk(obj, path):
        for child in getattr(obj, "Group", []) or []:
            if getattr(child, "HyperstatRole", "") in ("class", "callout"):
                continue  # results, not geometry
            key = path + (getattr(child, "HyperstatNode", "") or child.Label,)
            out[key] = child
            walk(child, key)

    walk(root, ())
    return out


def read_step(step: Path, node_names: set[str]) -> dict | None:
    """The placements and shapes of a STEP file's skeleton, keyed as :func:`_tree` keys them (no document changed).

    The file is imported into a hidden scratch document, read and closed.  Call it outside any
    undo transaction: opening and closing a document inside one ends the transaction in the
    GUI, and what follows would escape the undo.  ``None`` when the file has no single root.
    """
    import FreeCAD

    active = FreeCAD.ActiveDocument.Name if FreeCAD.ActiveDocument else None
    scratch = FreeCAD.newDocument("HyperstatScratch", hidden=True)
    try:
        imp = FreeCAD.ParamGet(IMPORT_PREFS)
        docp = FreeCAD.ParamGet(DOCUMENT_PREFS)
        old_link, old_dup = imp.GetBool("UseLinkGroup", True), docp.GetBool("DuplicateLabels", False)
        imp.SetBool("UseLinkGroup", False)
        docp.SetBool("DuplicateLabels", True)
        try:
            import Import

            Import.insert(str(step), scratch.Name)
        finally:
            imp.SetBool("UseLinkGroup", old_link)
            docp.SetBool("DuplicateLabels", old_dup)
        roots = [o for o in scratch.Objects if not o.InList and o.TypeId == "App::Part"]
        if len(roots) != 1:
            return None
        for o in scratch.Objects:
            if o.TypeId == "App::Part" and o.Label in node_names:
                o.addProperty("App::PropertyString", "HyperstatNode", "Hyperstat")
                o.HyperstatNode = o.Label
        return {key: (o.TypeId, o.Placement,
                      o.Shape.copy() if o.TypeId.startswith("Part::") and hasattr(o, "Shape") else None)
                for key, o in _tree(roots[0]).items()}
    finally:
        FreeCAD.closeDocument(scratch.Name)
        if active is not None and active in FreeCAD.listDocuments():
            FreeCAD.setActiveDocument(active)
            if FreeCAD.GuiUp:
                import FreeCADGui

                FreeCADGui.setActiveDocument(active)


def update_in_place(root, new: dict | None) -> bool:
    """Move and reshape the geometry below ``root`` to ``new`` (:func:`read_step`), in place.

    When ``new`` holds the same objects (same paths of node names and labels, same types),
    their placements and shapes are copied onto the existing ones and True is returned.  The
    document then changes only properties: an undo puts the old values back, with no part
    deleted and re-created (re-creating an ``App::Part`` on undo is what printed "Can't find
    Origin" in FreeCAD's report view).  False (nothing changed) when the structure differs:
    the caller replaces the geometry instead.
    """
    if new is None:
        return False
    old = _tree(root)
    if set(new) != set(old) or any(new[k][0] != old[k].TypeId for k in new):
        return False
    for key, (_, placement, shape) in new.items():
        dst = old[key]
        if _pose(dst.Placement) != _pose(placement):
            dst.Placement = placement
        if shape is not None:
            dst.Shape = shape
    return True


def _pose(placement) -> tuple:
    """A placement as numbers (position mm, quaternion), rounded far below any build's change."""
    return tuple(round(c, 12) for c in (*placement.Base, *placement.Rotation.Q))


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
    """Delete ``root`` and everything below it (parts, origins, shapes, class spheres)."""
    tree = [(o.Name, o.TypeId) for o in _walk(root)]
    origin_types = ("App::Origin", "App::Line", "App::Plane")
    # parts first (a part takes its origin with it), then whatever is left
    for name in [n for n, t in tree if t not in origin_types] + [n for n, t in tree if t in origin_types]:
        if doc.getObject(name) is not None:
            doc.removeObject(name)


def class_spheres(skeleton) -> dict:
    """Class spheres of a skeleton, keyed by element name."""
    out = {}
    for node, part in markers(skeleton).items():
        for child in part.Group:
            if getattr(child, "HyperstatRole", "") == "class":
                out[child.HyperstatElement] = child
    return out


def clear_classes(skeleton) -> None:
    """Remove the class spheres and their callouts (the markers stay)."""
    doc = skeleton.Document
    for sphere in class_spheres(skeleton).values():
        doc.removeObject(sphere.Name)
    for label in callout_labels(skeleton).values():
        doc.removeObject(label.Name)


def callout_labels(skeleton) -> dict:
    """The callouts (tolerance ids) of the markers, keyed by their joints (``"11,21,41"`` for a shared point)."""
    return {o.HyperstatElement: o for o in skeleton.Group if getattr(o, "HyperstatRole", "") == "callout"}


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
    """Add a sphere in its class colour to every element's marker, and the callouts; return elements without a marker.

    Each joint takes the most severe tolerance class of its defects (the colours of the report
    and the pictures).  Where several joints share a point (e.g. joints 11, 21 and 41 of the
    Tripteor), their spheres are spread on a small ring around it (:func:`coincident_offsets`).
    Every marker is called out with its joint and tolerance ids, the rows of the report's
    tolerance table (``41: T1, T20``); joints that share a point share one callout, one line each.
    """
    import FreeCAD
    import Part

    clear_classes(skeleton)
    doc = skeleton.Document
    parts = markers(skeleton)
    size = float(skeleton.MarkerSize.Value or 1.0)
    radius = SPHERE_SCALE * size
    missing = []
    classes, ids = element_classes(analysis)
    placed = {}
    for element in sorted(classes):
        part = parts.get(f"m_{element}")
        if part is None:
            missing.append(element)
            continue
        placed[element] = part
    centres = {e: tuple(p.getGlobalPlacement().Base) for e, p in placed.items()}
    offsets = coincident_offsets(centres, radius, 1e-6 * max(size, 1.0))
    for element, part in placed.items():
        cls = classes[element]
        color = CLASS_RGB[cls]
        sphere = doc.addObject("Part::Feature", "ClassMarker")
        sphere.Shape = Part.makeSphere(radius)
        offset = FreeCAD.Vector(*offsets[element])
        if offset.Length > 0:
            local = part.getGlobalPlacement().Rotation.inverted().multVec(offset)
            sphere.Placement = FreeCAD.Placement(local, FreeCAD.Rotation())
        sphere.Label = f"class_{element}"
        _tag(sphere, "HyperstatRole", "class", "What this object is for hyperstat")
        _tag(sphere, "HyperstatElement", element, "Element (joint or fixed transform) of this marker")
        _tag(sphere, "HyperstatClass", cls, "Most severe tolerance class of the element's defect parameters")
        sphere.addProperty("App::PropertyColor", "HyperstatColor", "Hyperstat", "Colour of the class")
        sphere.HyperstatColor = color
        sphere.setEditorMode("HyperstatColor", 1)
        part.addObject(sphere)
        if FreeCAD.GuiUp and sphere.ViewObject is not None:
            sphere.ViewObject.ShapeColor = color
    _callouts(skeleton, centres, offsets, ids, radius)
    if missing:
        FreeCAD.Console.PrintWarning(f"hyperstat: no marker found for element(s) {', '.join(missing)}.\n")
    return missing


def _callouts(skeleton, centres: dict, offsets: dict, ids: dict, radius: float) -> None:
    """One text callout per marker point, one line per joint there (``"21: T13, T15-T19"``), above its sphere."""
    import FreeCAD

    doc = skeleton.Document
    groups: dict[tuple, list[str]] = {}
    for element in offsets:
        groups.setdefault(tuple(round(c, 6) for c in centres[element]), []).append(element)
    middle = FreeCAD.Vector(*[sum(p[i] for p in groups) / max(len(groups), 1) for i in range(3)])
    for members in groups.values():
        members.sort()
        ring = max(max(sum(c * c for c in offsets[m]) ** 0.5 for m in members), radius)
        centre = FreeCAD.Vector(*centres[members[0]])
        away = centre - middle  # outwards from the middle of the skeleton, so that neighbours' callouts part
        away = away.normalize() if away.Length > 1e-9 else FreeCAD.Vector(1, 0, 0)
        label = doc.addObject("App::Annotation", "Callout")
        label.LabelText = [callout_text(e, ids.get(e, [])) for e in members]
        label.Position = centre + away * (2.0 * ring) + FreeCAD.Vector(0, 0, ring)
        _tag(label, "HyperstatRole", "callout", "What this object is for hyperstat")
        _tag(label, "HyperstatElement", ",".join(members), "Joints at this point")
        skeleton.addObject(label)  # a plain group: the position stays global


def frame_labels(skeleton) -> dict:
    """The labels of the part drawings' frames and datums in the 3D view, keyed by feature id."""
    return {o.HyperstatElement: o for o in skeleton.Group if getattr(o, "HyperstatRole", "") == "frames"}


def clear_frame_labels(skeleton) -> None:
    """Remove the part drawings' labels."""
    doc = skeleton.Document
    for label in frame_labels(skeleton).values():
        doc.removeObject(label.Name)


def label_frames(skeleton, drawings: list) -> int:
    """Label every feature that carries a frame or a datum in the 3D view, at the feature (mm, base frame at home):
    the part and the feature, its datum letter, its frames as drawn (``rod-F2 |//|0.024|A|``).  Returns how many.

    The labels start hidden (the Tripteor has about sixty: all at once they would bury the skeleton); selecting
    frames or datums in the Results panel's *Part drawings* tab shows theirs (:func:`show_frame_labels`).  The
    labels of features at one point (a joint's bore on one part, its journal on the next) are stacked a line
    apart, so that none hides another.
    """
    import FreeCAD

    from .drawings import feature_labels

    clear_frame_labels(skeleton)
    doc = skeleton.Document
    size = float(skeleton.MarkerSize.Value or 1.0)
    taken: dict = {}
    labels = feature_labels(drawings)
    for entry in labels:
        key = tuple(round(c, 6) for c in entry["point"])
        above = taken.get(key, 0)
        taken[key] = above + len(entry["lines"]) + 1
        label = doc.addObject("App::Annotation", "FrameLabel")
        label.LabelText = entry["lines"]
        label.Position = FreeCAD.Vector(*entry["point"]) + FreeCAD.Vector(0, 0, -0.35 * size * (above + 1))
        label.Label = f"frames {entry['feature']}"
        _tag(label, "HyperstatRole", "frames", "What this object is for hyperstat")
        _tag(label, "HyperstatElement", entry["feature"], "Feature of a part drawing (report.json's drawings)")
        skeleton.addObject(label)  # a plain group: the position stays global
        if FreeCAD.GuiUp and label.ViewObject is not None:
            label.ViewObject.TextColor = (0.1, 0.1, 0.45)
            label.ViewObject.FontSize = 11
        label.Visibility = False
    return len(labels)


def show_frame_labels(skeleton, features: set) -> list:
    """Show the labels of ``features`` (feature ids), hide the others; returns the labels shown."""
    shown = []
    for fid, label in frame_labels(skeleton).items():
        label.Visibility = fid in features
        if fid in features:
            shown.append(label)
    return shown
