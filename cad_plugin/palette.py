"""The tolerance classes' colours and legend words (one definition, shared with the FreeCAD workbench).

Units: none.

The definition is ``cad_plugin/freecad/classes.json``, read by the workbench's pure-Python
module ``cad_plugin/freecad/hyperstat_palette.py``; FreeCAD runs its own Python and imports
that module from the installed workbench, the project imports the same file from here.  The
report, the pyvista pictures and FreeCAD therefore draw every class in one colour.

>>> CLASS_COLORS["accuracy-critical"]
'#c62828'
>>> callout_text("41", ["T1", "T2", "T3"])
'41: T1-T3'
"""

from __future__ import annotations

from hyperstat.cad_plugin.freecad.hyperstat_palette import (CLASS_COLORS, CLASS_LABELS, CLASS_ORDER, CLASS_RGB,
                                                            DEFINITION, RETIRED_WORDS, TOLERANCE_CLASSES, callout_text,
                                                            element_classes, hex_to_rgb, tolerance_counts)

__all__ = ["CLASS_ORDER", "CLASS_COLORS", "CLASS_RGB", "CLASS_LABELS", "RETIRED_WORDS", "TOLERANCE_CLASSES",
           "DEFINITION", "element_classes", "callout_text", "tolerance_counts", "hex_to_rgb"]
