"""The part drawings of the report: one A4 page per part, drawn from the part's solid, with its frames and datums.

Units: lengths and zones in mm (the drawing's frame: the world frame at the home configuration); the page in
mm and type in pt (8 pt everywhere on the drawing: :data:`hyperstat.cad_plugin.drawing.FONT_PT`).

Each entry of ``report.json``'s ``drawings`` (``docs/drawing-format.md``) becomes a page: two orthographic
views of the part's solid (:func:`hyperstat.cad_plugin.part_solids.part_solid`; visible edges solid, hidden
edges dashed, from OCCT's hidden-line removal) at an ISO 5455 scale, the datum feature symbols of ISO 5459
(a filled triangle on the datum feature, a square with its letter), the feature control frames of ISO 1101
(characteristic symbol drawn from :mod:`hyperstat.cad_plugin.gdt`, ``⌀`` for a cylindrical zone, the datum
system in order of precedence, and the intersection / orientation plane indicator that states a planar
zone's direction) with a leader to their feature, then the table of the part's datums and frames in words
(feature and length, zone shape and direction, datum system, theoretically exact dimensions, the value's
kind: without or with calibration, the note).  :func:`part_pages` draws every page, :func:`parts_html` and
:func:`parts_markdown` lay them out.
"""

from __future__ import annotations

import html
import re
from functools import lru_cache

import numpy as np

from hyperstat.cad_plugin.drawing import FONT_PT, WIDTH_MM
from hyperstat.cad_plugin.gdt import sheet_symbol
from hyperstat.cad_plugin.svg_sheet import SvgSheet

__all__ = ["part_pages", "page_key", "drawing_code_version", "parts_html", "parts_markdown", "frame_cells", "zone_words", "ISO_SCALES", "view_axes",
           "PARTS_CSS", "prebuild", "geometry_key"]

#: drawing scales of ISO 5455 (paper mm per part mm), largest first
ISO_SCALES = (5.0, 2.0, 1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01)
_FAMILY = "DejaVu Sans"
_VIEWS_MM = 108.0  # width of the views' column
_GAP_MM = 6.0  # between a view and the band of the next (more where the view's datum symbols reach lower)
#: a datum feature symbol (ISO 5459), mm on the page: the triangle's length and half base, the stem's end, the square
_DATUM_TRIANGLE, _DATUM_HALF_BASE, _DATUM_STEM, _DATUM_BOX = 2.0, 1.2, 6.0, 4.6
_LABEL_TOP_MM = 1.3  # a view's label reaches this far below its band's top (8 pt centred 3 mm down)
_BAND_MM = 16.0  # above a view: its label and room for the datum symbols that stand out of it
_LINE = 1.28 * FONT_PT  # pt
_ROW = 1.55 * FONT_PT  # height of a frame's row, pt
_PT = 25.4 / 72.0  # mm per pt
_PAGE_MM = 273.0  # A4's height less the report's 12 mm margins
PARTS_CSS = """
section.part-page { break-before: page; page-break-before: always; }
section.part-page h3 { margin-top: 0; } table.part { font-size: .8em; width: 100%; }
table.part td { padding: 0 .25em; } .ted { border: 1px solid #111; padding: 0 .2em; }
ol.part-notes { font-size: .8em; margin: .2em 0; padding-left: 1.5em; }
@media print { section.part-page { font-size: 8pt; }
  table.part, ol.part-notes, section.part-page .note { font-size: 8pt; }
  section.part-page figure { margin: 0; } }
"""


@lru_cache(maxsize=None)
def _advance_pt(char: str) -> float:
    """The advance of one character of DejaVu Sans at 8 pt (pt), from the font file (FreeType, via matplotlib)."""
    font = _font()
    glyph = font.load_char(ord(char)) if font.get_char_index(ord(char)) else font.load_char(ord("M"))
    return glyph.linearHoriAdvance / 65536.0


@lru_cache(maxsize=1)
def _font():
    from matplotlib import font_manager, ft2font

    font = ft2font.FT2Font(font_manager.findfont(font_manager.FontProperties(family=_FAMILY)))
    font.set_size(FONT_PT, 72)
    return font


def text_width_pt(text: str) -> float:
    """Width of ``text`` at 8 pt (pt): the sum of its characters' advances, as a browser sets it (no kerning)."""
    return sum(_advance_pt(c) for c in text)


def _scale_text(s: float) -> str:
    return f"{s:g}:1" if s >= 1 else f"1:{1 / s:g}"


def _dominant(directions: list[np.ndarray]) -> np.ndarray | None:
    """The direction (up to sign) shared by most of ``directions``."""
    best, count = None, 0
    for d in directions:
        n = sum(abs(float(d @ e)) > 0.999 for e in directions)
        if n > count:
            best, count = d, n
    return best


def view_axes(features: list[dict]) -> list[dict]:
    """Two orthographic views of a part: along its dominant axis, and across it showing the axes' lengths.

    Each view is ``{"toward", "right", "up"}``: unit vectors of the drawing's frame (the eye looks along
    ``-toward``).  The first view looks along the direction most axes share (bores appear as circles), the
    second across it, so that the part's longest extent runs left to right in both.

    >>> v = view_axes([{"kind": "axis", "point_mm": [0, 0, 0], "direction": [0, 1, 0]},
    ...                {"kind": "axis", "point_mm": [100, 0, 0], "direction": [0, 1, 0]}])
    >>> [(np.round(x["toward"], 6) + 0.0).tolist() for x in v], (np.round(v[1]["up"], 6) + 0.0).tolist()
    ([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0, 1.0, 0.0])
    """
    axes = [np.asarray(f["direction"], float) / np.linalg.norm(f["direction"]) for f in features
            if f.get("kind") == "axis" and f.get("direction") is not None]
    planes = [np.asarray(f["direction"], float) / np.linalg.norm(f["direction"]) for f in features
              if f.get("kind") in ("plane", "median plane") and f.get("direction") is not None]
    main = _dominant(axes) if axes else (_dominant(planes) if planes else None)
    if main is None:
        main = np.array([0.0, 0.0, 1.0])
    k = int(np.argmax(np.abs(main)))
    if main[k] < 0:  # a view along -y looks as along +y: the positive one, for stable pictures
        main = -main
    pts = np.array([f["point_mm"] for f in features], float)
    flat = pts - pts.mean(axis=0)
    flat = flat - np.outer(flat @ main, main)
    if len(pts) > 1 and np.linalg.norm(flat) > 1e-6:
        long = np.linalg.svd(flat, full_matrices=False)[2][0]
    else:
        from hyperstat.cad_plugin.part_solids import feature_frame

        long = feature_frame(main)[0]
    long = long - (long @ main) * main
    long /= np.linalg.norm(long)
    j = int(np.argmax(np.abs(long)))
    if long[j] < 0:
        long = -long
    first = {"toward": main, "right": long, "up": np.cross(main, long)}
    across = np.cross(main, long)
    second = {"toward": -across if across @ np.ones(3) < 0 else across, "right": long}
    second["up"] = np.cross(second["toward"], long)
    return [first, second]


def _direction_words(d: np.ndarray) -> str:
    d = np.asarray(d, float) + 0.0  # no "-0"
    names = "xyz"
    k = int(np.argmax(np.abs(d)))
    if abs(abs(float(d[k])) - 1) < 1e-9:
        return ("+" if d[k] > 0 else "-") + names[k]
    return "(" + ", ".join(f"{c + 0.0:.3g}" for c in np.round(d, 3) + 0.0) + ")"


def _hlr(shape, view: dict) -> dict:
    """Visible and hidden edges of ``shape`` (OCP's ``TopoDS_Shape``) in ``view``: 2-D polylines (mm) from OCCT's
    polygonal hidden-line removal on a mesh whose deflection is 1/1500 of the part's size (the exact algorithm takes
    seconds on a bar meeting a boss; 1/1500 of the view is under a tenth of a millimetre on the page)."""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
    from OCP.HLRAlgo import HLRAlgo_Projector
    from OCP.HLRBRep import HLRBRep_PolyAlgo, HLRBRep_PolyHLRToShape
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS
    from OCP.BRepAdaptor import BRepAdaptor_Curve

    from hyperstat.cad_plugin.occ_solids import bounding_box

    x0, y0, z0, x1, y1, z1 = bounding_box(shape)  # CadQuery's BoundingBox(): its lengths are max - min
    BRepMesh_IncrementalMesh(shape, max(0.02, max(x1 - x0, y1 - y0, z1 - z0) / 1500.0), False, 0.2, True)
    algo = HLRBRep_PolyAlgo(shape)
    algo.Projector(HLRAlgo_Projector(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*view["toward"]), gp_Dir(*view["right"]))))
    algo.Update()
    out = HLRBRep_PolyHLRToShape()
    out.Update(algo)
    result = {}
    for key, parts in (("visible", (out.VCompound(), out.OutLineVCompound(), out.Rg1LineVCompound())),
                       ("hidden", (out.HCompound(), out.OutLineHCompound()))):
        lines = []
        for comp in parts:
            if comp.IsNull():
                continue
            ex = TopExp_Explorer(comp, TopAbs_EDGE)
            while ex.More():
                curve = BRepAdaptor_Curve(TopoDS.Edge_s(ex.Current()))
                a, b = curve.Value(curve.FirstParameter()), curve.Value(curve.LastParameter())
                lines.append(np.array([[a.X(), a.Y()], [b.X(), b.Y()]]))
                ex.Next()
        result[key] = _chain(lines)
    return result


def _chain(segments: list) -> list:
    """Segments joined end to end into polylines (fewer, smoother strokes in the SVG); a segment met twice (OCCT's
    outlines and smooth-edge lines repeat edges of its visible set: up to two in five on a Tripteor part) is drawn
    once, so that its neighbours chain through it.

    >>> sq = [np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[1.0, 0.0], [1.0, 1.0]]), np.array([[1.0, 0.0], [0.0, 0.0]])]
    >>> [line.tolist() for line in _chain(sq)]
    [[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]]
    """
    key = lambda q: (round(float(q[0]), 6), round(float(q[1]), 6))  # noqa: E731
    seen, unique = set(), []
    for seg in segments:
        k = tuple(sorted((key(seg[0]), key(seg[-1]))))
        if k not in seen:
            seen.add(k)
            unique.append(seg)
    segments = unique
    first = [key(seg[0]) for seg in segments]  # each end's key once
    last = [key(seg[-1]) for seg in segments]
    ends: dict = {}
    for i in range(len(segments)):
        for k in (first[i], last[i]):
            ends.setdefault(k, []).append(i)
    used = [False] * len(segments)
    out = []
    for i in range(len(segments)):
        if used[i]:
            continue
        used[i] = True
        line, keys = [segments[i][0], segments[i][-1]], [first[i], last[i]]
        for forward in (True, False):
            while True:
                tip = keys[-1] if forward else keys[0]
                nxt = next((j for j in ends.get(tip, []) if not used[j]), None)
                if nxt is None or len(ends[tip]) > 2:  # a branch point: stop the stroke there
                    break
                used[nxt] = True
                seg = segments[nxt]
                other, other_key = (seg[-1], last[nxt]) if first[nxt] == tip else (seg[0], first[nxt])
                if forward:
                    line.append(other)
                    keys.append(other_key)
                else:
                    line.insert(0, other)
                    keys.insert(0, other_key)
        out.append(np.array(line))
    return out


def _project(view: dict, p) -> np.ndarray:
    p = np.asarray(p, float)
    return np.array([float(p @ view["right"]), float(p @ view["up"])])


def _datum_direction(view: dict, out) -> np.ndarray:
    """The unit direction (page, y down) a datum feature symbol stands out along from its feature."""
    direction = _project(view, out)
    if np.linalg.norm(direction) < 1e-9:
        direction = np.array([0.0, 1.0])
    return direction / np.linalg.norm(direction) * np.array([1.0, -1.0])  # page y points down


def _symbol_reach(dx: float, dy: float) -> float:
    """How far below its feature (mm on the page) a datum feature symbol standing out along ``(dx, dy)`` (page, y
    down) reaches: the lowest of its triangle's corners, its tip and its square."""
    return max(_DATUM_HALF_BASE * abs(dx), _DATUM_TRIANGLE * dy, (_DATUM_STEM + 0.5 * _DATUM_BOX) * dy + 0.5 * _DATUM_BOX)


def _gap_for(reach: float) -> float:
    """The space under a view whose datum symbols reach ``reach`` mm below it: 1 mm clear of the next view's label."""
    return max(_GAP_MM, reach + 1.0 - _LABEL_TOP_MM)


def _symbol_gaps(views: list[dict], datums: list, anchors: dict, scale: float) -> list[float]:
    """The space under each view (mm): :data:`_GAP_MM`, or more where a datum feature symbol standing out below the
    view would reach the next view's label (or the frames under the last view)."""
    gaps = [_GAP_MM] * len(views)
    for d in datums:
        if d.get("feature") not in anchors:
            continue
        k, point, out = anchors[d["feature"]]
        dx, dy = _datum_direction(views[k], out)
        below = -(_project(views[k], point)[1] - views[k]["bounds"][0][1]) * scale  # the feature under the box's
        # bottom edge (mm, negative: above it; the bounds keep a margin, so never positive)
        gaps[k] = max(gaps[k], _gap_for(below + _symbol_reach(dx, dy)))
    return gaps


def zone_words(frame: dict) -> str:
    """The zone of a frame in words: its shape, width (mm) and direction.

    >>> zone_words({"zone_mm": 0.05, "zone_shape": "two parallel planes", "zone_direction": [0, 0, 1]})
    'two parallel planes 0.05 mm apart, normal to +z'
    >>> zone_words({"zone_mm": 0.02, "zone_shape": "cylinder"})
    'cylinder of diameter 0.02 mm'
    """
    shape = str(frame.get("zone_shape") or "zone")
    z = f"{float(frame['zone_mm']):.3g}"
    if "cylinder" in shape or "circle" in shape:
        text = f"{shape} of diameter {z} mm"
    elif "sphere" in shape:
        text = f"{shape} of diameter {z} mm"
    else:
        text = f"{shape} {z} mm apart"
    d = frame.get("zone_direction")
    if d is not None:
        text += ", normal to " + _direction_words(np.asarray(d, float) / np.linalg.norm(d))
    return text


def _diameter(frame: dict) -> bool:
    shape = str(frame.get("zone_shape") or "")
    return "cylinder" in shape or "circle" in shape


def frame_cells(frame: dict) -> list[str]:
    """The cells of a frame as printed: characteristic, zone (``⌀`` for a cylinder, ``S⌀`` a sphere), datums,
    then the direction indicator's cells (``"|| B"`` style words: relation symbol and datum).

    >>> frame_cells({"characteristic": "position", "zone_mm": 0.05, "zone_shape": "cylinder",
    ...              "datum_system": ["A", "B"]})
    ['position', '\u23000.05', 'A', 'B']
    """
    shape = str(frame.get("zone_shape") or "")
    prefix = "S\u2300" if "sphere" in shape else "\u2300" if _diameter(frame) else ""
    cells = [str(frame.get("characteristic", "")).lower(), f"{prefix}{float(frame['zone_mm']):.3g}"]
    return cells + [str(d) for d in frame.get("datum_system") or []]


_RELATION_SYMBOL = {"parallel": "parallelism", "perpendicular": "perpendicularity", "inclined": "angularity",
                    "angular": "angularity"}


def _indicator_text(ind: dict | None) -> str:
    if not ind:
        return ""
    return f"{ind.get('kind', '')}: {ind.get('relation', '')} to {ind.get('datum', '')}"


class _Layout:
    """Page geometry of one part drawing (mm, y downwards from the figure's top)."""

    def __init__(self, views: list[dict], scale: float, head_mm: float, width_mm: float,
                 gaps: list[float] | None = None):
        self.views, self.scale, self.head, self.width = views, scale, head_mm, width_mm
        self.boxes = []  # per view: (x0, y0, w, h) on the page and the view's 2-D bounds
        y = head_mm
        for k, v in enumerate(views):
            lo, hi = v["bounds"]
            w, h = (hi - lo) * scale
            self.boxes.append((0.0, y + _BAND_MM, w, h, lo))  # a band above each view: its label, datum symbols
            y += _BAND_MM + h + (gaps[k] if gaps else _GAP_MM)
        self.height = y

    def page(self, k: int, xy: np.ndarray) -> np.ndarray:
        """A point of view ``k`` (part mm, view coordinates) on the page (mm, y down); or the rows of an ``(n, 2)``
        array of points, each as the point alone would be (the same operations, element by element)."""
        x0, y0, w, h, lo = self.boxes[k]
        rel = (np.asarray(xy) - lo) * self.scale
        return np.stack([x0 + rel[..., 0] + 0.5 * (self.width - w), y0 + h - rel[..., 1]], axis=-1)


def _anchor(f, views: list[dict], part_centre: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Where a feature is called out: (view index, point in the base frame, outward direction there).

    ``f`` is the feature as drawn (:attr:`hyperstat.cad_plugin.part_solids.PartSolid.parsed`).
    """
    along = [abs(float(f.u @ v["toward"])) for v in views]
    if f.kind == "axis":
        k = 0 if along[0] > 0.9 else int(np.argmin(along))
        v = views[k]
        if along[k] > 0.9:  # seen end on: on its rim, upwards
            return k, f.p + 0.5 * f.diameter * v["up"], v["up"]
        side = np.cross(v["toward"], f.u)
        side /= np.linalg.norm(side)
        if (f.p - part_centre) @ side < 0:
            side = -side
        reach = 0.5 * f.diameter if f.role == "journal" else f.outer_radius
        return k, f.p + reach * side, side
    if f.kind in ("plane", "median plane"):
        k = int(np.argmin(along))  # edge on
        v = views[k]
        t = np.cross(v["toward"], f.u)
        t = t / np.linalg.norm(t) if np.linalg.norm(t) > 1e-9 else v["up"]
        if f.role == "slot":
            h = f.host
            side = np.cross(f.u, h.u)
            side /= np.linalg.norm(side)
            return k, f.p + 0.5 * f.length * f.u + 0.5 * h.diameter * side, f.u
        if f.role == "end" and f.host is not None:
            return k, f.p + (0.5 * f.host.diameter + 0.5 * f.host.wall) * t, f.u
        if f.role == "median":
            return k, f.p + 0.5 * f.length * f.u + 0.5 * f.outer_radius * t, f.u
        return k, f.p, f.u
    return 0, f.p + 0.5 * f.diameter * views[0]["up"], views[0]["up"]


def _frame_label(fr: dict, width_mm: float = WIDTH_MM - _VIEWS_MM - 8.0) -> str:
    """``base-F2, with calibration (T11)``: the frame's id, its value's kind, its tolerances (runs as ``T3-T5``),
    cut with an ellipsis to ``width_mm`` (the table below gives them in full)."""
    from hyperstat.cad_plugin.palette import callout_text

    ids = callout_text("", list(fr.get("tolerances") or [])).split(": ", 1)[-1] if fr.get("tolerances") else ""
    label = fr["id"] + (", with calibration" if "with cal" in str(fr.get("value_kind", "")) else "") + \
        (f" ({ids})" if ids else "")
    while text_width_pt(label) * _PT > width_mm and len(label) > 8:
        label = label[:-2] + "\u2026"
    return label


def _block_width(fr: dict) -> float:
    """Width (mm) of a frame's block: its label line or its row of cells and indicator, whichever is wider."""
    h = _ROW * _PT
    cells = frame_cells(fr)
    row = h + sum((text_width_pt(c) + 5.0) * _PT for c in cells[1:])
    ind = fr.get("indicator")
    if ind:
        row += 1.0 + 1.7 * h + (text_width_pt(str(ind.get("datum", ""))) + 5.0) * _PT
    return max(row, text_width_pt(_frame_label(fr)) * _PT)


def _draw_block(ax: SvgSheet, x: float, y: float, fr: dict, text: dict, words: dict) -> float:
    """A frame's block at (x, y) (top left, mm): its label, then its cells and indicator; returns the row's
    vertical middle."""
    label = _frame_label(fr)
    ax.text(x, y + 0.5 * _LINE * _PT, label, va="center", **text)
    words["callouts"].append(label)
    row_y = y + _LINE * _PT
    h = _ROW * _PT
    drawn = []
    for i, cell in enumerate(frame_cells(fr)):
        w = h if i == 0 else (text_width_pt(cell) + 5.0) * _PT
        ax.rect(x, row_y, w, h, fill="white", color="black", lw=0.6)
        if i == 0:
            if not sheet_symbol(ax, cell, x + 0.15 * h, row_y + 0.85 * h, 0.7 * h):
                ax.text(x + 0.5 * w, row_y + 0.5 * h, cell[:4], ha="center", va="center", **text)
        else:
            ax.text(x + 0.5 * w, row_y + 0.5 * h, cell, ha="center", va="center", **text)
        drawn.append(cell)
        x += w
    ind = fr.get("indicator")
    if ind:
        _draw_indicator(ax, x + 1.0, row_y, h, ind, text)
        drawn.append(f"{ind.get('kind')} {ind.get('relation')} {ind.get('datum')}")
    words["frames"].append(f"{fr['id']} |" + "|".join(drawn) + "|")
    return row_y + 0.5 * h


def _leader(ax: SvgSheet, start, target) -> None:
    ax.leader(start, target, lw=0.45, head_pt=7.0)


def _band_rows(frames: list, width: float) -> list[list]:
    """The frames' blocks in rows across ``width`` mm (the band under wide views): [(x, frame)] per row."""
    rows: list = [[]]
    x = 0.0
    for fr in frames:
        w = _block_width(fr) + 4.0
        if x + w > width and rows[-1]:
            rows.append([])
            x = 0.0
        rows[-1].append((x, fr))
        x += w
    return rows


def _views_of(features: list, solid) -> list[dict]:
    """The part's two views (:func:`view_axes`) with their visible and hidden edges (:func:`_hlr`)."""
    views = view_axes(features)
    for v in views:
        v.update(_hlr(solid.wrapped, v))
    return views


def part_sheet(drawing: dict, solid, max_height_mm: float = 175.0, views: list | None = None):
    """The sheet of one part drawing (views, datum symbols, frames with leaders); returns ``(sheet, words)``
    (:class:`hyperstat.cad_plugin.svg_sheet.SvgSheet`: its :meth:`~hyperstat.cad_plugin.svg_sheet.SvgSheet.svg`
    is the page's picture).

    ``views``: the part's views with their edges (:func:`_views_of` of the same features and solid) when already
    computed (:func:`prebuild`).

    The frames stand in a column right of the views, or, for a part whose views are wide (a long leg),
    in rows under views that take the page's width: whichever draws the part at the larger ISO 5455 scale
    within ``max_height_mm`` (what the page leaves beside the part's tables).
    """
    features = drawing.get("features") or []
    frames = drawing.get("frames") or []
    views = [dict(v) for v in views] if views is not None else _views_of(features, solid)
    for v in views:
        pts = np.vstack([np.vstack(v["visible"] or [np.zeros((1, 2))]), *(v["hidden"] or [])])
        v["bounds"] = (pts.min(axis=0) - 2.0, pts.max(axis=0) + 2.0)
    spans = [v["bounds"][1] - v["bounds"][0] for v in views]
    head_mm = 10.0
    block_h = (_LINE + _ROW + 3.0) * _PT
    tall = sum(x[1] for x in spans)

    def scale_for(width: float, height: float) -> float:
        fit = min(min(width / s[0] for s in spans), height / tall)
        return next((s for s in ISO_SCALES if s <= fit), ISO_SCALES[-1])

    centre = np.mean([np.asarray(f["point_mm"], float) for f in features], axis=0) if features else np.zeros(3)
    anchors = {fid: _anchor(f, views, centre) for fid, f in solid.parsed.items()}
    datums = drawing.get("datums") or []
    # the most a symbol standing out downwards can add under its view (its feature on the view's edge): kept free
    worst = _gap_for(_symbol_reach(0.0, 1.0)) - _GAP_MM
    down = {anchors[d["feature"]][0] for d in datums if d.get("feature") in anchors
            and _datum_direction(views[anchors[d["feature"]][0]], anchors[d["feature"]][2])[1] > 0}
    extra = worst * len(down)
    room = max(max_height_mm, 80.0) - head_mm - 8.0 - len(views) * _BAND_MM - (len(views) - 1) * _GAP_MM - extra
    side = scale_for(_VIEWS_MM, room)
    band_rows = _band_rows(frames, WIDTH_MM)
    wide = scale_for(WIDTH_MM, room - 4.0 - len(band_rows) * (block_h + 4.0))
    use_band = wide > side
    scale = wide if use_band else side
    views_width = WIDTH_MM if use_band else _VIEWS_MM
    lay = _Layout(views, scale, head_mm, views_width, _symbol_gaps(views, datums, anchors, scale))
    if use_band:
        band_top = lay.height + 4.0
        height = band_top + len(band_rows) * (block_h + 4.0) + 4.0
    else:
        height = max(lay.height, head_mm + 2.0 + len(frames) * block_h) + 4.0
    ax = SvgSheet(WIDTH_MM, height)
    part = drawing.get("part", "")
    words = {"format": "hyperstat-picture-words", "version": 1, "title": f"Part drawing: {part}", "views": [],
             "datums": [], "frames": [], "callouts": []}
    text = {"fontsize": FONT_PT, "family": _FAMILY}
    elements = ", ".join(str(e) for e in drawing.get("elements") or [])
    sub = (f"{drawing['title']}; " if drawing.get("title") and drawing["title"] != part else "") + \
        (f"elements {elements}; " if elements else "") + f"scale {_scale_text(scale)}; lengths and zones in mm"
    ax.text(0, 6.0, sub, va="center", **text)
    words["callouts"].append(sub)
    for k, v in enumerate(views):
        x0, y0, w, h, lo = lay.boxes[k]
        label = f"view {k + 1}: looking along {_direction_words(-v['toward'])}, right {_direction_words(v['right'])}"
        ax.text(0, y0 - _BAND_MM + 3.0, label, va="center", style="italic", color="#333333", **text)
        words["views"].append(label)
        for key, style in (("hidden", {"lw": 0.35, "dashes": (3, 2), "color": "#555555"}),
                           ("visible", {"lw": 0.7, "color": "black", "cap": "round", "join": "round"})):
            if v[key]:  # every line's points on the page at once (element by element: the same numbers)
                points = lay.page(k, np.concatenate(v[key]))
                ax.lines(np.split(points, np.cumsum([len(line) for line in v[key]])[:-1]), **style)
    def on_page(fid: str) -> np.ndarray:
        k, point, _ = anchors[fid]
        return lay.page(k, _project(views[k], point))

    # datum feature symbols (ISO 5459): filled triangle on the feature, a stem, the letter in a square
    for d in datums:
        if d["feature"] not in anchors:
            continue
        k, point, out = anchors[d["feature"]]
        base = on_page(d["feature"])
        direction = _datum_direction(views[k], out)
        normal = np.array([-direction[1], direction[0]])
        ax.polygon(np.array([base + _DATUM_HALF_BASE * normal, base - _DATUM_HALF_BASE * normal,
                             base + _DATUM_TRIANGLE * direction]), fill="black", color="black", lw=0.4)
        stem_end = base + _DATUM_STEM * direction
        ax.line([base[0] + _DATUM_TRIANGLE * direction[0], stem_end[0]],
                [base[1] + _DATUM_TRIANGLE * direction[1], stem_end[1]], color="black", lw=0.5)
        box = _DATUM_BOX
        middle = stem_end + 0.5 * box * direction
        ax.rect(middle[0] - 0.5 * box, middle[1] - 0.5 * box, box, box, fill="white", color="black", lw=0.6)
        ax.text(middle[0], middle[1], d["letter"], ha="center", va="center", **text)
        words["datums"].append(str(d["letter"]))
    # feature control frames, each with a leader to its feature
    if use_band:
        order = sorted(frames, key=lambda fr: on_page(fr["feature"])[0] if fr.get("feature") in anchors else 0.0)
        for r, row in enumerate(_band_rows(order, WIDTH_MM)):
            y = band_top + r * (block_h + 4.0)
            for x, fr in row:
                _draw_block(ax, x, y, fr, text, words)
                if fr.get("feature") in anchors:
                    _leader(ax, np.array([x + 2.0, y]), on_page(fr["feature"]))
    else:
        column_x = _VIEWS_MM + 8.0
        order = sorted(frames, key=lambda fr: on_page(fr["feature"])[1] if fr.get("feature") in anchors else 0.0)
        for i, fr in enumerate(order):
            middle = _draw_block(ax, column_x, head_mm + 2.0 + i * block_h, fr, text, words)
            if fr.get("feature") in anchors:
                _leader(ax, np.array([column_x - 1.0, middle]), on_page(fr["feature"]))
    return ax, words


def _draw_indicator(ax: SvgSheet, x: float, y: float, h: float, ind: dict, text: dict) -> float:
    """An intersection or orientation plane indicator (ISO 1101:2017) right of a frame: its relation symbol and
    datum letter; the intersection plane's frame has doubled ends, the orientation plane's pointed ends."""
    symbol = _RELATION_SYMBOL.get(str(ind.get("relation", "")).lower(), "parallelism")
    letter = str(ind.get("datum", ""))
    w_sym, w_let = h, (text_width_pt(letter) + 5.0) * _PT
    kind = str(ind.get("kind", ""))
    tip = 0.35 * h if "orientation" in kind else 0.0
    x0, x1 = x + tip, x + tip + w_sym + w_let
    if "orientation" in kind:
        outline = [(x, y + 0.5 * h), (x0, y), (x1, y), (x1 + tip, y + 0.5 * h), (x1, y + h), (x0, y + h),
                   (x, y + 0.5 * h)]
    else:
        outline = [(x0, y), (x1, y), (x1, y + h), (x0, y + h), (x0, y)]
    xs, ys = zip(*outline)
    ax.line(xs, ys, color="black", lw=0.6)
    if "intersection" in kind:
        for xe in (x0 + 0.6, x1 - 0.6):
            ax.line([xe, xe], [y, y + h], color="black", lw=0.6)
    ax.line([x0 + w_sym, x0 + w_sym], [y, y + h], color="black", lw=0.6)
    sheet_symbol(ax, symbol, x0 + 0.15 * h, y + 0.85 * h, 0.7 * h)
    ax.text(x0 + w_sym + 0.5 * w_let, y + 0.5 * h, letter, ha="center", va="center", **text)
    return x1 + tip


def part_pages(doc: dict, solids: bool = False, cache=None) -> list[dict]:
    """Every part drawing of a report: ``{"part", "svg", "words", "assumed", "solid", "error"}`` per entry of
    ``drawings``.

    A part whose solid cannot be built (``error``: the sentence why; ``svg`` and ``solid`` None) still gets its
    page, with its datums and frames in words and that sentence where the views would be: the report is
    written whole, only ``--step-drawings`` refuses (it cannot write that part's file).  ``assumed`` lists what the
    solid assumes (sizes and places the drawing does not give).

    ``cache`` (a :class:`hyperstat.solver.cache.Cache`) keeps each page under its drawing, the joint types and the
    version of the drawing code (:func:`page_key`): a report of the same drawings reads its pages (the solids and
    the hidden-line views are most of a report's drawing time).  With ``solids`` every page also carries its
    solid (a :class:`hyperstat.cad_plugin.part_solids.PartSolid`; ``--step-drawings`` writes them) and is
    computed; else ``solid`` is None.
    """
    types = {str(j["element"]): j.get("type") for j in doc.get("joints") or []}
    pages = []
    for drawing in doc.get("drawings") or []:
        k = page_key(drawing, types) if cache is not None and cache.enabled else None
        stored = None if solids or k is None else cache.load("part-page", k)
        if isinstance(stored, dict) and stored.get("part") == drawing["part"]:
            pages.append({**stored, "solid": None})
            continue
        page = _part_page(drawing, types)
        if k is not None:
            cache.store("part-page", k, {n: v for n, v in page.items() if n != "solid"})
        pages.append(page if solids else {**page, "solid": None})
    return pages


#: the solids and views built ahead of the drawing (:func:`prebuild`): geometry key -> (solid, views) or the sentence
#: why the solid cannot be built
_PREBUILT: dict = {}


def geometry_key(drawing: dict, types: dict) -> str:
    """What a part's solid and views depend on: its name, its features and the joint types (JSON; the frames and
    zones are left out: they are drawn on the views, not built into the solid).

    >>> d = {"part": "rod", "features": [{"id": "a", "kind": "axis"}], "frames": [{"zone_mm": 0.1}]}
    >>> geometry_key(d, {"j": "R"}) == geometry_key({**d, "frames": []}, {"j": "R"})
    True
    >>> geometry_key(d, {"j": "R"}) == geometry_key(d, {"j": "P"})
    False
    """
    import json

    return json.dumps({"part": drawing.get("part"), "features": drawing.get("features"),
                       "types": dict(sorted((str(k), v) for k, v in types.items()))}, sort_keys=True, default=str)


def _solid_and_views(drawing: dict, types: dict):
    """``(solid, views)`` of a part drawing, or the sentence why its solid cannot be built."""
    from hyperstat.cad_plugin.part_solids import part_solid

    try:
        solid = part_solid(drawing, types)
    except Exception as exc:  # noqa: BLE001 - HyperstatError, or OCCT's Standard_Failure from a Boolean
        return str(exc).strip() or type(exc).__name__
    return solid, _views_of(drawing.get("features") or [], solid)


def prebuild(drawings: list, types: dict) -> int:
    """Build the solids and hidden-line views of ``drawings`` ahead of their frames (in place in this process).

    The part pages' child calls it with the drawings predicted before the tolerance values
    (:func:`hyperstat.solver.tolerances.drawing.provisional_drawings`) while the values are computed: a page whose
    final drawing has the same geometry (:func:`geometry_key`) takes the solid and views built here, the same
    computation on the same input; any other page builds its own.  Returns the number of parts built.
    """
    n = 0
    for drawing in drawings:
        k = geometry_key(drawing, types)
        if k not in _PREBUILT:
            _PREBUILT[k] = _solid_and_views(drawing, types)
            n += 1
    return n


def _part_page(drawing: dict, types: dict) -> dict:
    """One part's page (:func:`part_pages`), its solid included."""
    built = _PREBUILT.pop(geometry_key(drawing, types), None) if _PREBUILT else None
    if built is None:
        built = _solid_and_views(drawing, types)
    if isinstance(built, str):
        return {"part": drawing["part"], "svg": None, "words": None, "assumed": [], "solid": None, "error": built}
    solid, views = built
    # the heading, the picture, then the tables: the picture shrinks (to 80 mm) so that the tables fit on
    # its page (their height is measured to within about 7 mm: 10 mm are kept); when they cannot, the picture
    # keeps 200 mm and the table of a part with many frames continues on the next page
    room = _PAGE_MM - 10.0 - _tables_height_mm(drawing, solid.assumed)
    sheet, words = part_sheet(drawing, solid, room if room >= 80.0 else 200.0, views=views)
    return {"part": drawing["part"], "svg": sheet.svg(), "words": words, "assumed": list(solid.assumed),
            "solid": solid, "error": None}


_PAGES_VERSION: str | None = None


def page_key(drawing: dict, types: dict) -> str:
    """The cache key of a part's page: its drawing (JSON), the joint types, and the version of the code that draws
    it (:func:`hyperstat.solver.cache.key`'s solver version, the SHA-256 of the ``cad_plugin`` package's sources and
    the versions of CadQuery, OCP and matplotlib).

    >>> d = {"part": "rod", "features": []}
    >>> page_key(d, {}) == page_key(dict(d), {}) != page_key({**d, "part": "arm"}, {})
    True
    """
    from hyperstat.solver.cache import key

    return key("part-page", drawing_code_version(), drawing, dict(sorted(types.items())))


def drawing_code_version() -> str:
    """SHA-256 of the ``cad_plugin`` package's sources and the versions of CadQuery, OCP and matplotlib (memoised):
    with :func:`hyperstat.solver.cache.code_version` (the solver's), the version of what the report draws."""
    global _PAGES_VERSION
    if _PAGES_VERSION is None:
        import hashlib
        from importlib.metadata import PackageNotFoundError, version
        from pathlib import Path

        h = hashlib.sha256()
        root = Path(__file__).resolve().parent
        for path in sorted(root.rglob("*.py")):
            h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
        for name in ("cadquery", "cadquery-ocp", "matplotlib"):
            try:
                h.update(f"{name}={version(name)}\0".encode())
            except PackageNotFoundError:  # pragma: no cover - a library installed without metadata
                h.update(f"{name}=?\0".encode())
        _PAGES_VERSION = h.hexdigest()
    return _PAGES_VERSION


def _e(text) -> str:
    return html.escape(str(text))


def _feature_words(f: dict | None, source: bool = True) -> str:
    """A feature in words with its size: ``bore of joint 2 (axis, 20 mm long, assumed support span)``; without
    ``source``, the length's origin is left out (the datum table says it)."""
    if not f:
        return "-"
    extra = [str(f.get("kind", ""))]
    if f.get("diameter_mm") is not None:
        extra.append(f"\u2300{float(f['diameter_mm']):g} mm")
    if f.get("length_mm") is not None:
        extra.append(f"{float(f['length_mm']):g} mm long"
                     + (f", {f['length_source']}" if source and f.get("length_source") else ""))
    return f"{f.get('name') or f['id']} ({', '.join(extra)})"


def _ted_words(frame: dict) -> str:
    teds = [t for t in frame.get("ted") or [] if t.get("direction") is None or np.linalg.norm(t["direction"]) > 0]
    return "; ".join(f"[{float(t['distance_mm']):g}] mm from {t.get('from', '')} along "
                     f"{_direction_words(np.asarray(t['direction'], float) / np.linalg.norm(t['direction']))}"
                     if t.get("direction") is not None else f"[{float(t['distance_mm']):g}] mm from {t.get('from', '')}"
                     for t in teds) or "-"


def _notes(frames: list) -> tuple[dict, list]:
    """A frame's note split at ``;``: its short parts stay in the frame's row, each long part (a sentence several
    frames share) is printed once below the table.  Returns frame id -> (numbers of its notes, its short
    words), and the numbered notes with their frames."""
    marks: dict = {}
    notes: list = []
    for fr in frames:
        numbers, short = [], []
        for piece in (p.strip() for p in str(fr.get("note") or "").split(";")):
            if not piece:
                continue
            if len(piece) <= 60:
                short.append(re.sub(r"^without calibration the value is ", "uncalibrated: ", piece))
                continue
            k = next((i for i, (t, _) in enumerate(notes) if t == piece), None)
            if k is None:
                notes.append((piece, []))
                k = len(notes) - 1
            notes[k][1].append(fr["id"])
            numbers.append(k + 1)
        marks[fr["id"]] = (numbers, short)
    return marks, notes


_COLUMNS = (("frame, tolerances", 12), ("toleranced feature", 22), ("zone (mm)", 26), ("datums", 7),
            ("theoretically exact", 15), ("value", 18))


def _lines(text: str, width_mm: float) -> int:
    """Lines a cell of ``text`` takes at 8 pt in a column ``width_mm`` wide: words wrapped greedily, each measured
    on the font's outlines (DejaVu Sans, the report's font); a word wider than the column breaks anywhere."""
    room = (width_mm - 1.6) / _PT  # less the cell's padding and borders, in pt
    space = text_width_pt("a b") - text_width_pt("ab")
    total = 0
    for para in text.split("\n"):
        lines, used = 1, 0.0
        for word in para.split():
            w = text_width_pt(word)
            if used and used + space + w > room:
                lines += 1
                used = 0.0
            if w > room:  # overflow-wrap: anywhere
                lines += int(w // room)
                w = w % room
            used += (space if used else 0.0) + w
        total += lines
    return total


_LINE_MM = 8.0 * 1.3 * _PT  # an 8 pt line at the report's line height


def _table_height_mm(rows: list[list[str]], widths: list[float]) -> float:
    return sum(max(_lines(c, w) for c, w in zip(row, widths)) * _LINE_MM + 0.35 for row in rows)


def _words_of(drawing: dict) -> dict:
    """The words of a part's tables (plain text): what the page prints below its picture."""
    features = {f["id"]: f for f in drawing.get("features") or []}
    frames = drawing.get("frames") or []
    marks, notes = _notes(frames)
    rows = []
    for fr in frames:
        numbers, short = marks[fr["id"]]
        value = "; ".join([str(fr.get("value_kind", ""))] + short) + \
            (f" (note {', '.join(str(n) for n in numbers)})" if numbers else "")
        rows.append([fr["id"] + ("\n" + ", ".join(fr["tolerances"]) if fr.get("tolerances") else ""),
                     _feature_words(features.get(fr.get("feature")), source=False), zone_words(fr)
                     + (f"; {_indicator_text(fr.get('indicator'))}" if fr.get("indicator") else ""),
                     "|".join(fr.get("datum_system") or []) or "none", _ted_words(fr), value])
    datums = [[str(d["letter"]), str(d.get("precedence", "")), _feature_words(features.get(d["feature"]))]
              for d in drawing.get("datums") or []]
    return {"rows": rows, "datums": datums, "notes": notes}


def _tables_height_mm(drawing: dict, assumed: list[str]) -> float:
    """How much of the page the part's heading, tables, notes and geometry note take (mm, 8 pt), measured word
    by word as :func:`_lines` wraps them."""
    w = _words_of(drawing)
    widths = [WIDTH_MM * pct / 100.0 for _, pct in _COLUMNS]
    height = 5.0  # the heading (9 pt) and its margin
    if w["rows"]:
        height += 2.0 + _table_height_mm([[h for h, _ in _COLUMNS]] + w["rows"], widths)
    else:
        height += _lines("No geometric tolerance on this part: its datums locate it for the frames of the parts it "
                         "carries.", WIDTH_MM) * _LINE_MM + 2.0
    if w["datums"]:
        height += 2.0 + _table_height_mm([["datum", "precedence", "datum feature"]] + w["datums"],
                                         [0.1 * WIDTH_MM, 0.15 * WIDTH_MM, 0.75 * WIDTH_MM])
    height += sum(_lines(f"{t} ({', '.join(ids)})", WIDTH_MM - 6.0) * _LINE_MM for t, ids in w["notes"])
    if w["notes"]:
        height += 2.0
    if assumed:
        height += _lines("Geometry drawn: " + "; ".join(assumed) + ".", WIDTH_MM) * _LINE_MM + 2.5
    return height


def _page_html(drawing: dict, page: dict | None) -> str:
    """One part's page: its picture, its datums, its frames in words, the notes, the geometry drawn."""
    part = drawing["part"]
    frames = drawing.get("frames") or []
    words = _words_of(drawing)
    out = [f'<section class="part-page" id="part-{_e(part)}"><h3>Part drawing: {_e(part)}</h3>']
    if page is not None and page.get("svg"):
        out.append(f"<figure>{page['svg']}</figure>")
    elif page is not None and page.get("error"):
        out.append(f'<p class="note"><b>The views of this part could not be drawn</b>: {_e(page["error"])}</p>')
    if words["datums"]:
        out.append('<table class="part"><colgroup><col style="width:10%"><col style="width:15%"><col style="width:75%">'
                   "</colgroup><thead><tr><th>datum</th><th>precedence</th><th>datum feature</th></tr></thead><tbody>"
                   + "".join("<tr>" + "".join(f"<td>{_e(c)}</td>" for c in row) + "</tr>" for row in words["datums"])
                   + "</tbody></table>")
    if frames:
        rows = []
        for fr, row in zip(frames, words["rows"]):
            cells = [_e(c).replace("\n", "<br>") for c in row]
            if fr.get("ted"):
                cells[4] = cells[4].replace("[", '<span class="ted">').replace("]", "</span>")
            rows.append(cells)
        out.append('<table class="part" style="table-layout: fixed"><colgroup>'
                   + "".join(f'<col style="width:{pct}%">' for _, pct in _COLUMNS) + "</colgroup><thead><tr>"
                   + "".join(f"<th>{h}</th>" for h, _ in _COLUMNS) + "</tr></thead><tbody>"
                   + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in rows)
                   + "</tbody></table>")
    else:
        out.append('<p class="note">No geometric tolerance on this part: its datums locate it for the frames of the '
                   "parts it carries.</p>")
    if words["notes"]:
        out.append('<ol class="part-notes">' + "".join(f"<li>{_e(text)} ({_e(', '.join(ids))})</li>"
                                                        for text, ids in words["notes"]) + "</ol>")
    if page is not None and page.get("assumed"):
        out.append('<p class="note">Geometry drawn: ' + _e("; ".join(page["assumed"])) + ".</p>")
    out.append("</section>")
    return "".join(out)


def _requirement_words(r: dict) -> str:
    """An assembly requirement in one line: its id and its text (else its tolerances, statement, value, parts)."""
    if r.get("text"):
        return f"{r.get('id', '')}: {r['text']}"
    value = r.get("value")
    return (f"{r.get('id', '')} ({', '.join(r.get('tolerances') or [])}): {r.get('statement', '')}"
            + (f" within \u00b1 {float(value):.3g} {r.get('unit', '')}" if isinstance(value, (int, float)) else "")
            + f", parts {', '.join(r.get('parts') or [])}")


def parts_html(doc: dict, pages: list | None) -> str:
    """The report's section ``parts``: the assembly requirements, then one page per part drawing."""
    drawings = doc.get("drawings") or []
    out = ['<section id="parts"><h2>Part drawings</h2>']
    if not drawings:
        out.append('<p class="note">This report carries no part drawings.</p></section>')
        return "".join(out)
    out.append(f'<p class="note">{len(drawings)} part drawings, one per page: two views of the part (visible edges '
               "solid, hidden dashed), ISO 5459 datum feature symbols, ISO 1101 feature control frames with the "
               "plane indicators that state a planar zone's direction; zones and lengths in mm, directions in the "
               "mechanism's base frame at its home configuration.</p>")
    reqs = doc.get("assembly_requirements") or []
    if reqs:
        out.append("<h3>Assembly and setup requirements (conditions no single part drawing carries)</h3><ul>"
                   + "".join(f"<li>{_e(_requirement_words(r))}</li>" for r in reqs) + "</ul>")
    by_part = {p["part"]: p for p in pages or []}
    out += [_page_html(d, by_part.get(d["part"])) for d in drawings]
    out.append("</section>")
    return "".join(out)


def parts_markdown(doc: dict) -> list[str]:
    """The part drawings in Markdown: per part its datums and frames (the pictures are left to the HTML)."""
    drawings = doc.get("drawings") or []
    lines = ["", "## Part drawings", ""]
    if not drawings:
        return lines + ["This report carries no part drawings."]
    lines += [f"* {_requirement_words(r)}" for r in doc.get("assembly_requirements") or []]
    for d in drawings:
        features = {f["id"]: f for f in d.get("features") or []}
        lines += ["", f"### Part drawing: {d['part']}", ""]
        lines += [f"* datum {x['letter']} ({x.get('precedence', '')}): {_feature_words(features.get(x['feature']))}"
                  for x in d.get("datums") or []]
        lines += ["", "| frame | tolerances | feature | frame as drawn | zone | datum system | theoretically exact | "
                      "value; note |", "|---|---|---|---|---|---|---|---|"]
        for fr in d.get("frames") or []:
            drawn = "|" + "|".join(frame_cells(fr)) + "|"
            if fr.get("indicator"):
                drawn += f" [{_indicator_text(fr['indicator'])}]"
            cells = [fr["id"], ", ".join(fr.get("tolerances") or []) or "-",
                     _feature_words(features.get(fr.get("feature"))),
                     drawn, zone_words(fr), "|".join(fr.get("datum_system") or []) or "none", _ted_words(fr),
                     str(fr.get("value_kind", "")) + ("; " + fr["note"] if fr.get("note") else "")]
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return lines

