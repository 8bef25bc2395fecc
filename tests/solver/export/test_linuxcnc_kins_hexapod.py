"""The generated kinematics module in the real LinuxCNC: an identified hexapod genhexkins cannot represent.

Units: mm and rad here; LinuxCNC works in mm and degrees (converted before comparing).

The identified virtual hexapod (random defects, seed 0) is the one ``export-linuxcnc``
refuses for genhexkins (its strut lengths miss the model by millimetres,
``test_linuxcnc.py``).  The generated component carries every defect: LinuxCNC, moved by
MDI in ``X Y Z A B C`` (output frame origin, ``R = Rz(C) Ry(B) Rx(A)``), must command the
actuated values of hyperstat's reference inverse model and report, through its forward
kinematics, the reference forward pose.  One LinuxCNC start for the module.
"""

from __future__ import annotations


import numpy as np
import pytest

from hyperstat.solver.cli import main
from hyperstat.solver.export.controller import ControllerModel, read_controller
from hyperstat.solver.export.linuxcnc import genhexkins_parameters
from hyperstat.solver.export.linuxcnc_sim import build_component, remove_component, run_moves


N_POSES = 20


@pytest.fixture(scope="module")
def run(identified_hexapod_controller, tmp_path_factory):
    out = tmp_path_factory.mktemp("kins")
    assert main(["export-linuxcnc-kins", "--controller", str(identified_hexapod_controller), "--out", str(out), "--quiet"]) == 0
    model = ControllerModel(read_controller(identified_hexapod_controller))
    mech = model.mechanism
    lo, hi = mech.ranges[mech.actuated].T
    qa = lo + (hi - lo) * (0.2 + 0.6 * np.random.default_rng(11).random((N_POSES, 6)))
    res = model.kin.solve(qa, model.xi)
    assert res.converged.all()
    pose = model.kin.evaluate(res.q, model.xi, jacobians=False).output_pose
    # X Y Z A B C of R = Rz(C) Ry(B) Rx(A), computed here from the rotation matrix (degrees)
    r = pose[:, :3, :3]
    world = np.column_stack([pose[:, :3, 3], np.degrees(np.arctan2(r[:, 2, 1], r[:, 2, 2])),
                             np.degrees(np.arcsin(-r[:, 2, 0])), np.degrees(np.arctan2(r[:, 1, 0], r[:, 0, 0]))])
    name = build_component(next(out.glob("*.comp")))
    try:
        report = run_moves(out / "machine.ini", "XYZABC", world)
    finally:
        remove_component(name)
    assert report["error"] is None, report["error"]
    assert len(report["moves"]) == N_POSES
    return {"model": model, "qa": qa, "pose": pose, "world": world, "report": report}


def test_the_geometry_is_beyond_genhexkins(run):
    model = run["model"]
    assert genhexkins_parameters(model.mechanism, model.xi)["max_strut_difference_mm"] > 1.0


def test_linuxcnc_inverse_equals_the_reference_inverse(run):
    model, pose = run["model"], run["pose"]
    reference = model.inverse(pose)
    assert np.abs(reference - run["qa"]).max() < 1e-9
    joints = np.array([m["joints"] for m in run["report"]["moves"]])
    err = np.abs(joints - reference).max()
    print(f"\nhexapod, LinuxCNC vs reference inverse over {len(joints)} poses: max {err:.3g} mm")
    assert err < 1e-6


def test_linuxcnc_forward_equals_the_reference_forward(run):
    model = run["model"]
    moves = run["report"]["moves"]
    joints = np.array([m["joints"] for m in moves])
    _, pose = model.forward(joints, with_effects=False)
    lcnc = np.array([m["world"][:6] for m in moves])
    # LinuxCNC's angles -> rotation matrix Rz(C) Ry(B) Rx(A), compared with the reference rotation
    a, b, c = (np.radians(lcnc[:, i]) for i in (3, 4, 5))
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rot = np.stack([np.stack([cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa], -1),
                    np.stack([sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa], -1),
                    np.stack([-sb, cb * sa, cb * ca], -1)], 1)
    e_pos = np.abs(lcnc[:, :3] - pose[:, :3, 3]).max()
    e_rot = np.abs(rot - pose[:, :3, :3]).max()  # matrix entries: rad to first order
    print(f"\nhexapod, LinuxCNC forward vs reference forward over {len(moves)} poses: max {e_pos:.3g} mm, "
          f"{e_rot:.3g} rad")
    assert e_pos < 1e-6 and e_rot < 1e-6
    assert np.abs(lcnc - run["world"]).max() < 1e-6  # and the machine reached every commanded pose
