"""hyperstat in FreeCAD: skeletons from templates, stationarity verdicts on the markers.

Units: lengths in mm, angles in rad (FreeCAD shows angles in degrees).

The scripting API (works in ``freecadcmd``, no GUI needed)::

    import FreeCAD, hyperstat_freecad as hs
    doc = FreeCAD.newDocument("study")
    sk = hs.insert_skeleton(doc, "tripteor_x7")
    analysis = hs.analyze(sk)          # paper 1, section 3: forced / coupled / free defects
    hs.identify(sk, "data.csv", "val.csv")

The solver runs as the ``hyperstat`` command line (see :mod:`.runner` for why and
how it is found); GUI commands live in :mod:`.commands` and :mod:`.panels`.
"""

from .feature import SkeletonFeature, is_skeleton
from .geometry import markers, verdict_spheres
from .operations import (
    analyze,
    describe_template,
    diagnose,
    export_controller,
    export_report,
    identify,
    insert_skeleton,
    needs_rebuild,
    rebuild,
    resolve_template,
    results,
    set_parameters,
    skeletons,
    work_dir,
)
from .parameters import current_parameters, parameter_specs
from .runner import CommandMissing, HyperstatWorkbenchError, find_cli, list_templates, run_cli, templates_dir
from .verdicts import VERDICT_COLORS, element_verdicts, parameter_class

__all__ = [
    "SkeletonFeature",
    "is_skeleton",
    "parameter_specs",
    "markers",
    "verdict_spheres",
    "analyze",
    "describe_template",
    "diagnose",
    "export_controller",
    "export_report",
    "identify",
    "insert_skeleton",
    "needs_rebuild",
    "rebuild",
    "resolve_template",
    "results",
    "set_parameters",
    "skeletons",
    "work_dir",
    "current_parameters",
    "CommandMissing",
    "HyperstatWorkbenchError",
    "find_cli",
    "list_templates",
    "run_cli",
    "templates_dir",
    "VERDICT_COLORS",
    "element_verdicts",
    "parameter_class",
]
