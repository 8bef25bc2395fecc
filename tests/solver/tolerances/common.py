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

__all__ = ["classified", "recorded_forks"]


def classified(name: str, values: bool = False, assembly: bool = True):
    """``(mechanism, kinematics, analysis, classification)`` of a template (``name`` without ``.py``).

    With ``values``, the values as ``hyperstat report`` computes them: a workspace sample of 200 (seed 0),
    the analysis' first configurations for the assembly conditions.  With the assembly conditions (the report's
    call), they are the report's own: its entry in the session's cache of results (``tests/conftest.py``), under
    the key ``hyperstat report TEMPLATE`` stores them (the same model, sample and options), computed
    by whichever process of the session gets there first (a report, or this) and read, to the bit, by the others.
    """
    path = TEMPLATES / f"{name}.py"
    mech = build_template(path).mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin)
        cl = classify(mech, result, kin)
        if values and assembly:
            _report_values(path, cl, mech, kin, result)
        elif values:
            q = sample_workspace(mech, 200, seed=0, kinematics=kin)
            assign_values(cl, mech, kin, q, assembly=assembly,
                          assembly_configurations=result.configurations[:ASSEMBLY_SAMPLE])
    return mech, kin, result, cl


def _report_values(path, cl, mech, kin, result) -> None:
    """``assign_values`` on ``cl`` through the cache as ``hyperstat report PATH`` calls it (``cad_plugin/cli.py``):
    its workspace sample and its values entry (:func:`hyperstat.solver.cli.cached.cached_values`); computed when
    the cache is off (``HYPERSTAT_CACHE=off``) or holds no such entry."""
    import argparse

    from hyperstat.solver.cli.cached import cached_sample, cached_values
    from hyperstat.solver.tolerances.workspace import workspace_of

    args = argparse.Namespace(source=str(path), param=None, no_cache=False)  # the report's model identity
    q = cached_sample(args, mech, 200, 0, workspace_of(mech), lambda: sample_workspace(mech, 200, seed=0, kinematics=kin))
    cached_values(args, cl, mech, kin, q, assign_values, position_accuracy=None, orientation_accuracy=None,
                  assembly_configurations=result.configurations[:ASSEMBLY_SAMPLE])


def recorded_forks(monkeypatch) -> list:
    """``(function name, child pid or None)`` of every :class:`hyperstat.solver.forked.Forked` started from now on
    (the class replaced, for the test, by one that records them): which stages a child computed."""
    from hyperstat.solver import forked

    started = []

    class Recorded(forked.Forked):
        def __init__(self, fn, *a, **k):
            super().__init__(fn, *a, **k)
            started.append((getattr(fn, "__name__", "?"), self._pid))
    monkeypatch.setattr(forked, "Forked", Recorded)
    return started
