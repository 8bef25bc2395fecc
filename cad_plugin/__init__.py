"""hyperstat CAD side: skeleton authoring (CadQuery), extraction, views, FreeCAD workbench.

Units: lengths in mm, angles in rad.  CadQuery and pyvista are imported lazily, by
the functions that need them.
"""

from hyperstat.cad_plugin.params import describe, param, parse_overrides, parse_value
from hyperstat.cad_plugin.skeleton import Link, Skeleton
from hyperstat.cad_plugin.templates import build_template, list_templates, load_template

__all__ = [
    "describe",
    "param",
    "parse_overrides",
    "parse_value",
    "Link",
    "Skeleton",
    "build_template",
    "list_templates",
    "load_template",
]
