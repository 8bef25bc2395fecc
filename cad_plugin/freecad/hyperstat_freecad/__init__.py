"""hyperstat in FreeCAD: skeletons from templates, tolerance classes and values on the markers.

Units: lengths in mm, angles in rad (FreeCAD shows angles in degrees).

The scripting API (works in ``freecadcmd``, no GUI needed)::

    import FreeCAD, hyperstat_freecad as hs
    doc = FreeCAD.newDocument("study")
    sk = hs.insert_skeleton(doc, "tripteor_x7")
    analysis = hs.analyze(sk)          # tolerance classes and values, as the report gives them
    hs.identify(sk, "data.csv", "val.csv")

The solver runs as the ``hyperstat`` command line (see :mod:`.runner` for why and
how it is found); GUI commands live in :mod:`.commands` and :mod:`.panels`.
"""

from .feature import SkeletonFeature, is_skeleton
from .classes import CLASS_COLORS, element_classes, parameter_classes
from .geometry import callout_labels, class_spheres, frame_labels, markers
from .operations import (
    analyze,
    describe_template,
    diagnose,
    drawings,
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
    tolerances,
    work_dir,
)
from .parameters import current_parameters, parameter_specs
from .runner import CommandMissing, HyperstatWorkbenchError, find_cli, list_templates, run_cli, templates_dir

__all__ = [
    "SkeletonFeature",
    "is_skeleton",
    "parameter_specs",
    "markers",
    "class_spheres",
    "callout_labels",
    "frame_labels",
    "drawings",
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
    "tolerances",
    "work_dir",
    "current_parameters",
    "CommandMissing",
    "HyperstatWorkbenchError",
    "find_cli",
    "list_templates",
    "run_cli",
    "templates_dir",
    "CLASS_COLORS",
    "element_classes",
    "parameter_classes",
]
