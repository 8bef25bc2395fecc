"""No silent export of a bad calibration, and exports that say which joint variables they expect.

Units: lengths in mm, angles in rad (the FANUC-like files: deg and m, as stated in them).

The data of ``test_small_data_warns_and_picks_a_smaller_parameter_set`` (12 poses of one SMR,
geometric errors below the noise's effect, 40 held-out poses): fitted with every parameter, the
calibration predicts the held-out poses worse than the nominal model.  Three SMRs stacked in one
column: identify calls the fit absurd.  ``export-controller``, ``export-urdf`` and ``export-dh``
refuse both (exit 2, one sentence with the reason, nothing written) unless ``--force``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from tests.conftest import run_cli
from tests.solver.calibration.fanuc_like import DH_YAML, Campaign




@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("gate")
    (tmp / "fanuc_like.dh.yaml").write_text(DH_YAML)
    model = tmp / "fanuc_like.skel.json"
    assert run_cli(["import-robot", str(tmp / "fanuc_like.dh.yaml"), "--out", str(model)])[0] == 0
    c = Campaign(0, errors=0.02, noise=(0.1, 0.0))
    (tmp / "small.csv").write_text(c.csv(c.poses(12), "P", only=("SMR1",)))
    (tmp / "small.val.csv").write_text(c.csv(c.poses(40), "V", only=("SMR1",)))
    c = Campaign(3)
    (tmp / "stacked.csv").write_text(c.csv(c.poses(30), "P", stacked=True, priors=False))
    return tmp, model


@pytest.mark.parametrize("command, out", [("export-controller", "machine.json"), ("export-urdf", "robot.urdf"),
                                          ("export-dh", "robot.dh.yaml")])
def test_a_calibration_worse_than_nominal_is_not_exported(robot, tmp_path, command, out):
    t, model = robot
    argv = [command, str(model), str(t / "small.csv"), "--validation", str(t / "small.val.csv"),
            "--select-size", "none", "--out", str(tmp_path / out)]
    if command == "export-controller":
        argv.remove("--select-size")
        argv.remove("none")  # export-controller fits every identifiable parameter
    code, text, err = run_cli(argv)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{out}: not written: " in err and "it predicts the held-out poses worse than the nominal model" in err
    assert "--force" in err and "Traceback" not in err and text == ""
    assert list(tmp_path.iterdir()) == []


def test_an_absurd_fit_is_not_exported(robot, tmp_path):
    t, model = robot
    code, _, err = run_cli(["export-controller", str(model), str(t / "stacked.csv"), "--out", str(tmp_path / "m.json")])
    assert code == 2 and "not written: identify calls the fit absurd" in err, err
    assert list(tmp_path.iterdir()) == []


def test_force_writes_it_with_a_warning_and_the_urdf_carries_the_joint_map(robot, tmp_path):
    """With --force the URDF is written, the warning says why it should not have been, and the controller's
    convention goes beside it: a side file holding the model's joint map, named in the URDF's comment."""
    t, model = robot
    urdf = tmp_path / "robot.urdf"
    code, text, err = run_cli(["export-urdf", str(model), str(t / "small.csv"), "--validation", str(t / "small.val.csv"),
                            "--select-size", "none", "--out", str(urdf), "--force"])
    assert code == 0, err
    assert "warning: " in err and "written with --force although " in err
    assert "it predicts the held-out poses worse" in err
    side = tmp_path / "robot.joint_map.yaml"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robot.joint_map.yaml", "robot.urdf"]
    assert f"wrote {side}" in text
    declared = json.loads(model.read_text())["metadata"]["joint_map"]
    assert yaml.safe_load(side.read_text())["joint_map"] == declared
    head = urdf.read_text().split("<robot", 1)[0]
    assert "They are NOT the controller's" in head and "q3 = J3 + J2" in head and side.name in head
    # the reasons it should not have been written are recorded in the file itself
    assert "WRITTEN WITH - -force ALTHOUGH " in head and "it predicts the held-out poses worse" in head
    # the side file is a joint map identify reads, and it maps like the model's own
    from hyperstat.solver.kinematics.joint_map import joint_map_from_dict

    mine = joint_map_from_dict(yaml.safe_load(side.read_text())["joint_map"], {str(i): "R" for i in range(1, 7)})
    theirs = joint_map_from_dict(declared, {str(i): "R" for i in range(1, 7)})
    j = np.random.default_rng(0).uniform(-1, 1, (5, 6))
    assert np.array_equal(mine.apply(j), theirs.apply(j))


def test_the_dh_export_says_which_joint_variables_it_expects(robot, tmp_path):
    t, model = robot
    dh = tmp_path / "robot.dh.yaml"
    code, _, err = run_cli(["export-dh", str(model), str(t / "small.csv"), "--out", str(dh), "--quiet"])
    assert code == 0, err  # without held-out poses there is no comparison to refuse on
    text = dh.read_text()
    line = next(x for x in text.splitlines() if x.startswith("# joint variables:"))
    assert "q3 = J3 + J2" in line and "the joint_map below" in line
    assert yaml.safe_load(text)["joint_map"] == json.loads(model.read_text())["metadata"]["joint_map"]
