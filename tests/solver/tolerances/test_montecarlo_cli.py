"""``hyperstat montecarlo``: every tolerance at its value, percent out of spec, both rankings as the JSON says.

Units: mm and rad.
"""

from __future__ import annotations

import json
import re

import numpy as np

from hyperstat.cad_plugin.cli import main

from tests.conftest import TEMPLATES


def test_montecarlo_prints_out_of_spec_and_both_rankings(tmp_path, capsys):
    out = tmp_path / "mc.json"
    assert main(["montecarlo", str(TEMPLATES / "tripteor_x7.py"), "--samples", "400", "--workspace-configurations",
                 "60", "--position-accuracy", "0.03", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    doc = json.loads(out.read_text())
    # percent out of spec, as the JSON has it, against the spec given on the command line
    pct = doc["out_of_spec_position_percent"]
    assert f"out of spec (position > 0.03 mm): {pct:.2f} % of the samples" in text
    ok = doc["samples"]
    assert 0.0 <= pct <= 100.0 and ok == 400
    # both rankings: each names its top contributors by its own share, with that share
    for share, label in (("position_share", "position"), ("orientation_share", "orientation")):
        line = next(ln for ln in text.splitlines() if f"main contributors to the {label} variance" in ln)
        ranked = sorted(doc["contributors"], key=lambda c: -c[share])[:3]
        printed = re.findall(r"(T\d+) [^()]*?\((\d+) %\)", line)  # a statement written out in full has spaces
        assert [p[0] for p in printed[:3]] == [c["parameter"] for c in ranked]
        for (tid, pct_text), c in zip(printed, ranked):
            assert int(pct_text) == round(100 * c[share])
    # the drawn parts are made to the drawing: the accuracy-critical and compensable tolerances at their drawing values
    assert doc["drawn"].startswith("parts made to the drawing: every accuracy-critical and compensable tolerance")
    assert doc["tolerance_counts"]["accuracy-critical"] + doc["tolerance_counts"]["compensable"] == \
        sum(1 for k in doc["tolerances"] if k.startswith("T"))
    # shares are fractions of the first-order variance: they sum to one per kind
    for share in ("position_share", "orientation_share"):
        assert np.isclose(sum(c[share] for c in doc["contributors"]), 1.0)
    # the linear worst case bounds every sample (first order; the samples are small)
    assert doc["position_mm"]["max"] <= doc["linear_worst_case"]["position_mm"] * 1.01
    # its calibrated machines are calibrated as the template declares (the tracker frame registered), which hyperstat
    # identify does not do: the classification's warning goes with their result, in the JSON and on the screen
    assert doc["calibrated"] and [w[:22] for w in doc["warnings"]] == ["CALIBRATION CAMPAIGN: "]
    assert f"  warning: {doc['warnings'][0]}" in text
