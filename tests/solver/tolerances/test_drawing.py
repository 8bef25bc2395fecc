"""ISO 1101 callouts of every template (issue 29 item 4): present where they must be, on the safe side.

Units: mm and rad; a callout's zone is a length in mm.

The expected values come from what a zone allows, not from the code's output: a parallelism,
perpendicularity or angularity zone ``t`` over a feature of length ``L`` admits a tilt of ``t / L``
(rad), a position zone ``t`` (centred on the true position) or a coaxiality zone of diameter ``t`` a
shift of ``t / 2`` (mm).  Every defect of a tolerance within what its callouts admit must keep the
tolerance's statement within its value: for a statement ``sum c_i d_i = 0 +- v``, the admitted
defects give ``sum |c_i| admitted_i <= v``, whatever their signs.  The values are set here (1e-3 rad
or 0.01 mm per tolerance) so that the test does not depend on the worst-case search.
"""

from __future__ import annotations

import pytest

from hyperstat.solver.tolerances.drawing import add_drawing

from tests.solver.tolerances.common import classified

NAMES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar"]
DRAWN = ("assembly", "accuracy-critical")


def _admitted(callout: dict) -> float:
    """The defect a callout admits: a tilt (rad) for an orientation zone, a shift (mm) for a location zone."""
    if callout["characteristic"] in ("parallelism", "perpendicularity", "angularity"):
        return callout["zone"] / callout["feature_length"]
    return callout["zone"] / 2.0


@pytest.fixture(scope="module", params=NAMES)
def drawn(request):
    mech, _, _, cl = classified(request.param)
    for t in cl.items:
        t.value = None if t.cls not in DRAWN else (1e-3 if t.unit == "rad" else 0.01)
    add_drawing(cl, mech)
    return request.param, mech, cl


def test_every_assembly_and_accuracy_critical_tolerance_has_callouts_and_no_other(drawn):
    name, _, cl = drawn
    for t in cl.items:
        if t.cls in DRAWN:
            assert t.drawing, (name, t.id, t.statement)
            for c in t.drawing:
                assert c["unit"] == "mm" and c["zone"] > 0 and c["datums"] == ["A"] and c["datum_features"]["A"]
                assert c["frame"].startswith(f"|{c['symbol']}|") and c["frame"].endswith("|A|")
                assert c["text"] and c["feature"]
                if c["characteristic"] in ("parallelism", "perpendicularity", "angularity"):
                    assert c["feature_length"] > 0 and f"over {c['feature_length']:g} mm" in c["text"]
        else:
            assert not t.drawing, (name, t.id)


def test_the_callouts_keep_every_statement_within_its_value(drawn):
    """The admitted defects, at their bounds with the worst signs, never break the statement."""
    name, mech, cl = drawn
    where = {p.name: p.component for p in mech.parameters}
    for t in [t for t in cl.items if t.cls in DRAWN]:
        terms = {n: c for n, c in t.terms.items() if n in where and where[n] in "IJKabc"}
        if len(t.drawing) == 1 and len(terms) == 2:  # a like pair: the second feature relative to the first
            worst = abs(next(iter(terms.values()))) * _admitted(t.drawing[0])
        else:
            assert len(t.drawing) == len(terms), (name, t.id, t.statement)
            worst = sum(abs(c) * _admitted(k) for c, k in zip(terms.values(), t.drawing))
        assert worst <= t.value * (1 + 1e-12), (name, t.id, t.statement, worst, t.value)
        # rounded down to three significant digits, not more: at least 99 % of the value is used
        assert worst >= 0.99 * t.value, (name, t.id, worst, t.value)


def test_a_prismatic_leg_is_perpendicular_to_its_base_revolute_in_the_tripteor():
    """The Tripteor's legs (joints 41-43) slide at right angles to the axis of the revolute that carries them
    (the base joints 21-23 turn each leg in its plane): a tilt of a leg's axis is a perpendicularity."""
    mech, _, _, cl = classified("tripteor_x7")
    for t in cl.items:
        t.value = None if t.cls not in DRAWN else (1e-3 if t.unit == "rad" else 0.01)
    add_drawing(cl, mech)
    legs = [c for t in cl.items if t.cls in DRAWN for c in t.drawing
            if c["feature"] in ("axis of joint 41", "axis of joint 43") and c["feature_length"]]
    assert legs
    for c in legs:
        assert c["characteristic"] == "perpendicularity", c["text"]
