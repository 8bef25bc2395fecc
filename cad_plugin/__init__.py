"""hyperstat CAD side: skeleton authoring (CadQuery), extraction, views, FreeCAD workbench.

Units: lengths in mm, angles in rad.  CadQuery and pyvista are imported lazily, by
the functions that need them.
"""

from .params import describe, param, parse_overrides, parse_value
from .skeleton import Link, Skeleton
from .templates import build_template, list_templates, load_template

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
