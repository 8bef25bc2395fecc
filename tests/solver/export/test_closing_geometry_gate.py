"""The controller file's geometry is the one checked: a closing geometry that predicts worse is refused.

Units: lengths in mm, angles in rad.

An identified geometry of an over-constrained linkage breaks, at second order, the mobility only its special
geometry has; ``export-controller`` moves it onto a geometry whose loops close, by the change that moves the
fitted poses' predictions the least, and that moved geometry is what a controller runs.  The file records the
identified model's held-out statistics, so the moved geometry must predict the held-out poses nearly as well, the
tracker frame placed again on each.  The corpus' Bricard line (a campaign of ``hyperstat simulate``): identified
0.013 mm held-out RMS, the noise; moved 0.13 mm (0.46 mm by the least-norm move before).  Refused in one sentence,
nothing written; with ``--force`` the reason is in the file, and the file's own reference model
(:class:`ControllerModel`, which reads nothing but the file) is off at the held-out poses by the figure the refusal
gives: the refusal says what is true.  The Bennett linkage, whose move is 1e-4 mm, is written as before.
"""

from __future__ import annotations

import re

import numpy as np

from tests.conftest import TEMPLATES, assert_refused, run_cli


def _campaign(tmp_path, member: str):
    src = TEMPLATES / "corpus" / f"{member}.py"
    data = tmp_path / "d.csv"
    assert run_cli(["simulate", src, "--out", data, "--quiet"])[0] == 0
    return src, data, tmp_path / "d.validation.csv"


def test_a_bricard_closing_geometry_far_off_the_held_out_poses_is_refused(tmp_path):
    from hyperstat.solver.calibration.identify import kabsch
    from hyperstat.solver.calibration.measurements import read_measurements
    from hyperstat.solver.export.controller import ControllerModel, read_controller
    from hyperstat.cad_plugin.templates import build_template

    src, data, val = _campaign(tmp_path, "bricard_line")
    out = tmp_path / "m.json"
    argv = ["export-controller", src, data, "--validation", val, "--out", out, "--quiet"]
    err = assert_refused(argv, "the nearest geometry that does", "held-out poses", outputs=(out,))
    assert "bricard_line" in err
    code, _, _ = run_cli(argv + ["--force"])
    assert code == 0 and out.is_file()
    doc = read_controller(out)
    reason = next(r for r in doc["calibration"]["reasons"] if "the nearest geometry that does" in r)
    said = float(re.search(r"poses to ([0-9.e+-]+) mm RMS", reason).group(1))
    # the file's own model at the held-out poses, its base frame registered on the measurements (the best rigid
    # fit, so only what no tracker placement explains is left): what the refusal said, far beyond the noise
    mech = build_template(src).mechanism()
    held = read_measurements(val, mech)
    point, _ = ControllerModel(doc).forward(held.q, held.metadata)
    rot, shift = kabsch(held.position, point)
    left = np.sqrt(np.mean(np.sum((held.position @ rot.T + shift - point) ** 2, axis=1)))
    noise = doc["calibration"]["targets"]["target"]["validation"]["noise_rms"]
    assert abs(left - said) <= 1e-3 * said and left > 5 * noise, (left, said, noise)


def test_a_bennett_closing_geometry_is_written(tmp_path):
    src, data, val = _campaign(tmp_path, "bennett")
    out = tmp_path / "m.json"
    code, _, err = run_cli(["export-controller", src, data, "--validation", val, "--out", out])
    assert code == 0 and out.is_file(), err
    assert "moves its predictions the least" in err  # it is a closing geometry that is written
