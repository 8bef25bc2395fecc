"""The parallel machines the diagnosis tests diagnose: the model, its stationarity analysis and its kinematics,
computed once per test process and shared by the test modules (the analysis is the slow part).

This is the side under test (hyperstat's own model loader and analysis), not a generator: the PKM generator
(``pkm_generator.py``) imports nothing from hyperstat.
"""

from __future__ import annotations

import functools
import warnings

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import load_model


@functools.lru_cache(maxsize=None)
def pkm_model(arm: str) -> tuple:
    """``(mechanism, analysis, kinematics)`` of the PKM generator's model ``arm`` (24 analysis configurations, seed 0).

    The callers only read these objects."""
    from tests.solver.diagnosis import pkm_generator as gen

    mech = load_model(gen.MODELS[arm])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, analyze(mech, n_configurations=24, seed=0), Kinematics(mech)
