"""Shared fixtures: templates built once per session (units: mm, rad)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TEMPLATES = ROOT / "templates"

# The cache of results (hyperstat.solver.cache) is off in the tests, in this process and the commands it starts:
# every test computes what it checks.  The cache's own tests turn it on in a temporary folder.
os.environ["HYPERSTAT_CACHE"] = "off"


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


def run_cli(argv: list) -> tuple[int, str, str]:
    """Run the ``hyperstat`` console script in-process: (exit code, stdout, stderr); warnings silenced."""
    import contextlib
    import io

    from hyperstat.cad_plugin.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def assert_refused(argv: list, *needles: str, outputs: tuple = ()) -> str:
    """The command exits 2 with one sentence on stderr containing ``needles``, no traceback, and leaves none of
    ``outputs``; returns the sentence."""
    code, out, err = run_cli(argv)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("hyperstat: error: "), (code, err)
    assert "Traceback" not in out + err
    for needle in needles:
        assert needle in err, err
    for path in outputs:
        assert not Path(path).exists(), f"{path} was written"
    return lines[0]
