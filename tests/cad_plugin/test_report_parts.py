"""The report's part pages drawn in a forked child or read from the cache: the pages drawn in-process, to the byte.

Units: lengths and zones in mm.

The session's slider-crank report (``tests/cad_plugin/conftest.py``, ``--step-drawings``: its pages drawn in the
report's own process, with their solids) is the reference: its ``report.html`` holds the part-drawing section that
:func:`parts_html` lays out from the pages.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from hyperstat.cad_plugin import report_parts
from hyperstat.cad_plugin.report_parts import geometry_key, page_key, part_pages, parts_html
from hyperstat.solver.cache import Cache


def _types(doc: dict) -> dict:
    return {str(j["element"]): j.get("type") for j in doc["joints"]}


#: a new process (OCCT not loaded: the part pages' child is forked) draws two pages through the child, stores them
_CHILD = """
import json, sys
from hyperstat.cad_plugin.report import part_pages_worker
from hyperstat.cad_plugin.report_parts import parts_html
from hyperstat.solver.cache import Cache
doc, cache, out = json.load(open(sys.argv[1])), Cache(sys.argv[2]), sys.argv[3]
assert "OCP" not in sys.modules
types = {str(j["element"]): j.get("type") for j in doc["joints"]}
job = part_pages_worker(cache, lambda: (doc["drawings"][:1], types))  # the first part's solid built ahead
assert job._background._proc is not None, "no child was forked"
pages = job.result({"drawings": doc["drawings"], "joints": doc["joints"]})
assert "OCP" not in sys.modules  # drawn by the child
open(out, "w").write(json.dumps([parts_html(doc, pages), [p["assumed"] for p in pages]]))
"""


def test_pages_from_the_child_and_from_the_cache_are_the_report_s(slider_crank_report, tmp_path):
    out, doc = slider_crank_report
    assert doc["drawings"], "the slider-crank's report carries part drawings"
    in_process = part_pages(doc)
    section = parts_html(doc, in_process)
    # the report wrote the section of the pages drawn in its process (the same function, with the solids)
    assert section in (out / "report.html").read_text(encoding="utf-8")
    assert all(p["svg"] and p["solid"] is None and p["error"] is None for p in in_process)
    # two pages drawn by the child of a new process, sent back as JSON: the same section
    two = {**doc, "drawings": doc["drawings"][:2]}
    (tmp_path / "doc.json").write_text(json.dumps(two))
    subprocess.run([sys.executable, "-c", _CHILD, str(tmp_path / "doc.json"), str(tmp_path / "cache"),
                    str(tmp_path / "pages.json")], check=True, timeout=600)
    html, assumed = json.loads((tmp_path / "pages.json").read_text())
    assert html == parts_html(two, in_process[:2])
    assert assumed == [p["assumed"] for p in in_process[:2]]
    # the child stored its pages: this process reads them, computing none
    again = Cache(tmp_path / "cache")
    assert parts_html(two, part_pages(two, cache=again)) == html
    assert again.hits == ["part-page"] * 2 and not again.misses


def test_pages_from_solids_built_ahead_are_the_pages_built_after(slider_crank_report):
    _, doc = slider_crank_report
    types = _types(doc)
    after = part_pages(doc)
    # built ahead (as the report's child does while the values are computed): the first drawing as it will be, the
    # second with its features moved (a prediction that missed: that page must build its own solid)
    first, second = doc["drawings"][:2]
    moved = {**second, "features": [{**f, "point_mm": [v + 1.0 for v in f["point_mm"]]} for f in second["features"]]}
    assert geometry_key(moved, types) != geometry_key(second, types)
    try:
        assert report_parts.prebuild([first, moved], types) == 2
        ahead = part_pages(doc)
        assert [p["svg"] for p in ahead] == [p["svg"] for p in after]  # to the byte
        assert [p["assumed"] for p in ahead] == [p["assumed"] for p in after]
        # the first page took its solid and views; the moved one's were not used
        assert set(report_parts._PREBUILT) == {geometry_key(moved, types)}
    finally:
        report_parts._PREBUILT.clear()


def test_the_report_s_children_draw_the_pages_this_process_draws(slider_crank_report, tmp_path):
    """``hyperstat report`` as a user runs it (a new process, everything computed: its part pages' child builds the
    solids while the values are computed and draws the pages once they are) writes the part-drawing section of the
    same drawings drawn in this process."""
    import os

    from tests.conftest import TEMPLATES

    _, doc = slider_crank_report
    env = {k: v for k, v in os.environ.items() if k != "HYPERSTAT_NO_FORK"}
    subprocess.run([sys.executable, "-m", "hyperstat.cad_plugin.cli", "report", str(TEMPLATES / "slider_crank.py"),
                    "--out", str(tmp_path / "rep"), "--quiet", "--no-cache"], check=True, timeout=600, env=env)
    theirs = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert theirs["drawings"] == doc["drawings"]  # the same drawings: the same pages expected
    assert parts_html(doc, part_pages(doc)) in (tmp_path / "rep" / "report.html").read_text(encoding="utf-8")


def test_a_changed_drawing_is_drawn_again(slider_crank_report, tmp_path):
    _, doc = slider_crank_report
    drawing = doc["drawings"][0]
    frames = [fr for d in doc["drawings"] for fr in d["frames"]]
    assert frames
    keys = {page_key(d, _types(doc)) for d in doc["drawings"]}
    assert len(keys) == len(doc["drawings"])  # a page per part
    wider = {**drawing, "frames": [{**fr, "zone_mm": fr["zone_mm"] * 2} for fr in drawing["frames"]]}
    moved = {**drawing, "features": [{**f, "point_mm": [v + 1.0 for v in f["point_mm"]]} for f in drawing["features"]]}
    for changed in (wider, moved) if drawing["frames"] else (moved,):
        assert page_key(changed, _types(doc)) not in keys
    other_types = {k: ("P" if v == "R" else "R") for k, v in _types(doc).items()}
    assert page_key(drawing, other_types) != page_key(drawing, _types(doc))
    # a stored page that is not this part's is not used
    cache = Cache(tmp_path / "cache")
    k = page_key(drawing, _types(doc))
    cache.store("part-page", k, {"part": "another part", "svg": "<svg/>", "words": {}, "assumed": [], "error": None})
    page = part_pages({**doc, "drawings": [drawing]}, cache=cache)[0]
    assert page["part"] == drawing["part"] and page["svg"] != "<svg/>"



def _ink_boxes(svg: str) -> tuple[list, list]:
    """The labels ``(text, (x0, y0, x1, y1))`` and the datum letters' squares ``(x0, y0, x1, y1)`` of a part page's
    SVG (pt, y down): a label's box from its anchor, its width (the font's advances) and its ascent and descent."""
    import xml.etree.ElementTree as ET

    from hyperstat.cad_plugin.report_parts import _DATUM_BOX, text_width_pt
    from hyperstat.cad_plugin.svg_sheet import text_box_pt

    ns, pt = "{http://www.w3.org/2000/svg}", 72.0 / 25.4
    root = ET.fromstring(svg)
    labels, squares = [], []
    for node in root.iter(f"{ns}text"):
        x, y, text = float(node.get("x")), float(node.get("y")), node.text or ""
        w = text_width_pt(text)
        a, d = text_box_pt(text, 8.0)
        x0 = x - {"middle": 0.5 * w, "end": w}.get(node.get("text-anchor"), 0.0)
        labels.append((text, (x0, y - a, x0 + w, y + d)))
    for node in root.iter(f"{ns}rect"):
        w, h = float(node.get("width")), float(node.get("height"))
        if abs(w - _DATUM_BOX * pt) < 0.01 and abs(h - _DATUM_BOX * pt) < 0.01:
            x, y = float(node.get("x")), float(node.get("y"))
            squares.append((x, y, x + w, y + h))
    return labels, squares


def _overlap(a, b, pad: float = 0.0) -> bool:
    return a[0] < b[2] - pad and b[0] < a[2] - pad and a[1] < b[3] - pad and b[1] < a[3] - pad


@pytest.mark.parametrize("which", ["slider_crank_report", "tripteor_report"])
def test_no_datum_symbol_or_label_covers_another_label(which, request):
    """Read as a checker reads a drawing: every label clear of the others and of the datum letters' squares (the
    Tripteor's base drew its datum C's square over the second view's title)."""
    import re

    out, _doc = request.getfixturevalue(which)
    html = (out / "report.html").read_text(encoding="utf-8")
    pages = re.findall(r'<section class="part-page".*?</section>', html, flags=re.S)
    assert pages
    clashes, squares_seen = [], 0
    for page in pages:
        part = re.search(r"<h3[^>]*>(.*?)</h3>", page).group(1)
        for svg in re.findall(r"<svg xmlns=.*?</svg>", page, flags=re.S):
            labels, squares = _ink_boxes(svg)
            squares_seen += len(squares)
            for sq in squares:
                clashes += [(part, "square", text) for text, box in labels if _overlap(sq, box)
                            and not (box[0] >= sq[0] - 0.5 and box[2] <= sq[2] + 0.5)]  # but its own letter
            clashes += [(part, text, other) for i, (text, box) in enumerate(labels) for other, box2 in labels[i + 1:]
                        if _overlap(box, box2, 0.3)]
    assert squares_seen >= len(pages)  # every part has a datum at least: the squares were found
    assert not clashes, clashes
