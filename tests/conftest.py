"""Shared fixtures: templates built once per session (units: mm, rad)."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TEMPLATES = ROOT / "templates"


@pytest.fixture(scope="session")
def slider_crank():
    """The slider-crank mechanism of paper 1, section 4.1 (template defaults)."""
    from hyperstat.cad_plugin.templates import build_template

    return build_template(TEMPLATES / "slider_crank.py").mechanism()


@pytest.fixture(scope="session")
def slider_crank_analysis(slider_crank):
    """Stationarity analysis of the slider-crank."""
    from hyperstat.solver.analysis.stationarity import analyze

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return analyze(slider_crank, n_configurations=24, seed=0)


@pytest.fixture(scope="session")
def tripteor():
    """The Tripteor X7 (paper 1, section 4.2) at the template defaults."""
    from hyperstat.cad_plugin.templates import build_template

    return build_template(TEMPLATES / "tripteor_x7.py").mechanism()


@pytest.fixture(scope="session")
def tripteor_analysis(tripteor):
    """Stationarity analysis of the Tripteor X7."""
    from hyperstat.solver.analysis.stationarity import analyze

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return analyze(tripteor, n_configurations=24, seed=0)


@pytest.fixture(scope="session")
def scara():
    """The SCARA template (a serial chain: R R R P)."""
    from hyperstat.cad_plugin.templates import build_template

    return build_template(TEMPLATES / "scara.py").mechanism()


@pytest.fixture(scope="session")
def scara_analysis(scara):
    """Stationarity analysis of the SCARA."""
    from hyperstat.solver.analysis.stationarity import analyze

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return analyze(scara, n_configurations=24, seed=0)
