"""Show errors and notices: FreeCAD's report view always, a message box when the GUI is up.

Units: none.
"""

from __future__ import annotations

import traceback

from .runner import HyperstatWorkbenchError

__all__ = ["show_error", "show_info", "icon_path", "guarded"]


def icon_path(name: str) -> str:
    """Path of an SVG icon of the workbench (``Resources/icons/<name>.svg``)."""
    import os

    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "Resources", "icons", f"{name}.svg")


def _main_window():
    import FreeCADGui

    return FreeCADGui.getMainWindow()


def show_error(title: str, exc: BaseException | str) -> None:
    """Report an error: one sentence for a known error, the traceback in the report view otherwise."""
    import FreeCAD

    if isinstance(exc, HyperstatWorkbenchError) or isinstance(exc, str):
        text = str(exc)
    else:
        text = f"unexpected {exc.__class__.__name__}: {exc} (details in the report view)"
        FreeCAD.Console.PrintError("".join(traceback.format_exception(exc)))
    FreeCAD.Console.PrintError(f"Hyperstat - {title}: {text}\n")
    if FreeCAD.GuiUp:
        from PySide import QtGui

        QtGui.QMessageBox.critical(_main_window(), f"Hyperstat - {title}", text)


def show_info(title: str, text: str) -> None:
    """A notice in the report view and the status bar."""
    import FreeCAD

    FreeCAD.Console.PrintMessage(f"Hyperstat - {title}: {text}\n")
    if FreeCAD.GuiUp:
        _main_window().statusBar().showMessage(f"{title}: {text}", 15000)


def guarded(title: str, function, *args, **kwargs):
    """Run ``function`` with a wait cursor; show any error and return ``None`` instead of raising."""
    import FreeCAD

    cursor = False
    if FreeCAD.GuiUp:
        from PySide import QtCore, QtGui

        QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
        QtGui.QApplication.processEvents()
        cursor = True
    try:
        return function(*args, **kwargs)
    except Exception as exc:  # noqa: BLE001 - every error becomes a message, never a dead panel
        if cursor:
            from PySide import QtGui

            QtGui.QApplication.restoreOverrideCursor()
            cursor = False
        show_error(title, exc)
        return None
    finally:
        if cursor:
            from PySide import QtGui

            QtGui.QApplication.restoreOverrideCursor()
