"""Clicking scenario run by the FreeCAD GUI under Xvfb (not by pytest): the real buttons of the real panels.

Units: lengths in mm, angles in rad (FreeCAD shows degrees).

Run by ``test_gui_clicks.py``::

    HYPERSTAT_CLICKS_OUT=DIR HYPERSTAT_CLICKS_DATA=data.csv HYPERSTAT_CLICKS_VALIDATION=val.csv \\
        xvfb-run -a -s "-screen 0 1700x1000x24" freecad gui_clicks.py

One FreeCAD start, as a user would: click the toolbar's *Insert skeleton*, choose the
Tripteor X7, click OK (``QTest.mouseClick``); the results panel opens; *Identify* and
*Diagnose* on simulated measurements (the file dialogs answer with the given CSV files);
*Edit parameters*, type a value the template refuses, OK, then a good one, OK; *Analyse*
from the toolbar while the results panel is open; then *Edit > Undo* step by step.  After
each step it records the document's state, the panels, the message boxes that appeared
(closed by a watchdog so that nothing blocks) and a screenshot, in ``DIR/report.json``.
The test (pytest side) judges them.  Never raises; exits through ``QApplication.quit``.
"""

import json
import os
import time
import traceback

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui
from PySide2 import QtTest

OUT = os.environ.get("HYPERSTAT_CLICKS_OUT", os.path.join(os.getcwd(), "hyperstat-clicks"))
DATA = os.environ.get("HYPERSTAT_CLICKS_DATA", "")
VALIDATION = os.environ.get("HYPERSTAT_CLICKS_VALIDATION", "")
TEMPLATE = "tripteor_x7"
#: every shipped template: inserted by clicks, its results panel read and compared with its report
TEMPLATES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar"]
STEP_TIMEOUT_S = 300
REPORT = {"ok": False, "stage": "start", "steps": {}, "boxes": [], "events": []}


def _write():
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, "report.json"), "w", encoding="utf-8") as fh:
        json.dump(REPORT, fh, indent=1, sort_keys=True, default=str)


def _cpu():
    """CPU seconds of this FreeCAD process so far: its main thread, and the rest (Mesa's llvmpipe threads draw)."""
    main = other = 0.0
    tick = os.sysconf("SC_CLK_TCK")
    for task in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{task}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        seconds = (int(fields[11]) + int(fields[12])) / tick
        if task == str(os.getpid()):
            main += seconds
        else:
            other += seconds
    return main, other


def _event(text):
    main, other = _cpu()
    REPORT["events"].append(f"{time.monotonic() - T0:7.1f} s cpu {main:6.1f}+{other:5.1f} s {REPORT['stage']}: {text}")
    _write()


def _close_boxes():
    """Watchdog: record and close every message box (a modal box would block the scenario)."""
    for w in QtGui.QApplication.topLevelWidgets():
        if isinstance(w, QtGui.QMessageBox) and w.isVisible():
            REPORT["boxes"].append({"stage": REPORT["stage"], "title": w.windowTitle(), "text": w.text()})
            _event(f"message box {w.windowTitle()!r}: {w.text()!r}")
            w.done(0)


def pump(seconds=0.2):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        QtGui.QApplication.processEvents(QtCore.QEventLoop.AllEvents, 50)
        time.sleep(0.02)


def wait_until(predicate, what, timeout=STEP_TIMEOUT_S):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        pump(0.2)
    raise RuntimeError(f"timed out after {timeout} s waiting for {what}")


def main_window():
    return FreeCADGui.getMainWindow()


def toolbar_button(command):
    """The real toolbar button of a workbench command."""
    toolbar = main_window().findChild(QtGui.QToolBar, "Hyperstat")
    for action in toolbar.actions():
        if action.objectName() == command:
            return toolbar.widgetForAction(action), action
    raise RuntimeError(f"no toolbar button for {command}")


def click_command(command):
    button, action = toolbar_button(command)
    REPORT["steps"].setdefault("enabled_before_click", {})[f"{REPORT['stage']}:{command}"] = action.isEnabled()
    QtTest.QTest.mouseClick(button, QtCore.Qt.LeftButton)


def task_button(text):
    """A visible button of the task panel (OK, Cancel, Close)."""
    for b in main_window().findChildren(QtGui.QPushButton):
        if b.isVisible() and b.text().replace("&", "") == text:
            return b
    return None


def click_task_button(text):
    wait_until(lambda: task_button(text) is not None and task_button(text).isEnabled(), f"the {text} button")
    t = time.monotonic()
    QtTest.QTest.mouseClick(task_button(text), QtCore.Qt.LeftButton)
    return time.monotonic() - t


def active_panel():
    from hyperstat_freecad import panels

    return panels.ACTIVE[0] if panels.ACTIVE else None


def wait_panel(cls_name):
    wait_until(lambda: type(active_panel()).__name__ == cls_name and FreeCADGui.Control.activeDialog()
               and not _job_running(), f"the {cls_name}")
    pump(0.5)
    return active_panel()


def _job_running():
    from hyperstat_freecad import jobs

    return jobs.running()


def state(doc):
    import hyperstat_freecad as hs

    found = hs.skeletons(doc)
    out = {"objects": len(doc.Objects), "skeletons": [o.Label for o in found],
           "undo": list(doc.UndoNames), "redo": list(doc.RedoNames),
           "undo_action_enabled": _undo_action().isEnabled()}
    if found:
        sk = found[0]
        sk.Document.recompute() if False else None
        out.update({
            "status": sk.Status, "touched": "Touched" in sk.State, "state": list(sk.State),
            "parameters": hs.current_parameters(sk),
            "classes": dict(sk.ParameterClasses),
            "markers": {n: list(p.getGlobalPlacement().Base) for n, p in hs.markers(sk).items()},
            "spheres": {el: {"class": s.HyperstatClass, "view_color": list(s.ViewObject.ShapeColor)[:3],
                             "center": list(s.getGlobalPlacement().Base)}
                        for el, s in hs.class_spheres(sk).items()},
            "callouts": {k: list(v.LabelText) for k, v in hs.callout_labels(sk).items()},
            "frame_labels": {k: {"text": list(v.LabelText), "position": list(v.Position), "visible": bool(v.Visibility)}
                             for k, v in hs.frame_labels(sk).items()},
            "analysis": json.loads(sk.Analysis) if sk.Analysis else None,
            "tolerances": hs.tolerances(sk),
            "identification": bool(sk.Identification), "diagnosis": bool(sk.Diagnosis),
        })
    return out


def table_rows(t):
    return [[t.item(r, c).text() if t.item(r, c) else "" for c in range(t.columnCount())] for r in range(t.rowCount())]


def _head(table, column: int) -> str:
    """A column's head as words (a head drawn on two lines reads as one)."""
    return " ".join(table.horizontalHeaderItem(column).text().split())


def panel_contents(panel):
    """What a panel shows: its table(s), their heads, its summary."""
    out = {}
    if panel is not None and hasattr(panel, "table"):
        t = panel.table
        out["table"] = table_rows(t)
        out["table_header"] = [_head(t, c) for c in range(t.columnCount())]
        out["id_class_colours"] = [(t.item(r, 0).background().color().name(), t.item(r, 1).background().color().name())
                                   for r in range(t.rowCount()) if t.item(r, 0) is not None and t.item(r, 1) is not None]
        header, width = t.horizontalHeader(), t.viewport().width()
        out["columns_in_view"] = [_head(t, c) for c in map(header.logicalIndex, range(t.columnCount()))  # as shown
                                  if 0 <= header.sectionViewportPosition(c)
                                  and header.sectionViewportPosition(c) + header.sectionSize(c) <= width]
    if panel is not None and hasattr(panel, "parameters") and hasattr(panel.parameters, "rowCount"):
        out["parameter_table"] = table_rows(panel.parameters)
    if panel is not None and hasattr(panel, "drawings") and hasattr(panel.drawings, "rowCount"):
        out["frame_table"] = table_rows(panel.drawings)
        out["frame_table_header"] = [_head(panel.drawings, c)
                                     for c in range(panel.drawings.columnCount())]
        out["datum_table"] = table_rows(panel.datums)
        out["drawings_note"] = panel.drawings_note.text()
    if panel is not None and hasattr(panel, "summary"):
        out["summary"] = panel.summary.text()
    if panel is not None and hasattr(panel, "legend"):
        out["legend"] = panel.legend.text()
    return out


def edges(panel):
    """Right edges (screen x) of the panel's form and of the dock that holds it (FreeCAD's Combo View)."""
    dock = main_window().findChild(QtGui.QDockWidget, "Combo View")
    return {"panel_width_hint": panel.form.minimumSizeHint().width(), "panel_width": panel.form.width(),
            "panel_right": panel.form.mapToGlobal(QtCore.QPoint(panel.form.width(), 0)).x(),
            "dock_right": dock.mapToGlobal(QtCore.QPoint(dock.width(), 0)).x()}


def _report_view():
    dock = main_window().findChild(QtGui.QDockWidget, "Report view")
    edits = dock.findChildren(QtGui.QTextEdit) if dock is not None else []
    return edits[0] if edits else None


def report_view_text():
    """Everything FreeCAD's report view shows (messages, warnings, errors)."""
    view = _report_view()
    return view.toPlainText() if view is not None else ""


def report_view_errors():
    """The lines the report view shows in its error colour (red by default).

    The report view colours its lines with a syntax highlighter, whose formats live in each
    text block's layout (not in the document's HTML): read them there.
    """
    view = _report_view()
    if view is None:
        return []
    out = []
    block = view.document().begin()
    while block.isValid():
        colours = [r.format.foreground().color() for r in block.layout().formats()]
        if any(c.red() > 180 and c.green() < 90 and c.blue() < 90 for c in colours):
            out.append(block.text().strip())
        block = block.next()
    return out


def _undo_action():
    return main_window().findChild(QtGui.QAction, "Std_Undo")


def screenshot(name):
    mw = main_window()
    for _ in range(5):
        QtGui.QApplication.processEvents()
    g = mw.frameGeometry()
    pix = QtGui.QGuiApplication.primaryScreen().grabWindow(0, g.x(), g.y(), g.width(), g.height())
    path = os.path.join(OUT, f"freecad_{name}.png")
    pix.save(path)
    return path


def record(name, doc, **extra):
    pump(0.5)  # let the panel's layout settle before measuring it
    panel = active_panel()
    info = {"state": state(doc), "panel": type(panel).__name__ if panel else None,
            "dialog_open": bool(FreeCADGui.Control.activeDialog()), **extra}
    info.update(panel_contents(panel))
    info["screenshot"] = screenshot(name)
    if panel is not None:
        info.update(edges(panel))
    REPORT["steps"][name] = info
    _event("recorded")


def _file_dialog(answers):
    real = QtGui.QFileDialog.getOpenFileName

    def fake(*args, **kwargs):
        return (answers.pop(0) if answers else "", "")

    QtGui.QFileDialog.getOpenFileName = fake
    return real


def run():
    global T0
    T0 = time.monotonic()
    watchdog = QtCore.QTimer()
    watchdog.timeout.connect(_close_boxes)
    watchdog.start(300)
    try:
        mw = main_window()
        mw.setGeometry(0, 0, 1660, 980)
        FreeCADGui.activateWorkbench("HyperstatWorkbench")
        for dock in mw.findChildren(QtGui.QDockWidget):
            if dock.objectName() in ("Python console", "Selection view"):
                dock.hide()
        REPORT["workbench"] = FreeCADGui.activeWorkbench().name()
        doc = FreeCAD.newDocument("clicks")
        REPORT["undo_mode"] = doc.UndoMode
        _event("started")

        # ---------------------------------------------------------------- insert (and analyse)
        REPORT["stage"] = "insert"
        click_command("Hyperstat_InsertSkeleton")
        panel = wait_panel("InsertPanel")
        REPORT["dock_width"] = panel.form.width()
        panel.combo.setCurrentIndex(panel.combo.findText(TEMPLATE))
        ticks = []
        ticker = QtCore.QTimer()
        ticker.timeout.connect(lambda: ticks.append(time.monotonic()))
        ticker.start(100)
        REPORT["steps"]["insert_click_s"] = click_task_button("OK")
        # right after the click: still the insert panel, busy, and nothing in the document yet
        status_text = main_window().findChild(QtGui.QLabel, "HyperstatProgressText")
        pump(1.2)  # the progress ticks twice a second
        REPORT["steps"]["after_ok"] = {"panel": type(active_panel()).__name__,
                                        "progress_text": panel.progress_label.text(),
                                        "status_text": status_text.text() if status_text is not None else None,
                                        "progress_visible": panel.progress_bar.isVisible(),
                                        "inputs_enabled": panel.combo.isEnabled(),
                                        "objects": len(doc.Objects), "job": _job_running(), **edges(panel)}
        screenshot("insert_running")
        pump(1.0)
        REPORT["steps"]["after_ok"]["ticks_during_first_second"] = len(ticks)
        wait_panel("ResultsPanel")
        ticker.stop()
        REPORT["steps"]["insert_ticks"] = len(ticks)
        record("insert", doc)
        screenshot("workbench")  # the picture of docs/freecad.md and the README
        # the Part drawings tab: a click on a frame's row labels its feature in the 3D view, and only it
        results = active_panel()
        results.tabs.setCurrentIndex(results.tabs.count() - 1)
        row = results.drawings.visualItemRect(results.drawings.item(0, 1)).center()
        QtTest.QTest.mouseClick(results.drawings.viewport(), QtCore.Qt.LeftButton, QtCore.Qt.NoModifier, row)
        pump(0.5)
        REPORT["steps"]["frame_clicked"] = {"row": table_rows(results.drawings)[0], "state": state(doc),
                                            "selected": [o.Label for o in FreeCADGui.Selection.getSelection()],
                                            "screenshot": screenshot("part_frame")}
        results.tabs.setCurrentIndex(0)

        # ---------------------------------------------------------------- identify, diagnose
        if DATA:
            REPORT["stage"] = "identify"
            real = _file_dialog([DATA, VALIDATION])
            try:
                click_command("Hyperstat_Identify")
                wait_until(lambda: type(active_panel()).__name__ == "IdentificationPanel" and not _job_running(),
                           "the identification panel")
            finally:
                QtGui.QFileDialog.getOpenFileName = real
            pump(0.5)
            record("identify", doc)
            REPORT["stage"] = "diagnose"
            click_command("Hyperstat_Diagnose")
            wait_until(lambda: type(active_panel()).__name__ == "DiagnosisPanel" and not _job_running(),
                       "the diagnosis panel")
            pump(0.5)
            record("diagnose", doc)

        # ---------------------------------------------------------------- edit parameters
        REPORT["stage"] = "edit (refused value)"
        click_command("Hyperstat_EditParameters")
        editor = wait_panel("ParametersPanel")
        editor.set_value("depth", 0.0)  # the template wants depth > 0 (the box stops at its lower bound)
        boxes_before = len(REPORT["boxes"])
        click_task_button("OK")
        wait_until(lambda: not _job_running() and len(REPORT["boxes"]) > boxes_before, "the refusal message")
        pump(0.5)
        REPORT["steps"]["refused"] = {"boxes": REPORT["boxes"][boxes_before:], "panel": type(active_panel()).__name__,
                                      "panel_is_same": active_panel() is editor,
                                      "dialog_open": bool(FreeCADGui.Control.activeDialog()),
                                      "inputs_enabled": editor.boxes["depth"][0].isEnabled(), **edges(editor),
                                      "state": state(doc)}
        REPORT["stage"] = "edit"
        editor.set_value("depth", 850.0)
        click_task_button("OK")
        wait_panel("ResultsPanel")
        record("edit", doc)

        # ---------------------------------------------------------------- analyse from the toolbar
        REPORT["stage"] = "analyse"
        click_command("Hyperstat_Analyze")
        wait_until(lambda: _job_running(), "the analysis to start", timeout=20)
        wait_panel("ResultsPanel")
        record("analyse", doc)

        # ---------------------------------------------------------------- cancel a running job
        REPORT["stage"] = "cancel"
        undo_before = list(doc.UndoNames)
        click_command("Hyperstat_Rebuild")
        wait_until(_job_running, "the rebuild to start", timeout=20)
        cancel = main_window().findChild(QtGui.QPushButton, "HyperstatCancel")
        pump(1.0)  # FreeCAD refreshes the commands' enabled state from its event loop
        boxes_before = len(REPORT["boxes"])
        enabled = toolbar_button("Hyperstat_Analyze")[1].isEnabled()
        if enabled:  # clickable: a second job must be refused with one message
            click_command("Hyperstat_Analyze")
            wait_until(lambda: len(REPORT["boxes"]) > boxes_before, "the refusal of a second job", timeout=20)
        REPORT["steps"]["cancel"] = {"button_visible": bool(cancel and cancel.isVisible()),
                                     "analyse_enabled_while_running": enabled,
                                     "second_job_boxes": REPORT["boxes"][boxes_before:],
                                     "job_still_running": _job_running()}
        QtTest.QTest.mouseClick(cancel, QtCore.Qt.LeftButton)
        wait_until(lambda: not _job_running(), "the cancelled job to end", timeout=60)
        pump(0.5)
        REPORT["steps"]["cancel"].update({"undo_before": undo_before, "state": state(doc),
                                          "cancel_button_left": main_window().findChild(QtGui.QPushButton,
                                                                                        "HyperstatCancel") is not None})

        # ---------------------------------------------------------------- spreadsheet edit: stale state
        REPORT["stage"] = "spreadsheet"
        import hyperstat_freecad as hs

        sk = hs.skeletons(doc)[0]
        sheet = sk.Spreadsheet
        doc.openTransaction("sheet edit")
        sheet.set(sheet.getCellFromAlias("depth"), "=860 mm")
        doc.commitTransaction()
        doc.recompute()
        pump(0.5)
        REPORT["steps"]["spreadsheet"] = state(doc)
        REPORT["steps"]["spreadsheet"]["tree_needs_recompute"] = "Touched" in sk.State
        doc.undo()
        doc.recompute()
        pump(0.5)
        REPORT["steps"]["spreadsheet_undone"] = state(doc)

        # ---------------------------------------------------------------- undo, then redo, step by step,
        # with the results panel open: it follows the document
        REPORT["stage"] = "undo"
        click_command("Hyperstat_Results")
        results_panel = wait_panel("ResultsPanel")
        undo = []
        while doc.UndoCount:
            action = _undo_action()
            name = doc.UndoNames[0]
            enabled = action.isEnabled()
            errors_before = len(report_view_errors())
            action.trigger()  # Edit > Undo
            pump(0.8)
            undo.append({"undone": name, "action_enabled": enabled, "state": state(doc),
                         "panel_is_same": active_panel() is results_panel, **panel_contents(active_panel()),
                         "new_error_lines": report_view_errors()[errors_before:]})
            if len(undo) > 12:
                break
        REPORT["steps"]["undo"] = undo
        screenshot("undo")
        REPORT["stage"] = "redo"
        redo = []
        while doc.RedoCount:
            name = doc.RedoNames[0]
            errors_before = len(report_view_errors())
            main_window().findChild(QtGui.QAction, "Std_Redo").trigger()  # Edit > Redo
            pump(0.8)
            redo.append({"redone": name, "state": state(doc), "panel_is_same": active_panel() is results_panel,
                         **panel_contents(active_panel()), "new_error_lines": report_view_errors()[errors_before:]})
            if len(redo) > 12:
                break
        REPORT["steps"]["redo"] = redo

        # ---------------------------------------------------------------- every template: insert, read the panel
        REPORT["stage"] = "templates"
        FreeCADGui.Control.closeDialog()
        pump(0.5)
        every = {TEMPLATE: REPORT["steps"]["insert"]}  # inserted by clicks at the start of the scenario
        for name in [t for t in TEMPLATES if t != TEMPLATE]:
            REPORT["stage"] = f"template {name}"
            tdoc = FreeCAD.newDocument(f"t_{name}")
            FreeCAD.setActiveDocument(tdoc.Name)  # the previous template's document may still be closing
            wait_until(lambda: FreeCAD.ActiveDocument is not None and FreeCAD.ActiveDocument.Name == tdoc.Name,
                       f"the document of {name} to be active", timeout=30)
            click_command("Hyperstat_InsertSkeleton")
            insert = wait_panel("InsertPanel")
            insert.combo.setCurrentIndex(insert.combo.findText(name))
            click_task_button("OK")
            wait_panel("ResultsPanel")
            every[name] = {"state": state(tdoc), **panel_contents(active_panel()), "screenshot": screenshot(name)}
            _event("recorded")
            FreeCADGui.Control.closeDialog()
            pump(0.3)
            FreeCAD.closeDocument(tdoc.Name)
            pump(0.3)
        REPORT["steps"]["templates"] = every
        REPORT["report_view"] = report_view_text()
        REPORT["report_view_errors"] = report_view_errors()
        REPORT["stage"] = "done"
        REPORT["ok"] = True
    except Exception:  # noqa: BLE001 - written to the report, the test reads it
        REPORT["error"] = traceback.format_exc()
        REPORT["report_view"] = report_view_text()
        REPORT["report_view_errors"] = report_view_errors()
    _write()
    QtCore.QTimer.singleShot(200, _quit)


def _quit():
    for name in list(FreeCAD.listDocuments()):
        FreeCAD.closeDocument(name)
    QtGui.QApplication.instance().quit()


T0 = time.monotonic()
QtCore.QTimer.singleShot(900000, _quit)
QtCore.QTimer.singleShot(500, run)
