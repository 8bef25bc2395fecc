"""View provider of the skeleton object: icon, tree children, double-click and context menu.

Units: none.  Double-click and the context menu run the workbench's commands by name
(``FreeCADGui.runCommand``), so that this module, which :mod:`.operations` imports, imports
neither the commands nor the panels (no import cycle).  Saved with the document (``GuiDocument.xml``) like the object's proxy:
``__getstate__/__setstate__`` for FreeCAD 0.20, ``dumps/loads`` for 0.21 and later.
"""

from __future__ import annotations

from .messages import icon_path

__all__ = ["ViewProviderSkeleton"]


def _run_on(obj, command: str) -> None:
    """Select the skeleton and run a workbench command on it (by name: this module imports no command code)."""
    import FreeCADGui

    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(obj)
    FreeCADGui.runCommand(command)


class ViewProviderSkeleton:
    """View provider of a hyperstat skeleton (``App::DocumentObjectGroupPython``)."""

    def __init__(self, vobj):
        vobj.Proxy = self

    def attach(self, vobj):
        self.Object = vobj.Object

    def getIcon(self) -> str:
        return icon_path("hyperstat")

    def doubleClicked(self, vobj) -> bool:
        _run_on(vobj.Object, "Hyperstat_EditParameters")
        return True

    def setupContextMenu(self, vobj, menu) -> None:
        from PySide import QtGui

        obj = vobj.Object
        for text, icon, command in (
            ("Edit parameters", "parameters", "Hyperstat_EditParameters"),
            ("Rebuild", "rebuild", "Hyperstat_Rebuild"),
            ("Analyse", "analyze", "Hyperstat_Analyze"),
            ("Results", "results", "Hyperstat_Results"),
        ):
            action = QtGui.QAction(QtGui.QIcon(icon_path(icon)), text, menu)
            action.triggered.connect(lambda checked=False, c=command: _run_on(obj, c))
            menu.addAction(action)

    def onDelete(self, vobj, subelements) -> bool:
        return True

    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None

    def dumps(self):
        return None

    def loads(self, state):
        return None
