"""Hypothesis files: relations linearised correctly, malformed files named precisely."""

import numpy as np
import pytest
import yaml

from hyperstat.solver import DataError, Kinematics
from hyperstat.solver.analysis.hypotheses import _geometry, _rows, check_hypotheses, load_hypotheses, parse_hypotheses


def _doc(**hyp):
    return {"format": "hyperstat-hypotheses", "version": 1,
            "axes": {"a2": {"element": "2"}, "a3": {"element": "3"}, "s4": {"element": "4"}},
            "points": {"p2": {"element": "2"}, "p3": {"element": "3"}},
            "hypotheses": [dict(id="h", **hyp)]}


def test_slider_crank_planarity_hypotheses(slider_crank, slider_crank_analysis):
    doc = {"format": "hyperstat-hypotheses", "version": 1,
           "axes": {"a2": {"element": "2"}, "a3": {"element": "3"}, "s4": {"element": "4"}},
           "points": {"p3": {"element": "3"}},
           "hypotheses": [{"id": "pins_parallel", "parallel": ["a2", "a3"]},
                          {"id": "slide_perp_pin", "perpendicular": ["s4", "a3"]},
                          {"id": "pin3_on_axis2", "point_on_axis": ["p3", "a2"]},
                          {"id": "pins_coplanar", "coplanar": ["a2", "a3"]}]}
    axes, points, hyps = parse_hypotheses(doc, slider_crank)
    with pytest.raises(DataError, match=r"hypothesis 'pin3_on_axis2' .* does not hold at the nominal geometry"):
        check_hypotheses(slider_crank, slider_crank_analysis, axes, points, hyps)
    doc["hypotheses"].pop(2)
    axes, points, hyps = parse_hypotheses(doc, slider_crank)
    v = {h.id: h for h in check_hypotheses(slider_crank, slider_crank_analysis, axes, points, hyps)}
    # planarity: pins parallel and the slide perpendicular to them are forced (dI3, dJ3, dJ4 forced)
    assert v["pins_parallel"].verdict == "required"
    assert v["slide_perp_pin"].verdict == "required"
    # two parallel lines are coplanar whatever the in-plane shifts: the condition is implied too
    assert v["pins_coplanar"].verdict == "required"


def test_linearised_relation_matches_finite_differences(slider_crank):
    """The perpendicularity row equals d(n4 . n3)/dxi computed on the nonlinear model."""
    kin = Kinematics(slider_crank)
    axes, points, hyps = parse_hypotheses(_doc(perpendicular=["s4", "a3"]), slider_crank)
    el_pose, frame_pose, twists = _geometry(kin)
    row = _rows(hyps[0], axes, points, el_pose, frame_pose, twists)[0]
    h = 1e-7
    q = slider_crank.home[None, :]
    fd = np.zeros(kin.n_xi)
    for j in range(kin.n_xi):
        e = np.zeros(kin.n_xi)
        e[j] = h
        vals = []
        for sgn in (1, -1):
            st = kin.evaluate(q, sgn * e, jacobians=False)
            frames = {slider_crank.chains[ci].elements[ei].name: t[0] for (ci, ei), t in st.element_frames.items()}
            vals.append(frames["4"][:3, 2] @ frames["3"][:3, 2])
        fd[j] = (vals[0] - vals[1]) / (2 * h)
    assert np.allclose(row, fd, atol=1e-6)


@pytest.mark.parametrize(
    "mutate,message",
    [
        (lambda d: d.update(format="x"), r"field 'format' must be 'hyperstat-hypotheses'"),
        (lambda d: d.update(version=3), r"field 'version' is 3"),
        (lambda d: d["axes"].update(bad={"element": "99"}), r"field 'axes.bad.element' names '99'"),
        (lambda d: d["hypotheses"][0].update(parallel=["a2", "zz"]), r"hypotheses\[0\]\.parallel\[1\]' names 'zz'"),
        (lambda d: d["hypotheses"][0].update(skew=["a2", "a3"]), r"field 'hypotheses\[0\]\.skew' is not a relation"),
        (lambda d: d["hypotheses"].append({"id": "h", "parallel": ["a2", "a3"]}), r"'h' is used twice"),
        (lambda d: d["hypotheses"][0].update(id="1x"), r"hypotheses\[0\]\.id' must be an identifier"),
    ],
)
def test_malformed_hypothesis_files_name_the_field(slider_crank, mutate, message):
    doc = _doc(parallel=["a2", "a3"])
    mutate(doc)
    with pytest.raises(DataError, match=message):
        parse_hypotheses(doc, slider_crank, "h.yaml")


def test_yaml_is_read_safely(tmp_path, slider_crank):
    f = tmp_path / "h.yaml"
    f.write_text("!!python/object/apply:os.system ['echo pwned']\n")
    with pytest.raises(DataError, match="not valid YAML"):
        load_hypotheses(f, slider_crank)
    f.write_text(yaml.safe_dump(_doc(parallel=["a2", "a3"])))
    assert load_hypotheses(f, slider_crank)[2][0].relation == "parallel"
