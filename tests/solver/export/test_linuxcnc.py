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


@pytest.fixture(scope="module")
def hexapod():
    from hyperstat.cad_plugin.templates import build_template

    return build_template(TEMPLATES / "hexapod.py").mechanism()


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
