"""Shared fixtures: templates built once per session (units: mm, rad)."""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TEMPLATES = ROOT / "templates"

# One folder for the whole test session (created here, by the process that starts the session, and inherited
# through the environment by the pytest-xdist workers and every command the tests start): it holds the session's
# cache of results and the background corpus run (tests/templates/conftest.py).  Removed when the session ends.
SESSION_ENV = "HYPERSTAT_TEST_SESSION_DIR"
_OWN_SESSION_DIR = not os.environ.get(SESSION_ENV)
if _OWN_SESSION_DIR:
    os.environ[SESSION_ENV] = tempfile.mkdtemp(prefix="hyperstat-tests-")
SESSION_DIR = Path(os.environ[SESSION_ENV])

# The cache of results (hyperstat.solver.cache) is one folder for the whole session, shared by this process, the
# xdist workers and the commands they start: the first run of a stage on a model computes it (uncached), every
# later run with the same model, data and options reads it, so the same report of the same template is computed
# once per session, not once per test.  The session starts with an empty folder: nothing computed by an earlier
# session or an older code is read.  Tests that must compute twice (determinism) or must exercise the uncached
# computation take the ``no_cache`` fixture; the cache's own tests use their own folders.
os.environ["HYPERSTAT_CACHE"] = str(SESSION_DIR / "cache")


@pytest.fixture
def no_cache(monkeypatch):
    """The cache of results off for this test and the commands it starts: every stage is computed."""
    monkeypatch.setenv("HYPERSTAT_CACHE", "off")


def pytest_unconfigure(config) -> None:
    if _OWN_SESSION_DIR and not hasattr(config, "workerinput"):
        from tests.templates.conftest import stop_shared_corpus

        stop_shared_corpus()
        shutil.rmtree(SESSION_DIR, ignore_errors=True)


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


# ------------------------------------------------------------------ pytest-xdist: which tests share a worker
#: modules that start LinuxCNC: one at a time (its simulations interfere with each other), so all on one worker
LINUXCNC_MODULES = ("tests/solver/export/test_genserkins.py", "tests/solver/export/test_linuxcnc")
#: session fixtures that compute a whole report (tests/cad_plugin/conftest.py): the modules that read them run on
#: one worker, so each report is computed once
SHARED_REPORTS = ("tripteor_report", "slider_crank_report")
#: groups that take minutes, sent to the workers first so that none of them ends the run alone on one worker: the
#: FreeCAD clicking scenario, the analyze/accuracy/report of every template, freecadcmd, the part drawings, ...
#: The LinuxCNC modules come second: their 90 s are mostly waits on the simulated machine (16 s of CPU), which
#: the clicking scenario and the corpus' background run fill at the start; later in the run they left a core idle.
_EQUAL = "tests/solver/tolerances/test_equal_counts.py::test_counts_and_classes_are_equal_across_outputs"
FIRST = ("tests/cad_plugin/freecad/test_gui_clicks.py", "@linuxcnc",
         f"{_EQUAL}[planar_3rrr]", f"{_EQUAL}[hexapod]",  # the two longest equal-values tests (129 s, 65 s of CPU)
         "tests/solver/tolerances/test_equal_counts.py",
         "tests/cad_plugin/freecad/test_workbench.py", "tests/solver/tolerances/test_part_drawings.py",
         "@reports", "tests/solver/tolerances/test_independent_worst_cases.py")
#: modules whose tests share no module-scoped fixture and each take a minute or more: one group per test, so that
#: both workers share them
SPLIT = ("tests/solver/tolerances/test_equal_counts.py",)
_READERS: set = set()


def xdist_group(nodeid: str) -> str:
    """The worker group of a test under ``make test`` (``-n 2 --dist loadgroup``): its module (its module-scoped
    fixtures are computed once), except that all LinuxCNC modules are one group, all readers of the session's
    reports (:data:`SHARED_REPORTS`) another, and each test of :data:`SPLIT` its own.  From the test id alone: the
    xdist controller collects nothing."""
    module = nodeid.split("::", 1)[0]
    if module.startswith(LINUXCNC_MODULES):
        return "@linuxcnc"
    if module in SPLIT:
        return nodeid
    if not _READERS:
        _READERS.update(p.relative_to(ROOT).as_posix() for p in (ROOT / "tests").rglob("test_*.py")
                        if any(name in p.read_text(encoding="utf-8") for name in SHARED_REPORTS))
    return "@reports" if module in _READERS else module


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadgroup`` by :func:`xdist_group`.  (xdist's own loadgroup reads an ``@group`` suffix it appends to
    the test ids, which pytest 9's structured test ids drop: its groups would be lost.)"""
    if config.getoption("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    config.option.loadscopereorder = False  # the groups in the workers' order (FIRST first), not by their sizes

    class ByGroup(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return xdist_group(nodeid)

    return ByGroup(config, log)


def pytest_collection_modifyitems(config, items) -> None:
    """In an xdist worker: the groups that take minutes first (:data:`FIRST`; the controller hands the groups out in
    the order the workers collected them).  Without xdist nothing changes."""
    if not hasattr(config, "workerinput"):
        return
    rank = {g: k for k, g in enumerate(FIRST)}
    items.sort(key=lambda item: min(rank.get(xdist_group(item.nodeid), len(FIRST)),
                                    rank.get(item.nodeid.split("::", 1)[0], len(FIRST))))  # stable: the rest keep their order


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_node_collection_finished(node, ids) -> None:
    """The controller of an xdist run starts the corpus' background worker once, for every xdist worker."""
    from tests.templates.conftest import start_shared_corpus

    start_shared_corpus()


def pytest_terminal_summary(terminalreporter) -> None:
    """Records a test left for the reader (``record`` user property: the corpus' durations), after the run."""
    for report in terminalreporter.stats.get("passed", []):
        for name, text in getattr(report, "user_properties", ()):
            if name == "record":
                terminalreporter.write_line(text)
