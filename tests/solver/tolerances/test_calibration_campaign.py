"""The calibration campaign a template declares, against the one hyperstat's own calibration runs.

Units: mm and rad.  A declaration's measurements hold the tracker frame (``registered``: measured on
references of the base) and the target offsets (``known``) by default; ``hyperstat identify`` and
``export-controller`` fit both.  The classification states what its values with calibration would be
worth under that calibration (``calibration.as_identify_fits``) and warns where it matters.  The
slider-crank here: declared, the calibration's 3-sigma task error is 1.6 µm; with the frame and the
offset fitted, 42 µm against a 20 µm spec.  The second test goes the way a calibration engineer does,
through the real commands: ``hyperstat simulate`` campaigns with noise alone, ``hyperstat identify``
on each, the actuators solved in the identified model for the nominal task over the workspace, and the
task error of the (nominal) machine there.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from hyperstat.solver.tolerances.accuracy import output_twist_maps, sample_workspace
from hyperstat.solver.tolerances.declaration import task_rows

from tests.conftest import TEMPLATES, run_cli
from tests.solver.tolerances.common import classified


@pytest.fixture(scope="module")
def slider_crank():
    return classified("slider_crank")


def test_the_classification_says_what_a_fitted_tracker_frame_and_offset_cost(slider_crank):
    mech, kin, result, cl = slider_crank
    declared, fitted = cl.calibration, cl.calibration["as_identify_fits"]
    assert cl.declaration.frame == "registered" and cl.declaration.offsets == "known"
    # more unknowns (the tracker frame's 6, the offset's 3) can only lose information: a larger 3-sigma
    assert fitted["unknowns"] == declared["unknowns"] + 9
    assert fitted["position_mm"] > 10 * declared["position_mm"] and fitted["position_mm"] > cl.declaration.position_mm
    assert fitted["worse"]
    words = [w for w in cl.warnings if w.startswith("CALIBRATION CAMPAIGN")]
    assert len(words) == 1 and f"{fitted['position_mm']:.3g} mm" in words[0] and "export-controller" in words[0]
    # a declaration that identifies both itself makes no such statement
    from dataclasses import replace

    from hyperstat.solver.tolerances.classification import classify

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        honest = classify(mech, result, kin, declaration=replace(cl.declaration, frame="unknown", offsets="unknown"))
    assert "as_identify_fits" not in honest.calibration
    assert honest.calibration["position_mm"] == pytest.approx(fitted["position_mm"], rel=1e-9)


def test_hyperstat_identify_leaves_the_error_the_fitted_campaign_predicts(slider_crank, tmp_path):
    mech, kin, result, cl = slider_crank
    decl = cl.declaration
    source = str(TEMPLATES / "slider_crank.py")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check = sample_workspace(mech, 60, seed=23, kinematics=kin)
    goal = kin.evaluate(check, None, jacobians=False).output_pose
    worst = []
    for seed in range(6):
        data, ident = tmp_path / f"m{seed}.csv", tmp_path / f"id{seed}.json"
        assert run_cli(["simulate", source, "--poses", str(decl.poses), "--noise", f"{decl.noise_mm} mm + 0 mm/m",
                        "--angle-tolerance", "0", "--length-tolerance", "0", "--seed", str(seed), "--out", data,
                        "--quiet"])[0] == 0
        assert run_cli(["identify", source, data, "--json", ident, "--quiet"])[0] == 0
        estimates = {p["name"]: p["estimate"] for p in json.loads(ident.read_text())["parameters"]}
        fitted = {n for n in estimates if n.startswith(("tracker", "target"))}
        assert {"tracker_rx", "tracker_y", "target_x"} <= fitted  # identify fits the frame and the offset
        xi = np.array([estimates.get(p.name, 0.0) for p in mech.parameters])
        # the controller: the actuators solved in the identified model for the nominal task poses
        q = check.copy()
        for _ in range(8):
            q = kin.assemble(q, xi).q
            st = kin.evaluate(q, xi, jacobians=True)
            sel = task_rows(decl.task, st.output_pose)
            err = np.einsum("krs,ks->kr", sel, _pose_error(st.output_pose, goal))
            rows = sel @ output_twist_maps(kin, st)[1]
            q[:, mech.actuated] -= np.stack([np.linalg.lstsq(rows[k], err[k], rcond=1e-10)[0] for k in range(len(q))])
        model = kin.evaluate(kin.assemble(q, xi).q, xi, jacobians=False).output_pose
        reached = np.abs(np.einsum("krs,ks->kr", task_rows(decl.task, model), _pose_error(model, goal))).max(axis=1) \
            < 1e-6
        true = kin.evaluate(kin.assemble(q, None).q, None, jacobians=False).output_pose  # the machine: nominal
        error = np.abs(np.einsum("krs,ks->kr", task_rows(decl.task, true), _pose_error(true, goal))).max(axis=1)
        assert reached.mean() > 0.9  # the stroke ends aside, the model reaches the task
        worst.append(float(error[reached].max()))
    declared, fitted = cl.calibration["position_mm"], cl.calibration["as_identify_fits"]["position_mm"]
    # every campaign exceeds the declared 3-sigma (a worst case over the workspace: a few campaigns in a hundred
    # would), half of them five times over; none the fitted campaign's (measured: 1.8-25 µm against 1.6 and 42 µm;
    # two of the six beyond the 20 µm spec from the noise alone)
    assert min(worst) > declared and np.median(worst) > 5 * declared and max(worst) < fitted, (worst, declared, fitted)


def _pose_error(pose: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Twist (rotation vector, position difference) taking ``goal`` to ``pose`` (K, 6): rad, mm."""
    from hyperstat.solver.kinematics.frames import so3_log

    return np.concatenate([so3_log(pose[:, :3, :3] @ np.swapaxes(goal[:, :3, :3], 1, 2)),
                           pose[:, :3, 3] - goal[:, :3, 3]], axis=1)
