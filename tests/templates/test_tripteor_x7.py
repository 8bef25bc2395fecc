"""Tripteor X7: mobility, every verdict confirmed nonlinearly, robustness to dimensions and seeds."""

import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin import build_template
from hyperstat.solver import Kinematics, analyze, verify
from hyperstat.solver.analysis.hypotheses import check_hypotheses, load_hypotheses

from tests.conftest import TEMPLATES


def test_mobility_and_overconstraint(tripteor_analysis):
    # two UPR legs (2 constraints each) and one SPR leg (1 constraint) leave the platform 3 degrees of
    # freedom: 5 constraints, 3 independent -> over-constraint 2; plus the 2 wrist axes -> mobility 5
    assert tripteor_analysis.mobility == 5
    assert tripteor_analysis.overconstraint == 2
    assert tripteor_analysis.gap > 1e8


def test_table2_parameter_count_and_normalisations(tripteor, tripteor_analysis):
    legs = [p for p in tripteor.parameters if p.element not in ("6", "7")]
    assert len(legs) == 75  # paper 1, Table 2
    norm = [p for p in tripteor_analysis.parameters if p.verdict == "gauge" and p.reason.startswith("normalisation")
            and p.element not in ("6", "7")]
    assert len(norm) == 14  # one per axis carrying orientation defects (section 4.2)


def test_every_verdict_is_confirmed_by_nonlinear_reassembly(tripteor, tripteor_analysis):
    checks = verify(tripteor, tripteor_analysis)
    forced = tripteor_analysis.by_verdict("forced")
    assert len(forced) >= 10
    assert {c.subject for c in checks if c.kind == "parameter" and c.expected == "does not assemble"} >= set(forced)
    failed = [(c.subject, c.kind, c.note) for c in checks if not c.confirmed]
    assert not failed


def test_the_leg_offset_relation_has_the_coefficient_geometry_predicts(tripteor_analysis):
    """Equal non-perpendicularity of both U joints is tolerated if the platform offset matches it.

    Tilting v1 and v3 by the same angle e toward u keeps them parallel, and moves the two leg
    planes apart along v by |A1 A3| * e: a relation with coefficient |A1A3| = 2 * base_half_width.
    """
    texts = {r.text for r in tripteor_analysis.relations}
    assert "dK21 - dK23 = 0" in texts
    rel = next(r for r in tripteor_analysis.relations if "dc63" in r.terms)
    assert abs(rel.terms["dK23"]) == pytest.approx(2 * 400.0)


@pytest.mark.parametrize("name,value", [("base_half_width", 320.0), ("depth", 960.0), ("platform_leg2_offset", 160.0)])
def test_verdicts_do_not_change_with_dimensions(tripteor_analysis, name, value):
    mech = build_template(TEMPLATES / "tripteor_x7.py", {name: value}).mechanism()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        other = analyze(mech, seed=3)
    assert [(p.verdict, p.influential) for p in other.parameters] == \
        [(p.verdict, p.influential) for p in tripteor_analysis.parameters]


def test_putschler_hypotheses(tripteor, tripteor_analysis):
    axes, points, hyps = load_hypotheses(TEMPLATES / "tripteor_x7.hypotheses.yaml", tripteor)
    verdicts = {v.id: v for v in check_hypotheses(tripteor, tripteor_analysis, axes, points, hyps)}
    assert len(verdicts) == 12
    # leg 2's spherical joint needs concurrent axes, not orthogonal ones (paper 1, Table 4: "empty")
    assert verdicts["u2_perp_v2"].verdict == "not-required"
    assert verdicts["u2p_perp_v2p"].verdict == "not-required"
    for hid in ("u1_par_u3", "A1A3_on_u1", "v1_par_w1", "v3_par_w3", "leg1_perp_v1", "leg3_perp_v3",
                "leg1_perp_w1", "leg3_perp_w3"):
        assert verdicts[hid].verdict == "required", hid
    # the U joints need not be perpendicular, only equally off (dK21 - dK23 = 0)
    assert verdicts["u1_perp_v1"].verdict == "not-required"
    lc = Kinematics(tripteor).length_scale
    for v in verdicts.values():
        per_unit = v.residual / (1e-4 * lc)
        if v.verdict == "required":
            assert per_unit > 1e-2, v.id  # breaking it: first-order residual
        else:
            assert per_unit < 1e-6, v.id  # an admissible defect that breaks it still assembles
            assert v.violation > 1e-5
    assert np.isfinite([v.residual for v in verdicts.values()]).all()


def _doc_rows(text: str, begin: str) -> list[tuple[str, ...]]:
    block = text.split(f"<!-- BEGIN {begin}")[1].split("<!-- END")[0]
    rows = []
    for line in block.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 4 and cells[0] and not cells[0].startswith("-") and cells[0] not in ("parameter", "group", "id"):
            rows.append(tuple(cells))
    return rows


def test_the_document_shows_what_the_commands_print(tripteor, tripteor_analysis):
    """docs/tripteor_x7.md embeds the output of `hyperstat compare` and `check-hypotheses`: still true."""
    from hyperstat.solver.analysis.compare import compare, load_reference

    text = (TEMPLATES.parent / "docs" / "tripteor_x7.md").read_text()
    comp = compare(tripteor, tripteor_analysis, load_reference(TEMPLATES / "tripteor_x7.paper.yaml"))
    documented = {r[0]: r[1:5] for r in _doc_rows(text, "hyperstat compare") if len(r) == 7}
    now = {p.name: (p.matrix, p.paper, p.ours, p.category) for p in comp.parameters if p.category != "agree"}
    assert documented == now
    axes, points, hyps = load_hypotheses(TEMPLATES / "tripteor_x7.hypotheses.yaml", tripteor)
    verdicts = check_hypotheses(tripteor, tripteor_analysis, axes, points, hyps, evidence=False)
    documented = {r[0]: r[1] for r in _doc_rows(text, "hyperstat check-hypotheses") if len(r) == 4}
    assert documented == {v.id: v.verdict for v in verdicts}
