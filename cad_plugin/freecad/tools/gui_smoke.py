"""GUI smoke run of the Hyperstat workbench, for ``freecad`` (the GUI) under Xvfb.

Units: lengths in mm, angles in rad.

Usage (the test and ``make freecad-screenshot`` do this)::

    HYPERSTAT_SMOKE_OUT=out/smoke xvfb-run -a -s "-screen 0 1600x1000x24" freecad cad_plugin/freecad/tools/gui_smoke.py

Drives the GUI as a user would: checks that the workbench is the active one, runs the
*Insert skeleton* command, picks the Tripteor X7 template in its task panel and
presses OK (which builds, imports, analyses and opens the results panel), then
saves a screenshot of the main window and writes what it saw to ``report.json`` in
``$HYPERSTAT_SMOKE_OUT``.  It never raises: every failure is written to the report,
and the window is closed at the end (a watchdog closes it after 240 s in any case).
"""

import json
import os
import traceback

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

OUT = os.environ.get("HYPERSTAT_SMOKE_OUT", os.path.join(os.getcwd(), "hyperstat-smoke"))
TEMPLATE = os.environ.get("HYPERSTAT_SMOKE_TEMPLATE", "tripteor_x7")


def _write(report):
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, "report.json"), "w", encoding="utf-8") as fh:
        json.dump(report, fh, indent=2, sort_keys=True)


def _quit():
    for name in list(FreeCAD.listDocuments()):
        FreeCAD.closeDocument(name)
    QtGui.QApplication.instance().quit()


def run():
    report = {"ok": False, "stage": "start"}
    os.makedirs(OUT, exist_ok=True)
    try:
        mw = FreeCADGui.getMainWindow()
        mw.setGeometry(0, 0, 1560, 960)
        report["active_workbench_at_start"] = FreeCADGui.activeWorkbench().name()
        report["stage"] = "activate"
        FreeCADGui.activateWorkbench("HyperstatWorkbench")
        report["active_workbench"] = FreeCADGui.activeWorkbench().name()
        report["commands"] = sorted(c for c in FreeCADGui.listCommands() if c.startswith("Hyperstat_"))
        toolbar = mw.findChild(QtGui.QToolBar, "Hyperstat")
        report["toolbar_actions"] = [a.text() for a in toolbar.actions()] if toolbar else []
        doc = FreeCAD.newDocument("hyperstat_smoke")
        report["stage"] = "insert"
        from hyperstat_freecad import panels
        from hyperstat_freecad.geometry import verdict_spheres
        from hyperstat_freecad.operations import results, skeletons

        FreeCADGui.runCommand("Hyperstat_InsertSkeleton")
        panel = panels.ACTIVE[0]
        report["insert_panel"] = type(panel).__name__
        report["templates_offered"] = [panel.combo.itemText(i) for i in range(panel.combo.count())]
        panel.select(TEMPLATE)
        report["stage"] = "accept"
        panel.accept()  # builds, imports, analyses, opens the results panel
        QtGui.QApplication.processEvents()
        found = skeletons(doc)
        report["skeletons"] = [o.Label for o in found]
        sk = found[0]
        report["status"] = sk.Status
        report["summary"] = sk.Summary
        analysis = results(sk) or {}
        report["analysis_parameters"] = [[p["name"], p["element"], p["verdict"], p.get("influential")]
                                         for p in analysis.get("parameters", [])]
        panel = panels.ACTIVE[0] if panels.ACTIVE else None
        report["results_panel"] = type(panel).__name__ if panel else None
        report["results_rows"] = panel.table.rowCount() if panel is not None and hasattr(panel, "table") else 0
        report["results_verdict_cells"] = [panel.table.item(r, 3).text() for r in range(report["results_rows"])]
        report["spheres"] = {el: {"verdict": s.HyperstatVerdict, "app_color": list(s.HyperstatColor)[:3],
                                  "view_color": list(s.ViewObject.ShapeColor)[:3], "visible": s.ViewObject.Visibility}
                             for el, s in verdict_spheres(sk).items()}
        report["stage"] = "parameters panel"
        shown = []
        real_critical = QtGui.QMessageBox.critical
        QtGui.QMessageBox.critical = lambda parent, title, text, *a: shown.append([title, text])
        try:
            panels.open_parameters(sk)
            editor = panels.ACTIVE[0]
            report["parameters_panel_rows"] = sorted(editor.boxes)
            editor.set_value("depth", 0.0)  # the template wants depth > 0
            report["bad_value_accepted"] = editor.accept()
            report["bad_value_messages"] = shown
            report["panel_alive_after_error"] = bool(panels.ACTIVE and panels.ACTIVE[0] is editor
                                                     and FreeCADGui.Control.activeDialog())
            report["status_after_error"] = sk.Status
            editor.reject()
            report["depth_after_cancel"] = sk.depth.Value
            report["status_after_cancel"] = sk.Status
        finally:
            QtGui.QMessageBox.critical = real_critical
        report["stage"] = "preference page"
        import hyperstat_freecad

        ui = os.path.join(os.path.dirname(os.path.dirname(hyperstat_freecad.__file__)), "Resources", "ui",
                          "preferences.ui")
        page = FreeCADGui.PySideUic.loadUi(ui)
        report["preference_widgets"] = {w.objectName(): w.metaObject().className()
                                        for w in page.findChildren(QtGui.QWidget)
                                        if w.objectName() in ("cliPath", "templatesDir")}
        FreeCADGui.runCommand("Hyperstat_Results")
        report["stage"] = "screenshot"
        for dock in mw.findChildren(QtGui.QDockWidget):
            if dock.objectName() in ("Python console", "Report view", "Selection view"):
                dock.hide()
            elif dock.objectName() == "Combo View":
                combo = dock
        mw.resizeDocks([combo], [600], QtCore.Qt.Horizontal)
        view = FreeCADGui.ActiveDocument.ActiveView
        view.viewIsometric()
        for _ in range(5):
            QtGui.QApplication.processEvents()
        view.fitAll()
        for _ in range(5):
            QtGui.QApplication.processEvents()
        # the screen, not the widget: a widget grab misses the OpenGL view under Xvfb
        geometry = mw.frameGeometry()
        screen = QtGui.QGuiApplication.primaryScreen().grabWindow(0, geometry.x(), geometry.y(),
                                                                  geometry.width(), geometry.height())
        screen.save(os.path.join(OUT, "freecad_workbench.png"))
        view.saveImage(os.path.join(OUT, "view.png"), 800, 600, "White")
        report["stage"] = "done"
        report["ok"] = True
    except Exception:  # noqa: BLE001 - written to the report, the test reads it
        report["error"] = traceback.format_exc()
    _write(report)
    QtCore.QTimer.singleShot(100, _quit)


QtCore.QTimer.singleShot(240000, _quit)
QtCore.QTimer.singleShot(500, run)
