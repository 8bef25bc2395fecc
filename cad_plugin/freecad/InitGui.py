# hyperstat workbench, GUI side.
#
# Units: lengths in mm, angles in rad (FreeCAD shows angles in degrees).
# FreeCAD 0.20 executes this file with exec() inside a function: names defined here
# are not visible inside the class's methods, so each method imports what it needs.


class HyperstatWorkbench(Workbench):  # noqa: F821 - Workbench is provided by FreeCAD
    """Skeleton templates, stationarity verdicts on the markers, identification, exports."""

    MenuText = "Hyperstat"
    ToolTip = "Geometric defects of over-constrained mechanisms: which the structure forces, which are free"

    def __init__(self):
        import os

        import hyperstat_freecad

        self.__class__.Icon = os.path.join(os.path.dirname(hyperstat_freecad.__file__), "..", "Resources",
                                           "icons", "hyperstat.svg")

    def Initialize(self):
        from hyperstat_freecad import commands

        commands.register()
        self.appendToolbar("Hyperstat", commands.TOOLBAR)
        self.appendMenu("Hyperstat", commands.MENU)
        commands.register_preferences()

    def Activated(self):
        pass

    def Deactivated(self):
        pass

    def ContextMenu(self, recipient):
        from hyperstat_freecad import commands

        self.appendContextMenu("Hyperstat", commands.CONTEXT)

    def GetClassName(self):
        return "Gui::PythonWorkbench"


Gui.addWorkbench(HyperstatWorkbench())  # noqa: F821 - Gui is provided by FreeCAD
