"""hyperstat: geometric defects of over-constrained robots and parallel kinematic machines.

Units everywhere: lengths in mm, angles in rad.

The repository root is this package: ``hyperstat.solver`` (numerical backend, one
sub-package per pipeline stage: kinematics, analysis, tolerances, calibration, diagnosis,
export, cli), ``hyperstat.cad_plugin`` (CadQuery skeletons, pyvista views, report
layout, FreeCAD workbench) and ``hyperstat.templates`` (parametric skeletons).

>>> import hyperstat as hs
>>> result = hs.analyze(hs.load("slider_crank"))
>>> result.counts()["total"]
15
"""

from importlib.metadata import PackageNotFoundError, version as _version

from hyperstat.cad_plugin.api import accuracy, analyze, diagnose, identify, load, report, template_path

try:
    __version__ = _version("hyperstat")
except PackageNotFoundError:  # pragma: no cover - running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["__version__", "load", "analyze", "accuracy", "identify", "diagnose", "report", "template_path"]
