"""Off-screen pyvista pictures of a skeleton: links, marker triads, verdict colours.

Units: lengths in mm, angles in rad.

The picture is drawn from the solver model at its home configuration, so every
source (template, model file, STEP file) gives the same view: each chain as a tube
through its frame origins, a small x/y/z triad (red, green, blue) at every joint
frame ``L_i`` and fixed transform, a larger triad at every configuration frame, and,
when an analysis is given, a sphere at each joint frame coloured by the most severe
verdict among its defects (:data:`hyperstat.cad_plugin.assembly.VERDICT_COLORS`), with a legend.
Spheres are drawn unlit so that their colour reaches the image unshaded.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from hyperstat.solver.atomic import write_bytes
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism

from hyperstat.cad_plugin.assembly import AXIS_COLORS, VERDICT_COLORS, element_verdicts

__all__ = ["render_png", "VIEWS", "LEGEND_LABELS", "CLASS_COLORS", "element_classes"]

VIEWS = ("iso", "front", "side", "top")
LEGEND_LABELS = {
    "forced": "forced by over-constraint",
    "coupled": "coupled (relation)",
    "free-influential": "free, influential",
    "free-non-influent": "free, non-influent",
    "none": "no defect / gauge only",
}
#: tolerance class -> marker colour (the vocabulary of hyperstat.solver.tolerances.classification)
CLASS_COLORS = {
    "assembly": (0.85, 0.1, 0.6),  # magenta
    "accuracy-critical": (0.78, 0.16, 0.16),  # red
    "compensable": (0.0, 0.7, 0.8),  # cyan
    "non-influent": (0.55, 0.55, 0.55),  # grey
    "none": (0.95, 0.95, 0.95),  # no tolerance (normalisation components only, or no defect)
}
_CLASS_LABELS = {"assembly": "assembly condition", "accuracy-critical": "accuracy-critical", "compensable": "compensable",
                 "non-influent": "non-influent", "none": "no tolerance"}


def element_classes(analysis: dict | None) -> tuple[dict, dict]:
    """Most severe tolerance class per element and the tolerance ids of each element.

    Reads the ``tolerances`` object of ``hyperstat analyze --json`` (``parameters[name]["class"]``
    and ``["tolerance_ids"]``) and the elements of its ``parameters`` list.

    >>> a = {"parameters": [{"name": "dc2", "element": "2"}, {"name": "dK2", "element": "2"}],
    ...      "tolerances": {"parameters": {"dc2": {"class": "assembly", "tolerance_ids": ["T5"]},
    ...                                    "dK2": {"class": "normalisation", "tolerance_ids": []}}}}
    >>> element_classes(a)
    ({'2': 'assembly'}, {'2': ['T5']})
    """
    order = ["assembly", "accuracy-critical", "compensable", "non-influent", "none"]
    classes: dict = {}
    ids: dict = {}
    tol = (analysis or {}).get("tolerances") or {}
    entries = tol.get("parameters", {})
    for p in (analysis or {}).get("parameters", []):
        e = entries.get(p["name"])
        if e is None:
            continue
        cls = e["class"] if e["class"] in order else "none"
        el = p["element"]
        if el not in classes or order.index(cls) < order.index(classes[el]):
            classes[el] = cls
        for t in e.get("tolerance_ids") or ([e["tolerance_id"]] if e.get("tolerance_id") else []):
            if t not in ids.setdefault(el, []):
                ids[el].append(t)
    return classes, ids


def _callout(name: str, ids: list) -> str:
    """``"21: T13, T15-T19"``: the joint and its tolerance ids, consecutive ids as ranges.

    >>> _callout("21", ["T17", "T13", "T15", "T16", "T18", "T19"])
    '21: T13, T15-T19'
    """
    nums = sorted(int(t[1:]) for t in ids if t[1:].isdigit())
    if not nums:
        return name
    runs, start = [], nums[0]
    for a, b in zip(nums, nums[1:] + [None]):
        if b != a + 1:
            runs.append(f"T{start}" if start == a else f"T{start}-T{a}")
            start = b
    return f"{name}: " + ", ".join(runs)


def _quiet_vtk() -> None:
    """Keep VTK's own log (e.g. "bad X server connection" before it falls back to off-screen
    rendering, with terminal colour codes) off the user's terminal; VTK errors still show."""
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)


def _scene_meshes(mech: Mechanism, verdicts: dict, size: float, colors: dict | None = None,
                  callouts: dict | None = None) -> tuple[list, list, list]:
    """The scene's geometry, built once for all views: ``(mesh, options)`` pairs merged by colour
    (one actor per colour instead of one per arrow: the views render several times faster),
    and the label points and names of the joint frames."""
    import pyvista as pv

    kin = Kinematics(mech)
    st = kin.evaluate(mech.home[None, :], jacobians=False)
    frames = {k: v[0] for k, v in st.frames.items()}
    elems = {k: v[0] for k, v in st.element_frames.items()}
    tubes = []
    for ci, chain in enumerate(mech.chains):
        pts = [frames[chain.start][:3, 3]] + [elems[(ci, ei)][:3, 3] for ei in range(len(chain.elements))]
        pts.append(frames[chain.end][:3, 3])
        pts = np.array(pts)
        keep = np.r_[True, np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9]
        pts = pts[keep]
        if len(pts) > 1:
            tubes.append(pv.lines_from_points(pts).tube(radius=0.08 * size))
    arrows = {a: [] for a in "xyz"}

    def triad(t: np.ndarray, scale: float) -> None:
        for i, a in enumerate("xyz"):
            arrows[a].append(pv.Arrow(start=t[:3, 3], direction=t[:3, i], scale=scale * size, tip_radius=0.12,
                                      shaft_radius=0.04))

    balls: dict[str, list] = {}
    names, points = [], []
    for ci, chain in enumerate(mech.chains):
        for ei, el in enumerate(chain.elements):
            if el.kind == "frame":
                continue
            t = elems[(ci, ei)]
            triad(t, 1.0)
            if verdicts:
                color = (colors or VERDICT_COLORS)[verdicts.get(el.name) or "none"]
                # off the origin along the joint axis, so that frames sharing a point stay apart
                balls.setdefault(color, []).append(pv.Sphere(radius=0.2 * size,
                                                             center=t[:3, 3] + 0.45 * size * t[:3, 2]))
            names.append(_callout(el.name, (callouts or {}).get(el.name, [])) if callouts is not None else el.name)
            points.append(t[:3, 3] + 0.3 * size * np.array([1.0, 1.0, 1.0]))
    for t in frames.values():
        triad(t, 1.6)
    meshes = []
    if tubes:
        meshes.append((pv.merge(tubes), {"color": (0.62, 0.62, 0.66), "smooth_shading": True}))
    meshes += [(pv.merge(m), {"color": AXIS_COLORS[a]}) for a, m in arrows.items() if m]
    meshes += [(pv.merge(m), {"color": c, "lighting": False}) for c, m in balls.items()]
    if callouts is not None:  # frames sharing a point (a U joint, a spherical joint) get one callout, not stacked ones
        merged: dict = {}
        for pt, name in zip(points, names):
            merged.setdefault(tuple(np.round(pt / max(size, 1e-9), 3)), [pt, []])[1].append(name)
        points = [v[0] for v in merged.values()]
        names = ["\n".join(v[1]) for v in merged.values()]
    return meshes, points, names


def _scene(plotter, meshes: list, points: list, names: list, label: bool) -> None:
    for mesh, options in meshes:
        plotter.add_mesh(mesh, **options)
    if label and points:
        plotter.add_point_labels(np.array(points), names, font_size=11, point_size=1, shape_opacity=0.0,
                                 text_color="black", show_points=False, always_visible=True)


def render_png(
    mech: Mechanism,
    path: str | os.PathLike,
    analysis: dict | None = None,
    marker_size: float | None = None,
    window_size: tuple[int, int] = (1600, 1200),
    title: str | None = None,
    views: tuple[str, ...] = VIEWS,
) -> Path:
    """Render ``mech`` at home in several views (one PNG, atomically written).

    Parameters
    ----------
    mech : Mechanism
        The model to draw.
    path : path-like
        Output PNG.
    analysis : dict, optional
        ``hyperstat analyze --json`` output; colours the joint markers by verdict.
    marker_size : float, optional
        Triad length in mm; defaults to 12 % of the mechanism's length scale.
    window_size : tuple of int
        Image size in pixels.
    title : str, optional
        Text at the top; defaults to the mechanism name.
    views : tuple of str
        Any of ``"iso"``, ``"front"`` (x-z), ``"side"`` (y-z), ``"top"`` (x-y).

    Returns
    -------
    Path
    """
    import pyvista as pv

    _quiet_vtk()
    pv.OFF_SCREEN = True
    classes, callouts = element_classes(analysis)
    if classes:  # tolerance classes and numbered callouts (the report's vocabulary)
        verdicts, colors, labels = classes, CLASS_COLORS, _CLASS_LABELS
    else:
        verdicts, colors, labels, callouts = element_verdicts(analysis), VERDICT_COLORS, LEGEND_LABELS, None
    size = marker_size or 0.12 * Kinematics(mech).length_scale
    n = len(views)
    shape = (1, 1) if n == 1 else (2, 2) if n <= 4 else (2, (n + 1) // 2)
    plotter = pv.Plotter(off_screen=True, shape=shape, window_size=list(window_size), border=False)
    meshes, points, names = _scene_meshes(mech, verdicts, size, colors, callouts)
    for k, view in enumerate(views):
        plotter.subplot(k // shape[1], k % shape[1])
        plotter.set_background("white")
        _scene(plotter, meshes, points, names, label=(view == "iso"))
        plotter.add_text(view if k else (title or mech.name) + "  (iso)", font_size=12, color="black")
        if view == "iso":
            plotter.view_isometric()
        elif view == "front":
            plotter.view_xz()
        elif view == "side":
            plotter.view_yz()
        elif view == "top":
            plotter.view_xy()
        plotter.reset_camera()
        plotter.camera.zoom(1.1)
        if k == 0 and verdicts:
            used = [c for c in colors if c in set(verdicts.values())]
            plotter.add_legend([[labels[c], colors[c]] for c in used], bcolor="white",
                               size=(0.45, 0.055 * len(used) + 0.03), loc="lower left", face="circle")
    img = plotter.screenshot(return_img=True)
    plotter.close()
    from PIL import Image
    import io

    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG", optimize=True)
    return write_bytes(path, buf.getvalue())
