"""A public real data set: FIGAROH's UR10 calibration (23 poses, one 6-D target, camera), Apache-2.0.

Units: lengths in mm, angles in rad.  The data are measurements, so no truth is known:
what is tested is what must hold whatever the truth is.  The answer does not depend on
which point of the target frame is read (the check per target), nor on which poses are
held out; and the diagnosis never leaves a model that predicts the held-out poses worse
than the rigid one.  ``docs/diagnosis.md`` gives the figures.
"""

from __future__ import annotations

import warnings

import pytest

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.kinematics.robot_import import import_robot

from tests.solver.diagnosis.real_data import UR10_TIP, UR10_URDF, ur10_measurements


@pytest.fixture(scope="module")
def ur10():
    mech = import_robot(UR10_URDF, tip=UR10_TIP)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, analyze(mech, n_configurations=24, seed=0)


def _diagnose(ur10, n_identification: int):
    mech, analysis = ur10
    id_text, val_text = ur10_measurements(mech.name, n_identification)
    data = parse_measurements(id_text, mech, "ur10.csv")
    val = parse_measurements(val_text, mech, "ur10.validation.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return diagnose(mech, analysis, data, val)


def test_the_urdf_masses_reach_the_diagnosis(ur10):
    """import-robot keeps the links' <inertial>: the diagnosis can size gravity-driven effects on this arm."""
    mech, _ = ur10
    masses = mech.metadata["masses"]
    assert set(masses) == {mech.joints[i].name for i in mech.actuated}
    assert masses["shoulder_lift_joint"]["mass"] == pytest.approx(12.93)  # upper_arm_link's <mass value>
    d = _diagnose(ur10, 15)
    assert d.cannot_size == []


def test_the_answer_is_stable_across_targets_and_held_out_poses(ur10):
    """One answer whichever point of the target frame is read and whichever poses are held out; never a model
    worse than the rigid one on the held-out poses."""
    answers = []
    for n_id in (12, 15, 18):
        d = _diagnose(ur10, n_id)
        assert len(d.per_target) == 3 and d.targets_agree is True, d.targets_evidence
        assert all(t["outcome"] != "not diagnosed" for t in d.per_target)
        if d.validation_after is not None:
            assert d.validation_after["rms"] <= d.validation_before["rms"]
        answers.append((d.outcome, tuple(d.named_effects)))
    assert len(set(answers)) == 1, answers
