"""Off-screen pyvista views of a skeleton for paper: declared links, joints, markers coloured by tolerance class.

Units: lengths in mm, angles in rad.

The picture is drawn from the solver model at its home configuration, so every source
(template, model file, STEP file) gives the same view:

* the links the template declares (``metadata["links"]``: base, platform, legs, each a tube
  through its points with its bar radius; the kinematic chains only for a model that declares
  none), base and platform links in darker greys than the others;
* every joint as a short barrel along its axis (a cylinder for a revolute joint, a square
  prism for a prismatic one) and every configuration frame as an x/y/z triad (red, green,
  blue);
* with an analysis, a sphere at each joint coloured by the most severe tolerance class of its
  parameters (the colours of :mod:`hyperstat.cad_plugin.palette`, the same as the report's and
  FreeCAD's), drawn unlit so that its colour reaches the image unshaded.

:func:`render_views` renders four orthographic (parallel-projection) views from directions
chosen by :func:`choose_views`: for a planar mechanism the three views of a frame whose cube
diagonal is the plane's normal (each sees the plane at 35.3 degrees, none edge-on) plus the
view along that diagonal, the true shape; otherwise front, side and top plus the isometric
view.  It returns the images and, per view, where every joint lands in the image, so that
:mod:`hyperstat.cad_plugin.drawing` can lay out the numbered callouts and feature control
frames as vector text (legible at 8 pt when printed on A4).  :func:`render_png` does both and
writes one PNG.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path

import numpy as np

from hyperstat.solver.atomic import write_bytes, write_text, dumps_json
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism

from hyperstat.cad_plugin.assembly import AXIS_COLORS
from hyperstat.cad_plugin.palette import CLASS_RGB, element_classes

__all__ = ["render_png", "render_views", "choose_views", "scene_of", "LINK_COLORS", "PLANAR_RATIO", "words_path",
           "write_record"]

#: link colours: base and platform links darker than the legs (neutral greys: the colours belong to the classes)
LINK_COLORS = {"base": (0.27, 0.35, 0.39), "platform": (0.38, 0.49, 0.55), "other": (0.62, 0.62, 0.64)}
#: a mechanism is planar when its points' smallest principal extent is below this share of the largest
PLANAR_RATIO = 0.02
#: share of a view's width left free on one side for the callouts, and of its height kept as a border
CALLOUT_MARGIN, BORDER = 0.30, 0.06


def _quiet_vtk() -> None:
    """Keep VTK's own log (e.g. "bad X server connection" before it falls back to off-screen
    rendering, with terminal colour codes) off the user's terminal; VTK errors still show."""
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)


def _link_kind(name: str) -> str:
    low = name.lower()
    return "base" if low.startswith("base") else "platform" if low.startswith("platform") else "other"


def scene_of(mech: Mechanism, marker_size: float | None = None) -> dict:
    """Everything the views draw, in world coordinates at home (mm).

    Returns
    -------
    dict
        ``links`` (name, kind, points, radius), ``joints`` (element, type, origin, axis,
        frame), ``frames`` (name, 4x4 pose), ``size`` (marker size, mm) and ``declared``
        (whether the links are the template's).
    """
    kin = Kinematics(mech)
    st = kin.evaluate(mech.home[None, :], jacobians=False)
    frames = {k: np.asarray(v[0]) for k, v in st.frames.items()}
    elems = {k: np.asarray(v[0]) for k, v in st.element_frames.items()}
    size = float(marker_size or 0.12 * kin.length_scale)
    declared = (mech.metadata or {}).get("links") or []
    if declared:
        links = [{"name": str(d["name"]), "kind": _link_kind(str(d["name"])), "radius": float(d.get("radius", 0.0)),
                  "points": np.asarray(d["points"], float)} for d in declared]
    else:  # a model without declared links: the chains through their frame origins
        links = []
        for ci, chain in enumerate(mech.chains):
            pts = [frames[chain.start][:3, 3]] + [elems[(ci, ei)][:3, 3] for ei in range(len(chain.elements))]
            links.append({"name": chain.name, "kind": "other", "radius": 0.0,
                          "points": np.asarray(pts + [frames[chain.end][:3, 3]])})
    joints = []
    for ci, chain in enumerate(mech.chains):
        for ei, el in enumerate(chain.elements):
            if el.kind == "frame":
                continue
            t = elems[(ci, ei)]
            joints.append({"element": el.name, "type": getattr(el, "type", "F"), "origin": t[:3, 3].copy(),
                           "axis": t[:3, 2].copy(), "frame": t})
    return {"links": links, "joints": joints, "frames": frames, "size": size, "declared": bool(declared)}


def _points(scene: dict) -> np.ndarray:
    pts = [j["origin"] for j in scene["joints"]] + [t[:3, 3] for t in scene["frames"].values()]
    pts += [p for link in scene["links"] for p in link["points"]]
    return np.asarray(pts, float)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def choose_views(points: np.ndarray) -> list[dict]:
    """Four view directions (from the scene towards the camera) and up vectors; none edge-on to a plane.

    A mechanism whose points lie in a plane (smallest principal extent below
    :data:`PLANAR_RATIO` of the largest) is drawn from the three axes of a frame whose cube
    diagonal is the plane's normal: each of these orthographic views sees the plane at
    ``asin(1/sqrt(3)) = 35.3`` degrees, and the fourth view, along the diagonal, shows its true
    shape.  Otherwise: front (from -y), side (from +x), top (from +z) and the isometric view.

    >>> square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    >>> [round(abs(float(v["direction"] @ [0, 0, 1])), 3) for v in choose_views(square)]
    [1.0, 0.577, 0.577, 0.577]
    """
    centred = points - points.mean(axis=0)
    _, s, vt = np.linalg.svd(centred, full_matrices=True)
    s = np.r_[s, np.zeros(3 - len(s))]
    if s[0] > 0 and s[2] < PLANAR_RATIO * s[0]:
        normal = vt[2] * (1.0 if vt[2] @ [0.1, 0.2, 1.0] >= 0 else -1.0)  # look from the side of world +z
        major = vt[0] - (vt[0] @ normal) * normal
        # in-plane axes: world x (or the major axis) and the normal's cross product with it
        world_x = np.array([1.0, 0.0, 0.0]) - normal[0] * normal
        b1 = _unit(world_x if np.linalg.norm(world_x) > 0.5 else major)
        b2 = np.cross(normal, b1)
        views = [{"name": "true shape", "label": "true shape (normal to the plane)", "direction": normal, "up": b2}]
        for k, name in enumerate(("A", "B", "C")):
            theta = -math.pi / 2 + 2 * math.pi * k / 3
            d = _unit(math.sqrt(2 / 3) * (math.cos(theta) * b1 + math.sin(theta) * b2) + normal / math.sqrt(3))
            right = _unit(b1 - (b1 @ d) * d)  # the plane's first axis stays horizontal in every view
            views.append({"name": f"view {name}", "label": f"view {name} (35\u00b0 to the plane)", "direction": d,
                          "up": np.cross(d, right)})
        return views
    z = np.array([0.0, 0.0, 1.0])
    return [{"name": "iso", "label": "isometric", "direction": _unit([1.0, -1.0, 1.0]), "up": z},
            {"name": "front", "label": "front (from \u2212y)", "direction": np.array([0.0, -1.0, 0.0]), "up": z},
            {"name": "side", "label": "side (from +x)", "direction": np.array([1.0, 0.0, 0.0]), "up": z},
            {"name": "top", "label": "top (from +z)", "direction": z, "up": np.array([0.0, 1.0, 0.0])}]


def _meshes(scene: dict, classes: dict) -> tuple[list, dict]:
    """``(mesh, options)`` pairs merged by colour (one actor per colour), and each joint's callout point."""
    import pyvista as pv

    size = scene["size"]
    by_color: dict = {}

    def add(color, mesh, **options):
        by_color.setdefault((tuple(color), tuple(sorted(options.items()))), []).append(mesh)

    for link in scene["links"]:
        pts = link["points"]
        keep = np.r_[True, np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9]
        pts = pts[keep]
        if len(pts) > 1:
            radius = max(link["radius"], 0.05 * size) if scene["declared"] else 0.06 * size
            add(LINK_COLORS[link["kind"]], pv.lines_from_points(pts).tube(radius=radius, n_sides=16))
    anchors = {}
    for j in scene["joints"]:
        o, z = j["origin"], _unit(j["axis"])
        if j["type"] == "R":
            add((0.22, 0.22, 0.26), pv.Cylinder(center=o, direction=z, radius=0.14 * size, height=0.6 * size))
        elif j["type"] == "P":
            add((0.22, 0.22, 0.26), pv.Cylinder(center=o + 0.45 * size * z, direction=z, radius=0.2 * size,
                                                height=0.9 * size, resolution=4))
        centre = o + 0.45 * size * z  # off the origin along the axis: joints sharing a point stay apart
        anchors[j["element"]] = centre
        if j["element"] in classes:
            add(CLASS_RGB[classes[j["element"]]], pv.Sphere(radius=0.28 * size, center=centre), lighting=False)
    for t in scene["frames"].values():
        for i, a in enumerate("xyz"):
            add(AXIS_COLORS[a], pv.Arrow(start=t[:3, 3], direction=t[:3, i], scale=1.2 * size, tip_radius=0.12,
                                         shaft_radius=0.04))
    meshes = [(pv.merge(ms), {"color": color, **dict(options)}) for (color, options), ms in by_color.items()]
    return meshes, anchors


def _camera(points: np.ndarray, direction: np.ndarray, up: np.ndarray, width: int, height: int,
            side: str) -> dict:
    """A parallel-projection camera framing ``points``, a free margin on ``side`` for the callouts."""
    d = _unit(direction)
    up = _unit(up - (up @ d) * d)
    right = np.cross(up, d)
    centre = points.mean(axis=0)
    xs, ys = (points - centre) @ right, (points - centre) @ up
    free_w = (1.0 - CALLOUT_MARGIN - 2 * BORDER) * width
    free_h = (1.0 - 2 * BORDER) * height
    extent_x, extent_y = max(float(np.ptp(xs)), 1e-9), max(float(np.ptp(ys)), 1e-9)
    scale = max(extent_x * height / free_w, extent_y * height / free_h) / 2.0  # world half-height
    mid_x, mid_y = 0.5 * (xs.max() + xs.min()), 0.5 * (ys.max() + ys.min())
    # shift the framed centre away from the callout side
    shift_px = (CALLOUT_MARGIN / 2) * width * (1 if side == "left" else -1)
    mid_x -= shift_px * (2 * scale / height)
    focal = centre + mid_x * right + mid_y * up
    return {"focal": focal, "direction": d, "up": up, "right": right, "scale": scale, "width": width,
            "height": height}


def _project(camera: dict, point: np.ndarray) -> list[float]:
    """Pixel (x right, y down) of a world point in a view of :func:`_camera`."""
    rel = np.asarray(point, float) - camera["focal"]
    k = 0.5 * camera["height"] / camera["scale"]
    return [float(0.5 * camera["width"] + k * (rel @ camera["right"])),
            float(0.5 * camera["height"] - k * (rel @ camera["up"]))]


def _tile_height(points: np.ndarray, views: list, width: int, largest: int) -> int:
    """The views' common height (px): as tall as the tallest view needs at ``width``, from half to all of ``largest``."""
    free_w = (1.0 - CALLOUT_MARGIN - 2 * BORDER) * width
    need = 0.0
    for view in views:
        d = _unit(view["direction"])
        up = _unit(view["up"] - (view["up"] @ d) * d)
        right = np.cross(up, d)
        extent_x = max(float(np.ptp(points @ right)), 1e-9)
        need = max(need, float(np.ptp(points @ up)) / extent_x * free_w / (1.0 - 2 * BORDER))
    return int(min(max(need, 0.5 * largest), largest)) // 2 * 2


def render_views(mech: Mechanism, analysis: dict | None = None, tile: tuple[int, int] = (900, 900),
                 marker_size: float | None = None) -> dict:
    """Render the four views of :func:`choose_views`; JSON-ready (PNG bytes, pixels).

    Returns
    -------
    dict
        ``views``: per view ``name``, ``label``, ``png`` (bytes), ``size`` (px), ``side`` (where
        its callouts go) and ``anchors`` (element -> pixel of its sphere); ``classes`` (element ->
        tolerance class) and ``ids`` (element -> tolerance ids) of the analysis; ``links``
        (names of the links drawn, or an empty list when the chains stand in for them).
    """
    import pyvista as pv
    from PIL import Image

    _quiet_vtk()
    pv.OFF_SCREEN = True
    classes, ids = element_classes(analysis)
    scene = scene_of(mech, marker_size)
    meshes, anchors = _meshes(scene, classes)
    pts = np.vstack([_points(scene), np.array(list(anchors.values()) or np.zeros((0, 3)))])
    width = tile[0]
    views = choose_views(_points(scene))
    height = _tile_height(pts, views, width, tile[1])
    plotter = pv.Plotter(off_screen=True, window_size=[width, height], border=False)
    plotter.set_background("white")
    for mesh, options in meshes:
        plotter.add_mesh(mesh, smooth_shading=True, **options)
    plotter.enable_parallel_projection()
    out = []
    for k, view in enumerate(views):
        side = "left" if k % 2 == 0 else "right"
        cam = _camera(pts, view["direction"], view["up"], width, height, side)
        distance = 10.0 * max(cam["scale"], 1.0)
        plotter.camera.focal_point = tuple(cam["focal"])
        plotter.camera.position = tuple(cam["focal"] + distance * cam["direction"])
        plotter.camera.up = tuple(cam["up"])
        plotter.camera.parallel_scale = cam["scale"]
        plotter.camera.clipping_range = (1e-3 * distance, 2.0 * distance + 10 * cam["scale"])
        # the camera is set before the first render, so pyvista does not frame its own there (it resets only a camera
        # not set): no render is thrown away (the same pixels as with one, 0.03-0.08 s of CPU less per report)
        plotter.render()
        img = plotter.screenshot(return_img=True)
        buf = io.BytesIO()
        # the fastest zlib level: these PNGs only carry the pixels to skeleton_figure (lossless at any level, the same
        # pixels); optimize=True took 0.14 s of CPU for the four 900 px views, level 1 0.04 s (about 2.4x the bytes)
        Image.fromarray(img).save(buf, format="PNG", compress_level=1)
        out.append({"name": view["name"], "label": view["label"], "png": buf.getvalue(), "size": [width, height],
                    "side": side, "direction": [float(c) for c in cam["direction"]],
                    "anchors": {e: _project(cam, p) for e, p in anchors.items()}})
    plotter.close()
    elements_of = {str(p["name"]): str(p["element"]) for p in (analysis or {}).get("parameters", [])}
    kinds = {link["kind"] for link in scene["links"]}
    link_colors = [[k, list(LINK_COLORS[k])] for k in ("base", "platform", "other") if k in kinds]
    return {"views": out, "classes": classes, "ids": ids, "elements_of": elements_of, "link_colors": link_colors,
            "links": [link["name"] for link in scene["links"]] if scene["declared"] else []}


def words_path(png: str | os.PathLike) -> Path:
    """The record of the words a picture shows: ``name.png`` -> ``name.png.json``."""
    png = Path(png)
    return png.with_name(png.name + ".json")


def write_record(png: str | os.PathLike, command: str, words: dict) -> Path:
    """Write the record of a committed picture: the command that drew it, its SHA-256 and the words it shows.

    ``tests/test_docs_images.py`` reads these records (``make images`` writes them).
    """
    import hashlib

    record = {"title": "", "classes": [], "legend": [], "callouts": [], "views": [], "frames": [], **words,
              "format": "hyperstat-picture-words", "command": command,
              "png_sha256": hashlib.sha256(Path(png).read_bytes()).hexdigest()}
    return write_text(words_path(png), dumps_json(record))


def render_png(mech: Mechanism, path: str | os.PathLike, analysis: dict | None = None,
               marker_size: float | None = None, width_px: int = 1600, title: str | None = None,
               words: str | os.PathLike | None = None) -> Path:
    """The skeleton picture as one PNG (atomically written): four views, callouts, frames, legend.

    Parameters
    ----------
    mech : Mechanism
        The model to draw.
    path : path-like
        Output PNG.
    analysis : dict, optional
        ``hyperstat analyze --json`` output (or the report's): colours the joints by tolerance
        class, calls out their tolerance ids and draws the feature control frames of its
        tolerance items.
    marker_size : float, optional
        Joint barrel length scale in mm; defaults to 12 % of the mechanism's length scale.
    width_px : int
        Width of the picture in pixels (its height follows the A4 layout).
    title : str, optional
        Heading; defaults to the mechanism name.
    words : path-like, optional
        Also write the words the picture shows (legend, view names, callouts) as JSON there.

    Returns
    -------
    Path
    """
    from hyperstat.cad_plugin.drawing import figure_png, skeleton_figure

    rendered = render_views(mech, analysis, marker_size=marker_size)
    items = ((analysis or {}).get("tolerances") or {}).get("items") or []
    fig, drawn = skeleton_figure(rendered, items, title or mech.name)
    out = write_bytes(path, figure_png(fig, width_px))
    if words is not None:
        write_text(words, dumps_json(drawn))
    return out
