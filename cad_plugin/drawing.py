"""The skeleton picture as a drawing: four views, numbered callouts, feature control frames, legend (matplotlib).

Units: the page in mm (A4: the picture is as wide as the printed report's text, 186 mm) and
type in pt; the views' pixels come from :func:`hyperstat.cad_plugin.view.render_views`.

Every joint is called out once, in the view where it stands most apart from the others (as a
draughtsman dimensions a feature once, where it shows best), with its tolerance ids (the rows
of the report's tolerance table, ``21: T13, T15-T19``) and, for each ISO 1101 callout of an
assembly or accuracy-critical tolerance (the ``drawing`` list of a tolerance item), its feature
control frame drawn as boxes: characteristic symbol (:mod:`hyperstat.cad_plugin.gdt`), zone in
mm, datums.  The callouts stand in a column beside each view with a leader to the joint; their
type is :data:`FONT_PT` (8 pt, printed at full size on A4).  The figure saves as PNG and as SVG
with its text kept as text (the report inlines the SVG, so that the printed callouts are real
8 pt type that ``pdftotext`` reads back).
"""

from __future__ import annotations

import io
import re

import numpy as np

from hyperstat.cad_plugin.gdt import draw_symbol, symbol_of, zone_text
from hyperstat.cad_plugin.palette import CLASS_LABELS, CLASS_ORDER, CLASS_RGB, callout_text

__all__ = ["skeleton_figure", "figure_png", "figure_svg", "FONT_PT", "WIDTH_MM", "frames_by_element", "text_width_pt"]

#: type size of the callouts, frames and legend (pt): legible on paper
FONT_PT = 8.0
#: the picture's width: A4 (210 mm) less the report's 12 mm margins
WIDTH_MM = 186.0
_FAMILY = "DejaVu Sans"
_LINK_LABELS = {"base": "base link", "platform": "platform link", "other": "other links"}


def text_width_pt(text: str, size: float = FONT_PT) -> float:
    """Width of one line of text in pt, measured on the font's outlines.

    >>> 10 < text_width_pt("T13") < 20
    True
    """
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    if not text:
        return 0.0
    return _extents_width(TextPath((0, 0), text, size=size, prop=FontProperties(family=_FAMILY)))


def _extents_width(path) -> float:
    """``path.get_extents().width``, the same number, with matplotlib's computation on the curves that can reach the
    extremes only (the rest was 4 ms a line of text: most of the skeleton drawing's layout).

    ``get_extents`` takes the minimum and maximum over the ends of every segment and the interior extrema of every
    curve (:meth:`matplotlib.bezier.BezierSegment.axis_aligned_extrema`).  A curve lies within its control points:
    one whose control points all stand inside the ends' range in x (by more than any rounding) cannot give the
    minimum or the maximum x, and is left out; the others are computed as ``get_extents`` does.  A path of another
    shape than a text's outlines (MOVETO, LINETO, CURVE3, CURVE4, CLOSEPOLY, finite) is measured by ``get_extents``.

    >>> from matplotlib.font_manager import FontProperties
    >>> from matplotlib.textpath import TextPath
    >>> p = TextPath((0, 0), "21: T13, T15-T19 (Ø0.02) gj", size=8, prop=FontProperties(family=_FAMILY))
    >>> _extents_width(p) == float(p.get_extents().width)
    True
    """
    from matplotlib.bezier import BezierSegment
    from matplotlib.path import Path

    verts, codes = path.vertices, path.codes
    if (codes is None or not len(codes) or codes[0] != Path.MOVETO or not np.isfinite(verts).all()
            or not np.isin(codes, (Path.MOVETO, Path.LINETO, Path.CURVE3, Path.CURVE4, Path.CLOSEPOLY)).all()):
        return float(path.get_extents().width)
    ends, curves = [], []  # the segments' ends (exact in get_extents: a curve at t = 0 and 1), the curves
    prev = None
    i, n = 0, len(codes)
    while i < n:
        code = codes[i]
        if code == Path.CLOSEPOLY:  # the segment back to the first point: both ends are in already
            if i + 1 < n and codes[i + 1] != Path.MOVETO:
                return float(path.get_extents().width)
            i += 1
            continue
        step = 2 if code == Path.CURVE3 else 3 if code == Path.CURVE4 else 1
        if i + step > n or (step > 1 and not (codes[i:i + step] == code).all()):
            return float(path.get_extents().width)
        if step > 1:
            curves.append(np.array([prev, *verts[i:i + step]]))
        prev = verts[i + step - 1]
        ends.append(prev)
        i += step
    ends = np.array(ends)
    lo, hi = float(ends[:, 0].min()), float(ends[:, 0].max())
    margin = 1e-9 * (1.0 + abs(lo) + abs(hi))
    xs = [lo, hi]
    for cp in curves:
        if cp[:, 0].min() <= lo + margin or cp[:, 0].max() >= hi - margin:
            curve = BezierSegment(cp)
            xs.extend(curve([0, *curve.axis_aligned_extrema()[1], 1])[:, 0])
    return float(max(xs) - min(xs))


def _wrap(text: str, width_pt: float) -> list[str]:
    """Split ``"21: T13, T15-T19"`` after commas so that no line is wider than ``width_pt``."""
    tokens = re.split(r"(?<=,) ", text)
    lines = [tokens[0]]
    for tok in tokens[1:]:
        if text_width_pt(lines[-1] + " " + tok) <= width_pt:
            lines[-1] += " " + tok
        else:
            lines.append("  " + tok)
    return lines


def frames_by_element(items: list, elements_of: dict, known: set) -> tuple[dict, dict]:
    """Feature control frames per element, and the datum letters each element carries.

    A frame goes to the joint its callout names (``"axis of joint 23"``), else to the joint of
    the tolerance's first parameter; a datum letter to the joint its datum feature names.
    """
    frames: dict = {}
    datums: dict = {}
    for item in items:
        for callout in item.get("drawing") or []:
            element = _named_joint(str(callout.get("feature", "")), known)
            if element is None:
                element = next((elements_of[p] for p in item.get("parameters", []) if elements_of.get(p) in known), None)
            if element is None:
                continue
            frames.setdefault(element, []).append((item["id"], callout))
            for letter, feature in (callout.get("datum_features") or {}).items():
                where = _named_joint(str(feature), known)
                if where is not None and letter not in datums.setdefault(where, []):
                    datums[where].append(letter)
    return frames, datums


def _named_joint(text: str, known: set) -> str | None:
    for name in re.findall(r"joint ([A-Za-z0-9_]+)", text):
        if name in known:
            return name
    return None


class _Block:
    """The text lines and frames of one joint's callout, and its size in pt."""

    LINE = 1.28 * FONT_PT
    FRAME = 1.55 * FONT_PT

    def __init__(self, element: str, lines: list[str], frames: list):
        self.element, self.lines, self.frames = element, lines, frames
        self.height_pt = len(lines) * self.LINE + len(frames) * (self.FRAME + 1.5)
        self.top = 0.0


def _frame_cells(tid: str, callout: dict) -> list[tuple[str, float]]:
    """(text, width pt) of the cells of one frame row; the symbol cell's text is its characteristic."""
    cells = [(symbol_of(callout), _Block.FRAME), (zone_text(callout), text_width_pt(zone_text(callout)) + 5.0)]
    cells += [(str(d), text_width_pt(str(d)) + 5.0) for d in callout.get("datums") or []]
    return cells


def _assign(views: list, heights: dict, budget_px: float, px_per_pt: float) -> list[list[str]]:
    """Each element to the view where its joint stands most apart from the others, within each view's height."""
    elements = [e for e in heights if all(e in v["anchors"] for v in views)]
    spread = {}
    for k, v in enumerate(views):
        pts = np.array([v["anchors"][e] for e in elements]) if elements else np.zeros((0, 2))
        dist = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2) if len(pts) else np.zeros((0, 0))
        np.fill_diagonal(dist, np.inf)
        for i, e in enumerate(elements):
            spread[(e, k)] = float(dist[i].min()) if len(elements) > 1 else 1.0
    used = [0.0] * len(views)
    cap = -(-len(elements) // len(views)) + 1  # no view carries many more callouts than the others
    out: list[list[str]] = [[] for _ in views]
    order = sorted(elements, key=lambda e: -max(spread[(e, k)] for k in range(len(views))))
    for e in order:
        need = heights[e] * px_per_pt + 2.0
        ranked = sorted(range(len(views)), key=lambda k: -spread[(e, k)])
        fitting = ([k for k in ranked if used[k] + need <= budget_px and len(out[k]) < cap]
                   or [min(range(len(views)), key=lambda k: used[k])])
        k = fitting[0]
        out[k].append(e)
        used[k] += need
    return out


def _place(blocks: list, anchors: dict, top: float, bottom: float, px_per_pt: float) -> None:
    """Stack the blocks in a column in the order of their joints' heights, none overlapping."""
    blocks.sort(key=lambda b: anchors[b.element][1])
    gap = 2.0 * px_per_pt
    for i, b in enumerate(blocks):
        h = b.height_pt * px_per_pt
        want = anchors[b.element][1] - 0.5 * _Block.LINE * px_per_pt
        b.top = max(want, top if i == 0 else blocks[i - 1].top + blocks[i - 1].height_pt * px_per_pt + gap)
    for i in range(len(blocks) - 1, -1, -1):
        b = blocks[i]
        h = b.height_pt * px_per_pt
        limit = bottom - h if i == len(blocks) - 1 else blocks[i + 1].top - gap - h
        b.top = max(min(b.top, limit), top)


def _draw_block(ax, b: _Block, side: str, edge: float, anchor, px_per_pt: float, drawn: dict) -> None:
    ha = "right" if side == "left" else "left"
    y = b.top
    for line in b.lines:
        ax.text(edge, y + 0.5 * _Block.LINE * px_per_pt, line, ha=ha, va="center", fontsize=FONT_PT, family=_FAMILY,
                color="black")
        drawn["callouts"].append(line.strip())
        y += _Block.LINE * px_per_pt
    for tid, callout in b.frames:
        cells = _frame_cells(tid, callout)
        label_w = text_width_pt(tid) + 3.0
        row_w = label_w + sum(w for _, w in cells)
        x = edge - row_w * px_per_pt if side == "left" else edge
        h = _Block.FRAME * px_per_pt
        ax.text(x, y + 0.5 * h, tid, ha="left", va="center", fontsize=FONT_PT, family=_FAMILY)
        x += label_w * px_per_pt
        from matplotlib.patches import Rectangle

        for k, (text, w) in enumerate(cells):
            ax.add_patch(Rectangle((x, y), w * px_per_pt, h, fill=True, fc="white", ec="black", lw=0.6))
            if k == 0 and draw_symbol(ax, text, x + 0.15 * h, y + 0.85 * h, 0.7 * h):
                pass
            else:
                ax.text(x + 0.5 * w * px_per_pt, y + 0.5 * h, text if k else text[:4], ha="center", va="center",
                        fontsize=FONT_PT, family=_FAMILY)
            x += w * px_per_pt
        drawn["frames"].append(f"{tid} |" + "|".join(t for t, _ in cells) + "|")
        y += h + 1.5 * px_per_pt
    ax.plot([edge + (3 if side == "left" else -3), anchor[0]], [b.top + 0.5 * _Block.LINE * px_per_pt, anchor[1]],
            color="black", lw=0.5)
    ax.plot([anchor[0]], [anchor[1]], marker="o", ms=1.8, color="black")


def skeleton_figure(rendered: dict, items: list | None = None, title: str = "", width_mm: float = WIDTH_MM):
    """The drawing of :func:`~hyperstat.cad_plugin.view.render_views`' output; returns ``(figure, words)``.

    ``items`` are the tolerance items (``tolerances.items`` of the analysis or report JSON); those
    with a ``drawing`` list get their feature control frames.  ``words`` records everything the
    picture says (title, view names, legend, callouts, frames), for the record kept beside
    committed pictures.
    """
    from PIL import Image
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle

    views = rendered["views"]
    classes, ids = rendered.get("classes", {}), rendered.get("ids", {})
    gap_mm, head_mm = 3.0, 7.0
    cols = 2
    rows = (len(views) + cols - 1) // cols
    tile_mm = (width_mm - gap_mm * (cols - 1)) / cols
    legend = _legend_entries(rendered, classes, bool(items and any(i.get("drawing") for i in items)))
    legend_rows = _legend_rows(legend, width_mm)
    legend_mm = 2.0 + 4.6 * (len(legend_rows) + 1)
    width_px, height_px = views[0]["size"]
    tile_h_mm = tile_mm * height_px / width_px
    height_mm = head_mm + rows * tile_h_mm + (rows - 1) * gap_mm + legend_mm
    fig = Figure(figsize=(width_mm / 25.4, height_mm / 25.4))
    drawn = {"format": "hyperstat-picture-words", "version": 1, "title": title, "views": [], "legend": [],
             "classes": [c for c in CLASS_ORDER if c in set(classes.values())], "callouts": [], "frames": []}
    fig.text(0.0, 1.0 - 1.0 / height_mm, title, ha="left", va="top", fontsize=10, family=_FAMILY, weight="bold")
    px_per_pt = width_px / (tile_mm / 25.4 * 72.0)
    margin_pt = 0.30 * tile_mm / 25.4 * 72.0 - 4.0
    known = set(views[0]["anchors"])
    frames, datums = frames_by_element(items or [], rendered.get("elements_of", {}), known)
    blocks = {}
    for element in views[0]["anchors"]:  # the renderer's order: a set's order changes with the process' string hashing
        text = callout_text(element, ids.get(element, []))
        if datums.get(element):
            text += ", datum " + " ".join(datums[element])
        blocks[element] = _Block(element, _wrap(text, margin_pt), frames.get(element, []))
    budget = (1.0 - 0.06) * height_px
    assignment = _assign(views, {e: b.height_pt for e, b in blocks.items()}, budget, px_per_pt)
    for k, view in enumerate(views):
        r, c = divmod(k, cols)
        left = c * (tile_mm + gap_mm) / width_mm
        bottom = (legend_mm + (rows - 1 - r) * (tile_h_mm + gap_mm)) / height_mm
        ax = fig.add_axes([left, bottom, tile_mm / width_mm, tile_h_mm / height_mm])
        # RGBA (opaque): the PNG's resampling then runs on float32 rather than float64 RGBA (matplotlib adds the
        # alpha channel as float64 to an RGB image), 0.1 s of CPU less; the same bytes in the PNG (each k / 255 in
        # float32 gives back k times 255 in float32 as in float64: all 256 checked; the tiles are opaque, sampled
        # nearest) and in the SVG (the image unsampled: RGB gets the same opaque alpha channel)
        img = np.asarray(Image.open(io.BytesIO(view["png"])).convert("RGBA"))
        ax.imshow(img, extent=(0, width_px, height_px, 0), interpolation="none")
        ax.set_xlim(0, width_px)
        ax.set_ylim(height_px, 0)
        ax.set_axis_off()
        ax.add_patch(Rectangle((0, 0), width_px, height_px, fill=False, ec="#999999", lw=0.6))
        side = view["side"]
        ax.text(width_px - 6 if side == "left" else 6, 8, view["label"], ha="right" if side == "left" else "left",
                va="top", fontsize=FONT_PT, family=_FAMILY, color="#333333", style="italic")
        drawn["views"].append(view["label"])
        column = [blocks[e] for e in assignment[k]]
        _place(column, view["anchors"], 0.03 * height_px, 0.97 * height_px, px_per_pt)
        edge = (0.30 * width_px - 4) if side == "left" else (0.70 * width_px + 4)
        for b in column:
            _draw_block(ax, b, side, edge, view["anchors"][b.element], px_per_pt, drawn)
    # legend: the classes drawn, the links, the frames
    lax = fig.add_axes([0.0, 0.0, 1.0, (legend_mm - 1.0) / height_mm])
    lax.set_xlim(0, width_mm)
    lax.set_ylim(legend_mm - 1.0, 0)
    lax.set_axis_off()
    y = 3.0
    for row in legend_rows:
        for x, (kind, label, color) in row:
            if kind == "class":
                lax.plot([x + 1.5], [y], marker="o", ms=6, color=color, mec="black", mew=0.3)
            elif kind == "link":
                lax.add_line(Line2D([x, x + 3.2], [y, y], lw=3, color=color))
            lax.text(x + (4.0 if kind != "text" else 0.0), y, label, va="center", ha="left", fontsize=FONT_PT,
                     family=_FAMILY)
            drawn["legend"].append(label)
        y += 4.6
    y -= 4.6
    note = "Tn: row n of the tolerance table" + ("" if rendered.get("links") else
                                                  "; no links declared: the kinematic chains are drawn")
    lax.text(0.0, y + 4.6, note, va="center", ha="left", fontsize=FONT_PT, family=_FAMILY, color="#333333")
    drawn["legend"].append(note)
    return fig, drawn


def _legend_entries(rendered: dict, classes: dict, with_frames: bool) -> list:
    """(kind, words, colour) of the legend: the classes drawn, the links, the frames."""
    entries = [("class", CLASS_LABELS[c], CLASS_RGB[c]) for c in CLASS_ORDER if c in set(classes.values())]
    entries += [("link", _LINK_LABELS[k], color) for k, color in _link_colors(rendered)]
    entries += [("text", "x, y, z frame axes: red, green, blue", None)]
    if with_frames:
        entries += [("text", "frames: ISO 1101, zones in mm", None)]
    return entries


def _legend_rows(entries: list, width_mm: float) -> list[list]:
    """The legend entries in rows that fit the width, each with its x (mm)."""
    rows: list[list] = [[]]
    x = 0.0
    for entry in entries:
        w = (4.0 if entry[0] != "text" else 0.0) + text_width_pt(entry[1]) * 25.4 / 72.0 + 5.0
        if x + w > width_mm and rows[-1]:
            rows.append([])
            x = 0.0
        rows[-1].append((x, entry))
        x += w
    return rows


def _link_colors(rendered: dict) -> list:
    """(kind, colour) of the links drawn, base first (from the rendered views)."""
    return [(k, tuple(c)) for k, c in rendered.get("link_colors") or [("other", (0.62, 0.62, 0.64))]]


def figure_png(fig, width_px: int = 1600) -> bytes:
    """The figure as PNG bytes, ``width_px`` wide (no timestamp: the same figure gives the same bytes)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=width_px / fig.get_figwidth(), metadata={"Software": None})
    return buf.getvalue()


def figure_svg(fig) -> str:
    """The figure as an SVG element for inlining in HTML: text kept as text, deterministic ids, no date."""
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "hyperstat", "svg.image_inline": True}):
        fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None})
    text = buf.getvalue()
    return text[text.index("<svg"):]
