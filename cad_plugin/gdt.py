"""ISO 1101 geometrical characteristic symbols, drawn as vector strokes (the report's and the pictures' one source).

Units: a symbol lives in the unit square (x right, y up); the renderers scale it to a cell.

Several ISO 1101 symbols (position, symmetry, profile, total run-out) have no glyph in the
fonts the report is printed with (DejaVu, which the machine's Chromium uses), so every
symbol is drawn from these strokes: :func:`symbol_svg` for the report's feature control frames,
:func:`sheet_symbol` for the part drawings (:class:`hyperstat.cad_plugin.svg_sheet.SvgSheet`) and
:func:`draw_symbol` for the matplotlib pictures.

>>> sorted(SYMBOLS)[:3]
['angularity', 'circular run-out', 'circularity']
>>> symbol_svg("perpendicularity", 12).startswith('<svg')
True
>>> frame_cells({"characteristic": "position", "zone": 0.2, "diameter_zone": True, "datums": ["A", "B"]})
['position', '\u23000.2', 'A', 'B']
"""

from __future__ import annotations

__all__ = ["SYMBOLS", "symbol_of", "symbol_svg", "draw_symbol", "sheet_symbol", "placed_strokes", "frame_cells", "zone_text"]

#: characteristic -> strokes: ("line", x0, y0, x1, y1), ("circle", cx, cy, r), ("arc", cx, cy, r, theta0, theta1) (deg)
SYMBOLS: dict[str, list[tuple]] = {
    "straightness": [("line", 0.1, 0.5, 0.9, 0.5)],
    "flatness": [("line", 0.25, 0.3, 0.9, 0.3), ("line", 0.9, 0.3, 0.75, 0.7), ("line", 0.75, 0.7, 0.1, 0.7),
                 ("line", 0.1, 0.7, 0.25, 0.3)],
    "circularity": [("circle", 0.5, 0.5, 0.32)],
    "cylindricity": [("circle", 0.5, 0.5, 0.26), ("line", 0.15, 0.1, 0.45, 0.9), ("line", 0.55, 0.1, 0.85, 0.9)],
    "profile of a line": [("arc", 0.5, 0.3, 0.38, 0.0, 180.0)],
    "profile of a surface": [("arc", 0.5, 0.3, 0.38, 0.0, 180.0), ("line", 0.12, 0.3, 0.88, 0.3)],
    "parallelism": [("line", 0.2, 0.15, 0.5, 0.85), ("line", 0.5, 0.15, 0.8, 0.85)],
    "perpendicularity": [("line", 0.5, 0.2, 0.5, 0.85), ("line", 0.12, 0.2, 0.88, 0.2)],
    "angularity": [("line", 0.12, 0.2, 0.88, 0.2), ("line", 0.12, 0.2, 0.8, 0.8)],
    "position": [("circle", 0.5, 0.5, 0.27), ("line", 0.08, 0.5, 0.92, 0.5), ("line", 0.5, 0.08, 0.5, 0.92)],
    "coaxiality": [("circle", 0.5, 0.5, 0.36), ("circle", 0.5, 0.5, 0.18)],
    "concentricity": [("circle", 0.5, 0.5, 0.36), ("circle", 0.5, 0.5, 0.18)],
    "symmetry": [("line", 0.1, 0.5, 0.9, 0.5), ("line", 0.25, 0.75, 0.75, 0.75), ("line", 0.25, 0.25, 0.75, 0.25)],
    "circular run-out": [("line", 0.2, 0.15, 0.8, 0.85), ("line", 0.8, 0.85, 0.52, 0.78), ("line", 0.8, 0.85, 0.74, 0.57)],
    "total run-out": [("line", 0.15, 0.15, 0.6, 0.85), ("line", 0.6, 0.85, 0.36, 0.78), ("line", 0.6, 0.85, 0.56, 0.6),
                      ("line", 0.4, 0.15, 0.85, 0.85), ("line", 0.85, 0.85, 0.61, 0.78),
                      ("line", 0.85, 0.85, 0.81, 0.6), ("line", 0.15, 0.15, 0.4, 0.15)],
}


def symbol_of(callout: dict) -> str:
    """The characteristic of a drawing callout, normalised to a key of :data:`SYMBOLS` (or as given)."""
    return str(callout.get("characteristic", "")).strip().lower().replace("_", " ")


def zone_text(callout: dict) -> str:
    """The tolerance cell: ``"0.37"``, or ``"\u23000.2"`` for a cylindrical zone (mm, as drawings print it)."""
    zone = callout.get("zone")
    text = "-" if zone is None else f"{float(zone):.3g}"
    return ("\u2300" if callout.get("diameter_zone") else "") + text


def frame_cells(callout: dict) -> list[str]:
    """The cells of a feature control frame: characteristic, tolerance, datums in order of precedence."""
    return [symbol_of(callout), zone_text(callout), *[str(d) for d in callout.get("datums") or []]]


def symbol_svg(characteristic: str, size: float, stroke: float = 1.0) -> str:
    """The symbol as an inline SVG of ``size`` (CSS px); unknown characteristics print their name."""
    from html import escape

    strokes = SYMBOLS.get(characteristic)
    if strokes is None:
        return f'<span class="gdt-name">{escape(characteristic)}</span>'
    parts = []
    for s in strokes:
        if s[0] == "line":
            _, x0, y0, x1, y1 = s
            parts.append(f'<line x1="{x0:.3f}" y1="{1 - y0:.3f}" x2="{x1:.3f}" y2="{1 - y1:.3f}"/>')
        elif s[0] == "circle":
            _, cx, cy, r = s
            parts.append(f'<circle cx="{cx:.3f}" cy="{1 - cy:.3f}" r="{r:.3f}"/>')
        else:
            import math

            _, cx, cy, r, a0, a1 = s
            x0, y0 = cx + r * math.cos(math.radians(a0)), 1 - (cy + r * math.sin(math.radians(a0)))
            x1, y1 = cx + r * math.cos(math.radians(a1)), 1 - (cy + r * math.sin(math.radians(a1)))
            parts.append(f'<path d="M{x0:.3f},{y0:.3f} A{r:.3f},{r:.3f} 0 0 0 {x1:.3f},{y1:.3f}"/>')
    return (f'<svg class="gdt" width="{size:g}" height="{size:g}" viewBox="0 0 1 1" role="img" '
            f'aria-label="{escape(characteristic)}"><title>{escape(characteristic)}</title>'
            f'<g fill="none" stroke="currentColor" stroke-width="{0.09 * stroke:.3f}" stroke-linecap="round">'
            + "".join(parts) + "</g></svg>")


def placed_strokes(characteristic: str, x: float, y: float, size: float) -> list[tuple] | None:
    """The symbol's strokes placed in the box ``[x, x + size] x [y - size, y]`` (y downwards, as on a page):
    ``("line", xs, ys)``, ``("circle", cx, cy, r)``, ``("arc", cx, cy, r, theta0, theta1)`` (degrees, counter-clockwise
    as seen, from +x towards the page's up); None when the characteristic has no symbol.

    >>> placed_strokes("perpendicularity", 0.0, 10.0, 10.0)[0]
    ('line', [5.0, 5.0], [8.0, 1.5])
    """
    strokes = SYMBOLS.get(characteristic)
    if strokes is None:
        return None
    out = []
    for s in strokes:
        if s[0] == "line":
            _, x0, y0, x1, y1 = s
            out.append(("line", [x + size * x0, x + size * x1], [y - size * y0, y - size * y1]))
        elif s[0] == "circle":
            _, cx, cy, r = s
            out.append(("circle", x + size * cx, y - size * cy, size * r))
        else:
            _, cx, cy, r, a0, a1 = s
            out.append(("arc", x + size * cx, y - size * cy, size * r, a0, a1))
    return out


def draw_symbol(ax, characteristic: str, x: float, y: float, size: float, **line) -> bool:
    """Draw the symbol in the box ``[x, x + size] x [y - size, y]`` of ``ax`` (data units, y downwards).

    Returns False when the characteristic has no symbol (the caller then writes its name).
    """
    from matplotlib.patches import Arc, Circle

    strokes = placed_strokes(characteristic, x, y, size)
    if strokes is None:
        return False
    line = {"color": "black", "lw": 0.7, **line}
    for s in strokes:
        if s[0] == "line":
            ax.plot(s[1], s[2], solid_capstyle="round", **line)
        elif s[0] == "circle":
            ax.add_patch(Circle(s[1:3], s[3], fill=False, ec=line["color"], lw=line["lw"]))
        else:
            _, cx, cy, r, a0, a1 = s  # y points down in the view axes: mirror the angles
            ax.add_patch(Arc((cx, cy), 2 * r, 2 * r, theta1=-a1, theta2=-a0, ec=line["color"], lw=line["lw"]))
    return True


def sheet_symbol(sheet, characteristic: str, x: float, y: float, size: float, color: str = "black",
                 lw: float = 0.7) -> bool:
    """Draw the symbol in the box ``[x, x + size] x [y - size, y]`` of a
    :class:`hyperstat.cad_plugin.svg_sheet.SvgSheet` (mm, y downwards), as :func:`draw_symbol` draws it.

    Returns False when the characteristic has no symbol (the caller then writes its name).
    """
    strokes = placed_strokes(characteristic, x, y, size)
    if strokes is None:
        return False
    for s in strokes:
        if s[0] == "line":
            sheet.line(s[1], s[2], color=color, lw=lw, cap="round")
        elif s[0] == "circle":
            sheet.circle(*s[1:], color=color, lw=lw)
        else:
            sheet.arc(*s[1:], color=color, lw=lw)
    return True
