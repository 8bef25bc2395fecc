"""The skeleton picture: pyvista off-screen views of the declared links, class colours, callouts and frames.

Units: lengths in mm, angles in rad.
"""

import io
import json
import warnings

import numpy as np
import pytest
from PIL import Image

from hyperstat.cad_plugin import build_template
from hyperstat.cad_plugin.palette import CLASS_LABELS, CLASS_RGB, RETIRED_WORDS, element_classes
from hyperstat.cad_plugin.view import choose_views, render_png, render_views, scene_of
from hyperstat.solver import analyze
from hyperstat.solver.cli import jsonable
from hyperstat.solver.tolerances.classification import classify

from tests.cad_plugin.contract import with_contract_fields
from tests.conftest import TEMPLATES


def _analysis(mech) -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech)
    return jsonable({**result.to_dict(), "tolerances": classify(mech, result).to_dict()})


def _pixels_of(img: np.ndarray, rgb, tol: int = 4) -> int:
    target = np.round(np.array(rgb) * 255)
    return int(np.sum(np.all(np.abs(img[:, :, :3].astype(float) - target) <= tol, axis=2)))


@pytest.fixture(scope="module")
def tripteor():
    mech = build_template(TEMPLATES / "tripteor_x7.py").mechanism()
    return mech, _analysis(mech)


def test_every_joint_lands_on_its_sphere_in_every_view(tripteor):
    mech, analysis = tripteor
    rendered = render_views(mech, analysis, tile=(600, 600))
    classes, _ = element_classes(analysis)
    assert set(rendered["classes"]) == set(classes) and len(rendered["views"]) == 4
    hits = total = 0
    for view in rendered["views"]:
        img = np.asarray(Image.open(io.BytesIO(view["png"])).convert("RGB")).astype(float)
        h, w = img.shape[:2]
        spots: dict = {}  # joints stacked on one point (a U or S joint) share one visible sphere
        for element, (x, y) in view["anchors"].items():
            assert 0 <= x < w and 0 <= y < h, (view["name"], element)
            if element in classes:  # the reference joint has no defect, no sphere
                spots.setdefault((round(x / 3), round(y / 3)), []).append((x, y, classes[element]))
        for group in spots.values():
            x, y = group[0][0], group[0][1]
            near = img[max(int(y) - 8, 0):int(y) + 9, max(int(x) - 8, 0):int(x) + 9].reshape(-1, 3)
            total += 1
            hits += any(np.any(np.all(np.abs(near - np.round(np.array(CLASS_RGB[c]) * 255)) <= 6, axis=1))
                        for _, _, c in group)  # unlit spheres: the exact class colour within 8 px
    assert hits >= 0.9 * total, (hits, total)


def test_the_picture_draws_the_declared_links(tripteor):
    mech, _ = tripteor
    scene = scene_of(mech)
    assert scene["declared"] and {"base", "platform", "leg1"} <= {link["name"] for link in scene["links"]}
    from dataclasses import replace

    links = mech.metadata["links"]
    without = replace(mech, metadata={**mech.metadata, "links": [d for d in links if d["name"] != "platform"]})
    a, b = render_views(mech, tile=(400, 400)), render_views(without, tile=(400, 400))
    assert a["links"] != b["links"] and "platform" not in b["links"]
    assert any(va["png"] != vb["png"] for va, vb in zip(a["views"], b["views"]))  # removing a link changes the picture


@pytest.mark.parametrize("name", ["five_bar", "slider_crank"])
def test_no_view_is_edge_on_to_a_planar_mechanism(name):
    mech = build_template(TEMPLATES / f"{name}.py").mechanism()
    scene = scene_of(mech)
    pts = np.array([j["origin"] for j in scene["joints"]] + [p for link in scene["links"] for p in link["points"]])
    normal = np.linalg.svd(pts - pts.mean(axis=0))[2][2]
    assert np.ptp(pts @ normal) < 1e-6  # planar
    views = choose_views(pts)
    cosines = [abs(float(v["direction"] @ normal)) for v in views]
    assert cosines[0] == pytest.approx(1.0) and min(cosines) == pytest.approx(1 / np.sqrt(3))
    for i in range(1, 4):  # three orthographic views of one frame
        for j in range(i + 1, 4):
            assert abs(float(views[i]["direction"] @ views[j]["direction"])) < 1e-12


def test_png_words_and_frames(tripteor, tmp_path):
    mech, analysis = tripteor
    contract = with_contract_fields(analysis)
    out = render_png(mech, tmp_path / "t.png", analysis=contract, width_px=1200, words=tmp_path / "t.json")
    img = np.asarray(Image.open(out).convert("RGB"))
    assert img.shape[1] == 1200
    words = json.loads((tmp_path / "t.json").read_text())
    classes = set(element_classes(analysis)[0].values())
    assert words["classes"] == [c for c in CLASS_LABELS if c in classes]
    for cls in classes:
        assert _pixels_of(img, CLASS_RGB[cls]) > 30, cls
        assert CLASS_LABELS[cls] in words["legend"]
    frames = [c for t in contract["tolerances"]["items"] for c in t["drawing"]]
    assert len(words["frames"]) == len(frames) > 0
    text = json.dumps(words).lower()
    assert not any(f'"{w}"' in text or f" {w} " in text for w in RETIRED_WORDS)
    # without an analysis there is no class sphere at all
    plain = np.asarray(Image.open(render_png(mech, tmp_path / "p.png", width_px=800)).convert("RGB"))
    assert all(_pixels_of(plain, CLASS_RGB[c]) == 0 for c in ("assembly", "accuracy-critical", "compensable"))
