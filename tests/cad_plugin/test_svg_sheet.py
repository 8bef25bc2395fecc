"""The SVG sheet of the part drawings: well-formed SVG, text placed where matplotlib places it, strokes where asked.

Units: mm on the sheet, pt in the SVG (72 / 25.4 pt per mm).
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from hyperstat.cad_plugin.svg_sheet import SvgSheet

NS = "{http://www.w3.org/2000/svg}"
PT = 72.0 / 25.4


def _tree(svg: str) -> ET.Element:
    return ET.fromstring(svg)


def _mpl_text_y(x_mm: float, y_mm: float, text: str, va: str, ha: str, style: str = "normal") -> tuple[float, float]:
    """Where matplotlib's SVG backend writes a text's anchor (pt, y down): a second method, the library's own layout."""
    from matplotlib.figure import Figure

    from hyperstat.cad_plugin.drawing import figure_svg

    width, height = 100.0, 50.0
    fig = Figure(figsize=(width / 25.4, height / 25.4))
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_axis_off()
    ax.text(x_mm, y_mm, text, va=va, ha=ha, fontsize=8.0, family="DejaVu Sans", style=style)
    svg = figure_svg(fig)
    # matplotlib writes the anchor as x/y attributes, or as a translate() of the text element
    m = re.search(r'<text[^>]*x="([-\d.]+)"[^>]*y="([-\d.]+)"', svg) or \
        re.search(r'<text[^>]*transform="translate\(([-\d.]+)[ ,]([-\d.]+)\)', svg)
    assert m, svg[:2000]
    return float(m.group(1)), float(m.group(2))


@pytest.mark.parametrize("va", ["center", "top", "baseline"])
@pytest.mark.parametrize("ha", ["left", "center", "right"])
@pytest.mark.parametrize("text", ["base-F1, with calibration (T26)", "\u23000.0371", "A", "gjp"])
def test_text_stands_where_matplotlib_puts_it(text, ha, va):
    sheet = SvgSheet(100.0, 50.0)
    sheet.text(30.0, 20.0, text, ha=ha, va=va)
    node = _tree(sheet.svg()).find(f"{NS}text")
    x_mpl, y_mpl = _mpl_text_y(30.0, 20.0, text, va, ha)
    assert float(node.get("x")) == pytest.approx(x_mpl, abs=0.05)
    assert float(node.get("y")) == pytest.approx(y_mpl, abs=0.02)  # 0.007 mm on paper
    anchor = {"left": None, "center": "middle", "right": "end"}[ha]
    assert node.get("text-anchor") == anchor
    assert node.text == text


def test_the_sheet_is_one_svg_of_its_size_with_text_as_text():
    sheet = SvgSheet(186.0, 120.0)
    sheet.rect(10, 10, 20, 5, fill="white", lw=0.6)
    sheet.text(20, 12.5, "A & <B>", ha="center", va="center", style="italic", color="#333333")
    root = _tree(sheet.svg())
    assert root.tag == f"{NS}svg"
    assert float(root.get("width").removesuffix("pt")) == pytest.approx(186.0 * PT, abs=1e-3)
    assert [float(v) for v in root.get("viewBox").split()] == pytest.approx([0, 0, 186.0 * PT, 120.0 * PT], abs=1e-3)
    texts = root.findall(f"{NS}text")
    assert [t.text for t in texts] == ["A & <B>"] and "italic" in texts[0].get("style")
    rect = root.findall(f"{NS}rect")[1]  # the first is the white page
    assert float(rect.get("x")) == pytest.approx(10 * PT, abs=1e-3) and float(rect.get("height")) == pytest.approx(
        5 * PT, abs=1e-3)


def test_many_lines_are_one_path_with_the_dash_scaled_by_the_width():
    sheet = SvgSheet(50.0, 50.0)
    lines = [np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]), np.array([[20.0, 20.0], [30.0, 25.0]])]
    sheet.lines(lines, lw=0.35, dashes=(3, 2), color="#555555")
    (path,) = _tree(sheet.svg()).findall(f"{NS}path")
    pieces = re.findall(r"M([^M]+)", path.get("d"))
    assert len(pieces) == 2
    pts = [np.array([[float(v) for v in p.split()] for p in piece.replace("L", ",").split(",") if p.strip()])
           for piece in pieces]
    for got, want in zip(pts, lines):
        assert got == pytest.approx(want * PT, abs=1e-3)
    assert [float(v) for v in path.get("stroke-dasharray").split(",")] == pytest.approx([3 * 0.35, 2 * 0.35])


def _svg_arc_midpoint(x1, y1, r, large, sweep, x2, y2) -> tuple[float, float]:
    """The midpoint of an SVG circular arc from its endpoint form (SVG 1.1, appendix F.6.5, no rotation): its centre,
    start angle and signed sweep as the renderer computes them (y down)."""
    xp, yp = (x1 - x2) / 2, (y1 - y2) / 2
    sq = max(0.0, (r * r * r * r - r * r * yp * yp - r * r * xp * xp) / (r * r * yp * yp + r * r * xp * xp))
    coef = math.sqrt(sq) * (1.0 if large != sweep else -1.0)
    cxp, cyp = coef * yp, -coef * xp
    cx, cy = cxp + (x1 + x2) / 2, cyp + (y1 + y2) / 2
    u = ((xp - cxp) / r, (yp - cyp) / r)
    v = ((-xp - cxp) / r, (-yp - cyp) / r)
    theta = math.degrees(math.atan2(u[1], u[0]))
    delta = math.degrees(math.atan2(u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1])) % 360.0
    if not sweep and delta > 0:
        delta -= 360.0
    mid = math.radians(theta + delta / 2)
    return cx + r * math.cos(mid), cy + r * math.sin(mid)


@pytest.mark.parametrize("start, end, top", [(0.0, 180.0, (25.0, 15.0)), (180.0, 360.0, (25.0, 35.0)),
                                             (90.0, 180.0, (25 - 10 * math.cos(math.pi / 4), 25 - 10 * math.sin(math.pi / 4))),
                                             (0.0, 270.0, (25 - 10 * math.cos(math.pi / 4), 25 - 10 * math.sin(math.pi / 4)))])
def test_an_arc_ends_on_its_circle_and_turns_counter_clockwise_as_seen(start, end, top):
    """The "profile of a line" symbol is a half circle over its chord (0 to 180 degrees): drawn on a page (y down) it
    must bulge up.  The arc's midpoint is found as a renderer finds it, from the SVG's endpoint form."""
    sheet = SvgSheet(50.0, 50.0)
    sheet.arc(25.0, 25.0, 10.0, start, end)
    d = _tree(sheet.svg()).find(f"{NS}path").get("d")
    m = re.fullmatch(r"M([-\d.]+) ([-\d.]+) A([-\d.]+) ([-\d.]+) 0 (\d) (\d) ([-\d.]+) ([-\d.]+)", d)
    x0, y0, rx, ry, large, sweep, x1, y1 = (float(v) for v in m.groups())
    for (x, y), angle in (((x0, y0), start), ((x1, y1), end)):  # the ends on the circle, angles counted upwards
        assert (x / PT, y / PT) == pytest.approx((25 + 10 * math.cos(math.radians(angle)),
                                                  25 - 10 * math.sin(math.radians(angle))), abs=1e-3)
    assert rx == ry == pytest.approx(10 * PT, abs=1e-3)
    mx, my = _svg_arc_midpoint(x0, y0, rx, int(large), int(sweep), x1, y1)
    assert (mx / PT, my / PT) == pytest.approx(top, abs=1e-2)


def test_a_leader_ends_at_its_target_with_its_head():
    sheet = SvgSheet(50.0, 50.0)
    sheet.leader([5.0, 5.0], [30.0, 20.0])
    line, head = _tree(sheet.svg()).findall(f"{NS}path")
    tri = np.array([[float(v) for v in p.split()] for p in head.get("d").strip("M Z").split(" L")]) / PT
    assert tri[0] == pytest.approx([30.0, 20.0], abs=1e-3)  # the tip on the target
    length = np.linalg.norm(tri[0] - 0.5 * (tri[1] + tri[2])) * PT
    width = np.linalg.norm(tri[1] - tri[2]) * PT
    assert length == pytest.approx(0.4 * 7.0, abs=1e-2) and width == pytest.approx(2 * 0.2 * 7.0, abs=1e-2)
    end = np.array([float(v) for v in line.get("d").split("L")[1].split()]) / PT
    assert end == pytest.approx(0.5 * (tri[1] + tri[2]), abs=1e-3)  # the stem stops at the head's base
