"""The workbench in the real FreeCAD GUI under Xvfb, driven by clicks on the real buttons (``gui_clicks.py``).

Units: lengths in mm, angles in rad.

One FreeCAD start runs the whole scenario (insert, identify, diagnose, edit parameters
with a refused then a good value, analyse from the toolbar, a spreadsheet edit, undo step
by step); this test judges what it recorded: the document's state after each click, the
panels, every message box, and the screenshots (verdict colours present in the 3D view).
Expected verdicts come from the solver run in this process on the template (no FreeCAD,
no STEP, no model file).  ``HYPERSTAT_REQUIRE_FREECAD=1`` (``make test``) makes a missing
FreeCAD or Xvfb a failure, not a skip.  ``HYPERSTAT_SCREENSHOTS=DIR`` copies the
screenshots that ``docs/freecad.md`` shows there (``make freecad-screenshot`` uses it for ``docs/img``).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import TEMPLATES
from tests.cad_plugin.freecad.test_workbench import WORKBENCH, _cli, _install, _require

SCRIPT = Path(__file__).resolve().parent / "gui_clicks.py"
TIMEOUT_S = 1500
#: the screenshots docs/freecad.md shows (docs/img/freecad_<name>.png)
DOC_SCREENSHOTS = ("workbench", "insert_running", "identify", "diagnose")

sys.path.insert(0, str(WORKBENCH))
from hyperstat_freecad.verdicts import VERDICT_COLORS, element_verdicts, parameter_class, tolerance_class  # noqa: E402

sys.path.pop(0)


@pytest.fixture(scope="module")
def clicks(tmp_path_factory) -> dict:
    tools = _require("freecad", "xvfb-run", "xauth")
    root = tmp_path_factory.mktemp("fc_clicks")
    home, out = root / "home", root / "out"
    home.mkdir()
    out.mkdir()
    cli = os.environ.get("HYPERSTAT_CLI") or _cli()
    proc = _install(home, "--start-in-workbench", "--cli", cli, "--templates", str(TEMPLATES))
    assert proc.returncode == 0, proc.stderr
    data, validation = root / "data.csv", root / "validation.csv"
    sim = subprocess.run([cli, "simulate", str(TEMPLATES / "tripteor_x7.py"), "--poses", "30", "--validation", "10",
                          "--out", str(data), "--validation-out", str(validation), "--quiet"],
                         capture_output=True, text=True, timeout=600)
    assert sim.returncode == 0, sim.stderr
    env = {k: v for k, v in os.environ.items() if k != "HYPERSTAT_CLI"}
    env.update({"HOME": str(home), "HYPERSTAT_CLICKS_OUT": str(out), "HYPERSTAT_CLICKS_DATA": str(data),
                "HYPERSTAT_CLICKS_VALIDATION": str(validation), "QTWEBENGINE_CHROMIUM_FLAGS": "--no-sandbox"})
    with open(out / "log.txt", "w", encoding="utf-8") as log:
        run = subprocess.Popen([tools["xvfb-run"], "-a", "-s", "-screen 0 1700x1000x24", tools["freecad"], str(SCRIPT)],
                               stdout=log, stderr=subprocess.STDOUT, env=env, cwd=out, start_new_session=True)
        try:
            run.wait(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"FreeCAD did not finish the clicking scenario within {TIMEOUT_S} s")
        finally:
            try:
                os.killpg(run.pid, signal.SIGKILL)  # what is left (Xvfb of xvfb-run)
            except ProcessLookupError:
                pass
    report_path = out / "report.json"
    assert report_path.is_file(), (out / "log.txt").read_text(errors="replace")[-3000:]
    report = json.loads(report_path.read_text())
    if os.environ.get("HYPERSTAT_SCREENSHOTS"):
        dest = Path(os.environ["HYPERSTAT_SCREENSHOTS"])
        dest.mkdir(parents=True, exist_ok=True)
        for name in DOC_SCREENSHOTS:
            shutil.copy(out / f"freecad_{name}.png", dest / f"freecad_{name}.png")
    return {"report": report, "out": out}


def _steps(clicks) -> dict:
    report = clicks["report"]
    assert report["ok"], report.get("error") or report["events"]
    return report["steps"]


def _hue_pixels(png: str, colour) -> int:
    import matplotlib.colors as mcolors
    import matplotlib.image as mimage

    image = mimage.imread(png)[..., :3]
    view = mcolors.rgb_to_hsv(image[:, int(0.3 * image.shape[1]):])  # right of the task panel
    hue = mcolors.rgb_to_hsv(np.array(colour))[0]
    distance = np.minimum(abs(view[..., 0] - hue), 1 - abs(view[..., 0] - hue))
    return int(((distance < 0.03) & (view[..., 1] > 0.5) & (view[..., 2] > 0.3)).sum())


def test_insert_ok_does_not_block_and_opens_the_results(clicks, tripteor, tripteor_analysis):
    steps = _steps(clicks)
    # the click on OK returned while the job ran: same panel, busy, nothing in the document yet
    after = steps["after_ok"]
    assert after["panel"] == "InsertPanel" and after["job"] is True and after["objects"] == 0
    assert after["progress_visible"] is True and after["inputs_enabled"] is False
    insert = steps["insert"]
    assert [b for b in clicks["report"]["boxes"] if b["stage"] == "insert"] == []  # no "Another task panel"
    assert insert["panel"] == "ResultsPanel" and insert["dialog_open"]
    state = insert["state"]
    assert state["skeletons"] == ["tripteor_x7"] and state["status"] == "analysed" and not state["touched"]
    want = tripteor_analysis.to_dict()
    assert state["verdicts"] == {p["name"]: parameter_class(p) for p in want["parameters"]}
    # the results table: one row per defect, class = the tolerance class when the JSON has one, else the verdict
    assert [row[0] for row in insert["table"]] == [p["name"] for p in want["parameters"]]
    assert [row[2] for row in insert["table"]] == [tolerance_class(state["analysis"], p)
                                                   for p in state["analysis"]["parameters"]]
    # the panel's counts per tolerance class are the analysis's, computed here in-process by the one
    # classification module (a second path: no CLI, no FreeCAD)
    from collections import Counter

    from hyperstat.solver.tolerances.classification import classify

    classes_here = classify(tripteor, tripteor_analysis).to_dict()["parameters"]
    assert Counter(row[2] for row in insert["table"]) == Counter(classes_here[p["name"]]["class"]
                                                                 for p in want["parameters"])
    classes = element_verdicts(want)
    assert set(state["spheres"]) == set(classes)
    for element, sphere in state["spheres"].items():
        np.testing.assert_allclose(sphere["view_color"], VERDICT_COLORS[classes[element]], atol=1e-6)
    for cls in ("forced", "coupled", "free-influential"):
        assert _hue_pixels(insert["screenshot"], VERDICT_COLORS[cls]) > 30, cls


def test_undo_one_transaction_per_action_and_edit_undo_enabled(clicks):
    steps = _steps(clicks)
    assert steps["insert"]["state"]["undo"] == ["Insert skeleton tripteor_x7"]
    assert steps["insert"]["state"]["undo_action_enabled"] is True
    names = [u["undone"] for u in steps["undo"]]
    assert names == ["Analyse tripteor_x7", "Edit parameters of tripteor_x7", "Diagnose tripteor_x7",
                     "Identify tripteor_x7", "Insert skeleton tripteor_x7"]
    assert all(u["action_enabled"] for u in steps["undo"])
    by_name = {u["undone"]: u["state"] for u in steps["undo"]}
    # undoing the edit puts back the parameters and the geometry of the insert, marker by marker
    back = by_name["Edit parameters of tripteor_x7"]
    assert back["parameters"]["depth"] == 800.0 and back["status"] == "analysed"
    before = steps["insert"]["state"]["markers"]
    assert set(back["markers"]) == set(before)
    for node, xyz in back["markers"].items():
        np.testing.assert_allclose(xyz, before[node], atol=1e-9, err_msg=node)
    gone = by_name["Insert skeleton tripteor_x7"]
    assert gone["skeletons"] == [] and gone["objects"] == 0


def test_edit_parameters_refused_then_accepted(clicks):
    steps = _steps(clicks)
    refused = steps["refused"]
    assert len(refused["boxes"]) == 1
    box = refused["boxes"][0]
    assert box["title"] == "Hyperstat - Edit parameters" and "'depth'" in box["text"] and "\n" not in box["text"]
    assert refused["panel"] == "ParametersPanel" and refused["panel_is_same"] and refused["dialog_open"]
    assert refused["inputs_enabled"] is True
    assert refused["state"]["parameters"]["depth"] == 800.0  # nothing written
    assert refused["state"]["undo"] == steps["diagnose"]["state"]["undo"]  # no transaction for a refused value
    edit = steps["edit"]
    state = edit["state"]
    assert edit["panel"] == "ResultsPanel"
    assert state["parameters"]["depth"] == 850.0 and state["status"] == "analysed" and not state["touched"]
    assert state["undo"][0] == "Edit parameters of tripteor_x7"
    # the platform went 50 mm further from the base: the largest marker displacement is 50 mm (rigid shift of
    # the platform side), and the base markers did not move
    before = steps["insert"]["state"]["markers"]
    moves = {n: float(np.linalg.norm(np.subtract(state["markers"][n], before[n]))) for n in before}
    assert max(moves.values()) == pytest.approx(50.0, abs=1e-6)
    assert min(moves.values()) == pytest.approx(0.0, abs=1e-9)
    assert _hue_pixels(edit["screenshot"], VERDICT_COLORS["forced"]) > 30


def test_commands_stay_available_while_result_panels_are_open(clicks):
    steps = _steps(clicks)
    enabled = steps["enabled_before_click"]
    # Analyse clicked while the results panel was open; Diagnose while the identification panel was
    assert enabled["analyse:Hyperstat_Analyze"] is True
    assert enabled["diagnose:Hyperstat_Diagnose"] is True
    assert enabled["edit (refused value):Hyperstat_EditParameters"] is True
    analyse = steps["analyse"]
    assert analyse["panel"] == "ResultsPanel" and analyse["state"]["undo"][0] == "Analyse tripteor_x7"
    assert not analyse["state"]["touched"]


def test_panels_fit_the_default_dock_width(clicks):
    steps = _steps(clicks)
    # insert panel (busy), parameters panel, results, identification, diagnosis
    for name in ("after_ok", "refused", "insert", "identify", "diagnose", "edit", "analyse"):
        # the panel's right edge is inside the dock (FreeCAD's default width): nothing cut off
        assert steps[name]["panel_right"] <= steps[name]["dock_right"], (name, steps[name])


def test_stale_state_spreadsheet_marks_identify_does_not(clicks):
    steps = _steps(clicks)
    sheet = steps["spreadsheet"]
    assert sheet["status"].startswith("outdated") and sheet["tree_needs_recompute"] is True
    undone = steps["spreadsheet_undone"]
    assert undone["status"] == "analysed" and not undone["touched"]
    assert steps["identify"]["state"]["identification"] and not steps["identify"]["state"]["touched"]
    assert steps["diagnose"]["state"]["diagnosis"] and not steps["diagnose"]["state"]["touched"]


def test_identify_and_diagnose_show_tables(clicks):
    steps = _steps(clicks)
    ident = steps["identify"]
    assert ident["panel"] == "IdentificationPanel" and len(ident["table"]) > 0
    assert [b for b in clicks["report"]["boxes"] if b["stage"] in ("identify", "diagnose")] == []
    diag = steps["diagnose"]
    assert diag["panel"] == "DiagnosisPanel" and len(diag["table"]) > 0


def test_cancel_stops_the_job_and_leaves_the_document(clicks):
    steps = _steps(clicks)
    cancel = steps["cancel"]
    assert cancel["button_visible"] is True
    # one job at a time: the command is greyed, or a click on it is refused with one sentence
    if cancel["analyse_enabled_while_running"]:
        assert len(cancel["second_job_boxes"]) == 1
        assert "'Rebuild' is still running" in cancel["second_job_boxes"][0]["text"]
    else:
        assert cancel["second_job_boxes"] == []
    assert cancel["job_still_running"] is True  # the refusal did not stop the first job
    assert cancel["state"]["undo"] == cancel["undo_before"]  # cancelled: nothing recorded
    assert cancel["state"]["status"] == "analysed" and cancel["state"]["parameters"]["depth"] == 850.0
