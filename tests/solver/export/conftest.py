"""Fixtures shared by the export tests (units: mm, rad)."""

from __future__ import annotations

import warnings

import pytest

from tests.conftest import TEMPLATES


@pytest.fixture(scope="session")
def hexapod():
    """The hexapod template at its defaults."""
    from hyperstat.cad_plugin.templates import build_template

    return build_template(TEMPLATES / "hexapod.py").mechanism()


@pytest.fixture(scope="session")
def identified_hexapod_controller(hexapod, tmp_path_factory):
    """Controller file of an identified hexapod (virtual machine with random defects, seed 0).

    Its U-joint and axis defects are beyond genhexkins' joint-centre model (``test_linuxcnc.py``)
    and carried by the generated kinematics component (``test_linuxcnc_kins_hexapod.py``).
    """
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.calibration.identify import identify
    from hyperstat.solver.calibration.virtual import VirtualMachine
    from hyperstat.solver.export.controller import controller_document, write_controller

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analysis = analyze(hexapod, n_configurations=24, seed=0)
        vm = VirtualMachine.random(hexapod, analysis, seed=0)
        q = vm.poses(60, seed=1)
        res = identify(hexapod, analysis, vm.measure(q[:40], seed=3), vm.measure(q[40:], seed=4, prefix="V"))
    path = tmp_path_factory.mktemp("hexid") / "machine.json"
    return write_controller(path, controller_document(hexapod, res, (), {"source": "hexapod.py"}))
