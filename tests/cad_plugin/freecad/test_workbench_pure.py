"""Pure-Python parts of the workbench (no FreeCAD): marker spreading and the class vocabulary.

Units: mm.
"""

from __future__ import annotations

import itertools
import math
import sys

import pytest

from tests.cad_plugin.freecad.test_workbench import WORKBENCH

sys.path.insert(0, str(WORKBENCH))
from hyperstat_freecad.geometry import coincident_offsets  # noqa: E402
from hyperstat_freecad.classes import (CLASS_ORDER, TOLERANCE_CLASSES, parameter_classes,  # noqa: E402
                                      tolerance_counts, tolerance_rows)
from hyperstat_freecad.estimates import expected, progress_text, record  # noqa: E402

sys.path.pop(0)


@pytest.mark.parametrize("n", [2, 3, 4, 6, 9])
def test_coincident_spheres_never_touch_and_lone_ones_stay(n):
    radius = 7.0
    centres = {f"j{k}": (100.0, -20.0, 5.0) for k in range(n)}
    centres["alone"] = (100.0, -20.0, 5.0 + 1.0)  # 1 mm away: not coincident, keeps its place
    offsets = coincident_offsets(centres, radius, 1e-6)
    assert offsets["alone"] == (0.0, 0.0, 0.0)
    placed = {k: [c + o for c, o in zip(centres[k], offsets[k])] for k in centres if k != "alone"}
    for a, b in itertools.combinations(placed, 2):
        assert math.dist(placed[a], placed[b]) >= 2.3 * radius * (1 - 1e-12), (a, b)
    # all on one ring around the shared point, in the global xy plane
    rings = {round(math.hypot(*offsets[k][:2]), 9) for k in placed}
    assert len(rings) == 1 and all(offsets[k][2] == 0.0 for k in placed)


def test_the_workbench_speaks_the_classification_vocabulary():
    """The classes of the one definition are the classification's, plus the two that are not tolerances."""
    from hyperstat.solver.tolerances.classification import CLASSES

    assert tuple(TOLERANCE_CLASSES) == tuple(CLASSES)
    assert set(CLASS_ORDER) == set(CLASSES) | {"redundant", "normalisation"}


def test_the_panel_table_is_the_report_table(tmp_path):
    """The rows the Results panel shows, from a real report JSON: ids, classes and values as the report prints them."""
    import json

    from hyperstat.cad_plugin.cli import main
    from hyperstat.cad_plugin.report_words import calibrated_value, tolerance_value

    from tests.cad_plugin.contract import with_contract_fields
    from tests.conftest import TEMPLATES

    assert main(["report", str(TEMPLATES / "slider_crank.py"), "--out", str(tmp_path), "--json-only", "--quiet"]) == 0
    doc = with_contract_fields(json.loads((tmp_path / "report.json").read_text()))
    rows = tolerance_rows(doc["tolerances"])
    assert tolerance_counts(doc["tolerances"]) == doc["summary"]["tolerance_classes"]
    for row, t in zip(rows, doc["tolerances"]["items"], strict=True):
        assert row[:4] == [t["id"], t["class"], t["statement"], t["feature"]]
        assert row[4] == tolerance_value(t) and row[5] == calibrated_value(t).split(" (")[0]
        assert row[6] == (" ".join(c["frame"] for c in t["drawing"]) or tolerance_value(t, "drawing_value"))
    assert parameter_classes({"tolerances": doc["tolerances"]}) == {
        n: e["class"] for n, e in doc["tolerances"]["parameters"].items()}


def test_estimates_learn_from_the_runs():
    seconds, measured = expected("report", "unit-test-template")
    assert not measured and seconds > 0  # the typical duration before any run
    record("report", "unit-test-template", 12.0)
    assert expected("report", "unit-test-template") == (12.0, True)
    record("report", "unit-test-template", 6.0)
    assert expected("report", "unit-test-template") == (9.0, True)
    assert "about 9 s (last runs)" in progress_text("Analyse", "tolerance values", 2, 3.0, 9.0, True)


def test_root_starts_freecad_as_the_docs_say():
    """As root FreeCAD's GUI needs QtWebEngine's sandbox off: `make freecad` does it (as root only), the docs say it,
    and the clicking GUI test starts FreeCAD with the same setting."""
    import re

    from tests.conftest import ROOT

    flag = "QTWEBENGINE_CHROMIUM_FLAGS=--no-sandbox"
    make = (ROOT / "Makefile").read_text(encoding="utf-8")
    recipe = make.split("\nfreecad: ", 1)[1].split("\n\n", 1)[0]
    assert re.search(r'if \[ "\$\$\(id -u\)" = 0 \]; then ' + re.escape(flag) + " freecad; else freecad; fi", recipe)
    for doc in ("README.md", "docs/freecad.md"):
        assert flag in (ROOT / doc).read_text(encoding="utf-8") and "root" in (ROOT / doc).read_text(encoding="utf-8")
    gui = (ROOT / "tests" / "cad_plugin" / "freecad" / "test_gui_clicks.py").read_text(encoding="utf-8")
    assert '"QTWEBENGINE_CHROMIUM_FLAGS": "--no-sandbox"' in gui


FAKE_CLI = """#!/bin/sh
# a stand-in for the hyperstat command line: 'wait FILE' ends when 'touch FILE' has run (so only if both run at once)
case "$1" in
  wait) i=0; while [ ! -e "$2" ]; do i=$((i+1)); [ $i -gt 600 ] && { echo "hyperstat: error: $2 never came." >&2; exit 2; }; sleep 0.05; done; echo "saw $2";;
  touch) touch "$2"; echo "made $2";;
  fail) echo "hyperstat: error: $2 is not a model file." >&2; exit 2;;
  *) echo "usage: hyperstat ..." >&2; echo "hyperstat: error: argument command: invalid choice: '$1' (choose from 'wait', 'touch', 'fail')" >&2; exit 2;;
esac
"""


def test_runs_together_start_at_once_and_answer_in_order(tmp_path, monkeypatch):
    """The Analyse's two commands (``analyze`` and ``report``) run at once (:class:`Together`): a run that waits for a
    file the other writes ends (30 s at most); the outputs come back in the order given, through :func:`drive` too; a
    failure is the command's own sentence, the first in order when several fail, raised once all have ended."""
    cli = tmp_path / "hyperstat"
    cli.write_text(FAKE_CLI)
    cli.chmod(0o755)
    monkeypatch.setenv("HYPERSTAT_CLI", str(cli))
    sys.path.insert(0, str(WORKBENCH))
    try:
        from hyperstat_freecad.operations import Call, Together, drive
        from hyperstat_freecad.runner import CommandMissing, HyperstatWorkbenchError, run_together
    finally:
        sys.path.pop(0)
    flag = tmp_path / "flag"
    waited, made = run_together([["wait", str(flag)], ["touch", str(flag)]])
    assert (waited.stdout, made.stdout) == (f"saw {flag}\n", f"made {flag}\n")

    def steps():
        first = yield Together((Call(["wait", str(tmp_path / "again")], "waits"),
                                Call(["touch", str(tmp_path / "again")], "writes")))
        return [r.stdout for r in first]

    assert drive(steps()) == [f"saw {tmp_path / 'again'}\n", f"made {tmp_path / 'again'}\n"]
    with pytest.raises(HyperstatWorkbenchError, match=r"^B is not a model file\.$"):
        run_together([["touch", str(tmp_path / "x")], ["fail", "b"], ["fail", "c"]])
    assert (tmp_path / "x").exists()  # the other runs ran to their end
    with pytest.raises(CommandMissing, match="has no 'report' command"):  # an older command line, named
        run_together([["touch", str(tmp_path / "y")], ["report", "model.json"]])
