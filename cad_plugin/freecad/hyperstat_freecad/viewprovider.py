"""View provider of the skeleton object: icon, tree children, double-click and context menu.

Units: none.  Saved with the document (``GuiDocument.xml``) like the object's proxy:
``__getstate__/__setstate__`` for FreeCAD 0.20, ``dumps/loads`` for 0.21 and later.
"""

from __future__ import annotations

from .messages import icon_path

__all__ = ["ViewProviderSkeleton"]


class ViewProviderSkeleton:
    """View provider of a hyperstat skeleton (``App::DocumentObjectGroupPython``)."""

    def __init__(self, vobj):
        vobj.Proxy = self

    def attach(self, vobj):
        self.Object = vobj.Object

    def getIcon(self) -> str:
        return icon_path("hyperstat")

    def doubleClicked(self, vobj) -> bool:
        from . import panels

        panels.open_parameters(vobj.Object)
        return True

    def setupContextMenu(self, vobj, menu) -> None:
        from PySide import QtGui

        from . import panels
        from .messages import guarded
        from .operations import analyze, rebuild

        obj = vobj.Object
        for text, icon, slot in (
            ("Edit parameters", "parameters", lambda: panels.open_parameters(obj)),
            ("Rebuild", "rebuild", lambda: guarded("Rebuild", rebuild, obj)),
            ("Analyse", "analyze", lambda: guarded("Analyse", analyze, obj) and panels.open_results(obj)),
            ("Results", "results", lambda: panels.open_results(obj)),
        ):
            action = QtGui.QAction(QtGui.QIcon(icon_path(icon)), text, menu)
            action.triggered.connect(slot)
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
