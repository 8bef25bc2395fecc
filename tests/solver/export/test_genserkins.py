"""LinuxCNC ``genserkins`` export of a 6R robot: DH parameters, refusal, and the real module moved by MDI.

Units: mm and rad here; LinuxCNC works in mm and degrees (converted before comparing).

The robot is built here from Craig's PUMA 560 table (modified DH) by composing the link
matrices written out below, independently of the export's own DH chain.  The export must
read back the table (``d2 + d3`` only: two parallel axes leave their split free) and a chain
that reproduces the model; a geometry with defects off the DH structure is refused; the
real ``genserkins``, fed the exported parameters and moved by MDI to 20 poses, commands the
joints of the poses and reports, through its forward kinematics, the model's pose.  One
LinuxCNC start for the module.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hyperstat.solver.errors import DataError
from hyperstat.solver.export.genserkins import genserkins_parameters, refuse_unrepresentable, write_sim
from hyperstat.solver.export.linuxcnc_sim import run_moves
from hyperstat.solver.kinematics.closure import Kinematics

A = [0.0, 0.0, 431.8, 20.3, 0.0, 0.0]
ALPHA = [0.0, -math.pi / 2, 0.0, -math.pi / 2, math.pi / 2, -math.pi / 2]
D = [0.0, 0.0, 149.09, 433.07, 0.0, 0.0]  # d_1 .. d_6


def _link(a: float, alpha: float, d: float) -> np.ndarray:
    """RotX(alpha) TransX(a) TransZ(d) at theta = 0, written out."""
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array([[1.0, 0.0, 0.0, a], [0.0, ca, -sa, -sa * d], [0.0, sa, ca, ca * d], [0.0, 0.0, 0.0, 1.0]])


@pytest.fixture(scope="module")
def puma():
    from hyperstat.cad_plugin.skeleton import Skeleton

    sk = Skeleton("puma560", base="R0", description="Craig's PUMA 560 table, modified DH")
    t = np.eye(4)
    for i in range(6):
        t = t @ _link(A[i], ALPHA[i], D[i])
        sk.revolute(str(i + 1), t[:3, 3], t[:3, 2], role="actuated", range=(-2.5, 2.5))
    sk.frame("T", t[:3, 3], t[:3, 2], t[:3, 0])
    sk.chain("arm", "R0", "T", [str(i) for i in range(1, 7)])
    sk.output = "T"
    return sk.mechanism()


def test_the_dh_table_is_read_back(puma):
    p = genserkins_parameters(puma)
    assert np.allclose(p["a"], A, atol=1e-9) and np.allclose(p["alpha"], ALPHA, atol=1e-12)
    assert p["d"][0] == pytest.approx(0.0, abs=1e-9) and p["d"][1] + p["d"][2] == pytest.approx(149.09, abs=1e-9)
    assert np.allclose(p["d"][3:], D[3:], atol=1e-9)
    assert p["max_position_difference_mm"] < 1e-9 and p["max_rotation_difference_rad"] < 1e-12


def test_a_geometry_off_the_dh_structure_is_refused(puma):
    """A 1 mrad tilt of axis 4 (component I) has no place in genserkins' chain; a shift along it (a) has."""
    names = {(p.element, p.component): i for i, p in enumerate(puma.parameters)}
    tilt = np.zeros(len(puma.parameters))
    tilt[names[("4", "I")]] = 1e-3
    p = genserkins_parameters(puma, tilt)
    assert p["max_position_difference_mm"] > 0.1  # ~ 1e-3 rad x 433 mm of wrist
    with pytest.raises(DataError, match="genserkins cannot represent"):
        refuse_unrepresentable(p, 0.01, puma.name, "given")
    shift = np.zeros(len(puma.parameters))
    shift[names[("4", "a")]] = 0.1
    q = genserkins_parameters(puma, shift)
    assert q["max_position_difference_mm"] < 1e-9  # absorbed by the DH parameters ...
    moved = np.abs(np.r_[q["a"], q["d"]] - np.r_[genserkins_parameters(puma)["a"], genserkins_parameters(puma)["d"]])
    assert moved.max() == pytest.approx(0.1, abs=1e-9)  # ... which moved by the shift
    refuse_unrepresentable(q, 1e-6, puma.name, "given")


@pytest.fixture(scope="module")
def run(puma, tmp_path_factory):
    params = genserkins_parameters(puma)
    home = np.array([0.0, -0.3, 0.4, 0.0, 0.6, 0.0])  # away from the wrist singularity (joint 5 = 0)
    ini = write_sim(tmp_path_factory.mktemp("genser"), puma, params, home=home)
    rng = np.random.default_rng(3)
    qa = home + 0.8 * (rng.random((20, 6)) - 0.5)
    pose = Kinematics(puma).evaluate(qa, jacobians=False).output_pose
    r = pose[:, :3, :3]
    world = np.column_stack([pose[:, :3, 3], np.degrees(np.arctan2(r[:, 2, 1], r[:, 2, 2])),
                             np.degrees(np.arcsin(-r[:, 2, 0])), np.degrees(np.arctan2(r[:, 1, 0], r[:, 0, 0]))])
    report = run_moves(ini, "XYZABC", world, unwrap="ABC")  # A is near +-180 degrees: no wrist turn-over
    assert report["error"] is None, report["error"]
    assert len(report["moves"]) == 20
    return {"qa": qa, "world": world, "report": report}


def test_genserkins_inverse_commands_the_joints_of_the_poses(run):
    joints = np.radians([m["joints"] for m in run["report"]["moves"]])
    err = np.abs(joints - run["qa"]).max()
    print(f"\ngenserkins (PUMA 560), LinuxCNC joints vs reference over 20 poses: max {err:.3g} rad")
    assert err < 1e-6


def test_genserkins_forward_gives_the_model_pose(run, puma):
    moves = run["report"]["moves"]
    joints = np.radians([m["joints"] for m in moves])
    pose = Kinematics(puma).evaluate(joints, jacobians=False).output_pose
    lcnc = np.array([m["world"][:6] for m in moves])
    a, b, c = (np.radians(lcnc[:, i]) for i in (3, 4, 5))
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rot = np.stack([np.stack([cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa], -1),
                    np.stack([sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa], -1),
                    np.stack([-sb, cb * sa, cb * ca], -1)], 1)
    e_pos = np.abs(lcnc[:, :3] - pose[:, :3, 3]).max()
    e_rot = np.abs(rot - pose[:, :3, :3]).max()
    print(f"\ngenserkins (PUMA 560), LinuxCNC forward vs reference forward: max {e_pos:.3g} mm, {e_rot:.3g} rad")
    assert e_pos < 1e-6 and e_rot < 1e-6


def test_export_linuxcnc_writes_genserkins_for_a_6r_model_file(puma, tmp_path, capsys):
    from hyperstat.solver.cli import main
    from hyperstat.solver.kinematics.modelfile import save_model

    model = save_model(puma, tmp_path / "puma.json")
    hal, ini = tmp_path / "robot.hal", tmp_path / "kins.ini"
    assert main(["export-linuxcnc", str(model), "--hal", str(hal), "--ini", str(ini)]) == 0
    assert "genserkins (modified DH)" in capsys.readouterr().out
    lines = hal.read_text().splitlines()
    assert "loadrt genserkins" in lines and "setp genserkins.A-2 431.8" in lines
    assert "KINEMATICS = genserkins" in ini.read_text()
