"""Shared set-up of the tolerance tests: a template's mechanism, kinematics, analysis, classification, values.

Units: mm and rad.
"""

from __future__ import annotations

import warnings

from hyperstat.cad_plugin.templates import build_template
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.accuracy import sample_workspace
from hyperstat.solver.tolerances.classification import classify
from hyperstat.solver.tolerances.values import ASSEMBLY_SAMPLE, assign_values

from tests.conftest import TEMPLATES

__all__ = ["classified"]


def classified(name: str, values: bool = False, assembly: bool = True):
    """``(mechanism, kinematics, analysis, classification)`` of a template (``name`` without ``.py``).

    With ``values``, the values as ``hyperstat report`` computes them: a workspace sample of 200 (seed 0),
    the analysis' first configurations for the assembly conditions.
    """
    mech = build_template(TEMPLATES / f"{name}.py").mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin)
        cl = classify(mech, result, kin)
        if values:
            q = sample_workspace(mech, 200, seed=0, kinematics=kin)
            assign_values(cl, mech, kin, q, assembly=assembly,
                          assembly_configurations=result.configurations[:ASSEMBLY_SAMPLE])
    return mech, kin, result, cl
