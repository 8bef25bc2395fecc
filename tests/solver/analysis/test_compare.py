"""Comparison with the paper's tables: categories follow from our verdicts, paper counts checked."""

from hyperstat.solver.analysis.compare import compare, load_reference

from tests.conftest import TEMPLATES


def test_tripteor_comparison(tripteor, tripteor_analysis):
    ref = load_reference(TEMPLATES / "tripteor_x7.paper.yaml")
    comp = compare(tripteor, tripteor_analysis, ref)
    rows = {r.name: r for r in comp.parameters}
    # every forced verdict of ours is a zero of Table 3 or a disagreement, never "agree" with "identified"
    for r in comp.parameters:
        if r.ours == "forced" and r.paper == "identified":
            assert r.category == "disagree"
        if r.paper == "both":
            assert r.category == "paper inconsistency"
    assert rows["dK52"].paper == "both"
    # the paper's own totals, counted from its Table 5 entries by the comparison
    text = "\n".join(comp.paper_checks)
    assert "Table 5 'leg 3': printed total 14, entries 13" in text
    assert "identified parallel: text says 46, Table 5 has 45 entries" in text
    assert len(comp.matrices) == 17
    assert sum(m["agree"] + m["differ"] for m in comp.matrices) == len(comp.parameters) == 87
    md = comp.to_markdown()
    assert md.count("\n| leg") >= 15 and "D_R52^R51" in md
