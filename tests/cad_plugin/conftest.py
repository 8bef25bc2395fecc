"""Reports computed once per session for the part-drawing tests (units: mm, rad).

``hyperstat report --step-drawings`` on the slider-crank and the Tripteor X7, through the real command line:
the report's files and one STEP AP242 file per part drawing (``parts/PART.step``).  The Tripteor's is also
the report ``tests/cad_plugin/test_report.py`` prints as its plain report.
"""

from __future__ import annotations

import json
import warnings

import pytest

from tests.conftest import TEMPLATES


def _report(tmp_path_factory, name: str):
    from hyperstat.cad_plugin.cli import main

    out = tmp_path_factory.mktemp(f"report_{name}") / "rep"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["report", str(TEMPLATES / f"{name}.py"), "--out", str(out), "--step-drawings", "--quiet"]) == 0
    return out, json.loads((out / "report.json").read_text())


@pytest.fixture(scope="session")
def slider_crank_report(tmp_path_factory):
    """(out dir, report.json) of ``hyperstat report templates/slider_crank.py --step-drawings``."""
    return _report(tmp_path_factory, "slider_crank")


@pytest.fixture(scope="session")
def tripteor_report(tmp_path_factory):
    """(out dir, report.json) of ``hyperstat report templates/tripteor_x7.py --step-drawings``."""
    return _report(tmp_path_factory, "tripteor_x7")
