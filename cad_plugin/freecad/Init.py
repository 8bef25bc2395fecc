# hyperstat workbench, application side (runs in FreeCAD and freecadcmd alike).
#
# Units: lengths in mm, angles in rad.  Registers the workbench's unit tests so that
# `freecadcmd -t TestHyperstatWorkbench` runs them (and Test workbench lists them).
# FreeCAD 0.20 executes this file with exec(): keep it to statements.

import FreeCAD

FreeCAD.__unit_test__ += ["TestHyperstatWorkbench"]
