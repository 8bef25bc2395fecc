"""GUI commands of the workbench (toolbar, menu, context menu) and the preference page.

Units: lengths in mm, angles in rad.

Each command finds its skeleton (the selected one, or the only one of the active
document), runs the steps of an operation of :mod:`.operations` as a :class:`.jobs.Job`
(in the background, with a progress bar and Cancel in the status bar; errors become
messages, never a dead panel) and, once it is done, opens a panel with the outcome.
"""

from __future__ import annotations

import os

from .messages import icon_path, show_error, show_info

__all__ = ["register", "register_preferences", "TOOLBAR", "MENU", "CONTEXT", "COMMANDS", "target_skeleton"]


def target_skeleton(report: bool = True):
    """The selected skeleton (or the one holding the selected marker), else the document's only one."""
    import FreeCAD
    import FreeCADGui

    from .feature import is_skeleton
    from .operations import skeletons

    doc = FreeCAD.ActiveDocument
    if doc is None:
        if report:
            show_error("Hyperstat", "Open a document and insert a skeleton first.")
        return None
    for sel in FreeCADGui.Selection.getSelection():
        candidates = [sel, *sel.InListRecursive]
        for c in candidates:
            if is_skeleton(c):
                return c
    found = skeletons(doc)
    if len(found) == 1:
        return found[0]
    if report:
        show_error("Hyperstat", "Select a skeleton first." if found else "Insert a skeleton first.")
    return None


class _Command:
    """Base: a FreeCAD command with an SVG icon."""

    icon = "hyperstat"
    menu = ""
    tip = ""
    needs_skeleton = True

    def GetResources(self) -> dict:
        return {"Pixmap": icon_path(self.icon), "MenuText": self.menu, "ToolTip": self.tip}

    def IsActive(self) -> bool:
        import FreeCAD

        from .jobs import running

        if running():
            return False  # one command-line job at a time; its progress bar has a Cancel button
        if not self.needs_skeleton:
            return True
        doc = FreeCAD.ActiveDocument
        if doc is None:
            return False
        from .feature import is_skeleton

        return any(is_skeleton(o) for o in doc.Objects)

    def Activated(self) -> None:
        try:
            self.run()
        except Exception as exc:  # noqa: BLE001 - a command never dies silently
            show_error(self.menu, exc)


class InsertSkeleton(_Command):
    icon = "insert"
    menu = "Insert skeleton"
    tip = "Insert a mechanism skeleton from a hyperstat template (parameters as properties and a spreadsheet)"
    needs_skeleton = False

    def run(self) -> None:
        import FreeCAD

        from .panels import InsertPanel, show_panel

        doc = FreeCAD.ActiveDocument or FreeCAD.newDocument("hyperstat")
        show_panel(InsertPanel(doc))


class EditParameters(_Command):
    icon = "parameters"
    menu = "Edit parameters"
    tip = "Edit the template parameters of the skeleton, then rebuild it"

    def run(self) -> None:
        from .panels import open_parameters

        obj = target_skeleton()
        if obj is not None:
            open_parameters(obj)


def _job(title: str, steps, on_done) -> None:
    from .jobs import Job

    Job(title, steps, on_done).start()


class Rebuild(_Command):
    icon = "rebuild"
    menu = "Rebuild"
    tip = "Re-run 'hyperstat build' with the current parameters and re-import the skeleton"

    def run(self) -> None:
        from .operations import rebuild_steps

        obj = target_skeleton()
        if obj is not None:
            _job("Rebuild", rebuild_steps(obj), lambda o: show_info("Rebuild", f"{o.Label}: {o.Summary}"))


class Analyze(_Command):
    icon = "analyze"
    menu = "Analyse"
    tip = "Analyse: tolerance classes and values of every defect, as the printed report gives them; colour the markers"

    def run(self) -> None:
        from .operations import analyze_steps
        from .panels import open_results, show_later

        obj = target_skeleton()
        if obj is not None:
            _job("Analyse", analyze_steps(obj), lambda _a: show_later(open_results, obj))


class Results(_Command):
    icon = "results"
    menu = "Results"
    tip = "Show the tolerances (ids, classes, values, drawing frames) and the class of every defect parameter"

    def run(self) -> None:
        from .panels import open_results

        obj = target_skeleton()
        if obj is not None:
            open_results(obj)


def _open_file(title: str, filters: str) -> str:
    from PySide import QtGui

    import FreeCADGui

    path, _ = QtGui.QFileDialog.getOpenFileName(FreeCADGui.getMainWindow(), title, "", filters)
    return path


class Identify(_Command):
    icon = "identify"
    menu = "Load measurements and identify"
    tip = "Choose measurement files (CSV) and identify the free influential defects ('hyperstat identify')"

    def run(self) -> None:
        from .operations import identify_steps
        from .panels import open_identification, show_later

        obj = target_skeleton()
        if obj is None:
            return
        data = _open_file("Identification measurements", "hyperstat measurements (*.csv)")
        if not data:
            return
        validation = _open_file("Validation measurements (cancel for none)", "hyperstat measurements (*.csv)")
        _job("Identify", identify_steps(obj, data, validation or None), lambda _r: show_later(open_identification, obj))


class Diagnose(_Command):
    icon = "diagnose"
    menu = "Diagnose the gap"
    tip = "Where the identified model still misses, which unmodelled effect, how far it shrinks ('hyperstat diagnose')"

    def run(self) -> None:
        from .operations import diagnose_steps
        from .panels import open_diagnosis, show_later

        obj = target_skeleton()
        if obj is None:
            return
        data = None
        if not obj.MeasurementFile:
            data = _open_file("Measurements", "hyperstat measurements (*.csv)")
            if not data:
                return
        _job("Diagnose", diagnose_steps(obj, data), lambda _r: show_later(open_diagnosis, obj))


def _default_dir(obj) -> str:
    name = obj.Document.FileName
    return os.path.dirname(name) if name else os.path.expanduser("~")


class Report(_Command):
    icon = "report"
    menu = "Export the tolerance report"
    tip = "Write the tolerance report (HTML, Markdown, JSON) with 'hyperstat report'"

    def run(self) -> None:
        from PySide import QtGui

        import FreeCADGui

        from .operations import report_steps

        obj = target_skeleton()
        if obj is None:
            return
        folder = QtGui.QFileDialog.getExistingDirectory(FreeCADGui.getMainWindow(), "Report folder", _default_dir(obj))
        if folder:
            _job("Report", report_steps(obj, folder), lambda _r: show_info("Report", f"written in {folder}"))


class ExportController(_Command):
    icon = "controller"
    menu = "Export the controller file"
    tip = "Write the controller parameter file with 'hyperstat export-controller'"

    def run(self) -> None:
        from PySide import QtGui

        import FreeCADGui

        from .operations import controller_steps

        obj = target_skeleton()
        if obj is None:
            return
        path, _ = QtGui.QFileDialog.getSaveFileName(FreeCADGui.getMainWindow(), "Controller file",
                                                    os.path.join(_default_dir(obj), f"{obj.Label}.machine.json"),
                                                    "JSON (*.json)")
        if path:
            _job("Controller file", controller_steps(obj, path), lambda _r: show_info("Controller file", f"written: {path}"))


COMMANDS = {
    "Hyperstat_InsertSkeleton": InsertSkeleton,
    "Hyperstat_EditParameters": EditParameters,
    "Hyperstat_Rebuild": Rebuild,
    "Hyperstat_Analyze": Analyze,
    "Hyperstat_Results": Results,
    "Hyperstat_Identify": Identify,
    "Hyperstat_Diagnose": Diagnose,
    "Hyperstat_Report": Report,
    "Hyperstat_ExportController": ExportController,
}
TOOLBAR = ["Hyperstat_InsertSkeleton", "Hyperstat_EditParameters", "Hyperstat_Rebuild", "Hyperstat_Analyze",
           "Hyperstat_Results", "Hyperstat_Identify", "Hyperstat_Diagnose", "Hyperstat_Report",
           "Hyperstat_ExportController"]
MENU = TOOLBAR
CONTEXT = ["Hyperstat_EditParameters", "Hyperstat_Rebuild", "Hyperstat_Analyze", "Hyperstat_Results"]


_OBSERVER: list = []


def register() -> None:
    """Add the commands to FreeCAD (once), and the observer that keeps outdated skeletons marked."""
    import FreeCAD
    import FreeCADGui

    from .feature import OutdatedObserver

    if not _OBSERVER:
        _OBSERVER.append(OutdatedObserver())
        FreeCAD.addDocumentObserver(_OBSERVER[0])

    known = set(FreeCADGui.listCommands())
    for name, cls in COMMANDS.items():
        if name not in known:
            FreeCADGui.addCommand(name, cls())


def register_preferences() -> None:
    """Edit > Preferences > Hyperstat: the command line and the templates folder."""
    import FreeCADGui

    ui = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "Resources", "ui",
                      "preferences.ui")
    FreeCADGui.addPreferencePage(ui, "Hyperstat")
    FreeCADGui.addIconPath(os.path.dirname(icon_path("hyperstat")))
