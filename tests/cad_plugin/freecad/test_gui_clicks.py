"""The workbench in the real FreeCAD GUI under Xvfb, driven by clicks on the real buttons (``gui_clicks.py``).

Units: lengths in mm, angles in rad.

One FreeCAD start runs the whole scenario (insert, identify, diagnose, edit parameters
with a refused then a good value, analyse from the toolbar, a spreadsheet edit, undo then
redo step by step with the results panel open, then every shipped template inserted by
clicks); this test judges what it recorded: the document's state after each click, the
panels, every message box, the report view's error lines, and the screenshots (class
colours present in the 3D view).  Expected classes come from the solver run in this process
on the template (no FreeCAD, no STEP, no model file); each template's panel is compared with
the report the command line writes here from the template.  ``HYPERSTAT_REQUIRE_FREECAD=1`` (``make test``) makes a missing
FreeCAD or Xvfb a failure, not a skip.  ``HYPERSTAT_SCREENSHOTS=DIR`` copies the
screenshots that ``docs/freecad.md`` shows there (``make freecad-screenshot`` uses it for ``docs/img``).
"""

from __future__ import annotations

import json
import os
import re
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
from hyperstat_freecad.classes import CLASS_RGB, element_classes, tolerance_rows  # noqa: E402

sys.path.pop(0)

#: every shipped template: the clicking scenario inserts each one and the test compares its panel with its report
TEMPLATE_NAMES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar"]


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
    reports = {}
    with open(out / "log.txt", "w", encoding="utf-8") as log:
        run = subprocess.Popen([tools["xvfb-run"], "-a", "-s", "-screen 0 1700x1000x24", tools["freecad"], str(SCRIPT)],
                               stdout=log, stderr=subprocess.STDOUT, env=env, cwd=out, start_new_session=True)
        try:
            # meanwhile, each template's report by the command line here, from the template (no FreeCAD, no STEP);
            # report.json only (--json-only: the same bytes as the full report's, tests/cad_plugin/test_report.py),
            # the only file these tests read
            for name in TEMPLATE_NAMES:
                rep = subprocess.run([cli, "report", str(TEMPLATES / f"{name}.py"), "--out", str(root / "reports" / name),
                                      "--json-only", "--quiet"], capture_output=True, text=True, timeout=600)
                assert rep.returncode == 0, rep.stderr
                reports[name] = json.loads((root / "reports" / name / "report.json").read_text())
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
    if os.environ.get("HYPERSTAT_SCREENSHOTS") and report.get("ok"):
        dest = Path(os.environ["HYPERSTAT_SCREENSHOTS"])
        dest.mkdir(parents=True, exist_ok=True)
        for name in DOC_SCREENSHOTS:
            shutil.copy(out / f"freecad_{name}.png", dest / f"freecad_{name}.png")
            _record_screenshot(dest / f"freecad_{name}.png", name, report["steps"])
    return {"report": report, "out": out, "reports": reports}


def _record_screenshot(png: Path, name: str, steps: dict) -> None:
    """The record of a screenshot docs/ shows (tests/test_docs_images.py): the words on it, from the panel."""
    from hyperstat.cad_plugin.view import write_record

    step = {"workbench": "insert", "insert_running": "after_ok"}.get(name, name)
    got = steps[step]
    words = {"title": f"FreeCAD: {name}"}
    if name == "workbench":
        words.update(classes=sorted({row[1] for row in got["table"]}),
                     legend=[re.sub(r"<[^>]+>", "", line).replace("&nbsp;", "").strip()
                             for line in got["legend"].split("<br>")],
                     callouts=[line for text in got["state"]["callouts"].values() for line in text])
    elif name == "insert_running":
        words["legend"] = [got["progress_text"]]
    else:
        words["legend"] = list(got.get("table_header") or [])
    write_record(png, "make freecad-screenshot (tests/cad_plugin/freecad/gui_clicks.py: FreeCAD 0.20 under Xvfb)",
                 words)


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
    # the progress names the step and its stage, with an estimate of its duration
    assert re.search(r"Insert skeleton, step \d: .+, \d+ s (of about \d+ s|\((usually|typically) \d+ s)",
                     after["progress_text"]), after["progress_text"]
    assert after["status_text"] == after["progress_text"] or "of about" in after["status_text"] or \
        "typically" in after["status_text"] or "usually" in after["status_text"]
    insert = steps["insert"]
    assert [b for b in clicks["report"]["boxes"] if b["stage"] == "insert"] == []  # no "Another task panel"
    assert insert["panel"] == "ResultsPanel" and insert["dialog_open"]
    state = insert["state"]
    assert state["skeletons"] == ["tripteor_x7"] and state["status"] == "analysed" and not state["touched"]
    # the classes: computed here in-process by the one classification module (a second path: no CLI, no FreeCAD)
    from hyperstat.solver.cli import jsonable
    from hyperstat.solver.tolerances.classification import classify

    here = jsonable({**tripteor_analysis.to_dict(), "tolerances": classify(tripteor, tripteor_analysis).to_dict()})
    assert state["classes"] == {n: e["class"] for n, e in here["tolerances"]["parameters"].items()}
    # the panel's tables: the tolerance table of the report, one row per defect parameter with its class
    assert insert["table"] == tolerance_rows(state["tolerances"])
    assert [row[0] for row in insert["parameter_table"]] == [p["name"] for p in here["parameters"]]
    assert [row[2] for row in insert["parameter_table"]] == [here["tolerances"]["parameters"][p["name"]]["class"]
                                                            for p in here["parameters"]]
    classes, ids = element_classes(here)
    assert set(state["spheres"]) == set(classes)
    for element, sphere in state["spheres"].items():
        assert sphere["class"] == classes[element]
        np.testing.assert_allclose(sphere["view_color"], CLASS_RGB[classes[element]], atol=1e-6)
    assert sum(len(v) for v in state["callouts"].values()) == len(classes)  # a callout line per marker
    for cls in ("assembly", "compensable"):
        assert _hue_pixels(insert["screenshot"], CLASS_RGB[cls]) > 30, cls


@pytest.mark.parametrize("name", TEMPLATE_NAMES)
def test_the_panel_says_what_the_report_says(clicks, name):
    """Inserted by clicks, each template's Results panel shows its report's counts, ids, classes and values."""
    from hyperstat.cad_plugin.palette import CLASS_LABELS, tolerance_counts
    from hyperstat.cad_plugin.report_words import tolerance_value

    got = _steps(clicks)["templates"][name]
    report = clicks["reports"][name]
    items = report["tolerances"]["items"]
    assert got["state"]["status"] == "analysed"
    assert [row[:4] for row in got["table"]] == [[t["id"], t["class"], t["statement"], t["feature"]] for t in items]
    assert [row[4] for row in got["table"]] == [tolerance_value(t) for t in items]  # the printed values
    counts = tolerance_counts({"counts": report["summary"]["tolerance_classes"]})
    assert ", ".join(f"{n} {c}" for c, n in counts.items()) in got["summary"]
    assert f"{len(items)} tolerances from {report['summary']['parameters']} defect parameters" in got["summary"]
    by_name = {p["name"]: p for j in report["joints"] for p in j["parameters"]}
    assert {row[0]: (row[2], row[3]) for row in got["parameter_table"]} == {
        n: (p["class"], p["tolerance_id"] or "-") for n, p in by_name.items()}
    for cls in counts:  # the legend uses the report's words
        assert CLASS_LABELS[cls] in got["legend"]
    for word in ("forced", "coupled", "free-", "gauge"):
        assert word not in got["legend"] and word not in got["summary"]


@pytest.mark.parametrize("name", TEMPLATE_NAMES)
def test_the_panel_and_the_3d_view_show_the_part_drawings_of_the_report(clicks, name):
    """Issue 36, item 8: the Part drawings tab lists every frame of every part of report.json (part, id, tolerances,
    feature, the cells as drawn, the zone, the datum system, the value's kind) and every datum; the 3D view labels
    each feature that carries a frame or a datum at the feature's point, with its frames and datum letter."""
    got = _steps(clicks)["templates"][name]
    drawings = clicks["reports"][name]["drawings"]
    names = {d["part"]: {f["id"]: f for f in d["features"]} for d in drawings}
    frames = [(d["part"], fr) for d in drawings for fr in d["frames"]]
    assert [row[:4] for row in got["frame_table"]] == [
        [part, fr["id"], ", ".join(fr["tolerances"]) or "-", names[part][fr["feature"]]["name"]] for part, fr in frames]
    for row, (_, fr) in zip(got["frame_table"], frames):
        cells = row[4].split(" ", 1)[0].strip("|").split("|")  # |sym|zone|A|C|, then the plane indicator in words
        zone = ("\u2300" if fr["zone_shape"] == "cylinder" else "") + f"{fr['zone_mm']:.3g}"
        assert cells[1:] == [zone, *fr["datum_system"]], (row, fr["id"])
        assert (fr["indicator"] is None) == (" plane " not in row[4]), row
        assert f"{fr['zone_mm']:.3g} mm" in row[5] and row[6] == ("|".join(fr["datum_system"]) or "none")
        assert row[7] == fr["value_kind"]
    assert got["datum_table"] == [[d["part"], x["letter"], x["precedence"], names[d["part"]][x["feature"]]["name"]]
                                  for d in drawings for x in d["datums"]]
    labels = got["state"]["frame_labels"]
    carried = {f for d in drawings for f in [fr["feature"] for fr in d["frames"]] + [x["feature"] for x in d["datums"]]}
    assert set(labels) == carried
    for d in drawings:
        for fid, feature in names[d["part"]].items():
            if fid not in labels:
                continue
            text = "\n".join(labels[fid]["text"])
            assert text.startswith(f"{d['part']}: {feature['name']}")
            assert all(fr["id"] in text for fr in d["frames"] if fr["feature"] == fid)
            assert all(f"[datum {x['letter']}]" in text for x in d["datums"] if x["feature"] == fid)
            # at the feature: its point, a few lines below where several labels share it (mm)
            offset = np.subtract(labels[fid]["position"], feature["point_mm"])
            assert np.allclose(offset[:2], 0.0, atol=1e-6) and -2000.0 < offset[2] < 0.0, (fid, offset)
    if drawings:
        assert f"{len(drawings)} part drawings, {len(frames)} frames" in got["drawings_note"]
    assert not any(label["visible"] for label in labels.values())  # hidden until a frame or a datum is selected


def test_a_click_on_a_frame_labels_its_feature_in_the_3d_view(clicks):
    """The Tripteor inserted by clicks: a click on the first row of the Part drawings tab shows and selects the
    label of that frame's feature (its frames as the report draws them), and only that label."""
    step = _steps(clicks)["frame_clicked"]
    drawings = clicks["reports"]["tripteor_x7"]["drawings"]
    part, frame_id = step["row"][:2]
    frame = next(fr for d in drawings if d["part"] == part for fr in d["frames"] if fr["id"] == frame_id)
    labels = step["state"]["frame_labels"]
    assert [fid for fid, label in labels.items() if label["visible"]] == [frame["feature"]]
    assert frame_id in "\n".join(labels[frame["feature"]]["text"])
    assert step["selected"] == [f"frames {frame['feature']}"]


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
    assert [r["redone"] for r in steps["redo"]] == names[::-1] + ["sheet edit"]  # the edit undone earlier, too


def test_the_results_panel_follows_undo_and_redo(clicks):
    steps = _steps(clicks)
    for step in steps["undo"] + steps["redo"]:
        assert step["panel_is_same"], step.get("undone", step.get("redone"))
        state = step["state"]
        if state["skeletons"]:
            assert step["table"] == tolerance_rows(state["tolerances"])
            # the tree's "needs recompute" says what the status says: touched exactly when outdated
            assert state["touched"] == state["status"].startswith("outdated"), (step.get("undone", step.get(
                "redone")), state["status"], state["state"])
        else:
            assert step["table"] == [] and "not in the document" in step["summary"]
    undone = {u["undone"]: u for u in steps["undo"]}
    # after undoing the edit (depth 850 -> 800 mm), the panel shows the insert's values again, not the undone ones
    assert undone["Edit parameters of tripteor_x7"]["table"] == steps["insert"]["table"]
    assert steps["edit"]["table"] != steps["insert"]["table"]
    assert steps["redo"][-1]["table"] == steps["analyse"]["table"]


def test_no_error_line_in_the_report_view(clicks):
    """Only the refusal of a bad value is an error line; undo and redo print none (no "Can't find Origin")."""
    steps = _steps(clicks)
    report = clicks["report"]
    assert "Can't find" not in report["report_view"]
    for step in steps["undo"] + steps["redo"]:
        assert step["new_error_lines"] == [], step.get("undone", step.get("redone"))
    refused = steps["refused"]["boxes"][0]["text"]
    errors = report["report_view_errors"]
    # the refusal is found as an error line (so the reading works), and nothing else is one
    assert errors and all(line.endswith(f"Hyperstat - Edit parameters: {refused}") for line in errors), errors


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
    assert _hue_pixels(edit["screenshot"], CLASS_RGB["assembly"]) > 30


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
    # the Results panel at that width shows the values next to the ids, the ids in their class's colour, the long
    # statements after them
    shown = steps["analyse"]["columns_in_view"]
    assert shown[:2] == ["id", "without calibration"] and "statement" not in shown, shown
    colours = steps["analyse"]["id_class_colours"]
    assert colours and all(a == b and a != "#000000" for a, b in colours), colours


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
