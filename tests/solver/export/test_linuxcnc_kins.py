"""The generated kinematics module in the real LinuxCNC: the identified Tripteor X7 moved by MDI.

Units: mm and rad here; LinuxCNC works in mm and degrees (converted before comparing).

One LinuxCNC start for the module: ``hyperstat export-linuxcnc-kins`` writes the C component
(identified geometry) and the simulation configuration from a controller file,
``halcompile --install`` builds it, LinuxCNC runs headless (estop reset, machine on, home,
``G1`` moves by MDI through the ``linuxcnc`` Python module of Debian's Python) to poses
across the workspace.  What LinuxCNC reports is compared with hyperstat's reference
model built from the controller file alone (:class:`ControllerModel`, Python, no code
shared with the C component):

* inverse: the joint positions LinuxCNC commands for each world target equal the
  reference inverse model of that pose (Newton from home) to 1e-6 mm / rad;
* forward: the world position LinuxCNC computes from its joints (``actual_position``,
  its ``kinematicsForward`` every servo cycle) equals the reference forward model at those
  joints to 1e-6 mm / degree.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hyperstat.solver.calibration.identify import identify
from hyperstat.solver.calibration.virtual import VirtualMachine
from hyperstat.solver.cli import main
from hyperstat.solver.export.controller import ControllerModel, controller_document, read_controller, write_controller
from hyperstat.solver.export.linuxcnc_sim import build_component, remove_component, run_moves

N_POSES = 24


@pytest.fixture(scope="module")
def machine_file(tripteor, tripteor_analysis, tmp_path_factory):
    """Controller file of an identified Tripteor X7 (virtual machine with random defects, seed 0)."""
    tmp = tmp_path_factory.mktemp("lcnc")
    vm = VirtualMachine.random(tripteor, tripteor_analysis, seed=0)
    q = vm.poses(60, seed=1)
    data, val = vm.measure(q[:45], seed=3), vm.measure(q[45:], seed=4, prefix="V")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(tripteor, tripteor_analysis, data, val)
    return write_controller(tmp / "machine.json", controller_document(tripteor, res, (), {"source": "tripteor_x7.py"}))


@pytest.fixture(scope="module")
def linuxcnc_run(machine_file, tmp_path_factory):
    """Export, build, and move the simulated machine to N_POSES poses across the workspace."""
    out = tmp_path_factory.mktemp("kins")
    assert main(["export-linuxcnc-kins", "--controller", str(machine_file), "--out", str(out), "--quiet"]) == 0
    comps = sorted(out.glob("*.comp"))
    assert len(comps) == 1 and (out / "machine.ini").is_file() and (out / "machine.hal").is_file()
    doc = read_controller(machine_file)
    model = ControllerModel(doc)
    mech = model.mechanism
    act = mech.actuated
    lo, hi = mech.ranges[act].T
    rng = np.random.default_rng(7)
    qa = lo + (hi - lo) * (0.15 + 0.7 * rng.random((N_POSES, len(act))))
    qa[0] = lo + 0.15 * (hi - lo)  # two corners of the sampled box
    qa[1] = lo + 0.85 * (hi - lo)
    res = model.kin.solve(qa, model.xi)
    assert res.converged.all()
    pose = model.kin.evaluate(res.q, model.xi, jacobians=False).output_pose
    # world coordinates of the module: tool-frame origin (mm), wrist joints B (axis y) and C (axis z) in degrees
    ini = (out / "machine.ini").read_text()
    letters = next(line.split("=", 1)[1].split() for line in ini.splitlines() if line.startswith("COORDINATES"))
    assert letters == ["X", "Y", "Z", "B", "C"]
    wrist = {"B": mech.joint_index["7"], "C": mech.joint_index["6"]}
    world = np.column_stack([pose[:, :3, 3]] + [np.degrees(res.q[:, wrist[a]]) for a in letters[3:]])
    name = build_component(comps[0])
    try:
        report = run_moves(out / "machine.ini", "".join(letters), world)
    finally:
        remove_component(name)
    assert report["error"] is None, report["error"]
    assert len(report["moves"]) == N_POSES
    return {"model": model, "qa": qa, "pose": pose, "world": world, "report": report, "letters": letters}


def _joints_si(model, joints_lcnc):
    """LinuxCNC joints (mm, degrees) in mm / rad."""
    j = np.array(joints_lcnc, dtype=float)
    rot = np.array([model.mechanism.joints[i].type == "R" for i in model.mechanism.actuated])
    j[..., rot] = np.radians(j[..., rot])
    return j, rot


def test_poses_span_the_workspace(linuxcnc_run):
    """At least 20 poses, each actuated joint over most of its sampled range (70 % of the full range)."""
    model, qa = linuxcnc_run["model"], linuxcnc_run["qa"]
    lo, hi = model.mechanism.ranges[model.mechanism.actuated].T
    assert len(qa) >= 20
    assert np.all((qa.max(0) - qa.min(0)) >= 0.6 * (hi - lo))


def test_linuxcnc_inverse_equals_the_reference_inverse(linuxcnc_run):
    """Joints LinuxCNC commands for each MDI target = reference inverse model of the pose, to 1e-6 mm / rad."""
    model, pose, qa = linuxcnc_run["model"], linuxcnc_run["pose"], linuxcnc_run["qa"]
    reference = model.inverse(pose)  # Newton from home, on the file's identified geometry
    assert np.abs(reference - qa).max() < 1e-9  # the reference inverse is the inverse of the sampled poses
    joints, rot = _joints_si(model, [m["joints"] for m in linuxcnc_run["report"]["moves"]])
    err = np.abs(joints - reference)
    print(f"\nLinuxCNC vs reference inverse over {len(joints)} poses: max {err[:, ~rot].max():.3g} mm, "
          f"{err[:, rot].max():.3g} rad")
    assert err.max() < 1e-6


def test_linuxcnc_forward_equals_the_reference_forward(linuxcnc_run):
    """World position LinuxCNC computes from its joints = reference forward model at those joints (1e-6)."""
    model, letters = linuxcnc_run["model"], linuxcnc_run["letters"]
    moves = linuxcnc_run["report"]["moves"]
    joints, rot = _joints_si(model, [m["joints"] for m in moves])
    _, pose = model.forward(joints, with_effects=False)
    field = {"X": 0, "Y": 1, "Z": 2, "A": 3, "B": 4, "C": 5}
    lcnc = np.array([[m["world"][field[a]] for a in letters] for m in moves])
    act = list(model.mechanism.actuated)
    col = {a: act.index(model.mechanism.joint_index[j]) for a, j in (("B", "7"), ("C", "6"))}
    ref = np.column_stack([pose[:, :3, 3]] + [np.degrees(joints[:, col[a]]) for a in letters[3:]])
    err = np.abs(lcnc - ref)
    print(f"\nLinuxCNC forward vs reference forward over {len(moves)} poses: max {err[:, :3].max():.3g} mm, "
          f"{math.radians(err[:, 3:].max()):.3g} rad")
    assert err[:, :3].max() < 1e-6 and math.radians(err[:, 3:].max()) < 1e-6
    # and the machine went where it was told (commanded world = reached world)
    assert np.abs(lcnc - linuxcnc_run["world"]).max() < 1e-6
