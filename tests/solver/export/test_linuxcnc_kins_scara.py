"""The generated kinematics module in the real LinuxCNC: a serial robot (SCARA, R R P R), world X Y Z C.

Units: mm and rad here; LinuxCNC works in mm and degrees (converted before comparing).

A serial chain has no loop: the component's forward model is the product of the element
matrices, its inverse Newton on the joints; the wrist roll (joint 4) is LinuxCNC's C axis.
The geometry has random defects (seeded, 0.05 mm / 0.5 mrad), standing for a calibrated
robot.  The machine homes with the elbow bent (the template's home, arm stretched, is a
singularity where Newton has no direction to leave by); the poses keep the elbow on that
side (joint 2 in 0.5 .. 2.0 rad) and are visited in order of the shoulder angle, so that
each straight MDI move stays inside the reach.  One LinuxCNC start for the module.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hyperstat.solver.export.linuxcnc_kins import kins_component, sample_world, world_layout
from hyperstat.solver.export.linuxcnc_sim import build_component, remove_component, run_moves, write_sim
from hyperstat.solver.kinematics.closure import Kinematics

N_POSES = 20


@pytest.fixture(scope="module")
def run(scara, tmp_path_factory):
    rng = np.random.default_rng(5)
    units = np.array([0.05 if p.component in "abc" else 5e-4 for p in scara.parameters])
    xi = units * rng.standard_normal(len(scara.parameters))
    layout = world_layout(scara)
    assert layout["coordinates"] == "XYZC"
    out = tmp_path_factory.mktemp("scara")
    name = "hs_scara_test_kins"
    comp = out / f"{name}.comp"
    home = scara.home.copy()
    home[scara.joint_index["2"]] = 1.0  # elbow bent: the template's home (arm stretched) is singular
    comp.write_text(kins_component(scara, xi, name=name, home=home))
    ini = write_sim(out, scara, name, layout, sample_world(scara, xi, layout), home=home)
    act = scara.actuated
    lo, hi = scara.ranges[act].T
    qa = lo + (hi - lo) * (0.15 + 0.7 * rng.random((N_POSES, 4)))
    qa[:, 1] = 0.5 + 1.5 * rng.random(N_POSES)
    qa = qa[np.argsort(qa[:, 0])]
    q = np.array(np.broadcast_to(scara.home, (N_POSES, len(scara.joints))))
    q[:, act] = qa
    pose = Kinematics(scara).evaluate(q, xi, jacobians=False).output_pose
    world = np.column_stack([pose[:, :3, 3], np.degrees(qa[:, 3])])
    build_component(comp)
    try:
        report = run_moves(ini, "XYZC", world)
    finally:
        remove_component(name)
    assert report["error"] is None, report["error"]
    assert len(report["moves"]) == N_POSES
    return {"mechanism": scara, "xi": xi, "qa": qa, "world": world, "report": report}


def test_linuxcnc_inverse_equals_the_joints_of_the_poses(run):
    """Serial: the poses were made from the joints, so the reference inverse is the joint vector itself."""
    joints = np.array([m["joints"] for m in run["report"]["moves"]])
    joints[:, [0, 1, 3]] = np.radians(joints[:, [0, 1, 3]])
    err = np.abs(joints - run["qa"])
    print(f"\nSCARA, LinuxCNC vs reference inverse over {len(joints)} poses: max {err[:, 2].max():.3g} mm, "
          f"{err[:, [0, 1, 3]].max():.3g} rad")
    assert err.max() < 1e-6


def test_linuxcnc_forward_equals_the_reference_forward(run):
    mech, xi = run["mechanism"], run["xi"]
    moves = run["report"]["moves"]
    joints = np.array([m["joints"] for m in moves])
    joints[:, [0, 1, 3]] = np.radians(joints[:, [0, 1, 3]])
    q = np.array(np.broadcast_to(mech.home, (len(moves), len(mech.joints))))
    q[:, mech.actuated] = joints
    pose = Kinematics(mech).evaluate(q, xi, jacobians=False).output_pose
    lcnc = np.array([[m["world"][i] for i in (0, 1, 2, 5)] for m in moves])
    e_pos = np.abs(lcnc[:, :3] - pose[:, :3, 3]).max()
    e_c = math.radians(np.abs(lcnc[:, 3] - np.degrees(joints[:, 3])).max())
    print(f"\nSCARA, LinuxCNC forward vs reference forward over {len(moves)} poses: max {e_pos:.3g} mm, {e_c:.3g} rad")
    assert e_pos < 1e-6 and e_c < 1e-6
    assert np.abs(lcnc - run["world"]).max() < 1e-6  # and the machine reached every commanded pose
