"""One class per parameter, one vocabulary (issue 29 item 5), walked through every template's JSON.

Units: none (words).  The report document (``report.json``: ``tolerances.items``,
``tolerances.parameters``, ``joints[].parameters``) and the analysis document (``hyperstat analyze
--json``) of every shipped template must give each parameter one class from the vocabulary of
docs/tolerances.md, the same in every place, consistent with the tolerance it belongs to, and never
say "gauge".
"""

from __future__ import annotations

import json

import pytest

from hyperstat.solver.export.report_content import report_document
from hyperstat.solver.tolerances.classification import CLASSES

from tests.solver.tolerances.common import classified

PARAMETER_CLASSES = set(CLASSES) | {"redundant", "normalisation"}
NEVER = {"gauge", "forced", "coupled", "free", "none"}
NAMES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar"]


@pytest.mark.parametrize("name", NAMES)
def test_every_parameter_has_one_class_from_the_vocabulary_everywhere(name):
    mech, kin, result, cl = classified(name)
    doc = json.loads(json.dumps(report_document(mech, {"source": name}, result, tolerances=cl), default=str))
    analysis = json.loads(json.dumps(result.to_dict(), default=str))
    assert "gauge" not in json.dumps(doc) and "gauge" not in json.dumps(analysis)
    tol = doc["tolerances"]
    items = {t["id"]: t for t in tol["items"]}
    assert {t["class"] for t in items.values()} <= set(CLASSES)
    joint_rows = {p["name"]: p for j in doc["joints"] for p in j["parameters"]}
    assert set(joint_rows) == set(tol["parameters"]) == {p.name for p in mech.parameters}
    for pname, entry in tol["parameters"].items():
        cls = entry["class"]
        assert cls in PARAMETER_CLASSES and cls not in NEVER, (pname, cls)
        row = joint_rows[pname]
        assert row["class"] == cls and row["verdict"] == cls, (pname, row, cls)  # the per-joint table says the same
        if cls == "normalisation":
            assert entry["tolerance_id"] is None and pname in {a["name"] for a in tol["appendix"]["normalisation"]}
            continue
        item = items[entry["tolerance_id"]]
        if cls == "redundant":  # merged with its equivalent: the same tolerance, which names both
            assert pname in item["parameters"] and entry["equivalent"] in item["parameters"]
            continue
        assert item["class"] == cls, (pname, cls, item["id"], item["class"])
        assert pname in item["parameters"]
        # a coupled parameter belongs to its relation (assembly); its admissible direction names what follows it
        for other in entry["tolerance_ids"][1:]:
            extra = items[other]
            assert (extra["class"] == "assembly" and pname in extra["parameters"]) or \
                (extra["kind"] == "direction" and " with " in extra["statement"]), extra["statement"]
    # the analysis' own table: a gauge is named for what it is
    for p in analysis["parameters"]:
        assert p["verdict"] in ("normalisation", "redundant", "forced", "coupled", "free")
        if p["verdict"] in ("normalisation", "redundant"):
            assert tol["parameters"][p["name"]]["class"] == p["verdict"]
