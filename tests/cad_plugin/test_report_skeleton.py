"""The report's skeleton drawing laid out ahead of the tolerance values by the views' child (units: mm, rad).

A report with part drawings keeps its feature control frames on the parts' pages: the skeleton drawing then shows
no frame, and the views' child draws it before the values are known
(:func:`hyperstat.cad_plugin.report.skeleton_views_drawn`).  It must be the drawing ``write_report`` would make at
the end, and be used only when it is.
"""

from __future__ import annotations

import warnings

import pytest

from hyperstat.cad_plugin import build_template
from hyperstat.cad_plugin import report
from hyperstat.solver import analyze
from hyperstat.solver.cli import jsonable
from hyperstat.solver.tolerances.classification import classify

from tests.cad_plugin.contract import with_contract_fields
from tests.conftest import TEMPLATES


@pytest.fixture(scope="module")
def crank():
    mech = build_template(TEMPLATES / "slider_crank.py").mechanism()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech)
    return mech, jsonable({**result.to_dict(), "tolerances": classify(mech, result).to_dict()})


def test_the_drawing_without_items_is_the_drawing_of_items_without_frames(crank):
    """skeleton_figure reads the items only for their frames: items that carry none draw what no item draws."""
    from hyperstat.cad_plugin.view import render_views

    mech, analysis = crank
    rendered = render_views(mech, analysis, tile=(300, 300))
    items = [{**t, "drawing": []} for t in with_contract_fields({"tolerances": analysis["tolerances"]})
             ["tolerances"]["items"]]
    title = f"Skeleton of {mech.name}"
    assert report.skeleton_drawing(rendered, items, title) == report.skeleton_drawing(rendered, [], title)


def test_write_report_uses_the_drawing_made_ahead_only_when_it_is_the_same(slider_crank_report, tmp_path,
                                                                          monkeypatch):
    _, doc = slider_crank_report
    drawn = []
    monkeypatch.setattr(report, "skeleton_drawing",
                        lambda rendered, items, title: drawn.append(items) or ("<svg>here</svg>", b"here", {}))
    ahead = {"title": f"Skeleton of {doc['mechanism']}", "svg": "<svg>ahead</svg>", "png": b"ahead", "words": {}}
    images = {"rendered": {"views": []}, "parts": []}
    assert doc["drawings"]  # frames on the parts' pages: the drawing made ahead is the one
    report.write_report(doc, tmp_path / "a", images={**images, "skeleton": ahead})
    assert drawn == [] and (tmp_path / "a" / "skeleton_views.png").read_bytes() == b"ahead"
    # no part drawing: the items' frames go on the skeleton, drawn here
    framed = with_contract_fields({**doc, "drawings": []})
    assert any(t.get("drawing") for t in framed["tolerances"]["items"])
    report.write_report(framed, tmp_path / "b", images={**images, "skeleton": ahead})
    assert len(drawn) == 1 and (tmp_path / "b" / "skeleton_views.png").read_bytes() == b"here"
    # another title (another mechanism's views): drawn here
    report.write_report(doc, tmp_path / "c", images={**images, "skeleton": {**ahead, "title": "Skeleton of x"}})
    assert len(drawn) == 2 and (tmp_path / "c" / "skeleton_views.png").read_bytes() == b"here"
