"""Off-screen pyvista views: the picture shows the verdict colours of the markers."""

import json
import warnings

import numpy as np
from PIL import Image

from hyperstat.cad_plugin import build_template
from hyperstat.cad_plugin.assembly import VERDICT_COLORS, element_verdicts
from hyperstat.cad_plugin.view import render_png
from hyperstat.solver import analyze
from hyperstat.solver.cli import jsonable

from tests.conftest import TEMPLATES


def _pixels_of(img: np.ndarray, rgb) -> int:
    target = np.round(np.array(rgb) * 255)
    return int(np.sum(np.all(np.abs(img[:, :, :3].astype(float) - target) <= 4, axis=2)))


def test_rendered_view_contains_every_verdict_colour(tmp_path):
    mech = build_template(TEMPLATES / "tripteor_x7.py").mechanism()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analysis = jsonable(analyze(mech).to_dict())
    classes = set(element_verdicts(analysis).values())
    assert {"forced", "coupled", "free-influential", "free-non-influent"} <= classes
    out = render_png(mech, tmp_path / "t.png", analysis=analysis, window_size=(1000, 800))
    img = np.asarray(Image.open(out).convert("RGB"))
    assert img.shape == (800, 1000, 3)
    for cls in classes:
        assert _pixels_of(img, VERDICT_COLORS[cls]) > 30, cls
    # without an analysis there is no verdict sphere at all
    plain = np.asarray(Image.open(render_png(mech, tmp_path / "p.png", window_size=(1000, 800))).convert("RGB"))
    assert _pixels_of(plain, VERDICT_COLORS["forced"]) == 0
    assert json.dumps(analysis)  # the analysis the view used is plain JSON
