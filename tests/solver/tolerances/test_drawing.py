"""Part drawings of every shipped template: every tolerance with a value carried by frames on real features.

Units: mm and rad; a frame's zone is a length in mm.

The values are set here (1e-3 rad or 0.01 mm per tolerance) so that the test does not depend on the
worst-case searches; ``test_part_drawings.py`` checks, with a drawing checker's own reading, that the frames
keep every statement within its value for three templates at their real values.  Here: what a frame admits,
read from its zone alone (an orientation zone ``t`` over a feature of length ``L`` admits a tilt ``t / L``, a
position zone ``t`` a shift ``t / 2``), on the parts' features and datum letters, for every template.
"""

from __future__ import annotations

import pytest

from hyperstat.solver.tolerances.drawing import add_drawing

from tests.solver.tolerances.common import classified

NAMES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar", "planar_3rrr"]
DRAWN = ("assembly", "accuracy-critical", "compensable")


@pytest.fixture(scope="module", params=NAMES)
def drawn(request):
    mech, _, _, cl = classified(request.param)
    for t in cl.items:
        t.value = None if t.cls not in DRAWN else (1e-3 if t.unit == "rad" else 0.01)
        t.drawing_value = t.value
    out = add_drawing(cl, mech)
    return request.param, mech, cl, out


def test_every_tolerance_with_a_value_is_on_a_part_drawing(drawn):
    name, _, cl, out = drawn
    assert not out["not_drawn"], (name, out["not_drawn"])
    for t in cl.items:
        if t.cls in DRAWN:
            assert t.drawing, (name, t.id, t.statement)
        else:
            assert not t.drawing, (name, t.id)
    parts = {d["part"] for d in out["drawings"]}
    for t in cl.items:
        for c in t.drawing:
            assert c["part"] in parts or c["characteristic"] in ("assembly requirement", "setup requirement"), c


def test_frames_name_their_datums_and_state_what_they_admit(drawn):
    """A frame's cells end with its datum letters, its zone is in mm, and the bound it states is its zone over the
    feature's length (a tilt) or half its zone (a shift)."""
    name, _, cl, out = drawn
    for d in out["drawings"]:
        letters = {x["letter"] for x in d["datums"]}
        for fr in d["frames"]:
            assert fr["frame"] == f"|{fr['symbol']}|{'⌀' if fr['zone_shape'] == 'cylinder' else ''}{fr['zone_mm']:g}|" \
                + "|".join(fr["datum_system"]) + "|", fr
            assert set(fr["datum_system"]) <= letters and fr["zone_mm"] > 0
            bound = fr["bounds"][0]
            if fr["characteristic"] in ("parallelism", "perpendicularity", "angularity"):
                assert bound["unit"] == "rad" and bound["limit"] == pytest.approx(fr["zone_mm"] / fr["length_mm"])
            else:
                assert bound["unit"] == "mm" and bound["limit"] == pytest.approx(fr["zone_mm"] / 2)


def test_a_prismatic_leg_is_perpendicular_to_its_base_revolute_in_the_tripteor():
    """The Tripteor's legs (joints 41-43) slide at right angles to the axis of the revolute that carries them (the
    base joints 21-23 turn each leg in its plane): a tilt of a leg's guide toward that axis is a perpendicularity."""
    mech, _, _, cl = classified("tripteor_x7")
    for t in cl.items:
        t.value = None if t.cls not in DRAWN else (1e-3 if t.unit == "rad" else 0.01)
        t.drawing_value = t.value
    out = add_drawing(cl, mech)
    legs = [fr for d in out["drawings"] for fr in d["frames"] if fr["feature"].split(".")[-1] in ("guide41", "guide43")]
    assert legs
    for fr in legs:
        assert fr["characteristic"] == "perpendicularity", fr["text"]
