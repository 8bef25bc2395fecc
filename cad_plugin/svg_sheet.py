"""A drawing sheet written straight to SVG: lines, polygons, circles, arcs, leaders and text kept as text.

Units: the sheet in mm (x right, y down from its top left corner); type sizes and line widths in pt.  The SVG's
user unit is the pt (its ``viewBox`` in pt, its ``width`` and ``height`` in pt), as matplotlib's SVG backend
writes a figure, so that a page inlines either the same way.

The part drawings are made of a few hundred strokes and labels.  Drawn through matplotlib's figure, every stroke
and label was an artist with its transforms and properties, and saving them took most of a report's drawing time
(1.6 s of CPU under cProfile for the Tripteor's 14 parts); this sheet writes each primitive as one SVG element
(0.16 s under cProfile).  Text
is placed as matplotlib places it: its anchor (``ha``) and its vertical alignment (``va``) from the font's own
metrics (FreeType, through matplotlib's ``ft2font``, the same font file), so a label lands where the layout,
which measures the same font, expects it.

>>> sheet = SvgSheet(20.0, 10.0)
>>> sheet.line([0, 0], [10, 5], lw=0.5)
>>> sheet.text(10, 5, "A", ha="center", va="center")
>>> svg = sheet.svg()
>>> svg.startswith("<svg") and svg.count("<path") == 1 and ">A</text>" in svg
True
"""

from __future__ import annotations

import math
from functools import lru_cache
from html import escape
from typing import Iterable, Sequence

import numpy as np

__all__ = ["SvgSheet", "text_box_pt"]

_PT_PER_MM = 72.0 / 25.4


def _num(v: float) -> str:
    """A coordinate in pt, to 1/1000 pt (0.35 µm on paper), without trailing zeros."""
    text = f"{float(v):.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


_FONT_SCALE = 100.0  # the size the metrics are taken at (pt), then scaled: as matplotlib's SVG backend measures


@lru_cache(maxsize=None)
def _font(family: str, style: str):
    from matplotlib import font_manager, ft2font

    font = ft2font.FT2Font(font_manager.findfont(font_manager.FontProperties(family=family, style=style)))
    font.set_size(_FONT_SCALE, 72)
    return font


@lru_cache(maxsize=4096)
def text_box_pt(text: str, size: float, family: str = "DejaVu Sans", style: str = "normal") -> tuple[float, float]:
    """``(ascent, descent)`` of one line of ``text`` (pt, from the baseline up and down) as matplotlib lays it out:
    the glyphs' own extent (FreeType, unhinted, measured at 100 pt and scaled, as its SVG backend measures) and at
    least the font's typographic ascender and descender (its OS/2 table).

    >>> a, d = text_box_pt("Ag", 8.0)
    >>> 5.0 < a < 10.0 and 1.0 < d < 3.0
    True
    """
    from matplotlib import ft2font

    font = _font(family, style)
    flags = ft2font.LoadFlags.NO_HINTING if hasattr(ft2font, "LoadFlags") else ft2font.LOAD_NO_HINTING
    scale = float(size) / _FONT_SCALE / 64.0  # FreeType's 1/64 pixels at 72 dpi, to pt at ``size``
    font.set_text(text, 0.0, flags=flags)
    height, descent = font.get_width_height()[1] * scale, font.get_descent() * scale
    typo = font.get_sfnt_table("OS/2")
    if typo is None:  # a font without the table: the extent of "lp", as matplotlib's fallback
        font.set_text("lp", 0.0, flags=flags)
        h, d = font.get_width_height()[1] * scale, font.get_descent() * scale
        least_ascent, least_descent = h - d, d
    else:
        em = float(size) / font.get_sfnt_table("head")["unitsPerEm"]
        least_ascent, least_descent = typo["sTypoAscender"] * em, -typo["sTypoDescender"] * em
    return max(height - descent, least_ascent), max(descent, least_descent)


class SvgSheet:
    """A sheet ``width_mm`` x ``height_mm``: add strokes and labels in mm (y down), then :meth:`svg`.

    Parameters
    ----------
    width_mm, height_mm : float
        The sheet's size (mm).
    """

    def __init__(self, width_mm: float, height_mm: float):
        self.width_mm, self.height_mm = float(width_mm), float(height_mm)
        self._parts: list[str] = []

    @staticmethod
    def _xy(x: float, y: float) -> str:
        return f"{_num(x * _PT_PER_MM)} {_num(y * _PT_PER_MM)}"

    def _d(self, points: np.ndarray, closed: bool = False) -> str:
        pts = np.asarray(points, float) * _PT_PER_MM
        d = "M" + " L".join(f"{_num(x)} {_num(y)}" for x, y in pts)
        return d + (" Z" if closed else "")

    @staticmethod
    def _stroke(color: str, lw: float, dashes: Sequence[float] | None = None, cap: str = "butt",
                join: str = "miter") -> str:
        s = f'stroke="{color}" stroke-width="{_num(lw)}"'
        if cap != "butt":
            s += f' stroke-linecap="{cap}"'
        if join != "miter":
            s += f' stroke-linejoin="{join}"'
        if dashes:  # in units of the line width, as matplotlib scales a dash pattern
            s += ' stroke-dasharray="' + ",".join(_num(v * lw) for v in dashes) + '"'
        return s

    def line(self, xs: Iterable[float], ys: Iterable[float], color: str = "black", lw: float = 1.0,
             cap: str = "butt") -> None:
        """One polyline through ``(xs[i], ys[i])`` (mm), ``lw`` pt wide."""
        pts = np.column_stack([np.asarray(list(xs), float), np.asarray(list(ys), float)])
        self._parts.append(f'<path d="{self._d(pts)}" fill="none" {self._stroke(color, lw, cap=cap)}/>')

    def lines(self, polylines: Sequence[np.ndarray], color: str = "black", lw: float = 1.0,
              dashes: Sequence[float] | None = None, cap: str = "butt", join: str = "miter") -> None:
        """Many polylines (each an ``(n, 2)`` array, mm) in one stroke style: one SVG path.  ``dashes``: the
        dash pattern in line widths (matplotlib's ``(0, (3, 2))`` is ``(3, 2)``)."""
        if not len(polylines):
            return
        d = " ".join(self._d(p) for p in polylines)
        self._parts.append(f'<path d="{d}" fill="none" {self._stroke(color, lw, dashes, cap, join)}/>')

    def polygon(self, points: np.ndarray, fill: str = "black", color: str = "black", lw: float = 1.0) -> None:
        """A closed polygon (mm), filled and outlined."""
        self._parts.append(f'<path d="{self._d(points, closed=True)}" fill="{fill}" {self._stroke(color, lw)}/>')

    def rect(self, x: float, y: float, w: float, h: float, fill: str = "none", color: str = "black",
             lw: float = 1.0) -> None:
        """A rectangle from its top left corner ``(x, y)`` (mm), ``w`` by ``h`` mm."""
        k = _PT_PER_MM
        self._parts.append(f'<rect x="{_num(x * k)}" y="{_num(y * k)}" width="{_num(w * k)}" height="{_num(h * k)}" '
                           f'fill="{fill}" {self._stroke(color, lw)}/>')

    def circle(self, cx: float, cy: float, r: float, color: str = "black", lw: float = 1.0,
               fill: str = "none") -> None:
        """A circle of centre ``(cx, cy)`` and radius ``r`` (mm)."""
        k = _PT_PER_MM
        self._parts.append(f'<circle cx="{_num(cx * k)}" cy="{_num(cy * k)}" r="{_num(r * k)}" fill="{fill}" '
                           f'{self._stroke(color, lw)}/>')

    def arc(self, cx: float, cy: float, r: float, start_deg: float, end_deg: float, color: str = "black",
            lw: float = 1.0) -> None:
        """A circular arc from ``start_deg`` to ``end_deg`` (counter-clockwise as seen on the sheet, angles from
        +x towards the sheet's up)."""
        k = _PT_PER_MM
        a0, a1 = math.radians(start_deg), math.radians(end_deg)
        x0, y0 = cx + r * math.cos(a0), cy - r * math.sin(a0)
        x1, y1 = cx + r * math.cos(a1), cy - r * math.sin(a1)
        large = 1 if (end_deg - start_deg) % 360.0 > 180.0 else 0
        self._parts.append(f'<path d="M{self._xy(x0, y0)} A{_num(r * k)} {_num(r * k)} 0 {large} 0 '
                           f'{self._xy(x1, y1)}" fill="none" {self._stroke(color, lw)}/>')

    def leader(self, start: Sequence[float], target: Sequence[float], lw: float = 0.45, head_pt: float = 7.0,
               color: str = "black") -> None:
        """A leader line from ``start`` to ``target`` (mm) ending in a filled arrowhead at ``target``: matplotlib's
        ``-|>`` arrow of ``mutation_scale`` ``head_pt`` (a head 0.4 of it long, 0.2 of it wide each side, pt)."""
        a, b = np.asarray(start, float), np.asarray(target, float)
        u = b - a
        n = float(np.linalg.norm(u))
        if n < 1e-12:
            return
        u /= n
        length, half = 0.4 * head_pt / _PT_PER_MM, 0.2 * head_pt / _PT_PER_MM
        base = b - length * u
        side = np.array([-u[1], u[0]]) * half
        self.line([a[0], base[0]], [a[1], base[1]], color=color, lw=lw)
        self.polygon(np.array([b, base + side, base - side]), fill=color, color=color, lw=lw)

    def text(self, x: float, y: float, text: str, ha: str = "left", va: str = "baseline", fontsize: float = 8.0,
             family: str = "DejaVu Sans", style: str = "normal", color: str = "black", weight: str = "normal") -> None:
        """A line of text at ``(x, y)`` (mm): ``ha`` left, center or right; ``va`` baseline, center or top (the
        line's box as matplotlib measures it: :func:`text_box_pt`)."""
        if not text:
            return
        a, d = text_box_pt(text, float(fontsize), family, style)
        shift = {"baseline": 0.0, "center": 0.5 * (a - d), "top": a, "bottom": -d}[va]
        anchor = {"left": "start", "center": "middle", "right": "end"}[ha]
        k = _PT_PER_MM
        css = f"font: {'italic ' if style == 'italic' else ''}{'bold ' if weight == 'bold' else ''}" \
              f"{_num(fontsize)}px '{family}'"
        attrs = f'x="{_num(x * k)}" y="{_num(y * k + shift)}" style="{css}"'
        if anchor != "start":
            attrs += f' text-anchor="{anchor}"'
        if color != "black":
            attrs += f' fill="{color}"'
        self._parts.append(f'<text {attrs}>{escape(text, quote=False)}</text>')

    def svg(self) -> str:
        """The sheet as an SVG element (text as text, no date, no ids: the same drawing gives the same bytes)."""
        w, h = _num(self.width_mm * _PT_PER_MM), _num(self.height_mm * _PT_PER_MM)
        return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}pt" height="{h}pt" viewBox="0 0 {w} {h}" '
                f'version="1.1">\n<rect width="{w}" height="{h}" fill="white"/>\n' + "\n".join(self._parts) + "\n</svg>\n")
