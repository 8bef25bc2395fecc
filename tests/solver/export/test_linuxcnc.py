"""LinuxCNC genhexkins export: strut lengths against our model, and the real module under halrun.

Units: lengths in mm.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.errors import DataError
from hyperstat.solver.export.linuxcnc import genhexkins_parameters, hal_lines, strut_lengths

from tests.conftest import TEMPLATES


def test_strut_lengths_match_the_model(hexapod):
    params = genhexkins_parameters(hexapod)
    kin = Kinematics(hexapod)
    rng = np.random.default_rng(1)
    act = hexapod.actuated
    lo, hi = hexapod.ranges[act].T
    qa = lo + (hi - lo) * (0.3 + 0.4 * rng.random((20, 6)))
    res = kin.solve(qa)
    poses = kin.evaluate(res.q, jacobians=False).output_pose
    lengths = strut_lengths(np.array(params["base"]), np.array(params["platform"]), poses)
    assert np.abs(lengths - qa).max() < 1e-9  # genhexkins' inverse kinematics = our actuated values


def test_only_hexapods(scara):
    with pytest.raises(DataError, match="6-UPS"):
        genhexkins_parameters(scara)


def test_genhexkins_loads_our_parameters(hexapod):
    """The real LinuxCNC module takes the exported geometry (read back from its pins)."""
    halrun = shutil.which("halrun")
    assert halrun, "LinuxCNC (Debian linuxcnc-uspace) is installed by 'make test'"
    params = genhexkins_parameters(hexapod)
    # rtapi_app refuses root without a fallback uid, which then needs a FIFO directory it can reach
    work = Path(tempfile.mkdtemp(prefix="hyperstat-hal-", dir="/tmp"))
    os.chmod(work, 0o777)
    hal = work / "hex.hal"
    hal.write_text(hal_lines(params) + "show pin genhexkins\n")
    env = dict(os.environ, RTAPI_FIFO_PATH=str(work / "fifo"))
    if os.geteuid() == 0:
        env["RTAPI_UID"] = "65534"
    try:
        out = subprocess.run([halrun, "-f", str(hal)], capture_output=True, text=True, timeout=120, env=env).stdout
    finally:
        subprocess.run([halrun, "-U"], capture_output=True, timeout=60, env=env)
        shutil.rmtree(work, ignore_errors=True)
    read = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 5 and parts[-1].startswith("genhexkins.") and parts[-1].count(".") == 3:
            read[parts[-1]] = float(parts[-2])
    for kind in ("base", "platform"):
        for n, p in enumerate(params[kind]):
            for axis, v in zip("xyz", p):
                assert read[f"genhexkins.{kind}.{n}.{axis}"] == pytest.approx(v, rel=1e-5, abs=1e-9)  # halcmd prints 6 digits


def test_hexapod_export_refuses_an_unrepresentable_identified_model(identified_hexapod_controller, tmp_path, capsys):
    """Random U-joint / axis defects: genhexkins' joint-centre model misses them by far more than the noise."""
    from hyperstat.solver.cli import main
    from hyperstat.solver.export.controller import ControllerModel, read_controller

    doc = read_controller(identified_hexapod_controller)
    model = ControllerModel(doc)
    params = genhexkins_parameters(model.mechanism, model.xi)
    noise = doc["statistics"]["noise_rms"]
    assert params["max_strut_difference_mm"] > 100 * noise  # the premise: not representable
    hal = tmp_path / "hex.hal"
    assert main(["export-linuxcnc", "--controller", str(identified_hexapod_controller), "--hal", str(hal)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot represent" in err and "noise floor" in err
    assert not hal.exists()  # nothing half-written
    # the user's threshold decides: above the difference, the export goes through (and says the difference)
    limit = 2 * params["max_strut_difference_mm"]
    assert main(["export-linuxcnc", "--controller", str(identified_hexapod_controller), "--hal", str(hal),
                 "--max-error", str(limit)]) == 0
    assert hal.is_file() and "largest strut-length difference" in capsys.readouterr().out
    # and below it, refused again, naming the option
    assert main(["export-linuxcnc", "--controller", str(identified_hexapod_controller), "--hal", str(tmp_path / "b.hal"),
                 "--max-error", str(params["max_strut_difference_mm"] / 2)]) == 2
    assert "--max-error" in capsys.readouterr().err


def test_nominal_hexapod_export_passes(tmp_path):
    from hyperstat.cad_plugin.cli import main

    hal = tmp_path / "hex.hal"
    assert main(["export-linuxcnc", str(TEMPLATES / "hexapod.py"), "--hal", str(hal), "--quiet"]) == 0
    assert hal.is_file() and "setp genhexkins.base.0.x" in hal.read_text()


def test_kins_export_refuses_a_mechanism_without_world_coordinates(tmp_path, capsys):
    """The slider-crank has one actuated joint: no LinuxCNC world-coordinate convention; nothing written."""
    from hyperstat.cad_plugin.cli import main

    out = tmp_path / "kins"
    assert main(["export-linuxcnc-kins", str(TEMPLATES / "slider_crank.py"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "1 actuated joint and" in err
    assert not out.exists()


def test_kins_component_of_the_nominal_tripteor(tmp_path):
    """The command's files: a component naming its geometry, an INI whose [KINS] and joints match the model."""
    from hyperstat.cad_plugin.cli import main

    assert main(["export-linuxcnc-kins", str(TEMPLATES / "tripteor_x7.py"), "--out", str(tmp_path), "--quiet"]) == 0
    comp = (tmp_path / "hs_tripteor_x7_kins.comp").read_text()
    assert comp.startswith("component hs_tripteor_x7_kins ") and "#define NACT 5" in comp
    ini = (tmp_path / "machine.ini").read_text()
    assert "KINEMATICS = hs_tripteor_x7_kins" in ini and "JOINTS = 5" in ini and "COORDINATES = X Y Z B C" in ini
    assert ini.count("TYPE = LINEAR") == 3 and ini.count("TYPE = ANGULAR") == 2


def test_kins_export_refuses_a_singular_home_and_takes_another(tmp_path, capsys):
    """The SCARA template homes with its arm stretched: singular for X Y Z C, refused; --home 2=1.0 bends it."""
    from hyperstat.cad_plugin.cli import main
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.export.linuxcnc_kins import inverse_conditioning

    scara = build_template(TEMPLATES / "scara.py").mechanism()
    assert inverse_conditioning(scara, None, scara.home) < 1e-12
    out = tmp_path / "kins"
    assert main(["export-linuxcnc-kins", str(TEMPLATES / "scara.py"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "singular" in err and "--home" in err and not out.exists()
    assert main(["export-linuxcnc-kins", str(TEMPLATES / "scara.py"), "--out", str(out), "--home", "2=1.0",
                 "--quiet"]) == 0
    ini = (out / "machine.ini").read_text()
    assert "HOME = 57.2957795131" in ini  # 1 rad, LinuxCNC's degrees
    assert main(["export-linuxcnc-kins", str(TEMPLATES / "scara.py"), "--out", str(out), "--home", "9=1"]) == 2
    assert "actuated joints: 1, 2, 3, 4" in capsys.readouterr().err
